"""Closed-loop speed: whole pendulum trials run by the learned skill (net + GP laws + learned inverse
model + safety + MuJoCo at 1 kHz), as simulated seconds per wall-clock second on one core.

Target (issue 6): ≥ 10× faster than real time. Also prints where a tick's time goes: the env step
(physics at 1 ms, the torque-mode env), one law evaluation, the inverse model, and the rest
(net tick, guards, safety, trace), from separate timings of each part on states of the same trials.

    .venv/bin/python benchmarks/bench_closed_loop.py [--model runs/pendulum/model] [--trials 10] [--results DIR]

The model directory comes from ``make demo`` (``runs/pendulum/model``) or ``multiform train``.
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("MUJOCO_GL", "egl")

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _results import Record, add_option, at_least  # noqa: E402
from _timing import describe, latencies, single_thread  # noqa: E402

from multiform.model import SkillModel  # noqa: E402
from multiform.task import load_task  # noqa: E402
task = load_task("pendulum")

ROOT = Path(__file__).resolve().parents[1]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--model", default=str(ROOT / "runs" / "pendulum" / "model"))
    ap.add_argument("--trials", type=int, default=10)
    add_option(ap)
    args = ap.parse_args()
    rec = Record(__file__, "Closed-loop speed of whole pendulum trials", section="speed")
    if not (Path(args.model) / "model.json").exists():
        sys.exit(f"{args.model}: no trained model; run `make demo` first (or pass --model)")
    model = SkillModel(args.model)
    rec.details["model"] = {"skill": model.apn.name, "net_version": model.version,
                            "created": model.manifest.get("created"), "laws": sorted(model.laws())}
    env = model.make_env()
    ex = model.executor(env)
    factors, ticks, obs = [], [], []
    values, names = [], ()
    with single_thread():
        for k in range(args.trials):
            seed = 90_000 + k
            tr = ex.run(seed=seed, options=task.trial_options(seed))
            factors.append(tr.duration / tr.wall_time)
            ticks.append(tr.wall_time / max(1, tr.num_ticks))
            values.append(tr.values[:: max(1, tr.num_ticks // 500)].astype(np.float64))
            obs.append(tr.obs[:: max(1, tr.num_ticks // 500)].astype(np.float64))
            names = tr.value_names
        f = np.array(factors)
        print(f"closed-loop trials ({model.apn.name} v{model.version}, {args.trials} trials, "
              f"{'learned inverse model' if model.inverse_model() is not None else 'reference controller'}): "
              f"real-time factor median {np.median(f):.1f}x (min {f.min():.1f}x, max {f.max():.1f}x); "
              f"{np.median(ticks) * 1e6:.0f} µs per 1 ms tick; target >= 10x")
        rec.figure("realtime", f"closed-loop pendulum trials (learned laws + net + "
                   f"{'learned inverse model' if model.inverse_model() is not None else 'reference controller'} + "
                   f"MuJoCo at 1 kHz), real-time factor, median of {args.trials} trials", float(np.median(f)),
                   "× real time", extra={"min": float(f.min()), "max": float(f.max()),
                                         "µs_per_tick": float(np.median(ticks) * 1e6)}, target=at_least(10))

        vals, obs = np.concatenate(values), np.concatenate(obs)
        for name, law in model.laws().items():
            X = np.ascontiguousarray(vals[:, [names.index(v) for v in law.input_names]])
            i = [0]

            def one(X=X, law=law):
                law.predict_one(X[i[0] % len(X)])
                i[0] += 1
            t = latencies(one, calls=5000)
            print("  " + describe(f"law {name} ({law.mode_}, n={law.n_train_})", t))
            rec.latency(f"law_{name}", f"closed loop: one evaluation of the law {name} ({law.mode_}, "
                        f"n = {law.n_train_})", t)
        inv = model.inverse_model()
        if inv is not None:
            cmd = np.zeros(len(model.apn.commands))
            j = [0]

            def torques():
                inv.torques(obs[j[0] % len(obs)], cmd)
                j[0] += 1
            t = latencies(torques, calls=5000)
            print("  " + describe("inverse model torques", t))
            rec.latency("inverse_model", "closed loop: the inverse model's torques for one tick", t)
        env.reset(seed=1, options=task.trial_options(1))
        a = np.zeros(env.action_space.shape)
        t = latencies(lambda: env.step(a), calls=5000)
        print("  " + describe("env.step (MuJoCo 1 ms + observation)", t))
        rec.latency("env_step", "closed loop: env.step, torque mode (MuJoCo 1 ms + observation)", t)
    env.close()
    rec.write(args.results)


if __name__ == "__main__":
    main()
