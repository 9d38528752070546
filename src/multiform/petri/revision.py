"""Revisions: the ways the robot changes its net, each recorded with its reason and evidence.

The paper's four operators change the net's structure, Λ and C (set λ, set a condition, add a
transition, add a place); **set a law** gives a transition another of the skill's laws (when the
mentor's demonstrations of that maneuver are better explained by it); two more come from learning
by practice: **refit a law** (the law runs
a new fit, learned from the mentor's demonstrations and the robot's own graded experience) and
**revert** (back to an earlier version, when a revision made the robot's own success rate clearly
worse).

Every operator returns a new :class:`~multiform.petri.net.APN` and a :class:`Revision` that holds
enough to replay it (``params``) and to show it (``before``/``after``). A :class:`History` keeps the
revisions as JSON lines beside the original definition, which it never writes; any version is
rebuilt as original + the first *n* revisions.
"""

from __future__ import annotations

import datetime as _dt
import os
from collections.abc import Mapping
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any

from ..errors import InvalidInput, Problem
from ..io import append_jsonl, read_jsonl
from .net import APN
from .skill_schema import IDENT, MAX_LAMBDA, parse_condition, parse_places, parse_transitions
from .skillfile import load_skill, skill_from_data, skill_to_data

OPERATORS = ("set_lambda", "set_condition", "set_law", "add_transition", "add_place", "refit_law", "revert")


@dataclass(frozen=True)
class Revision:
    """One recorded change of the net."""

    version: int                   # the version it creates (the original is 0); 0 until History.record numbers it
    operator: str
    target: str
    reason: str
    params: dict[str, Any]
    before: dict[str, Any] | None = None
    after: dict[str, Any] | None = None
    evidence: dict[str, Any] = field(default_factory=dict)
    time: str = ""

    def to_json(self) -> dict[str, Any]:
        return asdict(self)

    @classmethod
    def from_json(cls, d: Mapping[str, Any], where: str = "") -> Revision:
        if not isinstance(d, Mapping):
            raise InvalidInput(f"a revision record must be an object, got {type(d).__name__}", element=where)
        missing = [k for k in ("version", "operator", "target", "reason", "params") if k not in d]
        if missing:
            raise InvalidInput(f"revision record lacks {', '.join(missing)}", element=where)
        if d["operator"] not in OPERATORS:
            raise InvalidInput(f"unknown revision operator {d['operator']!r}", element=where)
        known = {f for f in cls.__dataclass_fields__}
        return cls(**{k: v for k, v in d.items() if k in known})


def _now() -> str:
    return _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds")


def _check(problems: list[Problem]) -> None:
    if problems:
        raise InvalidInput(problems)


# -- the operators --------------------------------------------------------------------------------

def set_lambda(apn: APN, transition: str, value: float, reason: str,
               evidence: Mapping[str, Any] | None = None) -> tuple[APN, Revision]:
    """Set λ of ``transition`` and renormalise its siblings (same input places).

    The choice group's total λ stays what it was: the siblings share what is left in proportion to
    their old values (equally if they were all zero). ``value`` must lie in [0, group total].
    """
    if transition not in apn.transition_ids:
        raise InvalidInput(f"unknown transition {transition!r}", element="set_lambda")
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not 0 <= value <= MAX_LAMBDA:
        raise InvalidInput(f"λ must be a number in 0..{MAX_LAMBDA:g}, got {value!r}", element=transition)
    group = [transition, *apn.siblings(transition)]
    old = {t: apn.transition(t).lam for t in group}
    total = sum(old.values())
    if len(group) > 1 and value > total:
        raise InvalidInput(f"λ {value} exceeds the choice group's total {total}", element=transition)
    new = dict(old)
    new[transition] = float(value)
    rest_old = total - old[transition]
    rest_new = total - value
    for s in group[1:]:
        if len(group) == 1:
            break
        new[s] = rest_new * (old[s] / rest_old) if rest_old > 0 else rest_new / (len(group) - 1)
    out = apn
    for t, lam in new.items():
        out = out.with_transition(replace(out.transition(t), lam=float(lam)))
    rev = Revision(version=0, operator="set_lambda", target=transition,
                   reason=reason, params={"transition": transition, "lambda": float(value)},
                   before={"lambda": old}, after={"lambda": new}, evidence=dict(evidence or {}), time=_now())
    return out, rev


