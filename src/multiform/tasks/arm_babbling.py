"""The arm's own motion data for its inverse model, and how well the learned model tracks.

Rounds of the robot's own motion in torque mode with the pendulum mounted (the inverse model learns
the arm *with* its swinging load), never using the mentor's data or the env's reference controller:

1. **joint babbling** — stiff joint-space PD around targets that sweep the hand along the swing axis
   (targets from the arm's *kinematic* model: q = home + J⁺ Δx; no dynamics known), with torque
   noise;
2. **self-driven babbling** — the first learned model in the loop, driven by random end-effector
   commands through the servo, with torque noise;
3. **exercising its maneuvers** — the robot runs each of its learned laws on its own (swinging from
   hanging; balancing from near upright) through the current inverse model, with torque noise: the
   states its skill will visit, which random motion rarely reaches. Refit after each exercise round.

Rows are ``[q, q̇, a]`` with ``a`` the achieved task acceleration (differenced from the robot's own
end-effector velocities) and the torques that produced it.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import gymnasium as gym
import mujoco
import numpy as np

from ..learn.inverse import InverseDynamicsModel


def _smooth_signal(rng: np.random.Generator, t: np.ndarray, amp: float, fmin: float, fmax: float, k: int = 3
                   ) -> np.ndarray:
    f = rng.uniform(fmin, fmax, k)
    ph = rng.uniform(0, 2 * np.pi, k)
    a = rng.uniform(0.3, 1.0, k)
    s = (a[:, None] * np.sin(2 * np.pi * f[:, None] * t[None, :] + ph[:, None])).sum(0)
    return amp * s / a.sum()


def joint_babbling(env: gym.Env, seconds: float, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Round 1: joint PD around kinematically chosen targets; returns (obs, torques) per step."""
    base = env.unwrapped
    obs, _ = env.reset(seed=int(rng.integers(1 << 31)))
    names = list(base.observation_names)
    qi = [names.index(f"q{i + 1}") for i in range(6)]
    qdi = [names.index(f"qd{i + 1}") for i in range(6)]
    home = obs[qi].copy()
    kin = mujoco.MjData(base.model)                    # the arm's kinematic model
    kin.qpos[:6] = home
    mujoco.mj_kinematics(base.model, kin)
    mujoco.mj_comPos(base.model, kin)
    jac = np.zeros((6, base.model.nv))
    mujoco.mj_jacSite(base.model, kin, jac[:3], jac[3:], base.model.site("flange").id)
    J_pinv = np.linalg.pinv(jac[:, :6])
    n = int(seconds / base.dt)
    t = np.arange(n) * base.dt
    task = np.stack([_smooth_signal(rng, t, 0.3, 0.15, 1.5), _smooth_signal(rng, t, 0.03, 0.2, 2.0),
                     _smooth_signal(rng, t, 0.03, 0.2, 2.0), _smooth_signal(rng, t, 0.05, 0.2, 2.0),
                     _smooth_signal(rng, t, 0.05, 0.2, 2.0), _smooth_signal(rng, t, 0.05, 0.2, 2.0)], 1)
    targets = home + task @ J_pinv.T
    kp = np.array([3000, 3000, 3000, 400, 400, 400.0])
    kd = np.array([150, 150, 150, 15, 15, 15.0])
    noise = rng.normal(0, 1, (n, 6)) * np.array([5, 5, 5, 1, 1, 1.0])
    O, U = np.zeros((n, len(names))), np.zeros((n, 6))
    for k in range(n):
        tau = kp * (targets[k] - obs[qi]) - kd * obs[qdi] + noise[k]
        tau = np.clip(tau, env.action_space.low, env.action_space.high)
        O[k], U[k] = obs, tau
        obs, _, term, _, _ = env.step(tau)
        if term:
            O, U = O[: k + 1], U[: k + 1]
            break
    return O, U


def self_babbling(env: gym.Env, model: InverseDynamicsModel, seconds: float, rng: np.random.Generator
                  ) -> tuple[np.ndarray, np.ndarray]:
    """Round 2: the learned model in the loop, random end-effector commands, torque noise."""
    base = env.unwrapped
    obs, _ = env.reset(seed=int(rng.integers(1 << 31)))
    n = int(seconds / base.dt)
    t = np.arange(n) * base.dt
    v = np.clip(_smooth_signal(rng, t, 1.4, 0.2, 2.5, k=4), -1.5, 1.5)
    noise = rng.normal(0, 1, (n, 6)) * np.array([4, 4, 4, 0.8, 0.8, 0.8])
    O, U = np.zeros((n, len(base.observation_names))), np.zeros((n, 6))
    for k in range(n):
        tau = np.clip(model.torques(obs, v[k:k + 1]) + noise[k], env.action_space.low, env.action_space.high)
        O[k], U[k] = obs, tau
        obs, _, term, _, _ = env.step(tau)
        if term:
            O, U = O[: k + 1], U[: k + 1]
            break
    return O, U


