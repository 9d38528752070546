"""Small statistics the run reports: the Wilson score interval for a success rate."""

from __future__ import annotations

import math


def wilson(successes: int, trials: int, z: float = 1.959964) -> tuple[float, float]:
    """Wilson score interval (95 % by default) for ``successes`` out of ``trials``."""
    if trials <= 0:
        return 0.0, 1.0
    p = successes / trials
    denom = 1 + z * z / trials
    centre = (p + z * z / (2 * trials)) / denom
    half = z * math.sqrt(p * (1 - p) / trials + z * z / (4 * trials * trials)) / denom
    return max(0.0, centre - half), min(1.0, centre + half)


def rate(successes: int, trials: int) -> dict[str, float | int]:
    """``{successes, trials, rate, low, high}`` with the Wilson interval."""
    lo, hi = wilson(successes, trials)
    return {"successes": successes, "trials": trials, "rate": successes / trials if trials else 0.0,
            "low": lo, "high": hi}