def set_condition(apn: APN, transition: str, condition: str | Mapping[str, str], reason: str,
                  evidence: Mapping[str, Any] | None = None) -> tuple[APN, Revision]:
    """Replace the condition of ``transition`` with an expression or ``{"model": name}``."""
    if transition not in apn.transition_ids:
        raise InvalidInput(f"unknown transition {transition!r}", element="set_condition")
    problems: list[Problem] = []
    cond = parse_condition(condition, f"transitions.{transition}.condition", apn.condition_variables(),
                           lambda el, msg: problems.append(Problem("", el, msg)),
                           set(apn.transition_ids) - {transition})
    _check(problems)
    t = apn.transition(transition)
    out = apn.with_transition(replace(t, condition=cond))
    rev = Revision(version=0, operator="set_condition", target=transition,
                   reason=reason, params={"transition": transition, "condition": cond.to_data()},
                   before={"condition": t.condition.to_data()}, after={"condition": cond.to_data()},
                   evidence=dict(evidence or {}), time=_now())
    return out, rev


def set_law(apn: APN, transition: str, law: str, reason: str, evidence: Mapping[str, Any] | None = None
            ) -> tuple[APN, Revision]:
    """Run ``law`` (one of the skill's laws) while ``transition``'s maneuver is active."""
    if transition not in apn.transition_ids:
        raise InvalidInput(f"unknown transition {transition!r}", element="set_law")
    if law not in apn.laws:
        raise InvalidInput(f"unknown law {law!r}; the skill's laws are {', '.join(sorted(apn.laws))}",
                           element=f"transitions.{transition}.law")
    t = apn.transition(transition)
    out = apn.with_transition(replace(t, law=law))
    rev = Revision(version=0, operator="set_law", target=transition, reason=reason,
                   params={"transition": transition, "law": law}, before={"law": t.law}, after={"law": law},
                   evidence=dict(evidence or {}), time=_now())
    return out, rev


def add_transition(apn: APN, transition: str, spec: Mapping[str, Any], reason: str,
                   evidence: Mapping[str, Any] | None = None) -> tuple[APN, Revision]:
    """Add a new transition described like in a skill file (``in``, ``out``, ``law``, ...)."""
    if transition in apn.transition_ids or transition in apn.place_ids:
        raise InvalidInput(f"id {transition!r} is already used", element="add_transition")
    problems: list[Problem] = []
    bad = lambda el, msg: problems.append(Problem("", el, msg))  # noqa: E731
    ids = set(apn.transition_ids) | {transition}
    allowed = apn.condition_variables() | {f"fires_{transition}"}
    (t,) = parse_transitions({transition: dict(spec)}, set(apn.place_ids), ids, allowed, dict(apn.laws), bad) or (None,)
    if t is not None and not t.inputs and not t.outputs:
        bad(f"transitions.{transition}", "a transition needs at least one arc")
    _check(problems)
    out = apn.with_transition(t)
    rev = Revision(version=0, operator="add_transition", target=transition,
                   reason=reason, params={"transition": transition, "spec": t.to_data()},
                   before=None, after=t.to_data(), evidence=dict(evidence or {}), time=_now())
    return out, rev


def add_place(apn: APN, place: str, spec: Mapping[str, Any] | None, reason: str,
              evidence: Mapping[str, Any] | None = None) -> tuple[APN, Revision]:
    """Add a new place (``label``, optional ``judge``); connect it with :func:`add_transition`."""
    if place in apn.place_ids or place in apn.transition_ids:
        raise InvalidInput(f"id {place!r} is already used", element="add_place")
    problems: list[Problem] = []
    (p,) = parse_places({place: dict(spec or {})}, lambda el, msg: problems.append(Problem("", el, msg))) or (None,)
    _check(problems)
    out = apn.with_place(p)
    rev = Revision(version=0, operator="add_place", target=place, reason=reason,
                   params={"place": place, "spec": p.to_data()}, before=None, after=p.to_data(),
                   evidence=dict(evidence or {}), time=_now())
    return out, rev


def refit_law(apn: APN, law: str, fit: str, reason: str,
              evidence: Mapping[str, Any] | None = None) -> tuple[APN, Revision]:
    """Point ``law`` at the fitted law ``fit`` (a model directory's ``laws/<fit>.npz``)."""
    if law not in apn.laws:
        raise InvalidInput(f"unknown law {law!r}", element="refit_law")
    if not isinstance(fit, str) or not IDENT.match(fit):
        raise InvalidInput(f"not a valid fit name: {fit!r}", element=f"laws.{law}.fit")
    old = apn.laws[law]
    out = replace(apn, laws={**apn.laws, law: replace(old, fit="" if fit == law else fit)})
    rev = Revision(version=0, operator="refit_law", target=law, reason=reason,
                   params={"law": law, "fit": fit}, before={"fit": old.fit_name}, after={"fit": fit},
                   evidence=dict(evidence or {}), time=_now())
    return out, rev


