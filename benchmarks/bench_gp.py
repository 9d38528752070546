"""GP control law: fit time and one-state latency on the 1 kHz path.

Targets (issue 4): fit with hyperparameters for n = 2,000 ≤ 10 s; one law evaluation for one state
(5 inputs) on one core, over ≥ 10,000 calls — exact GP n = 2,000 mean p99 ≤ 25 µs; sparse GP m = 300
built from n = 50,000, mean + variance p99 ≤ 30 µs. Also prints the exact GP's mean + variance cost
and the n above which `GPLaw` stops computing the variance exactly on the hot path, and the laws'
default fit (seven hyperparameter subsets) in one process against two (`n_jobs=2`).

Data: a smooth nonlinear law of 5 state variables (pendulum-like angle, rate, cart position and
velocity, a phase) with 2 command outputs plus noise — synthetic, so the truth is known.

Usage: .venv/bin/python benchmarks/bench_gp.py [--calls N] [--quick] [--results DIR]
"""

import argparse
import itertools
import os
import time

import numpy as np
from sklearn.base import clone

from _results import Record, add_option, at_most
from _timing import describe, latencies, single_thread
from multiform.learn.gp import GPLaw

NOISE = 0.05


def law(X: np.ndarray) -> np.ndarray:
    th, om, x, xd, ph = X.T
    a = 2.0 * np.sin(th) * np.cos(0.5 * om) - 0.8 * x - 0.4 * xd + 0.3 * np.sin(ph) * om
    b = np.tanh(1.5 * th + 0.5 * om) + 0.2 * x * xd + 0.1 * ph ** 2
    return np.column_stack([a, b])


