"""A learned firing condition: evaluation latency at the control rate, and where it holds.

Speed (target: one evaluation with ≤ 500 support vectors ≤ 20 µs median on one core): a
``LearnedCondition`` is fitted on overlapping data so that it keeps (close to) the cap of 500
support vectors, then ``cond(x)`` — what the net calls every tick — is timed per call, with BLAS
pinned to one thread through threadpoolctl (``_timing.single_thread``). scikit-learn's
``decision_function`` on one sample is timed for comparison.

Where it holds: on synthetic switch data by default; with ``--dataset demos.h5 [--skill pendulum]
[--transition t1] [--names theta omega]`` the condition is learned from the mentor's switches in the
first 70 % of the demonstrations (``training.fit_switch_condition``, as the repair loop does) and checked on the rest: the fraction of
held-out successful switches within ±0.15 rad of upright where it holds, and the fraction of
held-out swing samples far from a switch where it holds.

    .venv/bin/python benchmarks/bench_condition.py [--dataset demos.h5 ...]
"""

import argparse
import sys
from pathlib import Path

import numpy as np

from _timing import describe, latencies, single_thread
from multiform.learn.condition import LearnedCondition
from multiform.learn.fast_svm import FastDecision

ROOT = Path(__file__).resolve().parents[1]


def speed(d: int) -> float:
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
    print("  " + describe(f"cond(x), numpy fast path, {cond.n_support_} SVs", fast))
    print("  " + describe("cond(x), numpy fast path, exactly 500 SVs", cap))
    print("  " + describe("sklearn Pipeline(StandardScaler, SVC).decision_function, 1 sample", skl))
    print(f"  speed-up {np.median(skl) / np.median(fast):.1f}x")
    return float(max(np.median(fast), np.median(cap)) * 1e6)


def region_speed() -> float:
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
    return float(max(np.median(lb), np.median(lo)) * 1e6)


def synthetic_accuracy() -> None:
    sys.path.insert(0, str(ROOT))
    from tests.learn.synthetic import switch_data

    train, test = switch_data(0), switch_data(1)
    cond = LearnedCondition(("theta", "omega")).fit_switches(train.positives, train.negatives)
    print(f"synthetic switches: {cond.n_support_} support vectors; holds at {cond.holds(test.near).mean():.1%} of "
          f"held-out switch states within ±0.15 rad, at {cond.holds(test.negatives).mean():.2%} of held-out far "
          "swing samples")


def dataset_accuracy(path: str, skill: str, transition: str, names: list[str]) -> None:
    from multiform.demos.dataset import read_dataset
    from multiform.learn.views import switch_data
    from multiform.petri.skillfile import load_skill

    apn = load_skill(skill)
    eps = list(read_dataset(path).episodes)
    cut = max(1, int(0.7 * len(eps)))
    train, test = switch_data(apn, eps[:cut], transition, names), switch_data(apn, eps[cut:], transition, names)
    from multiform.learn.training import fit_switch_condition
    cond, _ = fit_switch_condition(apn, eps[:cut], transition, names)      # what the repair loop fits
    th = names.index("theta") if "theta" in names else 0
    near = test.switch_states[np.abs(test.switch_states[:, th]) <= 0.15]
    hold = cond.holds(near).mean() if len(near) else float("nan")
    every = cond.holds(test.switch_states).mean() if len(test.switch_states) else float("nan")
    far = cond.holds(test.negatives).mean() if len(test.negatives) else float("nan")
    print(f"{path}: {transition} over {names}, trained on {cut} demos ({len(train.positives)} switch / "
          f"{len(train.negatives)} non-switch samples), {cond.n_support_} support vectors")
    print(f"  holds at {hold:.1%} of {len(near)} held-out successful switches within ±0.15 rad (target ≥ 90 %); "
          f"at {every:.1%} of all {len(test.switch_states)} held-out successful switches (the mentor switches "
          f"up to 0.4 rad from upright)")
    print(f"  holds at {far:.2%} of {len(test.negatives)} held-out swing samples far from a switch (target ≤ 2 %)")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--dataset")
    ap.add_argument("--skill", default="pendulum")
    ap.add_argument("--transition", default="t1")
    ap.add_argument("--names", nargs="+", default=["theta", "omega", "x"],
                    help="the condition's variables (the repair loop uses the judged variables of P1)")
    args = ap.parse_args()
    print("BLAS pinned to one thread (threadpoolctl.threadpool_limits(1))")
    meds = [speed(d) for d in (2, 4)] + [region_speed()]
    print(f"target ≤ 20 µs median: {'met' if max(meds) <= 20 else 'NOT met'} (worst median {max(meds):.2f} µs)")
    if args.dataset:
        dataset_accuracy(args.dataset, args.skill, args.transition, args.names)
    else:
        synthetic_accuracy()


if __name__ == "__main__":
    main()