def rows(env: gym.Env, O: np.ndarray, U: np.ndarray, every: int = 4) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Training rows: observations, achieved task accelerations and torques, every ``every``-th step.

    The torque at step k produced the end-effector velocity change from k to k+1 (forward
    differences of the velocities the robot's own kinematics report)."""
    base = env.unwrapped
    names = list(base.observation_names)
    idx = [names.index(k) for k in ("ee_vx", "ee_vy", "ee_vz", "ee_wx", "ee_wy", "ee_wz")]
    A = (O[1:, idx] - O[:-1, idx]) / base.dt
    return O[:-1][::every], A[::every], U[:-1][::every]


class _Exploring:
    """An inverse model with torque noise that logs what it sent (the executor's inverse-model slot)."""

    def __init__(self, model: InverseDynamicsModel, low: np.ndarray, high: np.ndarray, rng: np.random.Generator,
                 scale: np.ndarray):
        self.model, self.low, self.high, self.rng, self.scale = model, low, high, rng, scale
        self.obs: list[np.ndarray] = []
        self.tau: list[np.ndarray] = []

    def torques(self, obs: np.ndarray, command: np.ndarray) -> np.ndarray:
        tau = np.clip(self.model.torques(obs, command) + self.rng.normal(0, 1, 6) * self.scale, self.low, self.high)
        self.obs.append(np.array(obs))
        self.tau.append(tau)
        return tau.copy()


def exercise(env: gym.Env, episodes: list[tuple[Any, dict[str, Any], float]], model: InverseDynamicsModel,
             rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Run ``(executor factory, reset options, seconds)`` episodes through ``model`` plus torque noise;
    returns (obs, torques) per step, episodes joined (rows straddling two episodes are dropped)."""
    Os, Us = [], []
    for make_executor, options, seconds in episodes:
        explorer = _Exploring(model, env.action_space.low, env.action_space.high, rng,
                              np.array([3, 3, 3, 0.6, 0.6, 0.6]))
        make_executor(env, explorer).run(seed=int(rng.integers(1 << 31)), options=options, max_duration=seconds)
        if len(explorer.obs) > 2:
            Os.append(np.array(explorer.obs))
            Us.append(np.array(explorer.tau))
    return Os, Us


def train_inverse(make_env: Callable[[], gym.Env], seed: int = 0, seconds: tuple[float, float] = (40.0, 40.0),
                  exercises: Callable[[np.random.Generator], list] | None = None, exercise_rounds: int = 2,
                  log: Callable[[str], None] = print) -> tuple[InverseDynamicsModel, dict[str, Any]]:
    """The babbling rounds, the exercise rounds and the fits; returns the model and a summary.

    ``exercises(rng)`` lists the exercise episodes as ``(executor factory, reset options, seconds)``;
    the factory gets the env and the inverse model to drive it with."""
    rng = np.random.default_rng([seed, 11])
    env = make_env()
    seconds_run = []
    try:
        O1, U1 = joint_babbling(env, seconds[0], rng)
        parts = [rows(env, O1, U1)]
        model = InverseDynamicsModel(random_state=seed).fit(*parts[0])
        O2, U2 = self_babbling(env, model, seconds[1], rng)
        parts.append(rows(env, O2, U2))
        seconds_run += [len(O1) * 1e-3, len(O2) * 1e-3]
        model = InverseDynamicsModel(random_state=seed).fit(*(np.concatenate(c) for c in zip(*parts)))
        for _ in range(exercise_rounds if exercises is not None else 0):
            Os, Us = exercise(env, exercises(rng), model, rng)
            for Oe, Ue in zip(Os, Us):
                parts.append(rows(env, Oe, Ue))
            seconds_run.append(sum(len(o) for o in Os) * 1e-3)
            model = InverseDynamicsModel(random_state=seed).fit(*(np.concatenate(c) for c in zip(*parts)))
    finally:
        env.close()
    O, A, T = (np.concatenate(c) for c in zip(*parts))
    resid = T - model.predict(O, A)
    info = {"own_motion_s": [round(x, 1) for x in seconds_run], "rows": int(len(O)),
            "train_rms_torque_error": [round(float(v), 3) for v in np.sqrt(np.mean(resid ** 2, axis=0))],
            **model.summary()}
    log(f"  inverse model: {info['rows']} rows from {sum(info['own_motion_s']):.0f} s of the arm's own motion; "
        f"training RMS torque error {info['train_rms_torque_error']} N m")
    return model, info


def tracking_error(env: gym.Env, controller, seconds: float, seed: int) -> dict[str, float]:
    """RMS of (commanded − achieved) end-effector velocity along the swing axis, and the RMS pose-hold
    error, for held-out random commands driven through ``controller.torques(obs, [v])``."""
    base = env.unwrapped
    rng = np.random.default_rng([seed, 13])
    obs, _ = env.reset(seed=seed)
    names = list(base.observation_names)
    ix, iy, iz = names.index("xdot"), names.index("ee_y"), names.index("ee_z")
    n = int(seconds / base.dt)
    t = np.arange(n) * base.dt
    v = np.clip(_smooth_signal(rng, t, 1.0, 0.2, 1.5, k=4), -1.2, 1.2)
    err_v, err_p = [], []
    y0, z0 = obs[iy], obs[iz]
    for k in range(n):
        tau = np.clip(controller.torques(obs, v[k:k + 1]), env.action_space.low, env.action_space.high)
        obs, _, term, _, _ = env.step(tau)
        if term:
            return {"velocity_rms": float("inf"), "hold_rms": float("inf"), "diverged": True}
        err_v.append(v[k] - obs[ix])
        err_p.append(np.hypot(obs[iy] - y0, obs[iz] - z0))
    return {"velocity_rms": float(np.sqrt(np.mean(np.square(err_v)))),
            "hold_rms": float(np.sqrt(np.mean(np.square(err_p)))), "diverged": False}
