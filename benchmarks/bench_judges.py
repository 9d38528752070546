"""Judges: held-out accuracy, the kernel chosen per judge and the cross-validated score of every kernel.

Default: synthetic pendulum-like segments (``tests/learn/synthetic.py``; success depends
nonlinearly on the end state and on extrema), 120 labelled segments per judge for training and 300
unseen ones for testing.

With ``--dataset demos.h5 [--skill pendulum]``: one judge per place that has ``judge`` variables
in the skill is fitted as the main job fits it (``training.fit_judge`` on the mentor's labels of
every demo of ``demos.h5``, one label per place stay) and tested on the mentor's labels of
held-out demonstrations the judge never saw:

* ``--test-dataset more.h5``: the demos of another dataset;
* ``--record N [--test-seed S]``: N new demos recorded here with the task's scripted mentor on
  seeds S, S+1, … (default S = 7,000,000, far from the main job's seeds ``seed * 100000 + i``),
  written to ``--test-dataset`` when that is given (and reused when it already holds N demos);
* neither: the last ``1 - split`` of ``demos.h5`` (few segments: no figure worth much).

Per judge it prints the kernel chosen, the CV score of every kernel of the pool, the held-out
accuracy with its Wilson 95 % interval, the confusion counts (mentor success = positive) and, with
``--errors``, the misclassified segments (end state, duration, score, the mentor's sub-labels).
Issue 5 asks ≥ 95 %.

    .venv/bin/python benchmarks/bench_judges.py --dataset runs/pendulum/demos.h5 --record 300 \\
        --test-dataset runs/heldout.h5 [--results DIR]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import Any


from _results import Record, add_option, at_least
from multiform.learn.judge import Judge

ROOT = Path(__file__).resolve().parents[1]
TEST_SEED = 7_000_000


def report(place: str, judge: Judge, acc: float, n_test: int, seconds: float) -> None:
    print(f"== {place}: fitted in {seconds:.1f} s")
    print(judge.summary())
    print(f"   held-out accuracy {acc:.3f} on {n_test} segments; kernel chosen: {judge.best_kernel_} "
          f"on the '{judge.pool_.best_subset_}' features")


def synthetic(rec: Record) -> None:
    sys.path.insert(0, str(ROOT))
    from tests.learn.synthetic import balanced_segments

    for place in ("P1", "P2"):
        train, y = balanced_segments(place, 120, 1)
        test, yt = balanced_segments(place, 300, 2)
        t0 = time.perf_counter()
        j = Judge(place, ("theta", "omega", "x")).fit(train, y)
        right = int((j.predict(test) == yt).sum())
        seconds = time.perf_counter() - t0
        report(place, j, right / len(yt), len(yt), seconds)
        rec.rate(f"synthetic_{place}", f"judge of {place} on synthetic pendulum-like segments (120 to train): "
                 "held-out accuracy", right, len(yt),
                 extra={"kernel": j.best_kernel_, "fit_s": round(seconds, 1)})


def heldout_episodes(test_dataset: str | None, record: int, seed: int, task: str = "pendulum",
                     workers: int = 2) -> list[Any]:
    """The held-out demonstrations: read ``test_dataset``, or record ``record`` new ones on seeds
    ``seed``, ``seed + 1``, … (saved to ``test_dataset`` when given). Empty when neither is asked."""
    from multiform.demos.dataset import read_dataset, write_dataset
    from multiform.task import load_task

    if test_dataset and Path(test_dataset).exists():
        eps = list(read_dataset(test_dataset).episodes)
        if not record or len(eps) == record:
            print(f"held-out demos: {len(eps)} from {test_dataset}")
            return eps
    if not record:
        return []
    from multiform.teach.record import record_many

    t = load_task(task)
    seeds = [seed + i for i in range(record)]
    t0 = time.perf_counter()
    eps = record_many(t.TASK, seeds, t.DEMO_ENV_KWARGS, workers=workers)
    print(f"held-out demos: recorded {len(eps)} on seeds {seeds[0]}..{seeds[-1]} in {time.perf_counter() - t0:.0f} s "
          f"({workers} workers); mentor succeeded in {sum(e.outcome == 'success' for e in eps)}")
    if test_dataset:
        Path(test_dataset).parent.mkdir(parents=True, exist_ok=True)
        write_dataset(test_dataset, eps, t.SKILL, t.ENV_ID, t.DEMO_ENV_KWARGS,
                      mentor=getattr(eps[0], "mentor", "") if eps else "")
        print(f"  written to {test_dataset}")
    return eps


def _interval(k: int, n: int) -> str:
    from multiform.stats import wilson

    lo, hi = wilson(k, n)
    return f"{k}/{n} = {k / n:.1%} (Wilson 95 % [{lo:.1%}, {hi:.1%}])" if n else "no segments"


def dataset(path: str, skill: str, split: float, test: list[Any], seed: int, errors: bool, rec: Record) -> None:
    from multiform.demos.dataset import read_dataset
    from multiform.learn.labels import LabelStore
    from multiform.learn.training import demo_segments, fit_judge, judged_places, mentor_records
    from multiform.petri.skillfile import load_skill

    apn = load_skill(skill)
    eps = list(read_dataset(path).episodes)
    if not test:
        cut = max(1, int(split * len(eps)))
        eps, test = eps[:cut], eps[cut:]
        print(f"{path}: no held-out dataset given; training on the first {cut} demos, testing on the last "
              f"{len(test)} (too few to say much: use --record or --test-dataset)")
    store = LabelStore()
    store.add_many(mentor_records(apn, eps))
    test_records = mentor_records(apn, test)
    print(f"training: {len(eps)} demos of {path} ({len(store)} labelled place stays), as the main job fits them; "
          f"held-out: {len(test)} demos ({len(test_records)} labelled place stays)")
    for place, variables in judged_places(apn).items():
        t0 = time.perf_counter()
        try:
            judge, info = fit_judge(apn, eps, store, place, seed=seed, heldout=0)
        except ValueError as exc:
            print(f"== {place}: {exc}")
            continue
        seconds = time.perf_counter() - t0
        segs, y = demo_segments(apn, test, [r for r in test_records if r.place == place], variables)
        if not len(y):
            print(f"== {place}: no held-out segments")
            continue
        score = judge.grade_many(segs)
        pred = score >= 0.5
        tp, fn = int((pred & y).sum()), int((~pred & y).sum())
        fp, tn = int((pred & ~y).sum()), int((~pred & ~y).sum())
        print(f"== {place}: fitted in {seconds:.1f} s on {info['segments']} segments "
              f"({info['success_labels']} success)")
        print(judge.summary())
        print(f"   kernel chosen: {judge.best_kernel_} {judge.pool_.best_params_} on the "
              f"'{judge.pool_.best_subset_}' features "
              f"({', '.join(judge.feature_names_[c] for c in judge.pool_.columns_)})")
        print(f"   held-out accuracy {_interval(tp + tn, len(y))}  (target ≥ 95 %)")
        rec.rate(f"heldout_{place}", f"judge of {place} ({skill}), trained on {len(eps)} demos' labels, on "
                 f"{len(test)} held-out demos: accuracy", tp + tn, len(y), target=at_least(0.95),
                 counts={"on the mentor's successes": [tp, tp + fn], "on its failures": [tn, tn + fp]},
                 extra={"kernel": judge.best_kernel_, "features": judge.pool_.best_subset_})
        print(f"   confusion (mentor success = positive): TP {tp}  FN {fn}  FP {fp}  TN {tn}; "
              f"on the mentor's successes {_interval(tp, tp + fn)}, on its failures {_interval(tn, tn + fp)}")
        if errors:
            for s, lab, p in zip(segs, y, score):
                if (p >= 0.5) == lab:
                    continue
                ep = test[int(s.source.split("_")[1])]
                sub = ", ".join(f"{l.transition}:{'ok' if l.success else 'FAIL'}" for l in ep.labels
                                if l.start < s.end and l.end > s.start)
                end = " ".join(f"{n}={v:+.2f}" for n, v in zip(s.names, s.values[-1]))
                print(f"     {s.source} (seed {ep.seed}) mentor {'success' if lab else 'failure'}, score {p:.2f}: "
                      f"end {end}, {s.duration:.2f} s; mentor's labels {sub}; start options {ep.reset_options}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--dataset", help="training demos (the main job's demos.h5)")
    ap.add_argument("--skill", default="pendulum")
    ap.add_argument("--test-dataset", help="held-out demos (read, or written by --record)")
    ap.add_argument("--record", type=int, default=0, help="record this many held-out demos")
    ap.add_argument("--test-seed", type=int, default=TEST_SEED, help="first seed of the recorded held-out demos")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--split", type=float, default=0.7, help="without held-out demos: fraction of demos for training")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--errors", action="store_true", help="list the misclassified held-out segments")
    add_option(ap)
    args = ap.parse_args()
    rec = Record(__file__, "Judges: held-out accuracy", section="components",
                 variant="dataset" if args.dataset else "synthetic")
    if args.dataset:
        test = heldout_episodes(args.test_dataset, args.record, args.test_seed, workers=args.workers)
        dataset(args.dataset, args.skill, args.split, test, args.seed, args.errors, rec)
    else:
        synthetic(rec)
    rec.write(args.results)


if __name__ == "__main__":
    main()
