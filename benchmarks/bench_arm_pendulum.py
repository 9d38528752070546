"""Simulation speed of ``multiform/ArmPendulum-v0`` at 1 kHz with the reference controller.

Prints steps per second and the real-time factor (simulated seconds per wall-clock second) of

* the env in end-effector mode (one ``step`` = reference controller + one 1 ms physics step),
* the env in torque mode driven by :class:`~multiform.envs.osc.ReferenceController` from the
  observations (the path the executor takes with an inverse model),
* the env with the scripted mentor recording a demonstration,
* the bare physics step (``mj_step``) for comparison,

each as the median over repeats of 5,000-step runs (a swinging pendulum, a sinusoidal command),
plus the per-step latency median and p99. Target: ≥ 20× real time on one core.

Run: ``python benchmarks/bench_arm_pendulum.py [--repeats 7] [--results DIR]``.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import mujoco
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _results import Record, add_option, at_least  # noqa: E402
from _timing import describe, single_thread  # noqa: E402

from multiform.tasks.pendulum_mentor import PendulumMentor  # noqa: E402
from multiform.teach.record import record_episode  # noqa: E402
from multiform.envs.arm_pendulum import ArmPendulumEnv  # noqa: E402
from multiform.envs.osc import ReferenceController  # noqa: E402

STEPS = 5000


def commands(n: int) -> np.ndarray:
    t = np.arange(n) * 0.001
    return (0.8 * np.sin(2 * math.pi * 0.9 * t)).reshape(-1, 1)


def run_ee(env: ArmPendulumEnv, cmds: np.ndarray, per_step: list[float]) -> float:
    env.reset(seed=0, options={"theta0": 2.0})
    clock = time.perf_counter
    t0 = clock()
    for a in cmds:
        s = clock()
        env.step(a)
        per_step.append(clock() - s)
    return clock() - t0


def run_torque(env: ArmPendulumEnv, rc: ReferenceController, cmds: np.ndarray) -> float:
    obs, _ = env.reset(seed=0, options={"theta0": 2.0})
    t0 = time.perf_counter()
    for a in cmds:
        obs, *_ = env.step(rc.torques(obs, a))
    return time.perf_counter() - t0


def run_physics(env: ArmPendulumEnv, n: int) -> float:
    env.reset(seed=0, options={"theta0": 2.0})
    m, d = env.model, env.data
    t0 = time.perf_counter()
    for _ in range(n):
        mujoco.mj_step(m, d)
    return time.perf_counter() - t0


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeats", type=int, default=7)
    add_option(ap)
    args = ap.parse_args(argv)
    rec = Record(__file__, "Simulation speed of ArmPendulum-v0 at 1 kHz", section="speed")
    env = ArmPendulumEnv()
    envt = ArmPendulumEnv(action_mode="torque")
    rc = ReferenceController()
    cmds = commands(STEPS)
    results: dict[str, list[float]] = {"ee": [], "torque+rc": [], "mentor": [], "mj_step": []}
    per_step: list[float] = []
    mentor = PendulumMentor(mistake="none")
    with single_thread():
        for r in range(args.repeats):
            results["ee"].append(STEPS / run_ee(env, cmds, per_step))
            results["torque+rc"].append(STEPS / run_torque(envt, rc, cmds))
            results["mj_step"].append(STEPS / run_physics(env, STEPS))
            t0 = time.perf_counter()
            ep = record_episode(env, mentor, seed=r, options={"randomize": True}, max_steps=STEPS)
            results["mentor"].append(ep.num_samples / (time.perf_counter() - t0))
    print(f"ArmPendulum-v0, dt = 1 ms, median of {args.repeats} runs of {STEPS} steps (one core):")
    labels = {"ee": "env step, end-effector mode (reference controller inside)",
              "torque+rc": "ReferenceController.torques(obs) + env step, torque mode",
              "mentor": "scripted mentor + env step (record_episode)",
              "mj_step": "bare mj_step (physics only)"}
    for key, label in labels.items():
        med = float(np.median(results[key]))
        print(f"  {label:60s} {med:9.0f} steps/s  {med / 1000:6.1f}x real time")
        rec.figure(f"realtime_{key.replace('+', '_')}", f"ArmPendulum-v0: {label}, real-time factor (median of "
                   f"{args.repeats} runs of {STEPS} steps, one core)", med / 1000, "× real time",
                   extra={"steps_per_second": round(med)}, target=at_least(20) if key == "ee" else None)
    print("  " + describe("env.step latency (end-effector mode)", np.array(per_step)))
    rec.latency("step_latency_ee", "ArmPendulum-v0: env.step latency, end-effector mode", np.array(per_step))
    ok = np.median(results["ee"]) / 1000 >= 20.0
    print(f"target >= 20x real time (end-effector mode): {'met' if ok else 'NOT met'}")
    rec.write(args.results)


if __name__ == "__main__":
    main()
