"""A learned firing condition: evaluation latency at the control rate, and where it holds.

Speed (target: one evaluation with ≤ 500 support vectors ≤ 20 µs median on one core): a
``LearnedCondition`` is fitted on overlapping data so that it keeps (close to) the cap of 500
support vectors, then ``cond(x)`` — what the net calls every tick — is timed per call, with BLAS
pinned to one thread through threadpoolctl (``_timing.single_thread``). scikit-learn's
``decision_function`` on one sample is timed for comparison.

Where it holds: on synthetic switch data by default; with ``--dataset demos.h5 [--skill pendulum]
[--transition t1] [--names theta omega]`` the condition is learned from the mentor's switches in
all of ``demos.h5`` (``training.fit_switch_condition``, as the repair loop does) and checked on
held-out demos (``--test-dataset more.h5`` and/or ``--record N``, as in ``bench_judges.py``;
without them the last 30 % of ``demos.h5``). Printed, each with a Wilson 95 % interval:

* exact: the fraction of held-out successful switches at whose first sample it holds (all, and
  those with |theta| ≤ 0.15 there);
* windowed (issue 5's "holds within ±0.15 rad of upright at ≥ 90 % of the mentor's held-out
  successful switches"): the fraction of switches for which it holds at some sample within ±0.3 s
  of the switch's first sample at which |theta| ≤ 0.15;
* far: the fraction of held-out samples of the maneuvers before the switch, further than 0.3 s
  from any switch, at which it holds (target ≤ 2 %).

    .venv/bin/python benchmarks/bench_condition.py [--dataset demos.h5 ...] [--results DIR]
"""

import argparse
import sys
import time
from pathlib import Path

import numpy as np

from _results import Record, add_option, at_least, at_most
from _timing import describe, latencies, single_thread
from bench_judges import TEST_SEED, heldout_episodes
from multiform.learn.condition import LearnedCondition
from multiform.learn.fast_svm import FastDecision

ROOT = Path(__file__).resolve().parents[1]


TARGET_US = at_most(20, of="median")


def speed(d: int, rec: Record) -> float:
    rng = np.random.default_rng(0)
    X = rng.normal(size=(6000, d))
    y = X[:, 0] + 0.5 * X[:, 1] ** 2 + rng.normal(0, 0.8, len(X)) > 0.6
    cond = LearnedCondition(tuple(f"v{i}" for i in range(d)), max_support=500).fit(X, y)
    x = X[123].copy()
    # the worst case the cap allows: exactly 500 support vectors (cost depends only on count and d)
    big = LearnedCondition(cond.input_names, max_support=10_000).fit(X[:3000], y[:3000])
    at_cap = LearnedCondition(cond.input_names)
    dec = big.decision_
    at_cap.decision_ = FastDecision(dec.support_vectors[:500], dec.dual_coef[:500], dec.intercept, dec.kernel,
                                    dec.gamma, mean=dec.mean, scale=dec.scale)
    with single_thread():
        fast = latencies(lambda: cond(x), 20_000, batch=10)
        cap = latencies(lambda: at_cap(x), 20_000, batch=10)
        one = X[:1].copy()
        skl = latencies(lambda: cond.estimator_.decision_function(one), 2_000, batch=5)
    print(f"{d}-D input, {cond.n_support_} support vectors (fit rounds: {cond.fit_rounds_})")
    print("  " + describe(f"cond(x), compiled path, {cond.n_support_} SVs", fast))
    print("  " + describe("cond(x), compiled path, exactly 500 SVs", cap))
    print("  " + describe("sklearn Pipeline(StandardScaler, SVC).decision_function, 1 sample", skl))
    print(f"  speed-up {np.median(skl) / np.median(fast):.1f}x")
    rec.latency(f"cond_{d}d", f"learned condition, {d}-D input, {cond.n_support_} support vectors: one evaluation "
                "(compiled path)", fast, target=TARGET_US)
    rec.latency(f"cond_{d}d_500", f"learned condition, {d}-D input, exactly 500 support vectors (the cap): one "
                "evaluation", cap, target=TARGET_US)
    rec.latency(f"cond_{d}d_sklearn", f"the same condition through scikit-learn's decision_function, {d}-D, "
                "1 sample (for comparison)", skl)
    return float(max(np.median(fast), np.median(cap)) * 1e6)


