"""Evaluation trials per second: the local process pool against Ray with the same number of CPUs.

Both backends run the same pendulum trials of one trained model, after the same warm-up (each
worker opens the model on its first trial; Ray's cluster start and worker start-up are timed
apart), in alternating rounds (local, Ray, local, Ray, ...) so that a busy spell of a shared
machine does not fall on one backend only; medians over the rounds. Prints trials per second of
each, their ratio (Ray / local), the per-trial overhead of each path (wall time per trial and CPU
minus the trial's own closed-loop time: scheduling, grading, moving the record back), the time to
start Ray, and the wall time of a 10,000-trial evaluation extrapolated from the measured rates.
Also checks that both gave the same trials.

    .venv/bin/python benchmarks/bench_ray.py [--model DIR] [--trials 16] [--cpus 2] [--rounds 2] [--results DIR]

Without ``--model`` it first trains a small model (4 mentor demos, the bundled pendulum skill) in a
temporary folder (about a minute); its trials run to the skill's time limit, as a weak model's do.
"""

from __future__ import annotations

import argparse
import os
import statistics
import tempfile
import time
import warnings
from pathlib import Path

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")
os.environ.setdefault("MUJOCO_GL", "egl")
warnings.filterwarnings("ignore", message="A single label was found", category=UserWarning)

from _results import Record, add_option, at_least  # noqa: E402
from multiform.evaluation import Evaluator, Variant  # noqa: E402
from multiform.task import load_task  # noqa: E402
task = load_task("pendulum")


def small_model(root: Path) -> Path:
    from multiform.demos.dataset import write_dataset
    from multiform.teach.record import record_many
    from multiform.trainer import train_model
    from multiform.model import SkillModel
    eps = record_many("pendulum", [0, 1, 2, 9], task.DEMO_ENV_KWARGS, workers=2)
    demos = write_dataset(root / "demos.h5", eps, task.SKILL, task.ENV_ID, task.DEMO_ENV_KWARGS)
    model = SkillModel.create(root / "model", task.SKILL, demos, task.ENV_ID, task.DEMO_ENV_KWARGS)
    train_model(model, seed=0, log=lambda *a: None)
    return model.path


def timed(variant: Variant, cpus: int, trials: int, ray: str | None) -> dict:
    """Warm up (one trial per CPU, other seeds), then run ``trials`` trials; their records and times."""
    t0 = time.perf_counter()
    with Evaluator("pendulum", cpus, ray=ray) as ev:
        ev.collect(variant, ev.submit(variant, task.evaluation_specs(cpus, 1, 0.5)))
        ready = time.perf_counter()
        specs = task.evaluation_specs(trials, 0, 0.5)
        res = ev.collect(variant, ev.submit(variant, specs))
        wall = time.perf_counter() - ready
    own = statistics.fmean(t["wall"] for t in res["trials_detail"])
    return {"records": res["trials_detail"], "wall": wall, "startup": ready - t0, "rate": trials / wall,
            "overhead": wall * cpus / trials - own, "own": own,
            "sim": statistics.fmean(t["duration"] for t in res["trials_detail"])}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--model", help="a trained pendulum model directory (default: train a small one)")
    ap.add_argument("--trials", type=int, default=16)
    ap.add_argument("--cpus", type=int, default=2)
    ap.add_argument("--rounds", type=int, default=2)
    add_option(ap)
    args = ap.parse_args()
    rec = Record(__file__, "Evaluation trials per second: the local process pool against Ray", section="speed")
    with tempfile.TemporaryDirectory(prefix="bench_ray_") as tmp:
        model = Path(args.model) if args.model else small_model(Path(tmp))
        variant = Variant("bench", str(model.resolve()))
        print(f"{args.trials} pendulum trials on {args.cpus} CPUs (load average before: "
              f"{os.getloadavg()[0]:.1f} on {os.cpu_count()} cores)", flush=True)
        rounds = []
        for i in range(args.rounds):
            rounds.append((timed(variant, args.cpus, args.trials, None),
                           timed(variant, args.cpus, args.trials, "local")))
            lo, ra = rounds[-1]
            print(f"round {i + 1}: local pool {lo['rate']:.3f} trials/s, Ray {ra['rate']:.3f} trials/s, "
                  f"ratio {ra['rate'] / lo['rate']:.2f}", flush=True)
    local, ray = ({k: statistics.median(r[j][k] for r in rounds) for k in ("wall", "startup", "rate", "overhead",
                                                                            "own", "sim")} for j in (0, 1))
    local["startup"], ray["startup"] = rounds[0][0]["startup"], rounds[0][1]["startup"]   # Ray's: with its start
    ratio = statistics.median(ra["rate"] / lo["rate"] for lo, ra in rounds)
    same = all({k: v for k, v in a.items() if k != "wall"} == {k: v for k, v in b.items() if k != "wall"}
               for lo, ra in rounds for a, b in zip(lo["records"], ra["records"]))
    print(f"trial: {local['sim']:.1f} s simulated, {local['own']:.2f} s of closed loop (local pool) / "
          f"{ray['own']:.2f} s (Ray) on one CPU")
    for name, r in (("local pool", local), ("Ray", ray)):
        print(f"{name:10s}: median {r['rate']:.3f} trials/s ({r['wall']:.1f} s for {args.trials}), overhead "
              f"{1e3 * r['overhead']:.0f} ms per trial, first start-up {r['startup']:.1f} s (incl. warm-up trials)")
    print(f"Ray / local pool: median {ratio:.2f} over {args.rounds} rounds (target >= 0.85); Ray's extra overhead "
          f"{1e3 * (ray['overhead'] - local['overhead']):.0f} ms per trial")
    print(f"same trials on both: {same}")
    model_text = "the given model" if args.model else "a small model (4 demos)"
    for key, name, r in (("local", "local process pool", local), ("ray", "Ray", ray)):
        rec.figure(f"rate_{key}", f"pendulum evaluation trials of {model_text} on {args.cpus} CPUs, {name}: trials "
                   f"per second (median of {args.rounds} rounds of {args.trials})", r["rate"], "trials/s",
                   extra={"overhead_ms_per_trial": round(1e3 * r["overhead"]), "first_start_s": round(r["startup"], 1),
                          "closed_loop_s_per_trial": round(r["own"], 2)})
    rec.figure("ratio", "Ray / local pool, trials per second (median over the rounds)", ratio, "",
               target=at_least(0.85))
    rec.figure("same_trials", "both backends gave the same trials, record for record", same, "",
               target="the same", met=same)
    for name, r in (("local pool", local), ("Ray", ray)):
        hours = 10_000 / r["rate"] / 3600
        print(f"10,000 trials (extrapolated from the measured rate): {name} {hours:.1f} h on {args.cpus} CPUs; "
              f"{hours * args.cpus / 64 * 60:.0f} min on a 64-CPU cluster at the same rate per CPU")
    rec.details["rounds"] = [{"local": lo["rate"], "ray": ra["rate"]} for lo, ra in rounds]
    rec.write(args.results)


if __name__ == "__main__":
    main()
