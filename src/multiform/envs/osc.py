"""Reference controller of the arm-pendulum: end-effector velocity command → joint torques.

Split in two because the learned auxiliary inverse model (:mod:`multiform.learn.inverse`) takes the
place of the second half and is compared with it:

1. :func:`task_acceleration` — the desired end-effector task acceleration (linear x, y, z, angular
   x, y, z in the world frame), computed *only from the observation vector*, so the robot's runtime
   can compute it from its own sensors: a first-order velocity servo along the swing axis towards
   ``v_cmd`` (with a soft wall at the workspace limits), and PD holds of y, z and orientation at the
   workspace centre.
2. :func:`torques_for` — model-based inverse dynamics (computed torque): the site Jacobian ``J``,
   its time derivative, the joint-space mass matrix ``M`` and the bias forces (Coriolis, centrifugal,
   gravity, from MuJoCo) and the joint damping give
   ``tau = M J^-1 (a - Jdot qdot) + bias - passive``, clipped to the torque
   limits. With six joints and a six-dimensional task there is no null space; the home posture is
   far from singularities over the whole ±0.35 m stroke (smallest singular value of ``J`` ≥ 0.2).
   The pendulum's reaction on the flange (a few N) is left to the feedback.

:class:`ReferenceController` packages both as the executor's ``InverseModel``
(``torques(obs, command)``) using its own copy of the arm model filled from the observation, as
the real robot would compute it from joint encoders.

Gains (:class:`Gains`, all in SI units):

==========  =======  ===========================================================================
kv          30 1/s   velocity servo along x: ``a_x = kv (v - xdot)``; bandwidth 30 rad/s, 33 ms lag
wall        12 1/s   soft wall: the speed towards a limit is at most ``wall × distance`` to it
a_max       40 m/s²  cap on the commanded x acceleration
kp, kd      1600, 80 y and z hold (natural frequency 40 rad/s, critically damped)
kr, kw      1600, 80 orientation hold on the rotation-vector error
==========  =======  ===========================================================================
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import NamedTuple

import mujoco
import numpy as np
from numba.extending import register_jitable
from scipy.linalg.lapack import dgesv as _dgesv

OBSERVATION_NAMES: tuple[str, ...] = (
    "theta", "omega", "x", "xdot",
    "ee_x", "ee_y", "ee_z", "ee_vx", "ee_vy", "ee_vz",
    "ee_rx", "ee_ry", "ee_rz", "ee_wx", "ee_wy", "ee_wz",
    "q1", "q2", "q3", "q4", "q5", "q6", "qd1", "qd2", "qd3", "qd4", "qd5", "qd6")
"""The arm-pendulum env's observation layout (published by the env as ``observation_names``)."""

WORKSPACE_CENTRE = (0.0, -0.55, 0.3)   # flange position in the home posture [m]
X_LIMIT = 0.35                        # |x| the servo keeps the end-effector inside [m]
V_MAX = 1.5                           # largest commanded speed along x [m/s]
TORQUE_LIMITS = np.array([150.0, 150.0, 150.0, 30.0, 30.0, 30.0])   # N m, the actuators' ctrlrange
_NEG_LIMITS = -TORQUE_LIMITS

_I = {n: i for i, n in enumerate(OBSERVATION_NAMES)}
_X, _XD = _I["x"], _I["xdot"]
_EY, _EZ, _VY, _VZ = _I["ee_y"], _I["ee_z"], _I["ee_vy"], _I["ee_vz"]
_R0, _W0 = _I["ee_rx"], _I["ee_wx"]
_Q0, _QD0 = _I["q1"], _I["qd1"]


class Gains(NamedTuple):
    """Gains and limits of the task-space servo (see the module docstring). A named tuple, so the
    compiled inverse-model features (:mod:`multiform.envs.arm_servo`) can take it as a constant."""

    kv: float = 30.0
    wall: float = 12.0
    a_max: float = 40.0
    kp: float = 1600.0
    kd: float = 80.0
    kr: float = 1600.0
    kw: float = 80.0
    v_max: float = V_MAX
    x_limit: float = X_LIMIT
    centre: tuple[float, float, float] = WORKSPACE_CENTRE


DEFAULT_GAINS = Gains()


@register_jitable
def limited_velocity(v_cmd: float, x: float, gains: Gains = DEFAULT_GAINS) -> float:
    """The velocity the servo actually tracks: ``v_cmd`` clipped to ±v_max and by the soft wall."""
    v = min(max(v_cmd, -gains.v_max), gains.v_max)
    hi = gains.wall * (gains.x_limit - x)
    lo = -gains.wall * (gains.x_limit + x)
    return min(max(v, lo), hi)