def region_speed(rec: Record) -> float:
    """The region conditions the repair loop adds (t7: "belongs to P1 rather than P2"; "outside every place")."""
    sys.path.insert(0, str(ROOT))
    from multiform.learn.region import PlaceRegions
    from tests.learn.synthetic import place_states

    regions = PlaceRegions(("theta", "omega")).fit(place_states(0, n=1500))
    back, out = regions.condition("P1", rather_than="P2"), regions.outside_condition()
    x = np.array([0.6, 3.0])
    with single_thread():
        lb = latencies(lambda: back(x), 20_000, batch=10)
        lo = latencies(lambda: out(x), 20_000, batch=10)
    print(f"region conditions, 2-D input, mixtures of {regions.components_} components")
    print("  " + describe("into P1 rather than P2", lb))
    print("  " + describe("outside every place", lo))
    mixtures = ", ".join(f"{k} {v}" for k, v in regions.components_.items())
    rec.latency("region_back", f"region condition \"into P1 rather than P2\" (2-D, Gaussian mixtures of {mixtures} "
                "components): one evaluation", lb, target=TARGET_US)
    rec.latency("region_outside", "region condition \"outside every place\": one evaluation", lo, target=TARGET_US)
    return float(max(np.median(lb), np.median(lo)) * 1e6)


def synthetic_accuracy(rec: Record) -> None:
    sys.path.insert(0, str(ROOT))
    from tests.learn.synthetic import switch_data

    train, test = switch_data(0), switch_data(1)
    cond = LearnedCondition(("theta", "omega")).fit_switches(train.positives, train.negatives)
    near, far = cond.holds(test.near), cond.holds(test.negatives)
    print(f"synthetic switches: {cond.n_support_} support vectors; holds at {near.mean():.1%} of "
          f"held-out switch states within ±0.15 rad, at {far.mean():.2%} of held-out far "
          "swing samples")
    section = "components"
    rec.rate("synthetic_near", f"learned condition on synthetic switches ({cond.n_support_} support vectors): holds "
             "at held-out switch states within ±0.15 rad", int(near.sum()), len(near), section=section)
    rec.rate("synthetic_far", "learned condition on synthetic switches: holds at held-out swing samples far from a "
             "switch", int(far.sum()), len(far), section=section)


