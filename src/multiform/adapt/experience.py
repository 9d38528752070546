"""The robot's own experience: segments of its practice trials that it graded successful.

The paper's third form: grading its own trials "allows the robot to clean its own experience data
and improve". During practice (never during evaluation) every trial is graded stay by stay by the
judges; a stay the robot grades successful *with a margin* (score ≥ 0.5 + ``margin``, in a trial it
graded successful as a whole) joins the training data of the laws that ran in it. A stay the mentor
graded overrides the robot's verdict (the mentor's word on a segment is final).

Why a margin: from few demonstrations a judge is often unsure (with 10 demos the swing-up judge
has a single failed example and scores most stays 0.5-0.6); a law refitted on segments the judge
only half believes in would learn its own failures. At 0.8 only stays the judge is clearly sure of
count, and the trial must have gone on to succeed, so a swing-up that reached the catch but left
the pendulum too fast to hold is not taken as a good swing-up.

Stored in the model directory, apart from the mentor's data::

    experience/segments.jsonl        one record per own segment: source, scenario, trial, seed, the
                                     net version and the fit of each law that ran it, place,
                                     start/end, judge score, the mentor's verdict if any
    experience/traces/<source>.npz   the trial's trace (pickle-free, written atomically)
    experience/takeovers/<source>.h5 the mentor's demonstration from where the robot got stuck in
                                     that trial (:mod:`.takeover`; the demonstration file format)
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import Any

from ..demos.episode import Episode, SegmentLabel
from ..io import append_jsonl, read_jsonl
from ..learn.judge import TrialGrade
from ..learn.labels import ROBOT
from ..petri.net import APN
from ..runtime.trace import Trace

DEFAULT_MARGIN = 0.3


@dataclass(frozen=True)
class OwnSegment:
    """One stay of a practice trial that trains the laws that ran in it, with its provenance."""

    source: str                   # the trial's id, as in the label store (``<scenario>_<trial>``)
    scenario: str
    trial: int
    seed: int
    net_version: int
    place: str
    start: int
    end: int
    transitions: tuple[str, ...]  # the maneuvers run during the stay
    laws: dict[str, str]          # law -> fit that ran it
    judge_score: float
    mentor: bool | None = None    # the mentor's verdict on this stay, if it graded the trial

    def to_json(self) -> dict[str, Any]:
        d = asdict(self)
        d["transitions"] = list(self.transitions)
        return d

    @classmethod
    def from_json(cls, d: Mapping[str, Any]) -> OwnSegment:
        return cls(**{**{k: d[k] for k in cls.__dataclass_fields__ if k in d}, "transitions": tuple(d["transitions"])})


def select_segments(apn: APN, trace: Trace, grade: TrialGrade, source: str, scenario: str, trial: int,
                    margin: float = DEFAULT_MARGIN, mentor: Mapping[tuple[int, int], bool] | None = None
                    ) -> list[OwnSegment]:
    """The stays of ``trace`` (graded in ``grade``) that train the laws: graded ≥ 0.5 + ``margin`` in a
    trial graded successful, or graded successful by the mentor (``mentor`` maps (start, end) of a
    stay to its verdict, and overrides the robot's)."""
    mentor = mentor or {}
    tags = trace.tags()
    trial_ok = grade.success and trace.success
    out = []
    for g in grade.segments:
        verdict = mentor.get((g.start, g.end))
        keep = verdict if verdict is not None else (trial_ok and g.score >= 0.5 + margin)
        if not keep:
            continue
        ran = tuple(dict.fromkeys(t for t in tags[g.start:g.end].tolist() if t))
        laws = {apn.transition(t).law: apn.laws[apn.transition(t).law].fit_name
                for t in ran if t in apn.transition_ids and apn.transition(t).law}
        if not laws:
            continue
        out.append(OwnSegment(source, scenario, trial, int(trace.seed), int(trace.net_version), g.place, g.start,
                              g.end, ran, laws, round(float(g.score), 4), verdict))
    return out


class Experience:
    """The own-experience store of one model directory (``MODEL/experience``)."""

    def __init__(self, model_path: str | os.PathLike):
        self.folder = Path(model_path) / "experience"

    @property
    def index(self) -> Path:
        return self.folder / "segments.jsonl"

    def trace_path(self, source: str) -> Path:
        return self.folder / "traces" / f"{source}.npz"

    def segments(self) -> list[OwnSegment]:
        return [OwnSegment.from_json(d) for d in read_jsonl(self.index)] if self.index.exists() else []

    def add(self, trace: Trace, segments: Sequence[OwnSegment], source: str) -> None:
        """Keep ``trace`` and its ``segments`` (the trace first, so an index line always has its trace;
        a trial added again after a resume replaces nothing and adds no duplicate)."""
        path = self.trace_path(source)
        if not path.exists():
            trace.save(path)
        known = {(s.source, s.start, s.end) for s in self.segments()}
        for s in segments:
            if (s.source, s.start, s.end) not in known:
                append_jsonl(self.index, s.to_json())

    def keep_trace(self, trace: Trace, source: str) -> None:
        """Keep a trial's trace without segments (the mentor graded it, the laws learn nothing from it)."""
        path = self.trace_path(source)
        if not path.exists():
            trace.save(path)

    def takeover_path(self, source: str) -> Path:
        return self.folder / "takeovers" / f"{source}.h5"

    def add_takeover(self, episode: Episode, source: str, skill: str, env_name: str) -> None:
        """Keep the mentor's demonstration from where trial ``source`` got stuck (once)."""
        from ..demos.dataset import write_dataset
        path = self.takeover_path(source)
        if not path.exists():
            path.parent.mkdir(parents=True, exist_ok=True)
            write_dataset(path, [episode], skill, env_name, mentor="takeover")

    def takeovers(self) -> dict[str, Episode]:
        """The mentor's demonstrations from where practice trials got stuck, by trial id."""
        from ..demos.dataset import read_dataset
        folder = self.folder / "takeovers"
        return {p.stem: next(iter(read_dataset(p))) for p in sorted(folder.glob("*.h5"))} if folder.exists() else {}

    def episode(self, source: str) -> Episode:
        return Trace.load(self.trace_path(source)).to_episode()

    def law_episodes(self, law: str, segments: Sequence[OwnSegment] | None = None) -> list[Episode]:
        """The trials with own segments of ``law``, as episodes whose labels are exactly those
        segments (so :func:`~multiform.learn.views.law_data` takes their samples and no other)."""
        by_source: dict[str, list[OwnSegment]] = {}
        for s in self.segments() if segments is None else segments:
            if law in s.laws:
                by_source.setdefault(s.source, []).append(s)
        out = []
        for source in sorted(by_source):
            ep = self.episode(source)
            out.append(replace(ep, labels=[SegmentLabel(s.start, s.end, s.place, True, ROBOT)
                                           for s in by_source[source]]))
        return out