def task_acceleration(obs: np.ndarray, v_cmd: float, gains: Gains = DEFAULT_GAINS) -> np.ndarray:
    """Desired end-effector acceleration ``[ax, ay, az, alpha_x, alpha_y, alpha_z]`` from ``obs``.

    ``obs`` is one observation of the arm-pendulum env (layout :data:`OBSERVATION_NAMES`); the
    orientation error is the rotation vector from the home orientation, so holding it at zero holds
    the pendulum's hinge axis along world y.
    """
    return np.array(task_acceleration_list(obs.tolist() if isinstance(obs, np.ndarray) else obs, v_cmd, gains))


@register_jitable
def task_acceleration_list(o: Sequence[float], v_cmd: float, gains: Gains = DEFAULT_GAINS) -> list[float]:
    """:func:`task_acceleration` on an observation list, as a list: plain floats in Python; also
    callable from compiled code (``register_jitable``), where ``o`` is an array."""
    g = gains
    x, xd = o[_X], o[_XD]
    ax = g.kv * (limited_velocity(float(v_cmd), x, g) - xd)
    ax = min(max(ax, -g.a_max), g.a_max)
    cy, cz = g.centre[1], g.centre[2]
    kp, kd, kr, kw = g.kp, g.kd, g.kr, g.kw
    return [
        ax,
        -kp * (o[_EY] - cy) - kd * o[_VY],
        -kp * (o[_EZ] - cz) - kd * o[_VZ],
        -kr * o[_R0] - kw * o[_W0],
        -kr * o[_R0 + 1] - kw * o[_W0 + 1],
        -kr * o[_R0 + 2] - kw * o[_W0 + 2]]


class PlanarGains(NamedTuple):
    """Gains and limits of the two-axis (x-z) velocity servo of a hand moving in the swing plane:
    the same first-order servo and soft walls as :class:`Gains` on each of x and z (the stroke
    ``x_limit`` either side of the centre, ``z_low``..``z_high`` about it), the same holds of y and
    the orientation; the commanded acceleration is capped at ``a_max`` in norm."""

    kv: float = 30.0
    wall: float = 12.0
    a_max: float = 40.0
    kp: float = 1600.0
    kd: float = 80.0
    kr: float = 1600.0
    kw: float = 80.0
    v_max: float = 2.0
    x_limit: float = 0.45
    z_low: float = -0.15
    z_high: float = 0.25
    centre: tuple[float, float, float] = WORKSPACE_CENTRE


def walled_velocity(v_cmd: float, pos: float, low: float, high: float, v_max: float, wall: float) -> float:
    """``v_cmd`` clipped to ±v_max and by soft walls at ``low`` and ``high``: the speed towards a
    wall is at most ``wall × distance`` to it."""
    v = v_max if v_cmd > v_max else -v_max if v_cmd < -v_max else v_cmd
    lo, hi = -wall * (pos - low), wall * (high - pos)
    return lo if v < lo else hi if v > hi else v


def planar_task_acceleration(x: float, z: float, xd: float, zd: float, ey: float, vy: float,
                             r: Sequence[float], w: Sequence[float], vx_cmd: float, vz_cmd: float,
                             gains: PlanarGains) -> list[float]:
    """Desired flange acceleration ``[ax, ay, az, alpha_x, alpha_y, alpha_z]`` for the velocity
    command ``(vx_cmd, vz_cmd)`` in the x-z plane: ``x``, ``z`` the flange's offset from the centre
    [m], ``xd``, ``zd`` its velocity, ``ey``, ``vy`` its y position and velocity in the world, ``r``
    the orientation error (rotation vector from home), ``w`` the angular velocity."""
    g = gains
    ax = g.kv * (walled_velocity(vx_cmd, x, -g.x_limit, g.x_limit, g.v_max, g.wall) - xd)
    az = g.kv * (walled_velocity(vz_cmd, z, g.z_low, g.z_high, g.v_max, g.wall) - zd)
    n = math.sqrt(ax * ax + az * az)
    if n > g.a_max:
        ax, az = ax * g.a_max / n, az * g.a_max / n
    return [ax, -g.kp * (ey - g.centre[1]) - g.kd * vy, az,
            -g.kr * r[0] - g.kw * w[0], -g.kr * r[1] - g.kw * w[1], -g.kr * r[2] - g.kw * w[2]]


