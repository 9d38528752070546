"""Nunchaku benchmark: simulation speed and stability, estimation from load, the scripted mentor, the
speeds the flip needs, and a feasibility check that the flip is learnable from the mentor's demos.

    .venv/bin/python benchmarks/bench_nunchaku.py                 # all parts, moderate sizes
    .venv/bin/python benchmarks/bench_nunchaku.py --stability 1000 --demos 60 --trials 100
    .venv/bin/python benchmarks/bench_nunchaku.py ... --results DIR  # where the JSON record goes

Feasibility: one simple regressor per law (scikit-learn GP, ARD squared-exponential + noise, fitted
on a random subset of the law's samples from the mentor's *successful* segments; predictions in
numpy), run closed loop on randomised nunchakus by the library's own executor with the bundled
skill's conditions, on the robot's estimates only. It is a stand-in for the lead's GP laws, to show
the flip can be learned; it is not the pipeline's result.
"""

from __future__ import annotations

import argparse
import math
import time
import warnings

import numpy as np
from _results import Record, add_option, at_most

from multiform.tasks.nunchaku_mentor import NunchakuMentor
from multiform.teach.record import record_episode
from multiform.envs.nunchaku import OBSERVATION_NAMES, NunchakuEnv
from multiform.stats import wilson

AUBO_JOINT_SPEED = 3.14       # rad/s, joints 1-3 of the AUBO i5
AUBO_WRIST_SPEED = 2.6        # rad/s, joints 4-6
AUBO_REACH = 0.8865           # m


def sim_speed(rec: Record, seconds: float = 3.0) -> None:
    import mujoco
    env = NunchakuEnv()
    env.reset(seed=0)
    mentor = NunchakuMentor(failure_rate=0.0)
    obs, info = env.reset(seed=0)
    mentor.reset(obs, np.random.default_rng(0))
    n = int(seconds / env.dt)
    per_step = []
    t = 0.0
    for _ in range(n):
        cmd, _ = mentor.act(obs, info, t)
        t0 = time.perf_counter()
        obs, _, term, _, info = env.step(cmd)
        per_step.append(time.perf_counter() - t0)
        t += env.dt
        if term or mentor.finished():
            obs, info = env.reset(seed=1)
            mentor.reset(obs, np.random.default_rng(1))
            t = 0.0
    s = np.array(per_step) * 1e6
    m, d = env.model, env.data
    raw = []
    for _ in range(2000):
        t0 = time.perf_counter()
        mujoco.mj_step(m, d)
        raw.append(time.perf_counter() - t0)
    raw = np.array(raw) * 1e6
    print(f"env.step (physics + servo + magnet + load EKF + observation): median {np.median(s):.0f} µs, "
          f"p99 {np.percentile(s, 99):.0f} µs -> {1e6 / np.median(s):.0f} steps/s, "
          f"{1e3 / np.median(s):.1f}x real time")
    print(f"mj_step alone: median {np.median(raw):.0f} µs, p99 {np.percentile(raw, 99):.0f} µs")
    rec.latency("step", "Nunchaku-v0: env.step (physics + servo + magnet + load EKF + observation) under the "
                "scripted mentor", s / 1e6, extra={"real_time_factor": round(1e3 / np.median(s), 1)}, section="speed")
    rec.latency("mj_step", "Nunchaku-v0: mj_step alone", raw / 1e6, section="speed")


def stability(n: int, rec: Record, duration: float = 1.5) -> None:
    """Randomised nunchakus, alternately under random hand/wrist motion with magnet switching and
    under the scripted flip with doubled noise and frequent fumbles."""
    env = NunchakuEnv(settle=0.0)
    mentor = NunchakuMentor(failure_rate=0.5, noise=2.0)
    diverged = dropped = 0
    steps = 0
    t0 = time.time()
    for k in range(n):
        seed = 100_000 + k
        rng = np.random.default_rng(seed)
        obs, info = env.reset(seed=seed)
        if k % 2:
            mentor.reset(obs, rng)
            t = 0.0
            while not mentor.finished() and t < 8.0:
                cmd, _ = mentor.act(obs, info, t)
                obs, _, term, _, info = env.step(cmd)
                t += env.dt
                steps += 1
                if term:
                    diverged += bool(info["diverged"])
                    dropped += bool(info["dropped"])
                    break
            continue
        amp = rng.uniform(0, 1, 3) * np.array([3.0, 3.0, 20.0])
        freq = rng.uniform(0.5, 4.0, 3)
        phase = rng.uniform(0, 2 * np.pi, 3)
        toggles = np.sort(rng.uniform(0, duration, 4))
        for i in range(int(duration / env.dt)):
            t = i * env.dt
            v = amp * np.sin(2 * np.pi * freq * t + phase)
            obs, _, term, _, info = env.step(np.array([v[0], v[1], v[2], float(np.searchsorted(toggles, t) % 2 == 0)]))
            steps += 1
            if term or not np.all(np.isfinite(obs)):
                diverged += bool(info.get("diverged", True))
                dropped += bool(info.get("dropped", False))
                break
    print(f"stability: {n} randomised trials ({steps * env.dt:.0f} s simulated; half random hand/wrist motion "
          f"with magnet switching, half noisy scripted flips): {diverged} diverged (NaN/explosion), "
          f"{dropped} dropped the nunchaku ({time.time() - t0:.0f} s)")
    rec.rate("diverged", "Nunchaku-v0: randomised trials that diverged (NaN or explosion), half random hand and "
             "wrist motion with magnet switching, half noisy scripted flips", diverged, n, section="tasks",
             counts={"dropped the nunchaku": [dropped, n]}, extra={"simulated_s": round(steps * env.dt)})


