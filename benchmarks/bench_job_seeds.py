"""The main job's spread over seeds: the same pipeline (record the mentor's demos, train, practise
with repair through both scenarios) run from several job seeds, each final skill evaluated on the
same randomised trials (half of them pushed). One seed's success rate says little about the method:
the demos, the learned conditions and the repairs the practice loop makes all follow the seed.

Prints, per seed: the revisions each scenario made, the final
success rate with its Wilson 95 % interval (unpushed / pushed), the practice trials (and how many
took the mentor's time) and the robot's time in practice, and how the failures ended; then the
median and range over seeds. No ablations, videos or report (``multiform demo`` does those).
The figures also go to ``benchmarks/results/bench_job_seeds_<task>.json`` (``--results DIR``).

    .venv/bin/python benchmarks/bench_job_seeds.py --out runs/seeds --seeds 0 1 2 [--trials 200]
        [--demos 5] [--practice '{"deliberate": true}'] [--kinesthetic] [--practice-seed-offset 1000]

``--demos``, ``--kinesthetic`` (the mentor guides the arm by hand) and ``--practice`` (PracticeConfig
settings over every scenario's own, as ``multiform demo --practice``) make a variant of the job; its
figures are recorded under a name of their own. ``--practice-seed-offset K`` changes nothing but the
trials practice draws (``multiform demo --practice-seed``): the same demonstrations, training and
evaluation trials. Run beside a change to practice, it says how far a result moves by luck alone.

About 6 minutes per seed on this 2-core machine with 200 trials. Each seed's run folder
(``OUT/seed_N``) is kept; a folder that already holds a finished seed is reused.
"""

from __future__ import annotations

import argparse
import collections
import json
import os
import statistics
import sys
import time
import warnings
from pathlib import Path

# as `multiform demo` runs (cli.py): one BLAS thread per process, so seed 0 here is the README's job
# bit for bit (a multi-threaded BLAS rounds differently, and a trained skill follows its rounding)
for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")
os.environ.setdefault("MUJOCO_GL", "egl")
# scikit-learn's per-fold notes when a judge's CV fold holds one class only (the scores stay defined)
warnings.filterwarnings("ignore", message="A single label was found", category=UserWarning)
warnings.filterwarnings("ignore", message="y_pred contains classes not in y_true", category=UserWarning)

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _results import Record, add_option, at_least  # noqa: E402
from multiform.evaluation import Variant, evaluate  # noqa: E402
from multiform.io import read_json, write_json  # noqa: E402
from multiform.job import Job, JobConfig  # noqa: E402
from multiform.model import SkillModel  # noqa: E402
from multiform.stats import wilson  # noqa: E402
from multiform.task import load_task  # noqa: E402


