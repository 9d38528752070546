"""The registry of robots' maneuver servos (:class:`Servo`) that inverse models name.

The method knows no robot: a robot's package registers its servo here by name
(:func:`register_servo`), and a saved inverse model names the servo it was fitted with, so loading
one never runs code from the file. The bundled arm's servo (``arm_pendulum``) is known without
importing its env: :func:`servo_factory` imports it from :data:`multiform.registry.SERVOS` when a
model first names it.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..registry import SERVOS as BUNDLED_SERVOS


@dataclass(frozen=True)
class Servo:
    """A robot's fixed maneuver servo and the load features its inverse model reads.

    ``load`` and ``basis`` take a math module and return a tuple of features: called with ``numpy``
    on the columns of many rows (fitting) and compiled into ``features`` for one state at the
    control rate — one formula for both. ``features(obs, command)`` returns the GP's inputs
    ``[q, q̇, load, a]`` followed by the linear features ``[q, q̇, a, basis]``, ``a`` the servo's
    desired task acceleration for the command.
    """

    features: Callable[[np.ndarray, tuple], np.ndarray]
    observation_names: tuple[str, ...]
    load: Callable[[Any, Sequence, Sequence], tuple]             # (math|numpy, obs, a) -> GP load inputs
    basis: Callable[[Any, Sequence, Sequence], tuple]            # (math|numpy, obs, a) -> linear load features


SERVOS: dict[str, Callable[[], Servo]] = {}


def register_servo(name: str, factory: Callable[[], Servo]) -> None:
    """Make the servo ``name`` known; ``factory()`` builds it when a model first needs it."""
    SERVOS[name] = factory


def servo_factory(name: Any) -> Callable[[], Servo] | None:
    """What builds the servo ``name``: a registered one, or a bundled one (imported now); None if unknown."""
    if name not in SERVOS and isinstance(name, str) and name in BUNDLED_SERVOS:
        module, func = BUNDLED_SERVOS[name].split(":")
        SERVOS[name] = getattr(importlib.import_module(module), func)
    return SERVOS.get(name)


def known_servos() -> list[str]:
    """The names of every registered and bundled servo."""
    return sorted(set(SERVOS) | set(BUNDLED_SERVOS))