def demos(n: int, failure_rate: float, seed0: int = 20_000):
    env = NunchakuEnv()
    mentor = NunchakuMentor(failure_rate=failure_rate)
    eps, errors, rate_err, fumbles = [], [], [], []
    iphi, iom = OBSERVATION_NAMES.index("phi"), OBSERVATION_NAMES.index("omega")
    for s in range(n):
        ep = record_episode(env, mentor, seed=seed0 + s)
        eps.append(ep)
        fumbles.append(mentor.fumble)
    # estimator error during the swing (t0/t1 samples after 0.3 s), against a replay with truth
    for ep in eps[: min(n, 20)]:
        obs, info = env.reset(seed=ep.seed)
        for k, cmd in enumerate(ep.actions):
            obs, _, term, _, info = env.step(cmd)
            if ep.transitions[k] not in ("t0", "t1") or term:
                break
            if k * ep.dt > 0.3:
                errors.append(math.remainder(obs[iphi] - info["truth"]["phi"], 2 * math.pi))
                rate_err.append(obs[iom] - info["truth"]["omega"])
    return eps, np.array(errors), np.array(rate_err), fumbles


def flip_speeds(eps, rec: Record) -> None:
    v, a, w, al = [], [], [], []
    for ep in eps:
        if ep.outcome != "success":
            continue
        vx, vz, wq = ep.column("hand_vx"), ep.column("hand_vz"), ep.column("hand_wq")
        sp = np.hypot(vx, vz)
        acc = np.hypot(np.gradient(vx, ep.dt), np.gradient(vz, ep.dt))
        v.append(sp.max())
        a.append(np.percentile(acc, 99.5))
        w.append(np.abs(wq).max())
        al.append(np.percentile(np.abs(np.gradient(wq, ep.dt)), 99.5))
    if not v:
        return
    print(f"flip speeds (successful demos): hand speed peak median {np.median(v):.2f} m/s (max {max(v):.2f}), "
          f"hand acceleration p99.5 median {np.median(a):.0f} m/s^2; wrist rate peak median {np.median(w):.1f} rad/s "
          f"(max {max(w):.1f}), wrist acceleration p99.5 median {np.median(al):.0f} rad/s^2")
    print(f"  AUBO i5: wrist joints <= {AUBO_WRIST_SPEED} rad/s (the flip needs {np.median(w) / AUBO_WRIST_SPEED:.1f}x), "
          f"shoulder/elbow <= {AUBO_JOINT_SPEED} rad/s: at most {AUBO_JOINT_SPEED * AUBO_REACH:.1f} m/s at full reach "
          "-> the arm cannot flip it; the env uses an actuated 6-DoF base")
    rec.figure("hand_speed", "the mentor's successful flips: peak hand speed, median", float(np.median(v)), "m/s",
               section="tasks", extra={"max": round(float(max(v)), 2)})
    rec.figure("wrist_rate", "the mentor's successful flips: peak wrist rate, median", float(np.median(w)), "rad/s",
               section="tasks", extra={"max": round(float(max(w)), 1), "aubo_i5_wrist_limit": AUBO_WRIST_SPEED})


class SubsetGP:
    """A GP law fitted with scikit-learn on a subset; ``predict_one`` in numpy (for the executor)."""

    def __init__(self, X: np.ndarray, Y: np.ndarray, n_fit: int = 500, seed: int = 0):
        from sklearn.gaussian_process import GaussianProcessRegressor
        from sklearn.gaussian_process.kernels import RBF, ConstantKernel, WhiteKernel
        rng = np.random.default_rng(seed)
        idx = rng.choice(len(X), min(n_fit, len(X)), replace=False)
        X, Y = X[idx], Y[idx]
        self.mx, self.sx = X.mean(0), X.std(0) + 1e-9
        self.my, self.sy = Y.mean(0), Y.std(0) + 1e-9
        Xs, Ys = (X - self.mx) / self.sx, (Y - self.my) / self.sy
        kernel = ConstantKernel(1.0) * RBF(np.ones(X.shape[1]), (1e-2, 1e3)) + WhiteKernel(1e-2, (1e-6, 1.0))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            gp = GaussianProcessRegressor(kernel, n_restarts_optimizer=0, random_state=seed).fit(Xs, Ys)
        k = gp.kernel_
        self.amp = k.k1.k1.constant_value
        self.length = np.atleast_1d(k.k1.k2.length_scale)
        self.alpha = gp.alpha_
        self.Xl = Xs / self.length

    def predict_one(self, x: np.ndarray) -> np.ndarray:
        z = (np.asarray(x) - self.mx) / self.sx / self.length
        d2 = ((self.Xl - z) ** 2).sum(1)
        return (self.amp * np.exp(-0.5 * d2)) @ self.alpha * self.sy + self.my


