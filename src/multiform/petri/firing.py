"""Marking, clocks and the stochastic firing rule: one trial's run of an APN, tick by tick.

The tick (called once per control step, see "Tick semantics" in docs/skill-files.md):

1. the state variables are read, derived variables computed, clocks updated (``time``,
   ``dwell_<place>`` = seconds since the place last received a token, ``fires_<t>``);
2. the candidates are the transitions enabled by the marking (every input place holds at least the
   arc weight) whose condition holds (a condition that cannot be evaluated — ``sqrt`` of a negative
   number, say — does not hold; such a derived variable is NaN);
3. if there are candidates, one fires, chosen with probability proportional to λ (a candidate with
   λ = 0 never fires); firing moves the marking by A[:, t] and resets the output places' clocks;
4. the law of the fired transition becomes the active law for the commands it writes; transitions
   without a law leave the active laws as they are.

At most ``max_firings_per_tick`` transitions fire in one tick (default 1: one stochastic decision
per control step, as in the paper; at 1 kHz the next decision is 1 ms later). Each transition fires
at most once per tick, so a self-loop whose condition stays true cannot spin.
"""

from __future__ import annotations

import math
import operator
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from ..errors import InvalidInput
from .net import APN


class LearnedCondition(Protocol):
    """What a learned condition model offers the net: its input names and a boolean decision.

    A model with ``at_peak`` true also offers ``decision(x) -> float`` and ``threshold``: it stands
    for a moment (the mentor's switch), not a region, and fires at the peak of its decision along
    each passage through the region (see :class:`_PeakGuard`).
    """

    input_names: tuple[str, ...]

    def __call__(self, x: np.ndarray) -> bool: ...


@dataclass(frozen=True)
class Firing:
    """One firing: tick index, trial time, transition id."""

    tick: int
    time: float
    transition: str


@dataclass(frozen=True)
class Choice:
    """A tick where several candidates competed: which one λ picked, and the field."""

    tick: int
    chosen: str
    candidates: tuple[str, ...]


