"""The append-only label store: who labelled which segment success or failure, and when.

One JSON-lines file (``labels.jsonl`` in the skill model directory); the first line is a format
header ``{"__format__": {"kind": "labels", "version": 1}}``, every further line one
:class:`LabelRecord`. Records are never edited or removed: a mentor who changes their mind adds a
new record for the same segment, which *supersedes* the earlier ones for training while the history
keeps both. Order in the file is the order of labelling (``time`` is for people to read).

Who counts as a mentor: any labeller whose name does not start with ``robot`` (the robot's own
grades can be kept here for the record, but never train a judge — that would teach the robot
its own mistakes).
"""

from __future__ import annotations

import datetime as _dt
import json
import os
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from ..errors import InvalidInput, Problem
from ..io import loads_json, read_bytes, write_text

KIND = "labels"
VERSION = 1
ROBOT = "robot"
_FIELDS = ("source", "start", "end", "transition", "place", "success", "labeller", "time")


def now() -> str:
    """The current UTC time as ISO 8601 (seconds)."""
    return _dt.datetime.now(_dt.timezone.utc).replace(microsecond=0).isoformat()


def is_mentor(labeller: str) -> bool:
    """Whether a label by ``labeller`` trains judges (everyone but the robot itself)."""
    return not labeller.startswith(ROBOT)


@dataclass(frozen=True)
class LabelRecord:
    """One verdict on segment ``[start, end)`` of ``source`` (a demo or trial id).

    ``place`` is the place whose judge the segment trains (the token's place during the maneuver
    ``transition``). ``score`` is set for the robot's own grades; ``note`` is free text.
    """

    source: str
    start: int
    end: int
    transition: str
    place: str
    success: bool
    labeller: str = "mentor"
    time: str = field(default_factory=now)
    score: float | None = None
    note: str = ""

    @property
    def key(self) -> tuple[str, int, int]:
        """The segment this record is about."""
        return (self.source, self.start, self.end)

    def to_json(self) -> dict[str, Any]:
        d = asdict(self)
        if d["score"] is None:
            del d["score"]
        if not d["note"]:
            del d["note"]
        return d


def parse_record(obj: Any, file: str = "", element: str = "") -> LabelRecord:
    """A :class:`LabelRecord` from a JSON object, every problem named."""
    if not isinstance(obj, dict):
        raise InvalidInput("must be a JSON object", file=file, element=element)
    problems = []

    def bad(key: str, msg: str) -> None:
        problems.append(Problem(file, f"{element}.{key}" if element else key, msg))

    for k in _FIELDS:
        if k not in obj:
            bad(k, "is missing")
    unknown = sorted(set(obj) - set(_FIELDS) - {"score", "note"})
    for k in unknown:
        bad(k, "unknown field")
    if problems:
        raise InvalidInput(problems)
    for k in ("source", "transition", "place", "labeller", "time"):
        if not isinstance(obj[k], str):
            bad(k, f"must be a string, got {obj[k]!r}")
    for k in ("source", "labeller"):
        if isinstance(obj[k], str) and not obj[k]:
            bad(k, "must not be empty")
    for k in ("start", "end"):
        if not isinstance(obj[k], int) or isinstance(obj[k], bool) or obj[k] < 0:
            bad(k, f"must be a non-negative integer, got {obj[k]!r}")
    if not problems and obj["end"] <= obj["start"]:
        bad("end", f"must be after start ({obj['start']}), got {obj['end']}")
    if not isinstance(obj["success"], bool):
        bad("success", f"must be true or false, got {obj['success']!r}")
    if isinstance(obj["time"], str):
        try:
            _dt.datetime.fromisoformat(obj["time"])
        except ValueError:
            bad("time", f"not an ISO 8601 time: {obj['time']!r}")
    score = obj.get("score")
    if score is not None and (not isinstance(score, (int, float)) or isinstance(score, bool) or not 0 <= score <= 1):
        bad("score", f"must be a number in [0, 1], got {score!r}")
    if not isinstance(obj.get("note", ""), str):
        bad("note", "must be a string")
    if problems:
        raise InvalidInput(problems)
    return LabelRecord(**{k: obj[k] for k in _FIELDS}, score=None if score is None else float(score),
                       note=obj.get("note", ""))