def one_seed(task: str, out: Path, seed: int, trials: int, eval_seed: int, workers: int,
             demos: int | None = None, practice: dict | None = None, kinesthetic: bool | None = None,
             practice_seed: int | None = None) -> dict:
    done = out / "seed_result.json"
    if done.exists():
        res = read_json(done, "seed result")
        if "practice_trials" in res:          # a result written before practice was counted: finish it again
            return res
    job = Job(task, out, JobConfig(seed=seed, workers=workers, demos=demos, practice=practice or {},
                                   kinesthetic=kinesthetic, practice_seed=practice_seed),
              log=lambda *a: None, progress=False)
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    demos = job.record()
    model = SkillModel(out / "model") if (out / "model" / "model.json").exists() else job.train(demos)
    practice = job.practise(model)
    model = SkillModel(out / "model")
    specs = job.task.evaluation_specs(trials, eval_seed, job.cfg.push_fraction)
    r = evaluate(job.task.TASK, Variant("final", str(model.path)), specs, workers)
    detail = r["trials_detail"]
    unpushed = [t for t in detail if not t["pushed"]]
    res = {"seed": seed, "revisions": {k: [f"{v['operator']} {v['target']}" for v in p["revisions"]] for k, p in practice.items()},
           "successes": r["successes"], "trials": r["trials"],
           "unpushed": [sum(t["success"] for t in unpushed), len(unpushed)],
           "pushed": [r["pushed"]["successes"], r["pushed"]["trials"]] if r.get("pushed") else [0, 0],
           "failures": dict(collections.Counter(t["outcome"] for t in detail if not t["success"])),
           "practice_trials": sum(p["trials"] for p in practice.values()),
           "robot_seconds": round(sum(p["robot_seconds"] for p in practice.values()), 1),
           "mentor_labelled_trials": sum(p.get("mentor_labelled_trials", 0) for p in practice.values()),
           "minutes": round((time.perf_counter() - t0) / 60, 1)}
    write_json(done, res)
    return res


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--task", default="pendulum")
    ap.add_argument("--out", required=True, help="folder for one run folder per seed")
    ap.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    ap.add_argument("--trials", type=int, default=200, help="evaluation trials per seed")
    ap.add_argument("--eval-seed", type=int, default=0, help="the evaluation trials every seed's skill meets")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--demos", type=int, default=None, help="demonstrations per job (default: the task's)")
    ap.add_argument("--practice", type=json.loads, default={}, metavar="JSON",
                    help="practice settings over every scenario's own, e.g. '{\"deliberate\": true}'")
    ap.add_argument("--kinesthetic", action="store_true",
                    help="the mentor guides the arm by hand (as `multiform demo --kinesthetic`)")
    ap.add_argument("--practice-seed-offset", type=int, default=0, metavar="K",
                    help="job seed S practises on the trial draws of seed S + K, all else the same: the spread "
                         "over K is what the result owes to the trials practice happened to draw")
    ap.add_argument("--target", type=float, default=None,
                    help="the success rate every seed must reach (default: the task's TARGET_SUCCESS_RATE)")
    add_option(ap)
    args = ap.parse_args()
    task = load_task(args.task)
    target = task.TARGET_SUCCESS_RATE if args.target is None else args.target
    variant = (task.TASK + (f"_{args.demos}_demos" if args.demos else "") + ("_kinesthetic" if args.kinesthetic else "")
               + "".join(f"_{k}_{str(v).lower()}" for k, v in sorted(args.practice.items()))
               + (f"_practice_seed_plus_{args.practice_seed_offset}" if args.practice_seed_offset else ""))
    rec = Record(__file__, "The main job's spread over job seeds", section="seeds", variant=variant)
    rows = []
    for seed in args.seeds:
        r = one_seed(args.task, Path(args.out) / f"seed_{seed}", seed, args.trials, args.eval_seed, args.workers,
                     args.demos, args.practice, args.kinesthetic or None,
                     seed + args.practice_seed_offset if args.practice_seed_offset else None)
        rows.append(r)
        lo, hi = wilson(r["successes"], r["trials"])
        print(f"seed {seed}: {100 * r['successes'] / r['trials']:.1f} % ({r['successes']}/{r['trials']}; "
              f"{100 * lo:.1f}-{100 * hi:.1f} %), unpushed {r['unpushed'][0]}/{r['unpushed'][1]}, "
              f"pushed {r['pushed'][0]}/{r['pushed'][1] or 'none'}; practice {r['practice_trials']} trials "
              f"({r['mentor_labelled_trials']} with the mentor, {r['robot_seconds']:.0f} s of robot time); "
              f"failures {r['failures'] or '-'}; {r['minutes']} min", flush=True)
        for name, revs in r["revisions"].items():
            print(f"    {name}: {', '.join(revs) or 'no revision'}")
    if rows:
        rates = [r["successes"] / r["trials"] for r in rows]
        print(f"over {len(rates)} seeds: median {100 * statistics.median(rates):.1f} %, "
              f"range {100 * min(rates):.1f}-{100 * max(rates):.1f} % "
              f"(target ≥ {100 * target:.0f} % for every seed); robot time in practice: median "
              f"{statistics.median(r['robot_seconds'] for r in rows):.0f} s, "
              f"most {max(r['robot_seconds'] for r in rows):.0f} s")
        record_seeds(rec, task, rows, args.eval_seed, target,
                     task.TASK + (f" from {args.demos} demonstrations" if args.demos else "")
                     + (" taught kinesthetically" if args.kinesthetic else "")
                     + (f", practice drawn from job seed + {args.practice_seed_offset}"
                        if args.practice_seed_offset else ""))
        rec.write(args.results)


def record_seeds(rec: Record, task, rows: list[dict], eval_seed: int, target: float, name: str = "") -> None:
    """Each seed's final success (unpushed / pushed, practice trials, robot time in practice), then the
    median and range over the seeds, against ``target`` for every seed; ``name`` (default: the task's)
    heads every figure."""
    name = name or task.TASK
    for r in rows:
        rec.rate(f"seed_{r['seed']}", f"{name}, job seed {r['seed']}: the final skill on {r['trials']} "
                 f"evaluation trials (evaluation seed {eval_seed})", r["successes"], r["trials"],
                 target=at_least(target), counts={"unpushed": r["unpushed"], "pushed": r["pushed"]},
                 extra={"practice_trials": r["practice_trials"], "mentor_labelled_trials": r["mentor_labelled_trials"],
                        "robot_seconds_in_practice": r["robot_seconds"]})
    rates = [r["successes"] / r["trials"] for r in rows]
    rec.figure("median", f"{name}: median over job seeds {', '.join(str(r['seed']) for r in rows)}",
               statistics.median(rates), "%", values={"median": statistics.median(rates), "min": min(rates),
                                                       "max": max(rates)},
               target=at_least(target, of="min", text=f"every seed ≥ {100 * target:g} %"))
    rec.details["seeds"] = rows


if __name__ == "__main__":
    main()
