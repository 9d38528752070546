"""One demonstration or trial as arrays, and the protocol a mentor follows.

The loop that records a mentor is in :mod:`multiform.teach.record`.

An :class:`Episode` is what the dataset stores per ``demo_N``: the observations the robot's own
sensors gave (named by the env's ``observation_names``), the mentor's end-effector commands, the
transition of the skill net the mentor said it was executing at every sample, and the mentor's
per-segment labels.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np


@dataclass(frozen=True)
class SegmentLabel:
    """A mentor's (or the robot's) verdict on one segment ``[start, end)`` of an episode."""

    start: int
    end: int
    transition: str
    success: bool
    labeller: str = "mentor"


@dataclass
class Episode:
    """Arrays of one recorded episode; ``T`` samples at the control rate. ``mentor`` names the person
    (or scripted mentor) who demonstrated it; its labels name who labelled them (``labeller``)."""

    obs: np.ndarray                  # (T, n_obs) float64
    actions: np.ndarray              # (T, n_cmd) float64, the command applied at each sample
    transitions: np.ndarray          # (T,) str, transition the mentor was executing
    observation_names: tuple[str, ...]
    command_names: tuple[str, ...]
    dt: float
    seed: int
    reset_options: dict[str, Any] = field(default_factory=dict)
    labels: list[SegmentLabel] = field(default_factory=list)
    outcome: str = ""                # "success" / "failure" as the mentor saw it
    mentor: str = ""                 # who demonstrated it ("" if not recorded)

    @property
    def num_samples(self) -> int:
        return int(self.obs.shape[0])

    @property
    def duration(self) -> float:
        return self.num_samples * self.dt

    def segments(self) -> list[tuple[int, int, str]]:
        """Maximal runs of one transition tag as ``(start, end, transition)``."""
        tags = self.transitions
        if len(tags) == 0:
            return []
        cut = np.flatnonzero(tags[1:] != tags[:-1]) + 1
        starts = np.concatenate([[0], cut])
        ends = np.concatenate([cut, [len(tags)]])
        return [(int(s), int(e), str(tags[s])) for s, e in zip(starts, ends)]

    def column(self, name: str) -> np.ndarray:
        """One observation entry by name."""
        return self.obs[:, self.observation_names.index(name)]


class Mentor(Protocol):
    """What a mentor (scripted or a person at a joystick) provides to the recorder.

    A scripted mentor stands in for a person: it may look at whatever a person would see, but the
    robot never calls its code. A task makes one with :meth:`multiform.Task.make_mentor`.

    ``name`` says who the mentor is (stored with every episode and label it makes). After the
    labels, the recorder reads an optional ``outcome`` attribute, ``"success"`` or
    ``"failure"``: the mentor's verdict on the whole attempt (a pushed demonstration the mentor
    recovered is a success with one failed segment); without it, a demonstration whose every
    segment succeeded is a success.
    """

    name: str

    def reset(self, obs: np.ndarray, rng: np.random.Generator) -> None:
        """Start a new demonstration from ``obs``; ``rng`` is seeded from the demonstration's seed.
        A mentor whose ``reset`` also takes a ``seed`` keyword is told that seed."""

    def act(self, obs: np.ndarray, info: dict[str, Any], t: float) -> tuple[np.ndarray, str]:
        """Return the command for this sample and the transition the mentor is executing.

        ``info`` is the env's step info; a person watching the scene sees what the env puts under
        ``info["scene"]`` (e.g. the true rod angles of a nunchaku), which the robot never reads.
        """

    def finished(self) -> bool:
        """True when the mentor ends the demonstration (skill done, or given up)."""

    def label(self, episode: Episode) -> list[SegmentLabel]:
        """Label every segment of ``episode`` success or failure, from what the mentor observed."""


MENTOR_NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.@+ -]{0,63}")


def check_mentor_name(name: str, element: str = "mentor") -> str:
    """A mentor's name as stored with episodes and labels: 1-64 letters, digits, ``_ . @ + -`` or
    spaces, starting with a letter or digit, and not the robot's own (``robot...``)."""
    from ..errors import InvalidInput
    if not isinstance(name, str) or not MENTOR_NAME.fullmatch(name) or name != name.strip():
        raise InvalidInput(f"a mentor's name is 1-64 letters, digits, '_', '.', '@', '+', '-' or spaces, starting "
                           f"with a letter or digit; got {name!r}", element=element)
    if name.startswith("robot"):
        raise InvalidInput(f"names starting with 'robot' are the robot's own grades; got {name!r}", element=element)
    return name


def mentors_of(episodes: Sequence[Episode]) -> list[str]:
    """The distinct mentors of ``episodes``, in order of first appearance (an episode without a
    recorded mentor counts as the mentor ``""``)."""
    out: list[str] = []
    for ep in episodes:
        if ep.mentor not in out:
            out.append(ep.mentor)
    return out
