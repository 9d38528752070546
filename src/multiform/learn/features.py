"""A segment's trajectory as a fixed-length feature vector, with a name for every feature.

A judge never sees raw time series: the mentor's verdict on a sub-procedure is mostly about where
it ended (upright or not), how wild it got on the way (extrema) and how long it took. For each of
the judge's variables the features are, in this order::

    <v>.start  <v>.end  <v>.min  <v>.max  <v>.mean  <v>.std  <v>.absmax

followed by ``duration`` (seconds). Names are stored with every saved judge, so a model trained on
other variables is refused when loaded.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

from ..errors import InvalidInput

STATS = ("start", "end", "min", "max", "mean", "std", "absmax")


class EpisodeLike(Protocol):
    """What segment extraction reads: an :class:`~multiform.demos.episode.Episode` or a trial's
    ``Trace.to_episode()`` both qualify."""

    obs: np.ndarray
    observation_names: tuple[str, ...]
    dt: float


@dataclass(frozen=True)
class Segment:
    """Samples ``[start, end)`` of one episode: ``values`` (T, k) of the variables ``names``.

    ``source`` names the episode (``demo_3``, ``trial_12``) so a grade or a label can point back at it.
    """

    values: np.ndarray
    names: tuple[str, ...]
    dt: float
    source: str = ""
    start: int = 0
    end: int = 0
    transition: str = ""

    @property
    def duration(self) -> float:
        return int(self.values.shape[0]) * float(self.dt)

    def columns(self, names: Sequence[str]) -> np.ndarray:
        """The (T, len(names)) values of ``names``; a missing one raises :class:`InvalidInput`."""
        missing = [n for n in names if n not in self.names]
        if missing:
            raise InvalidInput(f"segment has no variable(s) {', '.join(missing)} (it has: {', '.join(self.names)})",
                               element=f"{self.source}[{self.start}:{self.end}]")
        idx = [self.names.index(n) for n in names]
        return np.asarray(self.values, dtype=np.float64)[:, idx]


def segment_from_episode(ep: EpisodeLike, start: int, end: int, names: Sequence[str] | None = None,
                         source: str = "", transition: str = "") -> Segment:
    """Cut samples ``[start, end)`` of ``ep``, keeping the observation entries ``names`` (all if None).

    Derived variables must be columns of ``ep.obs`` (``Trace.to_episode`` adds them); for a
    demonstration, build the values with :func:`multiform.learn.views.value_matrix` and use
    :class:`Segment` directly.
    """
    n = int(ep.obs.shape[0])
    where = f"{source or 'episode'}[{start}:{end}]"
    if not (0 <= start < end <= n):
        raise InvalidInput(f"segment bounds outside the episode's {n} samples", element=where)
    names = tuple(ep.observation_names) if names is None else tuple(names)
    missing = [v for v in names if v not in ep.observation_names]
    if missing:
        raise InvalidInput(f"episode has no variable(s) {', '.join(missing)} "
                           f"(it has: {', '.join(ep.observation_names)})", element=where)
    idx = [list(ep.observation_names).index(v) for v in names]
    if not transition and hasattr(ep, "transitions"):
        transition = str(ep.transitions[start])
    return Segment(np.asarray(ep.obs[start:end][:, idx], dtype=np.float64), names, float(ep.dt),
                   source, int(start), int(end), transition)


def feature_names(variables: Sequence[str]) -> list[str]:
    """Names of the features :func:`segment_features` returns for ``variables``."""
    return [f"{v}.{s}" for v in variables for s in STATS] + ["duration"]


def trajectory_features(values: np.ndarray, dt: float) -> np.ndarray:
    """Features of one trajectory ``values`` (T, k) sampled every ``dt`` s; shape (7k + 1,)."""
    v = np.asarray(values, dtype=np.float64)
    if v.ndim == 1:
        v = v[:, None]
    if v.shape[0] == 0:
        raise ValueError("an empty segment has no features")
    stats = np.stack([v[0], v[-1], v.min(0), v.max(0), v.mean(0), v.std(0), np.abs(v).max(0)], axis=1)
    return np.concatenate([stats.reshape(-1), [v.shape[0] * float(dt)]])


def segment_features(segment: Segment, variables: Sequence[str]) -> np.ndarray:
    """Features of ``segment`` over ``variables`` (a subset of its names), in :func:`feature_names` order."""
    return trajectory_features(segment.columns(variables), segment.dt)


def feature_matrix(segments: Sequence[Segment], variables: Sequence[str]) -> np.ndarray:
    """One row of features per segment; shape (n, 7k + 1)."""
    if not segments:
        return np.zeros((0, len(feature_names(variables))))
    return np.stack([segment_features(s, variables) for s in segments])


def check_names(expected: Sequence[str], got: Sequence[str], file: str, element: str) -> None:
    """Raise :class:`InvalidInput` unless two name lists agree exactly (saved vs the skill's)."""
    if list(expected) != list(got):
        raise InvalidInput(f"saved for {list(got)}, but the skill uses {list(expected)}", file=file, element=element)


def as_str_list(value: Any, file: str, element: str) -> list[str]:
    """A JSON list of strings from saved metadata, or :class:`InvalidInput`."""
    if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
        raise InvalidInput("must be a list of names", file=file, element=element)
    return list(value)