class LabelStore:
    """Append-only labels, in memory (``path=None``) or in a JSON-lines file.

    Every write re-reads and re-validates the file first and then replaces it atomically, so a
    corrupt file is reported (``InvalidInput`` naming file, line and field) and left untouched, and
    two writers never lose each other's records outright.
    """

    def __init__(self, path: str | os.PathLike | None = None):
        self.path = None if path is None else Path(path)
        self._records: list[LabelRecord] = []
        if self.path is not None and self.path.exists():
            self._records = self._read()

    # -- reading ------------------------------------------------------------------------------------
    def _read(self) -> list[LabelRecord]:
        assert self.path is not None
        f = str(self.path)
        try:
            lines = read_bytes(self.path, "label file").decode("utf-8").splitlines()
        except UnicodeDecodeError as exc:
            raise InvalidInput(f"not UTF-8 text ({exc})", file=f) from None
        objs = []
        for i, line in enumerate(lines, 1):
            if line.strip():
                objs.append((i, loads_json(line, f, f"line {i}")))
        if not objs:
            return []
        i0, head = objs[0]
        fmt = head.get("__format__") if isinstance(head, dict) else None
        if not isinstance(fmt, dict):
            raise InvalidInput("missing format header; not a multiform label file", file=f, element=f"line {i0}")
        if fmt.get("kind") != KIND:
            raise InvalidInput(f"holds {fmt.get('kind')!r}, expected {KIND!r}", file=f, element=f"line {i0}")
        if fmt.get("version") != VERSION:
            raise InvalidInput(f"format version {fmt.get('version')!r}, this multiform reads version {VERSION}",
                               file=f, element=f"line {i0}")
        return [parse_record(o, f, f"line {i}") for i, o in objs[1:]]

    @property
    def records(self) -> tuple[LabelRecord, ...]:
        """Every record, in the order they were added."""
        return tuple(self._records)

    def __len__(self) -> int:
        return len(self._records)

    def __iter__(self) -> Iterator[LabelRecord]:
        return iter(self._records)

    def history(self, source: str, start: int, end: int) -> list[LabelRecord]:
        """All records on one segment, oldest first."""
        return [r for r in self._records if r.key == (source, start, end)]

    def effective(self, place: str | None = None, transition: str | None = None,
                  sources: Iterable[str] | None = None) -> list[LabelRecord]:
        """The labels that train judges: per segment, the latest mentor record (robot grades are
        left out), optionally only for one ``place`` / ``transition`` / set of ``sources``."""
        latest: dict[tuple[str, int, int], LabelRecord] = {}
        for r in self._records:
            if is_mentor(r.labeller):
                latest[r.key] = r
        keep = set(sources) if sources is not None else None
        return [r for r in latest.values()
                if (place is None or r.place == place) and (transition is None or r.transition == transition)
                and (keep is None or r.source in keep)]

    # -- writing ------------------------------------------------------------------------------------
    def add(self, record: LabelRecord) -> LabelRecord:
        """Append one record."""
        self.add_many([record])
        return record

    def add_many(self, records: Sequence[LabelRecord]) -> None:
        """Append several records in one atomic write (all or none)."""
        records = [parse_record(r.to_json(), element=f"new record {i}") if isinstance(r, LabelRecord)
                   else parse_record(r, element=f"new record {i}") for i, r in enumerate(records)]
        if not records:
            return
        if self.path is not None:
            current = self._read() if self.path.exists() else []
            text = self.path.read_text(encoding="utf-8") if self.path.exists() else ""
            if not text.strip():
                text = json.dumps({"__format__": {"kind": KIND, "version": VERSION}}) + "\n"
            elif not text.endswith("\n"):
                text += "\n"
            text += "".join(json.dumps(r.to_json()) + "\n" for r in records)
            write_text(self.path, text)
            self._records = current
        self._records.extend(records)


def records_from_episode(source: str, labels: Iterable[Any], place_of: Callable[[str], str | None]
                         | Mapping[str, str], time: str | None = None) -> list[LabelRecord]:
    """Records for an episode's :class:`~multiform.demos.episode.SegmentLabel` list.

    ``place_of`` maps a transition to the place its segment is judged in (e.g.
    ``lambda t: token_place(apn, t)``); labels of transitions with no place are skipped.
    """
    get = place_of.get if isinstance(place_of, Mapping) else place_of
    stamp = time or now()
    out = []
    for lab in labels:
        place = get(lab.transition)
        if place is None:
            continue
        out.append(LabelRecord(source=source, start=int(lab.start), end=int(lab.end), transition=str(lab.transition),
                               place=str(place), success=bool(lab.success), labeller=str(lab.labeller), time=stamp))
    return out
