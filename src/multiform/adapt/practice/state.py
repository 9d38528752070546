"""What practice has done so far, as typed records, and ``state.json`` (read back checked).

Every record is a dataclass; :func:`state_to_json` writes them as plain JSON and
:func:`state_from_json` reads them back, refusing a file whose entries have the wrong type or are
out of range (naming the entry), so a hand-edited or damaged ``state.json`` never runs a trial.
Files written before the records were typed load as before: keys a record no longer has are
ignored (``lambda_exhausted``, which is derived from ``revisions``; ``probe`` and ``held_off`` of
trials that held a way back off, which count as no evidence).
"""

from __future__ import annotations

import math
import types
import typing
from dataclasses import MISSING, asdict, dataclass, field, fields, is_dataclass
from typing import Any, Union

from ...errors import InvalidInput

STATE_VERSION = 2


@dataclass
class MentorGrade:
    """The mentor's grade of one practice trial: how many stays it labelled, how many it agreed on
    with the robot, and the judges it revised (place -> segments, CV score, kernel)."""

    trial: int
    stays: int = 0
    agree: int = 0
    mentor_success: int = 0
    robot_success: int = 0
    revised: dict[str, dict[str, Any]] | None = None


@dataclass
class Takeover:
    """The mentor took over a failed trial at ``tick`` (None: nowhere to take over from)."""

    trial: int
    tick: int | None = None
    time: float | None = None
    samples: int | None = None
    outcome: str | None = None


@dataclass
class TrialRecord:
    """One practice trial: its draw (seed, start, push), the net version that ran it, what happened
    and how it was graded."""

    trial: int
    success: bool
    seed: int = 0
    net_version: int = 0
    outcome: str = ""
    judge_score: float | None = None
    judge_places: dict[str, float] | None = None
    duration: float = 0.0
    fired: list[str] = field(default_factory=list)
    clips: dict[str, int] = field(default_factory=dict)
    wall: float = 0.0
    time: str = ""
    evidence: bool = True                  # False: it ended for a reason outside the net (no evidence for repair)
    explored: bool = False
    pushed: bool = False                   # the experimenter pushed in it
    draw: int | None = None                # the trial whose draw it replayed (an exam); None: its own
    mentor: MentorGrade | None = None
    takeover: Takeover | None = None
    own_segments: int = 0
    switch_states: dict[str, list[dict[str, float]]] = field(default_factory=dict)   # per transition with a
    # learned condition, the state at each of its firings (the firing-range exam's evidence)

    @property
    def drawn(self) -> int:
        """The draw this trial ran."""
        return self.trial if self.draw is None else self.draw


@dataclass
class RevisionRecord:
    """A revision practice made (``version`` None: constant failure that changed nothing, with why)."""

    version: int | None
    operator: str
    target: str = ""
    reason: str = ""
    after_trial: int = -1
    scenario: str = ""
    diagnosis: dict[str, Any] | None = None
    recovered: bool = False                # adopted on resume: recorded after the state was last saved


@dataclass
class Watch:
    """Revisions up to ``version`` on watch since ``after_trial``: the plain trials before them
    (``before``) against those after; with ``draws`` the same draws replayed (a paired exam)."""

    before_version: int
    version: int
    after_trial: int
    before: list[bool] = field(default_factory=list)
    draws: list[int] | None = None
    must_win: bool = False                 # a change no failure asked for: kept only if it wins
    by_margin: bool = False                # ... by EXAM_MARGIN trials: one trial won is what chaos gives
    then_stop: str | None = None           # practice stops after the exam, for this reason
    refit_on_revert: bool = False          # a revert lets the laws refit at once (the shortfall was shown)


@dataclass
class Trying:
    """The repair on trial: its candidate key, the versions around it, what it must beat."""

    key: str
    before_version: int
    version: int
    after_trial: int
    visited: list[str] = field(default_factory=list)
    failed: list[int] = field(default_factory=list)


@dataclass
class PracticeState:
    """What the loop has done so far (``state.json``)."""

    trial: int = 0
    trials: list[TrialRecord] = field(default_factory=list)
    revisions: list[RevisionRecord] = field(default_factory=list)
    failed_since_repair: list[int] = field(default_factory=list)
    repairs_without_effect: int = 0
    mentor_graded: list[MentorGrade] = field(default_factory=list)
    takeovers: list[Takeover] = field(default_factory=list)
    watch: Watch | None = None
    trying: Trying | None = None
    tried: list[str] = field(default_factory=list)
    last_refit_trial: int = -1
    refit_now: bool = False                # the next refit is due now and need not show a shortfall again
    checked: bool = False                  # the definition was held against the demonstrations
    floor_examined: bool = False           # the ways back's deeper floor was considered (``floor_exam``)
    switch_examined: bool = False          # the learned switches' smoothest setting was examined (``switch_exam``)
    ranges_examined: list[str] = field(default_factory=list)   # "<transition>:<variable>" held to the mentor's range
    done: bool = False
    stop_reason: str = ""
    format_version: int = STATE_VERSION

    @property
    def lambda_exhausted(self) -> list[str]:
        """Transitions whose λ was already lowered without curing the failures (:func:`~..repair.adjust_lambda`
        tries Λ on them no more), read off ``revisions``: a λ repair of a transition whose λ a repair
        set before exhausts it; a repair of anything else (a condition, a law, the structure) starts
        afresh; reverts and refits change nothing."""
        exhausted: set[str] = set()
        lowered: set[str] = set()
        for r in self.revisions:
            if r.operator == "set_lambda":
                if r.target in lowered:
                    exhausted.add(r.target)
                lowered.add(r.target)
            elif r.operator not in ("revert", "refit_law", "none"):
                exhausted = set()
        return sorted(exhausted)

    @property
    def streak(self) -> tuple[int, int]:
        """(successes, failures) in a row at the end; trials that are no evidence are passed over."""
        s = f = 0
        for tr in reversed(self.trials):
            if not tr.evidence:
                continue
            if tr.success and not f:
                s += 1
            elif not tr.success and not s:
                f += 1
            else:
                break
        return s, f

    def plain(self) -> list[TrialRecord]:
        """The trials that did not explore: they measure the skill as it is."""
        return [t for t in self.trials if not t.explored]

    def plain_rate(self, n: int) -> float:
        """The success rate over the last ``n`` plain trials (0 with none)."""
        last = self.plain()[-n:]
        return sum(t.success for t in last) / len(last) if last else 0.0

    def plain_of(self, version: int) -> list[TrialRecord]:
        """The plain trials net version ``version`` ran."""
        return [t for t in self.plain() if t.net_version == version]

    def robot_seconds(self) -> float:
        """The robot time its trials took [s]."""
        return float(sum(t.duration for t in self.trials))

    def last_revision_trial(self) -> int:
        """The trial after which the last revision (or no-repair record) was made; -1 before any."""
        return max((r.after_trial for r in self.revisions), default=-1)