def dataset_accuracy(path: str, skill: str, transition: str, names: list[str] | None, test: list, near: float,
                     around: float, rec: Record) -> None:
    from multiform.demos.dataset import read_dataset
    from multiform.learn.condition import switch_windows, window_hits
    from multiform.learn.training import fit_switch_condition, switch_variables
    from multiform.learn.views import switch_data
    from multiform.petri.skillfile import load_skill
    from multiform.stats import wilson

    def rate(k: int, n: int) -> str:
        lo, hi = wilson(k, n)
        return f"{k}/{n} = {k / n:.1%} (Wilson 95 % [{lo:.1%}, {hi:.1%}])" if n else "none"

    apn = load_skill(skill)
    eps = list(read_dataset(path).episodes)
    if not test:
        cut = max(1, int(0.7 * len(eps)))
        eps, test = eps[:cut], eps[cut:]
        print(f"{path}: no held-out dataset; training on the first {cut} demos, testing on the other {len(test)}")
    names = list(names or switch_variables(apn, transition))
    t0 = time.perf_counter()
    cond, info = fit_switch_condition(apn, eps, transition, names)      # what the repair loop fits
    print(f"{transition} over {names}: fitted on {len(eps)} demos of {path} in {time.perf_counter() - t0:.1f} s "
          f"({info['mentor_switches']} switches; positives: the first {info['window']} s after each, "
          f"{info['positives']} samples; {info['negatives']} non-switch samples), {info['params']}, "
          f"{cond.n_support_} support vectors; CV: holds in the first {info['moment']} s of "
          f"{info['cv_hit_in_moment']:.1%} of switches, at the first sample of {info['cv_hit_at_switches']:.1%}, "
          f"on {info['cv_holds_far_from_switches']:.2%} of far samples")
    d = switch_data(apn, test, transition, names)
    th = names.index("theta") if "theta" in names else 0
    v = names[th]
    sw = d.switch_states
    at = cond.holds(sw) if len(sw) else np.zeros(0, bool)
    close = np.abs(sw[:, th]) <= near
    print(f"held-out: {len(test)} demos, {len(sw)} successful switches into {transition}")
    print(f"  exact: holds at the switch's first sample (the state the mentor switched in) at "
          f"{rate(int(at.sum()), len(sw))}; of those with |{v}| <= {near} there: {rate(int(at[close].sum()), int(close.sum()))}")
    wins = switch_windows(apn, test, transition, names, before=around, after=around, near=(v, near))
    hit = window_hits(cond, wins)
    has = np.array([len(W) > 0 for _, _, W in wins], dtype=bool)
    print(f"  windowed (target ≥ 90 %): a switch counts as hit when the condition holds at some sample within "
          f"±{around} s of the switch's first sample at which |{v}| <= {near} rad (the robot would switch in the "
          f"window around upright): {rate(int(hit.sum()), len(wins))}; {int((~has).sum())} switch(es) have no such "
          f"sample (counted as misses); of those that have: {rate(int(hit[has].sum()), int(has.sum()))}")
    far = cond.holds(d.negatives) if len(d.negatives) else np.zeros(0, bool)
    print(f"  far (target ≤ 2 %): holds at {rate(int(far.sum()), len(far))} of held-out samples of the maneuvers "
          f"before {transition} further than 0.3 s from any switch")
    what = f"{transition} learned over {', '.join(names)} from {len(eps)} demos, on {len(test)} held-out demos"
    rec.details.update(transition=transition, names=names, training_demos=len(eps), heldout_demos=len(test),
                       support_vectors=cond.n_support_, fit=info)
    rec.rate("exact", f"{what}: holds at the first sample of the mentor's successful switches", int(at.sum()), len(sw),
             section="components")
    rec.rate("windowed", f"{what}: holds within ±{around} s of each switch's first sample at |{v}| ≤ {near}",
             int(hit.sum()), len(wins), target=at_least(0.9), section="components")
    rec.rate("far", f"{what}: holds at samples before {transition} further than 0.3 s from any switch",
             int(far.sum()), len(far), target=at_most(0.02), section="components")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--dataset")
    ap.add_argument("--skill", default="pendulum")
    ap.add_argument("--transition", default="t1")
    ap.add_argument("--names", nargs="+",
                    help="the condition's variables (default: those the repair loop reads, "
                         "training.switch_variables: the judged variables of the place it leaves)")
    ap.add_argument("--test-dataset", help="held-out demos (read, or written by --record)")
    ap.add_argument("--record", type=int, default=0, help="record this many held-out demos")
    ap.add_argument("--test-seed", type=int, default=TEST_SEED, help="first seed of the recorded held-out demos")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--near", type=float, default=0.15, help="rad from upright counted as near")
    ap.add_argument("--around", type=float, default=0.3, help="s either side of a switch in the windowed figure")
    add_option(ap)
    args = ap.parse_args()
    rec = Record(__file__, "A learned firing condition: evaluation latency, and where it holds", section="speed",
                 variant="dataset" if args.dataset else None)
    print("BLAS pinned to one thread (threadpoolctl.threadpool_limits(1))")
    meds = [speed(d, rec) for d in (2, 4)] + [region_speed(rec)]
    print(f"target ≤ 20 µs median: {'met' if max(meds) <= 20 else 'NOT met'} (worst median {max(meds):.2f} µs)")
    if args.dataset:
        test = heldout_episodes(args.test_dataset, args.record, args.test_seed, workers=args.workers)
        dataset_accuracy(args.dataset, args.skill, args.transition, args.names, test, args.near, args.around, rec)
    else:
        synthetic_accuracy(rec)
    rec.write(args.results)


if __name__ == "__main__":
    main()
