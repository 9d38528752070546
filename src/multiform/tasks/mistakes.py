"""How a scripted mentor picks the mistake of an attempt, the same way for every task's mentor."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np


def draw_mistake(rng: np.random.Generator, kinds: Sequence[str], fixed: str | None, rate: float,
                 weights: Sequence[float]) -> str:
    """``fixed`` if given; else one of ``kinds`` (drawn by ``weights``) with probability ``rate``, or
    ``"none"``. The draws are ``rng.random()`` then, for a mistake, ``rng.choice``: a mentor's attempts
    are fixed by its generator."""
    if fixed is not None:
        return fixed
    if rng.random() < rate:
        w = np.asarray(weights, dtype=float)
        return kinds[int(rng.choice(len(kinds), p=w / w.sum()))]
    return "none"
