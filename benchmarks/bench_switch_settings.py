"""A learned switch condition: does the cross-validation that picks its setting predict how the robot
does with it in closed loop?

A switch condition the repair relearns from the mentor's switches (``training.fit_switch_condition``)
is an RBF SVM whose setting (C, γ and the window of states after each switch that count as positives)
is chosen by cross-validation over whole demonstrations: the highest rate of held-out switches it
holds at, among the settings under a 1 % false-positive budget on held-out non-switch states. This
benchmark takes a trained model whose net runs such a condition, refits it with every setting of the
grid on the same demonstrations (the same mentors' switches the repair learned from, the firing rule
chosen as the repair chooses it), and runs each on the same evaluation trials (half pushed where the
task pushes). It prints, per setting, the cross-validation figures beside the closed-loop success,
marks the setting the repair chose and its rank among them by closed-loop success.

The given model is never changed: each setting runs in a copy.

    .venv/bin/python benchmarks/bench_switch_settings.py --model runs/pendulum/model [--transition t1]
        [--trials 40] [--seed 1] [--workers 2] [--results DIR]
"""

from __future__ import annotations

import argparse
import os
import shutil
import sys
import tempfile
import time
import warnings
from pathlib import Path

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")
os.environ.setdefault("MUJOCO_GL", "egl")
warnings.filterwarnings("ignore", category=UserWarning)

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _results import Record, add_option  # noqa: E402

from multiform.adapt.learners import ModelLearners  # noqa: E402
from multiform.evaluation import Variant, evaluate  # noqa: E402
from multiform.learn.training import SWITCH_GRID, SWITCH_WINDOWS, fit_switch_condition, switch_condition  # noqa: E402
from multiform.learn.views import switch_data  # noqa: E402
from multiform.model import SkillModel  # noqa: E402
from multiform.task import task_for_env  # noqa: E402


def learned_switch(model: SkillModel, transition: str | None) -> tuple[str, str]:
    """(transition, condition model name) of the net's learned switch condition ``transition``
    (default: the first transition whose condition is a learned model it switches on)."""
    apn = model.apn
    for t in apn.transitions:
        name = getattr(t.condition, "model", None)
        if name and (transition is None or t.id == transition) and name.startswith(f"{t.id}_switch"):
            return t.id, name
    raise SystemExit(f"{model.path}: no learned switch condition" + (f" on {transition}" if transition else ""))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--model", type=Path, required=True, help="a trained model directory (not changed)")
    ap.add_argument("--transition", default=None, help="the learned switch (default: the first the net has)")
    ap.add_argument("--trials", type=int, default=40, help="evaluation trials per setting")
    ap.add_argument("--seed", type=int, default=1, help="evaluation seed of the trials (the main job's: its job seed)")
    ap.add_argument("--fold-seed", type=int, default=0, help="seed of the cross-validation's folds (the repair's: the job seed)")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--label", default=None, help="what the model is, for the record (e.g. 'pendulum job seed 0')")
    add_option(ap)
    args = ap.parse_args()

    source = SkillModel(args.model)
    tid, name = learned_switch(source, args.transition)
    task = task_for_env(source.manifest["env"])
    tmp = Path(tempfile.mkdtemp(prefix="switch_settings_"))
    try:
        copy = tmp / "model"
        shutil.copytree(args.model, copy)
        model = SkillModel(copy)
        learners = ModelLearners(model, seed=args.fold_seed)
        apn0 = model.history.version(0)
        names = learners.switch_variables(apn0, tid)
        episodes = learners.switch_episodes(tid)
        t0 = time.perf_counter()
        _, info = fit_switch_condition(apn0, episodes, tid, names, seed=args.fold_seed)
        cv = {(c["window"], c["params"]["C"], c["params"]["gamma"]): c for c in info["cv"]}
        chosen = (info["window"], info["params"]["C"], info["params"]["gamma"])
        specs = task.evaluation_specs(args.trials, args.seed, 0.5)
        rows = []
        print(f"{args.model}: {tid} ({', '.join(names)}), {len(episodes)} demonstrations, {args.trials} trials each "
              f"(evaluation seed {args.seed}); the repair's choice marked *", flush=True)
        print(f"{'window':>7} {'C':>6} {'gamma':>6} {'rule':>9} {'cv hit':>7} {'cv fp':>7} {'success':>8} "
              f"{'unpushed':>9} {'pushed':>7}")
        for window in SWITCH_WINDOWS:
            d = switch_data(apn0, episodes, tid, names, window=window)
            for params in SWITCH_GRID:
                cond, _ = switch_condition(apn0, episodes, tid, names, d, params, args.fold_seed)
                model.save_condition(name, cond)
                r = evaluate(task.spec or task.TASK, Variant(f"{window}-{params}", str(copy)), specs, args.workers)
                key = (window, params["C"], params["gamma"])
                c = cv[key]
                pushed = r.get("pushed") or {"successes": 0, "trials": 0}
                rows.append({"window": window, **params, "at_peak": cond.at_peak, "cv_hit": c["hit_in_moment"],
                             "cv_fp": c["false_positive"], "successes": r["successes"], "trials": r["trials"],
                             "pushed": [pushed["successes"], pushed["trials"]], "chosen": key == chosen})
                mark = "*" if key == chosen else " "
                print(f"{window:>7} {params['C']:>6g} {params['gamma']:>6g} {'peak' if cond.at_peak else 'entering':>9} "
                      f"{c['hit_in_moment']:>7.3f} {c['false_positive']:>7.4f} {r['successes']:>5}/{r['trials']:<3}"
                      f"{r['successes'] - pushed['successes']:>5}/{r['trials'] - pushed['trials']:<3}"
                      f"{pushed['successes']:>4}/{pushed['trials']:<3}{mark}", flush=True)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)

    succ = np.array([r["successes"] for r in rows])
    picked = next(r for r in rows if r["chosen"])
    best = max(rows, key=lambda r: r["successes"])
    rank = 1 + int(np.sum(succ > picked["successes"]))
    print(f"\nthe repair's setting: {picked['successes']}/{picked['trials']}, rank {rank} of {len(rows)}; "
          f"best {best['successes']}/{best['trials']} (window {best['window']}, C {best['C']:g}, gamma {best['gamma']:g}); "
          f"worst {int(succ.min())}/{args.trials}; {time.perf_counter() - t0:.0f} s")

    label = args.label or f"{source.apn.name} {tid}"
    rec = Record(__file__, f"a learned switch condition's setting: cross-validation against closed loop ({label})",
                 section="components", variant=args.label.replace(" ", "_") if args.label else None)
    rec.rate("chosen", f"{label}: closed-loop success with the setting the repair chose ({args.trials} trials, "
             "half pushed where the task pushes)", picked["successes"], picked["trials"])
    rec.rate("best", f"{label}: the best of the {len(rows)} settings on the same trials", best["successes"], best["trials"])
    rec.rate("worst", f"{label}: the worst of them", int(succ.min()), args.trials)
    rec.figure("rank", f"{label}: the chosen setting's rank by closed-loop success (1 = best)", rank)
    rec.details["rows"] = rows
    rec.write(args.results)


if __name__ == "__main__":
    main()
