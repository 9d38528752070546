"""The arm's maneuver servo and the load features its inverse model reads
(:class:`~multiform.learn.servos.Servo`, registered as ``arm_pendulum`` by :mod:`multiform.envs`).

Each formula is written once, on a math module ``m`` and indexable ``o`` (observation) and ``a``
(task acceleration): with ``numpy`` on the columns of many rows when fitting, and compiled
(``register_jitable``) inside the servo's one-state ``features`` function at the control rate. The
same Python built on lists took 8.5 µs a tick, the compiled function 1.8 µs, bit for bit the same.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numba import njit
from numba.extending import register_jitable

from ..learn.servos import Servo
from .osc import DEFAULT_GAINS, OBSERVATION_NAMES, task_acceleration_list

_TH, _OM = OBSERVATION_NAMES.index("theta"), OBSERVATION_NAMES.index("omega")
_ARM_JOINTS = tuple(OBSERVATION_NAMES.index(f"q{i + 1}") for i in range(6)) + \
    tuple(OBSERVATION_NAMES.index(f"qd{i + 1}") for i in range(6))


@register_jitable
def arm_pendulum_load(m: Any, o: Any, a: Any) -> tuple:
    """The pendulum's state as the residual GP reads it: sin θ, cos θ, ω."""
    th = o[_TH]
    return m.sin(th), m.cos(th), o[_OM]


@register_jitable
def arm_pendulum_basis(m: Any, o: Any, a: Any) -> tuple:
    """A rigid pendulum's pull on its pivot: gravity and centripetal terms, and its swing's
    response to the pivot's own acceleration (a_x, a_z) through θ̈."""
    th, om = o[_TH], o[_OM]
    s, c = m.sin(th), m.cos(th)
    w2, ax, az = om * om, a[0], a[2]
    return s, c, om, w2 * s, w2 * c, s * c, c * c, ax * c * c, ax * s * c, az * s * s, az * s * c


@njit(cache=True, nogil=True)
def arm_pendulum_features(obs: np.ndarray, command: tuple) -> np.ndarray:
    """One observation and end-effector command → ``[q, q̇, load, a, q, q̇, a, basis]``: the
    residual GP's inputs followed by the linear part's features, ``a`` the servo's desired task
    acceleration for the commanded velocity."""
    a = task_acceleration_list(obs, command[0], DEFAULT_GAINS)
    load = arm_pendulum_load(math, obs, a)
    basis = arm_pendulum_basis(math, obs, a)
    nj, nl, na = len(_ARM_JOINTS), len(load), len(a)
    lin = nj + nl + na                                  # where the linear part's features start
    out = np.empty(lin + nj + na + len(basis))
    for j, i in enumerate(_ARM_JOINTS):
        out[j] = out[lin + j] = obs[i]
    for j, v in enumerate(load):
        out[nj + j] = v
    for j, v in enumerate(a):
        out[nj + nl + j] = out[lin + nj + j] = v
    for j, v in enumerate(basis):
        out[lin + nj + na + j] = v
    return out


def arm_pendulum_servo() -> Servo:
    """The arm carrying a pendulum: its velocity servo along the swing axis and the pendulum's load."""
    return Servo(arm_pendulum_features, OBSERVATION_NAMES, arm_pendulum_load, arm_pendulum_basis)
