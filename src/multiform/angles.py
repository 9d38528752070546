"""Angles: one wrap to (-π, π], used by the guard language, the envs' sensors and the mentors."""

from __future__ import annotations

import math


def wrap_angle(a: float) -> float:
    """``a`` wrapped to (-π, π]."""
    w = math.fmod(a + math.pi, 2.0 * math.pi)
    if w <= 0.0:
        w += 2.0 * math.pi
    return w - math.pi