class Workspace:
    """Preallocated buffers and array views for :func:`torques_for` on one ``(model, data)`` pair.

    Views into ``data`` are taken once, because every attribute access of an ``MjData`` builds a new
    numpy view (about 0.2 µs each) — too much on a 1 kHz path.
    """

    def __init__(self, model: mujoco.MjModel, data: mujoco.MjData, site: str = "flange"):
        self.data = data
        self.jac = np.zeros((6, model.nv))
        self.jdot = np.zeros((6, model.nv))
        self.jdq = np.zeros(6)
        self.jac6 = self.jac[:, :6]
        self.qacc = np.zeros(model.nv)
        self.qacc6 = self.qacc[:6]
        self.out = np.zeros(model.nv)
        self.out6 = self.out[:6]
        self.site = model.site(site).id
        self.body = int(model.site_bodyid[self.site])
        self.site_pos = data.site_xpos[self.site]
        self.qvel = data.qvel
        self.bias6 = data.qfrc_bias[:6]
        self.passive6 = data.qfrc_passive[:6]


def torques_for(a6: np.ndarray, model: mujoco.MjModel, data: mujoco.MjData,
                limits: np.ndarray = TORQUE_LIMITS, work: Workspace | None = None) -> np.ndarray:
    """Joint torques that give the flange the task acceleration ``a6`` (computed torque).

    ``data`` must hold the position- and velocity-dependent quantities of its current state
    (after ``mj_forward``, or ``mj_step1`` as the env does): site pose, ``qM``, ``qfrc_bias``,
    ``qfrc_passive``, ``cvel``. The joints' own damping (``qfrc_passive``) is compensated, like an
    identified friction model on a real arm. Only the six arm joints are actuated; the pendulum's
    coordinate gets no acceleration demand. The result is clipped to ``limits``. ``work`` (a :class:`Workspace` of this ``model``
    and ``data``) saves allocations on a 1 kHz path.
    """
    w = work if work is not None and work.data is data else Workspace(model, data)
    jac, jdot = w.jac, w.jdot
    mujoco.mj_jacSite(model, data, jac[:3], jac[3:], w.site)
    mujoco.mj_jacDot(model, data, jdot[:3], jdot[3:], w.site_pos, w.body)
    mujoco.mju_mulMatVec(w.jdq, jdot, w.qvel)          # the pendulum's column of J is zero
    rhs = a6 - w.jdq
    _, _, qacc, info = _dgesv(w.jac6, rhs)
    if info != 0:
        qacc = np.linalg.lstsq(w.jac6, rhs, rcond=None)[0]
    w.qacc6[:] = qacc
    mujoco.mj_mulM(model, data, w.out, w.qacc)
    tau = w.out6 + w.bias6
    tau -= w.passive6
    np.maximum(tau, _NEG_LIMITS if limits is TORQUE_LIMITS else -limits, out=tau)
    return np.minimum(tau, limits, out=tau)


class ReferenceController:
    """``torques(obs, command)``: the reference inverse model, from observations only.

    Keeps its own ``MjData`` of the arm model, sets its joints from the observed ``q1..q6``,
    ``qd1..qd6`` (the pendulum's hinge from ``theta``/``omega`` relative to the flange's tilt), and
    applies :func:`task_acceleration` then :func:`torques_for`. This is what a learned inverse
    model is compared with.
    """

    def __init__(self, model: mujoco.MjModel | None = None, gains: Gains = DEFAULT_GAINS):
        if model is None:
            from .arm_model import load_model
            model = load_model()
        self.model = model
        self.data = mujoco.MjData(model)
        self.gains = gains
        self._work = Workspace(model, self.data)
        self._hinge_q = int(model.joint("pendulum").qposadr[0])
        self._hinge_v = int(model.joint("pendulum").dofadr[0])
        self._qpos, self._qvel = self.data.qpos, self.data.qvel

    def set_state(self, obs: np.ndarray) -> None:
        """Load the robot's own model with the state an observation reports."""
        qpos, qvel = self._qpos, self._qvel
        qpos[:6] = obs[_Q0:_Q0 + 6]
        qvel[:6] = obs[_QD0:_QD0 + 6]
        qpos[self._hinge_q] = obs[0] - obs[_R0 + 1]
        qvel[self._hinge_v] = obs[1] - obs[_W0 + 1]
        mujoco.mj_fwdPosition(self.model, self.data)
        mujoco.mj_fwdVelocity(self.model, self.data)

    def torques_at(self, a6: np.ndarray, obs: np.ndarray) -> np.ndarray:
        """Torques for task acceleration ``a6`` in the state ``obs`` reports."""
        self.set_state(obs)
        return torques_for(a6, self.model, self.data, work=self._work)

    def torques(self, obs: np.ndarray, command: np.ndarray) -> np.ndarray:
        """Torques that track the end-effector command ``[v_cmd]`` from state ``obs``."""
        return self.torques_at(task_acceleration(obs, float(command[0]), self.gains), obs)