def sample(n: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    X = np.column_stack([rng.uniform(-np.pi, np.pi, n), rng.uniform(-4, 4, n), rng.uniform(-0.5, 0.5, n),
                         rng.uniform(-1.5, 1.5, n), rng.uniform(-1, 1, n)])
    Y = law(X)
    return X, Y + NOISE * Y.std(axis=0) * rng.normal(size=Y.shape)


def timed(name: str, fn, states: list[np.ndarray], calls: int, repeats: int) -> np.ndarray:
    """Per-call latencies of ``fn`` over states cycled in turn; ``repeats`` runs of ``calls`` calls,
    the run with the lowest p99 (least disturbed by other processes) is printed in full, and the
    worst run's p99 beside it."""
    runs = []
    for _ in range(repeats):
        it = itertools.cycle(states)
        runs.append(latencies(lambda: fn(next(it)), calls=calls, warmup=1000))
    runs.sort(key=lambda t: np.percentile(t, 99))
    best = runs[0]
    extra = f"; best of {repeats} runs, worst run p99 {np.percentile(runs[-1], 99) * 1e6:.2f} µs" if repeats > 1 else ""
    print("  " + describe(name, best) + extra)
    return best


def calibration(calls: int) -> float:
    """Median µs of the FACTS.md reference — one numpy ``exp(K(x, X)) @ alpha`` over n = 5,000
    samples with 4 inputs, ≈ 14 µs median when measured on a quiet machine of this kind."""
    rng = np.random.default_rng(1)
    Xr, a, x = rng.normal(size=(5000, 4)), rng.normal(size=5000), rng.normal(size=4)
    sq = 0.5 * np.einsum("ij,ij->i", Xr, Xr)
    return float(np.median(latencies(lambda: np.exp(Xr @ x - sq - 0.5 * x @ x) @ a, calls=calls)) * 1e6)


def avx512() -> bool:
    try:
        from numpy._core._multiarray_umath import __cpu_features__
    except ImportError:
        return False
    return bool(__cpu_features__.get("AVX512F"))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--calls", type=int, default=20_000)
    ap.add_argument("--repeats", type=int, default=3, help="runs per latency figure (best one printed)")
    ap.add_argument("--quick", action="store_true", help="skip the n = 50,000 sparse fit")
    add_option(ap)
    args = ap.parse_args()
    rec = Record(__file__, "GP control law: fit time and one-state latency", section="speed",
                 variant="quick" if args.quick else None)
    rng = np.random.default_rng(0)
    Xt, Yt = sample(2000, rng)
    Yt_true = law(Xt)
    states = [Xt[i].copy() for i in range(1000)]
    print(f"machine: {os.cpu_count()} cores, load average {os.getloadavg()[0]:.2f} "
          f"(other work on a shared machine inflates every figure)")
    exact, X, Y = fit_exact(rng, Xt, Yt_true, rec)
    side_by_side(rng, rec)
    one_state(exact, X, Y, Xt, states, rng, args, rec)
    if not args.quick:
        sparse_section(rng, Xt, Yt_true, states, args, rec)
        print(f"\nload average at the end: {os.getloadavg()[0]:.2f} (1 min), {os.getloadavg()[1]:.2f} (5 min)")
    rec.write(args.results)


def fit_exact(rng: np.random.Generator, Xt: np.ndarray, Yt_true: np.ndarray,
              rec: Record) -> tuple[GPLaw, np.ndarray, np.ndarray]:
    """The exact law on 2,000 points: fit time, hyperparameters, held-out error."""
    print("\n== fit with hyperparameters, n = 2,000, 5 inputs, 2 outputs (defaults: ARD, n_hyper=1000, "
          "2 restarts on a 300-point probe, fitting pinned to 1 BLAS thread) ==")
    X, Y = sample(2000, rng)
    t0 = time.perf_counter()
    exact = GPLaw(input_names=["theta", "omega", "x", "xdot", "phase"], output_names=["ax", "az"]).fit(X, Y)
    fit_s = time.perf_counter() - t0
    exact.record_heldout_error(Xt, Yt_true)
    s = exact.summary()
    print(f"  fit: {fit_s:.2f} s (target ≤ 10 s: {'met' if fit_s <= 10 else 'NOT met'})")
    print(f"  mode {s['mode']}, variance {s['var_mode']} ({s['n_inducing']} inducing points); "
          f"σf {s['sigma_f']:.3g}, noise {s['noise']:.3g} (standardised)")
    print("  length scales: " + ", ".join(f"{k} {v:.3g}" for k, v in s["length_scale"].items()))
    print("  held-out nRMSE vs the noiseless law: " + ", ".join(f"{v:.4f}" for v in s["heldout_nrmse"]))
    rec.figure("fit_exact", "GP law fit with hyperparameters, n = 2,000, 5 inputs, 2 outputs", fit_s, "s",
               target=at_most(10))
    rec.figure("nrmse_exact", "GP law, exact n = 2,000 (a synthetic 5-input law): held-out NRMSE against the "
               "noiseless law, per output", max(s["heldout_nrmse"]), "", values={name: v for name, v in zip(("ax", "az"), s["heldout_nrmse"])},
               section="components")
    return exact, X, Y


def side_by_side(rng: np.random.Generator, rec: Record) -> None:
    """The laws' default fit (seven hyperparameter subsets of 1,000 points, one restart, sparse
    posterior: :class:`~multiform.learn.training.LawSettings`) on 5,000 points, in one process and with
    ``n_jobs=2``: the speed-up, and that every fitted number is the same."""
    from multiform.learn.training import LawSettings
    s = LawSettings()
    X, Y = sample(5000, rng)
    kw = dict(n_hyper=s.n_hyper, n_restarts=s.n_restarts, sparse_threshold=s.sparse_threshold,
              n_inducing=s.n_inducing, subset_noise=s.subset_noise, hyper_subsets=s.hyper_subsets, random_state=0)
    print(f"\n== the laws' default fit ({s.hyper_subsets} hyperparameter subsets), n = 5,000: one process "
          "against two (n_jobs=2) ==")
    GPLaw(**kw, n_jobs=2).fit(X[:200], Y[:200])        # the worker processes start once, before timing
    times, fits = {}, {}
    for n_jobs in (1, 2):
        t0 = time.perf_counter()
        fits[n_jobs] = GPLaw(**kw, n_jobs=n_jobs).fit(X, Y)
        times[n_jobs] = time.perf_counter() - t0
    same = all(np.array_equal(getattr(fits[1], a), getattr(fits[2], a))
               for a in ("length_scale_", "sigma_f_", "noise_", "alpha_"))
    ratio = times[1] / times[2]
    print(f"  one process {times[1]:.1f} s, two {times[2]:.1f} s: {ratio:.2f}× faster; the same law bit for bit: {same}")
    label = "the laws' default fit (7 hyperparameter subsets), n = 5,000"
    rec.figure("fit_one_process", f"{label}, one process", round(times[1], 2), "s")
    rec.figure("fit_two_processes", f"{label}, two processes (n_jobs=2)", round(times[2], 2), "s")
    rec.figure("fit_side_by_side", f"{label}: one process's time over two processes'", round(ratio, 2), "×")
    rec.figure("fit_side_by_side_same", f"{label}: two processes give the same law bit for bit", same)


def one_state(exact: GPLaw, X: np.ndarray, Y: np.ndarray, Xt: np.ndarray, states: list[np.ndarray],
              rng: np.random.Generator, args: argparse.Namespace, rec: Record) -> None:
    """Latency of one state's mean and variance, exact laws of 250 to 2,000 points."""
    theta = np.concatenate([np.log(exact.length_scale_), [np.log(exact.sigma_f_), np.log(exact.noise_)]])
    print("\n== one state, one core (BLAS pinned to 1 thread with threadpoolctl), "
          f"{args.calls} calls each ==")
    with single_thread():
        ref = calibration(5000)
        best = f"the run with the lowest p99 of {args.repeats}"
        rec.figure("calibration", "calibration: a plain-numpy GP mean (n = 5,000, 4 inputs), ≈ 14 µs median on a "
                   "quiet machine of this kind", ref, "µs")
        print(f"  calibration: FACTS.md's plain-numpy GP mean (n=5000, 4-D) was ≈ 14 µs median where it was "
              f"measured; here {ref:.1f} µs ({ref / 14:.1f}×). numpy's float64 exp is "
              f"{'SIMD (AVX-512)' if avx512() else 'scalar here (no AVX-512 on this CPU), ≈ 5 ns a point'}, "
              "and the exp of every training point dominates the exact mean")
        ref = clone(exact).set_params(fast_exp=False, theta=theta).fit(X, Y)
        Xq = np.vstack([Xt, Xt + Xt.std(0) * rng.uniform(0.5, 5, (len(Xt), 1)) * rng.normal(size=Xt.shape)])
        dev = max(np.max(np.abs(exact.predict_one(x) - ref.predict_one(x)) / exact.y_scale_) for x in Xq)
        print(f"  float32 kernel exponentials: {'on' if exact.fast_exp_ else 'off'} (probe-measured deviation "
              f"{exact.fast_exp_error_:.2e} of y scale; admitted ≤ 2e-4); max deviation from the float64 path "
              f"over {len(Xq)} states near and up to 5 std away: {dev:.2e} of y scale")
        t = timed("exact n=2000, mean only (predict_one)", exact.predict_one, states, args.calls, args.repeats)
        p99 = np.percentile(t, 99) * 1e6
        print(f"  target p99 ≤ 25 µs: {'met' if p99 <= 25 else 'NOT met'} ({p99:.2f} µs)")
        rec.latency("exact_mean", "GP law, one state on one core: exact n = 2,000, mean only", t,
                    target=at_most(25, of="p99"), note=best)
        t = timed("exact n=2000, mean only, float64 exponentials (fast_exp=False)", ref.predict_one, states,
                  args.calls, args.repeats)
        rec.latency("exact_mean_f64", "GP law, exact n = 2,000, mean only, float64 kernel exponentials", t, note=best)
        t = timed(f"exact n=2000 mean + variance through its FITC companion (default, n > "
                  f"exact_var_max_n={exact.exact_var_max_n})", exact.predict_one_var, states, args.calls, args.repeats)
        rec.latency("exact_mean_var", "GP law, exact n = 2,000, mean + variance (through its FITC companion)", t,
                    note=best)
        for n in (250, 500, 1000, 2000):
            full = GPLaw(sparse_threshold=None, exact_var_max_n=None, theta=theta).fit(X[:n], Y[:n])
            t = timed(f"exact n={n} mean + exact variance (O(n²) triangular solve)", full.predict_one_var,
                      states, min(args.calls, 10_000), args.repeats)
            rec.latency(f"exact_var_{n}", f"GP law, exact n = {n:,}, mean + exact variance", t, note=best)
        print(f"  → GPLaw computes the variance exactly on the hot path up to n = {exact.exact_var_max_n} "
              "(exact_var_max_n); above, through a FITC companion on n_inducing points (O(m²)).")


def sparse_section(rng: np.random.Generator, Xt: np.ndarray, Yt_true: np.ndarray, states: list[np.ndarray],
                   args: argparse.Namespace, rec: Record) -> None:
    """The sparse law on 50,000 points: fit time, held-out error, latency."""
    print("\n== sparse GP: n = 50,000, m = 300 inducing points (k-means), FITC ==")
    Xb, Yb = sample(50_000, rng)
    t0 = time.perf_counter()
    sparse = GPLaw(n_inducing=300).fit(Xb, Yb)
    fit_s = time.perf_counter() - t0
    sparse.record_heldout_error(Xt, Yt_true)
    ss = sparse.summary()
    print(f"  fit (hyperparameters on 1,000 points + k-means + FITC on 50,000): {fit_s:.2f} s; mode "
          f"{ss['mode']}, held-out nRMSE " + ", ".join(f"{v:.4f}" for v in ss["heldout_nrmse"]))
    rec.figure("fit_sparse", "sparse GP fit, n = 50,000, m = 300 inducing points (hyperparameters on 1,000 points "
               "+ k-means + FITC)", fit_s, "s")
    rec.figure("nrmse_sparse", "GP law, sparse m = 300 from n = 50,000 (the same synthetic law): held-out NRMSE, "
               "per output", max(ss["heldout_nrmse"]), "", values={name: v for name, v in zip(("ax", "az"), ss["heldout_nrmse"])},
               section="components")
    best = f"the run with the lowest p99 of {args.repeats}"
    with single_thread():
        print(f"  float32 exponentials for the sparse mean: {'on' if sparse.fast_exp_ else 'off'} (probe-measured "
              f"deviation {sparse.fast_exp_error_:.2e} of y scale: FITC weights up to "
              f"{np.abs(sparse.beta_).max():.2g} cancel); the variance is float64 in every mode")
        t = timed("sparse m=300, mean only", sparse.predict_one, states, args.calls, args.repeats)
        rec.latency("sparse_mean", "GP law, one state on one core: sparse m = 300, mean only", t, note=best)
        t = timed("sparse m=300, mean + variance (predict_one_var)", sparse.predict_one_var, states, args.calls, args.repeats)
        p99 = np.percentile(t, 99) * 1e6
        print(f"  target p99 ≤ 30 µs: {'met' if p99 <= 30 else 'NOT met'} ({p99:.2f} µs)")
        rec.latency("sparse_mean_var", "GP law, one state on one core: sparse m = 300, mean + variance", t,
                    target=at_most(30, of="p99"), note=best)


if __name__ == "__main__":
    main()
