"""Exploration during practice: a law that tries small, smooth variations of its own command.

A law learned from a few demonstrations is unsure away from them, and the robot cannot learn a
better command there from trials that only repeat the current one. On exploring trials each law's
command gets an Ornstein-Uhlenbeck deviation (smooth over ``tau`` seconds) whose size is a
fraction of the law's own noise level, the spread of the mentor's commands about the law in the
same states: the robot varies its maneuver about as much as the mentor's own hand did. Segments of
such trials that the judges grade successful then teach the law the variations that worked
(filtered imitation of its own successes, as in reward-weighted regression).

Written here rather than with a library: it runs inside the 1 kHz tick (one multiply-add per
command), and it must be reproducible from the trial's seed.
"""

from __future__ import annotations

import math
import numpy as np

from ..runtime.executor import Law


def law_noise(law: object) -> np.ndarray:
    """The law's noise level per output in command units (a :class:`~multiform.learn.gp.GPLaw`'s
    fitted noise, de-standardised)."""
    return float(getattr(law, "noise_")) * np.asarray(getattr(law, "y_scale_"), dtype=float).reshape(-1)


class ExploringLaw:
    """``law``'s command plus an OU deviation of standard deviation ``scale`` (per output)."""

    def __init__(self, law: Law, scale: np.ndarray, tau: float, dt: float, seed: int = 0):
        self.law = law
        self.scale = np.asarray(scale, dtype=float)
        self._a = math.exp(-dt / tau)
        self._b = math.sqrt(1.0 - self._a * self._a)
        self.reseed(seed)

    def reseed(self, seed: int) -> None:
        """Start a new deviation stream (one per trial, from the trial's seed)."""
        self._rng = np.random.default_rng([seed, 11])
        self._z = self._rng.standard_normal(len(self.scale))

    def predict_one(self, x: np.ndarray) -> np.ndarray:
        self._z = self._a * self._z + self._b * self._rng.standard_normal(len(self._z))
        return self.law.predict_one(x) + self.scale * self._z
