"""The main job's spread over seeds: the same pipeline (record the mentor's demos, train, practise
with repair through both scenarios) run from several job seeds, each final skill evaluated on the
same randomised trials (half of them pushed). One seed's success rate says little about the method:
the demos, the learned conditions and the repairs the practice loop makes all follow the seed.

Prints, per seed: the revisions each scenario made, the final
success rate with its Wilson 95 % interval (unpushed / pushed), and how the failures ended; then the
median and range over seeds. No ablations, videos or report (``multiform demo`` does those).

    .venv/bin/python benchmarks/bench_job_seeds.py --out runs/seeds --seeds 0 1 2 [--trials 200]

About 6 minutes per seed on this 2-core machine with 200 trials. Each seed's run folder
(``OUT/seed_N``) is kept; a folder that already holds a finished seed is reused.
"""

from __future__ import annotations

import argparse
import collections
import os
import statistics
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

from multiform.evaluation import Variant, evaluate  # noqa: E402
from multiform.io import read_json, write_json  # noqa: E402
from multiform.job import Job, JobConfig  # noqa: E402
from multiform.model import SkillModel  # noqa: E402
from multiform.stats import wilson  # noqa: E402


def one_seed(task: str, out: Path, seed: int, trials: int, eval_seed: int, workers: int) -> dict:
    done = out / "seed_result.json"
    if done.exists():
        return read_json(done, "seed result")
    job = Job(task, out, JobConfig(seed=seed, workers=workers), log=lambda *a: None, progress=False)
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
           "pushed": [r["pushed"]["successes"], r["pushed"]["trials"]],
           "failures": dict(collections.Counter(t["outcome"] for t in detail if not t["success"])),
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
    args = ap.parse_args()
    rates = []
    for seed in args.seeds:
        r = one_seed(args.task, Path(args.out) / f"seed_{seed}", seed, args.trials, args.eval_seed, args.workers)
        lo, hi = wilson(r["successes"], r["trials"])
        rates.append(r["successes"] / r["trials"])
        print(f"seed {seed}: {100 * rates[-1]:.1f} % ({r['successes']}/{r['trials']}; {100 * lo:.1f}-{100 * hi:.1f} %), "
              f"unpushed {r['unpushed'][0]}/{r['unpushed'][1]}, pushed {r['pushed'][0]}/{r['pushed'][1]}; "
              f"failures {r['failures'] or '-'}; {r['minutes']} min", flush=True)
        for name, revs in r["revisions"].items():
            print(f"    {name}: {', '.join(revs) or 'no revision'}")
    if rates:
        print(f"over {len(rates)} seeds: median {100 * statistics.median(rates):.1f} %, "
              f"range {100 * min(rates):.1f}-{100 * max(rates):.1f} % (target ≥ 95 %)")


if __name__ == "__main__":
    main()