def feasibility(eps, trials: int, n_fit: int, rec: Record) -> None:
    from multiform.learn.views import law_data
    from multiform.petri.skillfile import load_skill
    from multiform.runtime.executor import Executor
    apn = load_skill("nunchaku")
    env = NunchakuEnv()
    laws = {}
    t0 = time.time()
    for name in apn.laws:
        d = law_data(apn, eps, name)
        laws[name] = SubsetGP(d.X, d.Y, n_fit)
    print(f"feasibility: {len(apn.laws)} laws fitted on <= {n_fit} samples each from "
          f"{sum(e.outcome == 'success' for e in eps)} successful demos ({time.time() - t0:.0f} s)")
    ex = Executor(apn, env, laws)
    outcomes: dict[str, int] = {}
    stops: dict[str, int] = {}
    wall = sim = 0.0
    for s in range(trials):
        tr = ex.run(seed=900_000 + s)
        outcomes[tr.outcome] = outcomes.get(tr.outcome, 0) + 1
        last = tr.firings[-1].transition if tr.firings else "-"
        stops[last] = stops.get(last, 0) + 1
        wall += tr.wall_time
        sim += len(tr.obs) * tr.dt
    k = outcomes.get("success", 0)
    lo, hi = wilson(k, trials)
    print(f"  learned flip closed loop on estimates: {k}/{trials} = {k / trials:.0%} "
          f"(Wilson 95% {lo:.0%}-{hi:.0%}); outcomes {outcomes}; last transition {stops}; "
          f"{sim / wall:.1f}x real time")
    rec.rate("feasibility", f"feasibility: a flip learned by a stand-in regressor (scikit-learn GP on <= {n_fit} "
             "samples per law) in closed loop on the robot's estimates", k, trials, section="tasks",
             extra={"outcomes": outcomes})


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--stability", type=int, default=200, help="randomised stability trials")
    ap.add_argument("--demos", type=int, default=50, help="mentor demonstrations (>= 50 for the rate)")
    ap.add_argument("--failure-rate", type=float, default=0.3, help="mentor's fumble probability")
    ap.add_argument("--trials", type=int, default=40, help="closed-loop trials of the feasibility check")
    ap.add_argument("--fit", type=int, default=500, help="samples per law for the feasibility GP")
    ap.add_argument("--skip", default="", help="comma-separated parts to skip: speed,stability,feasibility")
    add_option(ap)
    args = ap.parse_args()
    rec = Record(__file__, "The nunchaku: simulation, estimation from load, the mentor, feasibility", section="tasks")
    skip = set(filter(None, args.skip.split(",")))
    if "speed" not in skip:
        sim_speed(rec)
    if "stability" not in skip:
        stability(args.stability, rec)
    t0 = time.time()
    eps, err, rate_err, fumbles = demos(args.demos, args.failure_rate)
    rms = float(np.sqrt(np.mean(err ** 2)))
    print(f"estimation from load, during the swing ({len(err)} samples of up to 20 demos): free-rod angle "
          f"RMS {rms:.3f} rad (p95 {np.percentile(np.abs(err), 95):.3f}), rate RMS "
          f"{np.sqrt(np.mean(rate_err ** 2)):.2f} rad/s -> {'meets' if rms <= 0.1 else 'MISSES'} the 0.1 rad target")
    rec.figure("estimate_phi", "estimation from the wrist load during the swing: free-rod angle error, RMS", rms, "rad",
               target=at_most(0.1), extra={"p95_rad": round(float(np.percentile(np.abs(err), 95)), 3),
                                           "rate_rms_rad_per_s": round(float(np.sqrt(np.mean(rate_err ** 2))), 2),
                                           "samples": len(err)})
    ok = sum(e.outcome == "success" for e in eps)
    clean = [e for e, f in zip(eps, fumbles) if not f]
    ok_clean = sum(e.outcome == "success" for e in clean)
    lo, hi = wilson(ok, len(eps))
    print(f"scripted mentor: {ok}/{len(eps)} flips = {ok / len(eps):.0%} (Wilson 95% {lo:.0%}-{hi:.0%}) with "
          f"fumble rate {args.failure_rate}; without a fumble {ok_clean}/{len(clean)}; "
          f"{time.time() - t0:.0f} s")
    rec.rate("mentor", f"the scripted mentor's flips (fumble probability {args.failure_rate})", ok, len(eps),
             counts={"without a fumble": [ok_clean, len(clean)]})
    flip_speeds(eps, rec)
    if "feasibility" not in skip:
        feasibility(eps, args.trials, args.fit, rec)
    rec.write(args.results)


if __name__ == "__main__":
    main()