class NetRunner:
    """Runs the discrete part of a skill for one trial at a time.

    ``state_names`` are the names of the entries of the state vector passed to :meth:`tick` (an
    env's ``observation_names``); every variable the skill declares must be among them.
    ``learned`` maps model names used by ``{model: name}`` conditions to their models.
    """

    def __init__(self, apn: APN, state_names: Sequence[str],
                 learned: Mapping[str, LearnedCondition] | None = None,
                 rng: np.random.Generator | int | None = None, max_firings_per_tick: int = 1):
        self.apn = apn
        self.rng = rng if isinstance(rng, np.random.Generator) else np.random.default_rng(rng)
        self.max_firings_per_tick = max_firings_per_tick
        learned = dict(learned or {})
        missing_vars = [v for v in apn.variables if v not in state_names]
        if missing_vars:
            raise InvalidInput(f"the state has no variable(s) {', '.join(missing_vars)} "
                               f"(it has: {', '.join(state_names)})", element="variables")
        missing_models = sorted({t.condition.model for t in apn.transitions
                                 if t.condition.is_learned and t.condition.model not in learned})
        if missing_models:
            raise InvalidInput(f"learned condition model(s) {', '.join(missing_models)} not provided",
                               element="transitions")

        # Slot layout of the flat value list the compiled guards read.
        names = apn.value_names
        self.slots = {n: i for i, n in enumerate(names)}
        self._n_state = len(apn.variables)
        self._state_getter = operator.itemgetter(*[list(state_names).index(v) for v in apn.variables]) \
            if apn.variables else None
        self._derived = [(self.slots[n], g.compile(self.slots)) for n, g in apn.derived.items()]
        self._time_slot = self.slots["time"]
        self.dwell_slots = [self.slots[f"dwell_{p}"] for p in apn.place_ids]     # per place, in place order
        self._fires_slot = [self.slots[f"fires_{t}"] for t in apn.transition_ids]

        # Per transition: its 'dwell' slot (an alias for a single input place; an extra slot holding
        # the minimum over several input places; 'time' for a source transition) and its guard.
        self._multi_dwell: list[tuple[int, list[int]]] = []
        self._guards: list[Callable[[list[float]], bool]] = []
        self._within: list[Callable[[list[float]], bool] | None] = []
        n_slots = len(names)
        for t in apn.transitions:
            ins = [apn.place_index(p) for p in t.inputs]
            if len(ins) == 1:
                dwell = self.dwell_slots[ins[0]]
            elif not ins:
                dwell = self._time_slot
            else:
                dwell = n_slots
                n_slots += 1
                self._multi_dwell.append((dwell, [self.dwell_slots[i] for i in ins]))
            if t.condition.is_learned:
                self._guards.append(self._learned_guard(learned[t.condition.model]))
                self._within.append(None if t.condition.within is None else
                                    t.condition.within.compile({**self.slots, "dwell": dwell}))
            else:
                self._within.append(None)
                self._guards.append(t.condition.guard.compile({**self.slots, "dwell": dwell}))
        # A condition that yields to other transitions holds only where none of theirs does (where
        # theirs holds, whether or not it fires there yet).
        own = list(self._guards)
        self._peaks: list[_PeakGuard] = []
        for j, t in enumerate(apn.transitions):
            if t.condition.is_learned and getattr(learned[t.condition.model], "at_peak", False):
                model = learned[t.condition.model]
                self._peaks.append(_PeakGuard(self, model, self._reader(model)))
                self._guards[j] = self._peaks[-1]
        for j, within in enumerate(self._within):
            if within is not None:
                self._guards[j] = _within(self._guards[j], within)
        for j, t in enumerate(apn.transitions):
            if t.condition.unless:          # the skill loader checked that they are transitions of the net
                others = [own[apn.transition_index(u)] for u in t.condition.unless]
                self._guards[j] = _yielding(self._guards[j], others)
        self._n_slots = n_slots
        self._pre_cols = [[(apn.place_index(p), w) for p, w in t.inputs.items()] for t in apn.transitions]
        self._post_cols = [[(apn.place_index(p), w) for p, w in t.outputs.items()] for t in apn.transitions]
        self._lam = [float(t.lam) for t in apn.transitions]
        self._law = [t.law for t in apn.transitions]
        self._law_outputs = {name: law.outputs for name, law in apn.laws.items()}
        self._final = {apn.place_index(p): kind for p, kind in apn.final_places.items()}
        self.reset()

    def _reader(self, model: LearnedCondition) -> Callable[[list[float]], np.ndarray]:
        """A function that loads ``model``'s inputs from the value slots into one reused array."""
        unknown = [n for n in model.input_names if n not in self.slots]
        if unknown:
            raise InvalidInput(f"learned condition reads unknown variable(s) {', '.join(unknown)}",
                               element="transitions")
        idx = [self.slots[n] for n in model.input_names]
        getter = operator.itemgetter(*idx)
        buf = np.empty(len(idx))
        if len(idx) == 1:
            def read(v: list[float]) -> np.ndarray:
                buf[0] = v[idx[0]]
                return buf
        else:
            def read(v: list[float]) -> np.ndarray:
                buf[:] = getter(v)
                return buf
        return read

    def _learned_guard(self, model: LearnedCondition) -> Callable[[list[float]], bool]:
        read = self._reader(model)
        return lambda v: bool(model(read(v)))

    # -- trial lifecycle -------------------------------------------------------------------------
    def reset(self) -> None:
        """Back to the initial marking, clocks and counters at zero."""
        self.marking = [int(x) for x in self.apn.m0]
        self.values = [0.0] * self._n_slots
        self._entered = [0.0] * len(self.marking)
        self.tick_index = 0
        self.time = 0.0
        self.firings: list[Firing] = []
        self.choices: list[Choice] = []
        self.active_laws: dict[str, str] = {}
        self.outcome: str | None = None
        n = len(self._guards)
        self.enabled_ticks = [0] * n
        self.held_ticks = [0] * n
        for p in self._peaks:
            p.reset()
        self._refresh_enabled()

    def _refresh_enabled(self) -> None:
        m = self.marking
        self._enabled = [j for j, col in enumerate(self._pre_cols) if all(m[i] >= w for i, w in col)]
        self._marked = [i for i, n in enumerate(m) if n]
        for i, n in enumerate(m):
            if not n:
                self.values[self.dwell_slots[i]] = 0.0

    def observe(self, state: Sequence[float], time: float) -> list[float]:
        """Load one state vector and the trial time into the value slots (steps 1 of the tick)."""
        v = self.values
        if self._state_getter is not None:
            got = self._state_getter(state)
            if self._n_state == 1:
                v[0] = float(got)
            else:
                v[: self._n_state] = got
        for slot, f in self._derived:
            try:
                v[slot] = f(v)
            except (ArithmeticError, ValueError):     # sqrt(-1), overflow: the value is undefined
                v[slot] = math.nan
        v[self._time_slot] = time
        entered, dslot = self._entered, self.dwell_slots
        for i in self._marked:                       # an empty place's dwell is 0, set when it emptied
            v[dslot[i]] = time - entered[i]
        for slot, ins in self._multi_dwell:
            v[slot] = min(v[s] for s in ins)
        self.time = time
        return v

    def candidates(self) -> list[int]:
        """Indices of the transitions enabled by the marking whose condition holds now."""
        v = self.values
        out = []
        for j in self._enabled:
            self.enabled_ticks[j] += 1
            try:
                held = self._guards[j](v)
            except (ArithmeticError, ValueError):      # an undefined condition does not hold
                held = False
            if held:
                self.held_ticks[j] += 1
                out.append(j)
        return out

    def choose(self, candidates: Sequence[int]) -> int | None:
        """Pick one candidate with probability proportional to λ; None if all have λ = 0."""
        if len(candidates) == 1:
            j = candidates[0]
            return j if self._lam[j] > 0 else None
        weights = [self._lam[j] for j in candidates]
        total = sum(weights)
        if total <= 0:
            return None
        r = self.rng.random() * total
        acc = 0.0
        for j, w in zip(candidates, weights):
            acc += w
            if r < acc:
                return j
        return candidates[-1]

    def fire(self, j: int) -> None:
        """Fire transition ``j`` (it must be enabled): m' = m − pre[:, j] + post[:, j]."""
        m = self.marking
        for i, w in self._pre_cols[j]:
            if m[i] < w:
                raise RuntimeError(f"transition {self.apn.transition_ids[j]} fired while not enabled")
            m[i] -= w
        for i, w in self._post_cols[j]:
            m[i] += w
            self._entered[i] = self.time
            self.values[self.dwell_slots[i]] = 0.0
        self.values[self._fires_slot[j]] += 1
        law = self._law[j]
        if law is not None:
            for c in self._law_outputs.get(law, ("*",)):
                self.active_laws[c] = law
        self.firings.append(Firing(self.tick_index, self.time, self.apn.transition_ids[j]))
        self._refresh_enabled()
        for i, kind in self._final.items():
            if m[i] > 0:
                self.outcome = kind
                break

    def tick(self, state: Sequence[float], time: float) -> list[str]:
        """One control tick: observe, then fire up to ``max_firings_per_tick`` transitions.

        Returns the ids fired this tick (usually none). After a final place gets a token,
        :attr:`outcome` is ``"success"`` or ``"failure"`` and the trial is over.
        """
        self.observe(state, time)
        if self.max_firings_per_tick == 1:           # the common case, kept lean for the 1 kHz path
            fired = self._fire_one(self.candidates()) if self.outcome is None else []
        else:
            fired = []
            for _ in range(self.max_firings_per_tick):
                if self.outcome is not None:
                    break
                one = self._fire_one([j for j in self.candidates() if self.apn.transition_ids[j] not in fired])
                if not one:
                    break
                fired += one
        self.tick_index += 1
        return fired

    def _fire_one(self, cands: list[int]) -> list[str]:
        """Choose among ``cands`` by λ and fire; the id fired, as a list (empty if none)."""
        if not cands:
            return []
        j = self.choose(cands)
        if j is None:
            return []
        ids = self.apn.transition_ids
        if len(cands) > 1:
            self.choices.append(Choice(self.tick_index, ids[j], tuple(ids[c] for c in cands)))
        self.fire(j)
        return [ids[j]]

    # -- views -----------------------------------------------------------------------------------
    def marking_dict(self) -> dict[str, int]:
        return {p: n for p, n in zip(self.apn.place_ids, self.marking) if n}

    def fire_counts(self) -> dict[str, int]:
        return {t: int(self.values[s]) for t, s in zip(self.apn.transition_ids, self._fires_slot)}