def state_to_json(state: PracticeState) -> dict[str, Any]:
    """``state`` as plain JSON data (trial entries leave out what is at its default)."""
    d = asdict(state)
    d["trials"] = [_trial_json(t) for t in state.trials]
    d["format_version"] = STATE_VERSION
    return d


def _trial_json(t: TrialRecord) -> dict[str, Any]:
    d = asdict(t)
    for key in ("draw", "mentor", "takeover"):
        if d[key] is None:
            del d[key]
    for key, default in (("evidence", True), ("explored", False), ("pushed", False), ("own_segments", 0),
                         ("switch_states", {})):
        if d[key] == default:
            del d[key]
    return d


def state_from_json(data: Any, file: str) -> PracticeState:
    """The state in ``data`` (a parsed ``state.json``), checked: a wrong type or a number out of
    range raises :class:`~multiform.errors.InvalidInput` naming ``file`` and the entry."""
    if not isinstance(data, dict):
        raise InvalidInput("is not a practice state (expected a JSON object)", file=file)
    data = dict(data)
    for t in data.get("trials", []) if isinstance(data.get("trials"), list) else []:
        if isinstance(t, dict) and t.get("probe"):
            t["evidence"] = False            # a trial that held a way back off (older files)
    state = _build(PracticeState, data, file, "")
    if state.trial != len(state.trials):
        raise InvalidInput(f"says {state.trial} trials were run but lists {len(state.trials)}", file=file,
                           element="trial")
    for i, t in enumerate(state.trials):
        if t.trial != i:
            raise InvalidInput(f"is trial {t.trial}, expected {i}", file=file, element=f"trials[{i}].trial")
    for name in ("failed_since_repair",):
        bad = [k for k in getattr(state, name) if not 0 <= k < max(state.trial, 1)]
        if bad:
            raise InvalidInput(f"names trials that were not run: {bad[:5]}", file=file, element=name)
    return state


def _build(cls: type, data: Any, file: str, where: str) -> Any:
    if not isinstance(data, dict):
        raise InvalidInput(f"expected an object, got {type(data).__name__}", file=file, element=where or cls.__name__)
    hints = typing.get_type_hints(cls)
    known = {f.name for f in fields(cls)}
    kwargs = {}
    for name, value in data.items():
        if name in known:
            kwargs[name] = _value(hints[name], value, file, f"{where}.{name}" if where else name)
    missing = [f.name for f in fields(cls) if f.name not in kwargs and f.default is MISSING and f.default_factory is MISSING]
    if missing:
        raise InvalidInput(f"lacks {', '.join(missing)}", file=file, element=where or cls.__name__)
    return cls(**kwargs)


def _value(kind: Any, v: Any, file: str, where: str) -> Any:
    origin, args = typing.get_origin(kind), typing.get_args(kind)
    if origin in (Union, types.UnionType):
        if v is None and type(None) in args:
            return None
        (inner,) = [a for a in args if a is not type(None)]
        return _value(inner, v, file, where)
    if is_dataclass(kind):
        return _build(kind, v, file, where)
    if kind is Any:
        return v
    if kind is bool:
        if not isinstance(v, bool):
            raise InvalidInput(f"must be true or false, got {v!r}", file=file, element=where)
        return v
    if kind is int:
        if isinstance(v, bool) or not isinstance(v, int) or not -2**53 <= v <= 2**53:
            raise InvalidInput(f"must be a whole number, got {_show(v)}", file=file, element=where)
        if (where == "trial" or where.endswith(".trial")) and v < 0:
            raise InvalidInput(f"must not be negative, got {v}", file=file, element=where)
        return v
    if kind is float:
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            raise InvalidInput(f"must be a finite number, got {_show(v)}", file=file, element=where)
        return v
    if kind is str:
        if not isinstance(v, str):
            raise InvalidInput(f"must be a string, got {_show(v)}", file=file, element=where)
        return v
    if origin is list:
        if not isinstance(v, list):
            raise InvalidInput(f"must be a list, got {_show(v)}", file=file, element=where)
        return [_value(args[0], x, file, f"{where}[{i}]") for i, x in enumerate(v)]
    if origin is dict:
        if not isinstance(v, dict):
            raise InvalidInput(f"must be an object, got {_show(v)}", file=file, element=where)
        return {k: _value(args[1], x, file, f"{where}.{k}") for k, x in v.items()}
    raise TypeError(f"no check for {kind!r}")


def _show(v: Any) -> str:
    text = repr(v)
    return text if len(text) <= 40 else text[:37] + "..."
