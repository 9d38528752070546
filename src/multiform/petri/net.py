"""The adaptive Petri net M = (P, T, A, m0, Λ, C) and the skill data that travels with it.

An :class:`APN` is immutable: a revision produces a new one (see :mod:`multiform.petri.revision`),
so every version of a net can be kept, compared and drawn. Places are judged states, transitions
are maneuvers run by one control law each; ``lam`` is a transition's firing weight λ and
``condition`` its firing condition over continuous state.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from functools import cached_property
from typing import Any

import numpy as np

from .guard import Guard, parse_guard

FINAL_KINDS = ("success", "failure")
CLOCK_VARIABLES = ("time", "dwell")      # trial time; the dwell of the transition's own input place


def is_clock(name: str) -> bool:
    """Whether ``name`` is one of a net's clocks and counters (``time``, ``dwell``, ``dwell_<place>``,
    ``fires_<transition>``) rather than a state or derived variable."""
    return name in CLOCK_VARIABLES or name.startswith(("dwell_", "fires_"))


def value_names(variables: Sequence[str], derived: Sequence[str], place_ids: Sequence[str],
                transition_ids: Sequence[str]) -> tuple[str, ...]:
    """The values a net keeps while it runs, in the order :class:`~.firing.NetRunner` stores them:
    the state variables, the derived variables, ``time``, ``dwell_<place>`` per place and
    ``fires_<transition>`` per transition."""
    return (*variables, *derived, "time", *(f"dwell_{p}" for p in place_ids),
            *(f"fires_{t}" for t in transition_ids))


def condition_names(variables: Sequence[str], derived: Sequence[str], place_ids: Sequence[str],
                    transition_ids: Sequence[str]) -> frozenset[str]:
    """Every name a condition or law input may read: the :func:`value_names` and ``dwell`` (the
    dwell of the transition's own input place). The skill loader asks before the net exists;
    :meth:`APN.condition_variables` for a net."""
    return frozenset(value_names(variables, derived, place_ids, transition_ids)) | set(CLOCK_VARIABLES)


@dataclass(frozen=True)
class Condition:
    """A firing condition: a guard expression, or a reference to a learned model by name.

    A learned condition may name transitions it yields to (``unless``): it holds only where none of
    their conditions holds. A way back from P2 to P1 learned from regions yields to the way in (P1
    to P2); otherwise at a state where both hold the token would flip between the places every tick.
    It may also be held to a region of the state (``within``, a guard expression): it holds only
    where that expression holds too (practice's firing-range exam keeps a learned switch to where
    the mentor switched in a variable the switch does not read).
    """

    guard: Guard | None = None
    model: str | None = None
    unless: tuple[str, ...] = ()
    within: Guard | None = None

    @classmethod
    def always(cls) -> Condition:
        return cls(guard=parse_guard("true"))

    @classmethod
    def expression(cls, text: str, allowed: set[str] | frozenset[str] | None = None) -> Condition:
        return cls(guard=parse_guard(text, allowed))

    @classmethod
    def learned(cls, name: str, unless: Sequence[str] = (), within: Guard | None = None) -> Condition:
        return cls(model=name, unless=tuple(unless), within=within)

    @property
    def is_learned(self) -> bool:
        return self.model is not None

    @property
    def variables(self) -> frozenset[str]:
        """The variables its expressions read (a learned model's inputs are the model's)."""
        out = self.guard.variables if self.guard is not None else frozenset()
        return out | self.within.variables if self.within is not None else out

    def to_data(self) -> str | dict[str, Any]:
        """The skill-file form: the expression text, or ``{"model": name}`` (with ``unless`` and ``within``)."""
        if self.model is None:
            return self.guard.text
        out: dict[str, Any] = {"model": self.model}
        if self.unless:
            out["unless"] = list(self.unless)
        if self.within is not None:
            out["within"] = self.within.text
        return out

    def __str__(self) -> str:
        if self.model is None:
            return self.guard.text
        return (f"learned:{self.model}" + (f" unless {', '.join(self.unless)}" if self.unless else "")
                + (f" within {self.within.text}" if self.within is not None else ""))


@dataclass(frozen=True)
class Place:
    """A judged state of the skill; ``final`` marks the end places of a trial."""

    id: str
    label: str = ""
    final: str | None = None
    judge: tuple[str, ...] = ()

    def to_data(self) -> dict[str, Any]:
        out: dict[str, Any] = {}
        if self.label:
            out["label"] = self.label
        if self.final:
            out["final"] = self.final
        if self.judge:
            out["judge"] = list(self.judge)
        return out


@dataclass(frozen=True)
class Transition:
    """A maneuver: consumes ``inputs`` tokens, produces ``outputs``, runs ``law`` while active."""

    id: str
    inputs: Mapping[str, int]
    outputs: Mapping[str, int]
    law: str | None = None
    lam: float = 1.0
    condition: Condition = field(default_factory=Condition.always)
    label: str = ""

    @property
    def preset(self) -> frozenset[str]:
        return frozenset(self.inputs)

    def to_data(self) -> dict[str, Any]:
        out: dict[str, Any] = {}
        if self.label:
            out["label"] = self.label
        out["in"] = _arcs_data(self.inputs)
        out["out"] = _arcs_data(self.outputs)
        if self.law:
            out["law"] = self.law
        out["lambda"] = float(self.lam)
        out["condition"] = self.condition.to_data()
        return out


def _arcs_data(arcs: Mapping[str, int]) -> list[str] | dict[str, int]:
    if all(w == 1 for w in arcs.values()):
        return list(arcs)
    return {p: int(w) for p, w in arcs.items()}


@dataclass(frozen=True)
class Law:
    """A control law: which variables it reads, which commands it writes, its GP's mean function
    (``constant``, or ``linear`` for a maneuver that is a feedback about an operating point and
    should extrapolate as one), and the mentor's reaction time it is learned across (``lag`` s: the
    state at t is paired with the command the mentor gave at t + lag). ``fit`` names the fitted
    law a model directory runs for it (``laws/<fit>.npz``; default the law's own name): a refit
    from the robot's own experience is a revision that points the law at a new fit."""

    name: str
    inputs: tuple[str, ...]
    outputs: tuple[str, ...]
    mean: str = "constant"
    description: str = ""
    lag: float = 0.0
    fit: str = ""

    @property
    def fit_name(self) -> str:
        return self.fit or self.name

    def to_data(self, commands: tuple[str, ...]) -> dict[str, Any]:
        out: dict[str, Any] = {"inputs": list(self.inputs)}
        if self.outputs != commands:
            out["outputs"] = list(self.outputs)
        if self.mean != "constant":
            out["mean"] = self.mean
        if self.lag:
            out["lag"] = self.lag
        if self.description:
            out["description"] = self.description
        if self.fit:
            out["fit"] = self.fit
        return out


@dataclass(frozen=True)
class APN:
    """An adaptive Petri net with the skill's variables, commands and laws.

    Places and transitions keep their file order; matrices are indexed in that order.
    """

    name: str
    places: tuple[Place, ...]
    transitions: tuple[Transition, ...]
    initial_marking: Mapping[str, int]
    variables: Mapping[str, str] = field(default_factory=dict)
    derived: Mapping[str, Guard] = field(default_factory=dict)
    commands: tuple[str, ...] = ()
    laws: Mapping[str, Law] = field(default_factory=dict)
    description: str = ""
    env: str = ""
    control_rate: float = 1000.0
    max_duration: float = 60.0
    safety: Mapping[str, Any] = field(default_factory=dict)
    mirror: Mapping[str, int] = field(default_factory=dict)   # the task's mirror symmetry: sign of each
    # state variable and command in the mirror image (unnamed ones keep their sign); empty = none declared

    # -- lookup -------------------------------------------------------------------------------
    @cached_property
    def place_ids(self) -> tuple[str, ...]:
        return tuple(p.id for p in self.places)

    @cached_property
    def transition_ids(self) -> tuple[str, ...]:
        return tuple(t.id for t in self.transitions)

    @cached_property
    def _place_index(self) -> dict[str, int]:
        return {p: i for i, p in enumerate(self.place_ids)}

    @cached_property
    def _transition_index(self) -> dict[str, int]:
        return {t: i for i, t in enumerate(self.transition_ids)}

    def place(self, pid: str) -> Place:
        return self.places[self._place_index[pid]]

    def transition(self, tid: str) -> Transition:
        return self.transitions[self._transition_index[tid]]

    def place_index(self, pid: str) -> int:
        return self._place_index[pid]

    def transition_index(self, tid: str) -> int:
        return self._transition_index[tid]

    @property
    def final_places(self) -> dict[str, str]:
        """Final place id -> "success" or "failure"."""
        return {p.id: p.final for p in self.places if p.final}

    def leads_to_failure(self, tid: str) -> bool:
        """Whether transition ``tid`` puts a token into a failure place (a give-up rule)."""
        return any(self.place(p).final == "failure" for p in self.transition(tid).outputs)

    # -- the incidence structure --------------------------------------------------------------
    @cached_property
    def pre(self) -> np.ndarray:
        """Input arc weights, shape (|P|, |T|): tokens a transition consumes from each place."""
        m = np.zeros((len(self.places), len(self.transitions)), dtype=np.int64)
        for j, t in enumerate(self.transitions):
            for p, w in t.inputs.items():
                m[self._place_index[p], j] = w
        return m

    @cached_property
    def post(self) -> np.ndarray:
        """Output arc weights, shape (|P|, |T|)."""
        m = np.zeros((len(self.places), len(self.transitions)), dtype=np.int64)
        for j, t in enumerate(self.transitions):
            for p, w in t.outputs.items():
                m[self._place_index[p], j] = w
        return m

    @cached_property
    def incidence(self) -> np.ndarray:
        """The incidence matrix A = post − pre; firing t moves the marking by A[:, t]."""
        return self.post - self.pre

    @cached_property
    def m0(self) -> np.ndarray:
        """The initial marking as a vector over places."""
        m = np.zeros(len(self.places), dtype=np.int64)
        for p, n in self.initial_marking.items():
            m[self._place_index[p]] = n
        return m

    def siblings(self, tid: str) -> tuple[str, ...]:
        """Transitions with the same input places as ``tid`` (its choice group), itself excluded."""
        pre = self.transition(tid).preset
        return tuple(t.id for t in self.transitions if t.id != tid and t.preset == pre)

    def place_law(self, place: str) -> str | None:
        """The law that runs while ``place`` holds the token: the commonest law of transitions into it."""
        laws = Counter(t.law for t in self.transitions if place in t.outputs and t.law and place not in t.inputs)
        if not laws:
            laws = Counter(t.law for t in self.transitions if place in t.outputs and t.law)
        return laws.most_common(1)[0][0] if laws else None

    def is_repeat(self, tid: str) -> bool:
        """A self-loop that reruns the maneuver its place already runs (a repeat, not a switch): the
        mentor's tags show a maneuver once however often the robot repeats it, so its switches say
        nothing about when to repeat."""
        t = self.transition(tid)
        return set(t.outputs) == set(t.inputs) and all(self.place_law(p) in (None, t.law) for p in t.inputs)

    @cached_property
    def value_names(self) -> tuple[str, ...]:
        """The values this net keeps while it runs, in the runner's order (:func:`value_names`)."""
        return value_names(tuple(self.variables), tuple(self.derived), self.place_ids, self.transition_ids)

    def condition_variables(self) -> frozenset[str]:
        """Every name a condition or law input may use in this net: its ``value_names`` and ``dwell``."""
        return condition_names(tuple(self.variables), tuple(self.derived), self.place_ids, self.transition_ids)

    # -- structural edits (used by revisions; each returns a new net) ---------------------------
    def with_transition(self, t: Transition) -> APN:
        """Replace the transition with ``t.id``, or append ``t`` if the id is new."""
        ts = list(self.transitions)
        if t.id in self._transition_index:
            ts[self._transition_index[t.id]] = t
        else:
            ts.append(t)
        return replace(self, transitions=tuple(ts))

    def with_place(self, p: Place) -> APN:
        """Replace the place with ``p.id``, or append ``p`` if the id is new."""
        ps = list(self.places)
        if p.id in self._place_index:
            ps[self._place_index[p.id]] = p
        else:
            ps.append(p)
        return replace(self, places=tuple(ps))

    def fresh_id(self, prefix: str) -> str:
        """The first ``prefix<N>`` not used by a place or a transition."""
        used = set(self.place_ids) | set(self.transition_ids)
        n = 0
        while f"{prefix}{n}" in used:
            n += 1
        return f"{prefix}{n}"