class _PeakGuard:
    """A learned switch condition that fires at the peak of its decision, not on entering its region.

    Learned from the mentor's switches, the region where the condition holds spans all of them, and
    a trajectory entering it first meets its edge: the earliest moment any switch was seen, not the
    typical one. Along each passage through the region (consecutive ticks where it holds) this
    guard holds from the first tick whose decision is no higher than the tick before (the state most
    like the mentor's switches on that passage was the tick before: one control step late, as at
    any peak found by looking) until the passage ends. The first tick after a passage that was still
    rising when it left counts as such a tick, so the condition fires on every passage that entering
    would fire on. Ticks the transition was not enabled break the passage.
    """

    def __init__(self, runner: NetRunner, model: LearnedCondition, read: Callable[[list[float]], np.ndarray]):
        self.runner, self.model, self._read = runner, model, read
        self.threshold = float(model.threshold)     # type: ignore[attr-defined]
        self.reset()

    def reset(self) -> None:
        self._tick, self._last, self._held = -2, -math.inf, False

    def __call__(self, v: list[float]) -> bool:
        t = self.runner.tick_index
        if t == self._tick:                          # asked again in the same tick
            return self._held
        d = float(self.model.decision(self._read(v)))   # type: ignore[attr-defined]
        if self._tick != t - 1:                      # the passage is broken (or this is its first tick)
            self._held = False
        elif self._held:                              # past the peak: holds while still inside
            self._held = d > self.threshold
        else:                                         # the tick before was the peak
            self._held = self._last > self.threshold and d <= self._last
        self._tick, self._last = t, d
        return self._held


def _within(guard: Callable[[list[float]], bool], region: Callable[[list[float]], bool]
            ) -> Callable[[list[float]], bool]:
    """``guard`` held to ``region``: outside it the guard is not asked, so a peak guard's passage is one
    through both."""
    return lambda v: bool(region(v)) and guard(v)


def _yielding(guard: Callable[[list[float]], bool], others: list[Callable[[list[float]], bool]]
              ) -> Callable[[list[float]], bool]:
    def g(v: list[float]) -> bool:
        if not guard(v):
            return False
        for o in others:
            try:
                if o(v):
                    return False
            except (ArithmeticError, ValueError):      # an undefined condition does not hold
                pass
        return True
    return g
