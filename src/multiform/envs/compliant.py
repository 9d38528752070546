"""The arm's hand-guiding mode, and the command recovered from the motion a person guided.

In hand-guiding mode (an env's ``action_mode="kinesthetic"``) the arm is compliant, as a real
collaborative arm is when a person teaches it by moving it: its controller compensates gravity,
the Coriolis and centrifugal forces and its joints' own friction (the model's joint damping, as the
reference controller compensates it), and adds a low impedance at the flange — a light damping
along the axes the person guides, virtual walls at the ends of the stroke, and stiff holds of the
other axes and of the orientation (the axis locks a teaching mode offers). The person's hand is a
force at the flange: the env's action in that mode. It moves the arm through the arm's own inertia,
and the robot has no force sensor that reads it.

What the robot keeps of a guided demonstration is what it senses (its encoders, the object's
motion) and, as the command its laws must learn, the command under which its own end-effector
servo reproduces the guided motion (:func:`command_from_motion`): the servo tracks ``v_cmd`` with
``a = kv (v_cmd - v)``, so the motion ``v(t)`` is reproduced by ``v_cmd = v + a / kv``, with ``a``
the derivative of the measured velocity. The person's force appears nowhere in it.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

import mujoco
import numpy as np

from .osc import Workspace


class Compliance(NamedTuple):
    """The hand-guiding mode's impedance at the flange (SI units).

    ``damping`` along the guided axes (the arm then feels like its own inertia plus a light
    viscous drag); ``wall_k``, ``wall_d`` the virtual walls beyond the stroke; ``lock_k``, ``lock_d``
    the holds of the locked translation axes; ``rot_k``, ``rot_d`` the orientation lock;
    ``force_max`` the largest force a person's hand applies per axis.
    """

    damping: float = 3.0
    wall_k: float = 4000.0
    wall_d: float = 60.0
    lock_k: float = 8000.0
    lock_d: float = 200.0
    rot_k: float = 800.0
    rot_d: float = 30.0
    force_max: float = 150.0


DEFAULT_COMPLIANCE = Compliance()


def wall_force(pos: float, vel: float, low: float, high: float, c: Compliance) -> float:
    """The virtual wall's push back into the stroke ``[low, high]`` (zero inside it)."""
    if pos > high:
        return -c.wall_k * (pos - high) - c.wall_d * max(vel, 0.0)
    if pos < low:
        return c.wall_k * (low - pos) - c.wall_d * min(vel, 0.0)
    return 0.0


def compliant_torques(model: mujoco.MjModel, data: mujoco.MjData, work: Workspace, wrench: Sequence[float],
                      limits: np.ndarray) -> np.ndarray:
    """Joint torques of the compliant mode: gravity, Coriolis and joint friction compensated, plus
    ``J^T wrench`` (the impedance's force and torque at the flange site, world frame), clipped to
    ``limits``. ``data`` must hold the current state's position- and velocity-dependent quantities."""
    jac = work.jac
    mujoco.mj_jacSite(model, data, jac[:3], jac[3:], work.site)
    tau = work.jac6.T @ np.asarray(wrench, dtype=np.float64)
    tau += work.bias6
    tau -= work.passive6
    np.maximum(tau, -limits, out=tau)
    return np.minimum(tau, limits, out=tau)


def apply_hand_force(model: mujoco.MjModel, data: mujoco.MjData, site: int, force: np.ndarray) -> None:
    """The person's hand: ``force`` (world frame, N) at the flange site, as generalised forces in
    ``data.qfrc_applied`` (replacing what was there)."""
    data.qfrc_applied[:] = 0.0
    mujoco.mj_applyFT(model, data, np.asarray(force, dtype=np.float64), np.zeros(3), data.site_xpos[site],
                      int(model.site_bodyid[site]), data.qfrc_applied)


def command_from_motion(velocity: np.ndarray, dt: float, kv: float, window: float = 0.005) -> np.ndarray:
    """The velocity command under which a first-order servo of gain ``kv`` reproduces the measured
    ``velocity`` (``T`` samples by axes): ``v + a / kv``, ``a`` the velocity's central difference
    over ``±window`` s (one-sided at the ends)."""
    v = np.asarray(velocity, dtype=np.float64)
    if v.ndim == 1:
        v = v[:, None]
    n = len(v)
    if n < 2:
        return v.copy()
    k = max(1, int(round(window / dt)))
    idx = np.arange(n)
    hi, lo = np.minimum(idx + k, n - 1), np.maximum(idx - k, 0)
    a = (v[hi] - v[lo]) / ((hi - lo)[:, None] * dt)
    return v + a / kv