def revert(apn: APN, to_version: int, net: APN, reason: str,
           evidence: Mapping[str, Any] | None = None) -> tuple[APN, Revision]:
    """Go back to ``net``, the net as it was at ``to_version``; the revision holds that net whole,
    so replaying it needs nothing but the record."""
    if not isinstance(to_version, int) or to_version < 0:
        raise InvalidInput(f"to_version must be a version number >= 0, got {to_version!r}", element="revert")
    data = skill_to_data(net)
    rev = Revision(version=0, operator="revert", target=f"version {to_version}",
                   reason=reason, params={"to_version": to_version, "net": data},
                   before={"laws": {k: v.fit_name for k, v in apn.laws.items()}},
                   after={"laws": {k: v.fit_name for k, v in net.laws.items()}},
                   evidence=dict(evidence or {}), time=_now())
    return net, rev


def apply(apn: APN, rev: Revision) -> APN:
    """Replay one revision on ``apn`` (the version before it)."""
    p = rev.params
    try:
        if rev.operator == "set_lambda":
            out, _ = set_lambda(apn, p["transition"], p["lambda"], rev.reason)
        elif rev.operator == "set_condition":
            out, _ = set_condition(apn, p["transition"], p["condition"], rev.reason)
        elif rev.operator == "set_law":
            out, _ = set_law(apn, p["transition"], p["law"], rev.reason)
        elif rev.operator == "add_transition":
            out, _ = add_transition(apn, p["transition"], p["spec"], rev.reason)
        elif rev.operator == "add_place":
            out, _ = add_place(apn, p["place"], p["spec"], rev.reason)
        elif rev.operator == "refit_law":
            out, _ = refit_law(apn, p["law"], p["fit"], rev.reason)
        elif rev.operator == "revert":
            if not isinstance(p["net"], Mapping):
                raise InvalidInput("a revert's net must be a skill mapping", element=f"version {rev.version}")
            out = skill_from_data(p["net"], f"version {rev.version}")
        else:
            raise InvalidInput(f"unknown revision operator {rev.operator!r}", element=f"version {rev.version}")
    except KeyError as exc:
        raise InvalidInput(f"revision parameters lack {exc}", element=f"version {rev.version}") from None
    return out


class History:
    """The revision history of one skill: the original definition plus a JSON-lines file of revisions.

    ``original`` is the path of the definition as the mentor wrote it; it is only ever read.
    The history lives at ``path`` (default: ``<original stem>.history.jsonl`` beside it).
    """

    def __init__(self, original: str | os.PathLike, path: str | os.PathLike | None = None):
        self.original = Path(original)
        self.path = Path(path) if path is not None else self.original.with_name(
            self.original.stem + ".history.jsonl")

    def revisions(self) -> list[Revision]:
        if not self.path.exists():
            return []
        revs = []
        for i, rec in enumerate(read_jsonl(self.path), 1):
            if not isinstance(rec, dict):
                raise InvalidInput(f"must be a JSON object, got {type(rec).__name__}", file=str(self.path),
                                   element=f"record {i}")
            try:
                rev = Revision.from_json(rec, where=f"record {i}")
            except InvalidInput as exc:
                raise InvalidInput([Problem(str(self.path), p.element, p.message) for p in exc.problems]) from None
            if not isinstance(rev.params, dict) or isinstance(rev.version, bool) or not isinstance(rev.version, int):
                raise InvalidInput("version must be a whole number and params an object", file=str(self.path),
                                   element=f"record {i}")
            if rev.version != i:
                raise InvalidInput(f"record {i} says version {rev.version}; versions must count 1, 2, ...",
                                   file=str(self.path))
            revs.append(rev)
        return revs

    def versions(self) -> list[APN]:
        """Every version: [original, after revision 1, after revision 2, ...]."""
        nets = [load_skill(self.original)]
        for rev in self.revisions():
            try:
                nets.append(apply(nets[-1], rev))
            except InvalidInput as exc:   # name the history file and the record that does not replay
                raise InvalidInput([Problem(str(self.path), f"record {rev.version} ({rev.operator} {rev.target})",
                                            str(p)) for p in exc.problems]) from None
            except (TypeError, ValueError, AttributeError) as exc:
                raise InvalidInput(f"does not replay: {exc}", file=str(self.path),
                                   element=f"record {rev.version} ({rev.operator} {rev.target})") from None
        return nets

    def latest(self) -> APN:
        return self.versions()[-1]

    def version(self, n: int) -> APN:
        nets = self.versions()
        if not -len(nets) <= n < len(nets):
            raise InvalidInput(f"no version {n}: versions are 0..{len(nets) - 1}", file=str(self.path))
        return nets[n]

    def record(self, rev: Revision) -> Revision:
        """Append ``rev`` as the next version and return it so numbered: the history alone numbers versions."""
        rev = replace(rev, version=self.next_version())
        append_jsonl(self.path, rev.to_json())
        return rev

    def next_version(self) -> int:
        """The number the next recorded revision gets."""
        return len(self.revisions()) + 1
