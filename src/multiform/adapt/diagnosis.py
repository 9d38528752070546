"""Diagnosis: what the traces of failed trials say about the net.

Reads only the traces (what the robot saw and did) and the net: which transitions never fired,
which places were never visited, which conditions never held while their transition was enabled,
which transition led into failure and which maneuver was running then, where λ had a real choice
on the way to failure, and — with place regions — where the state left its place and which place
it resembled when it did. With the mentor's demonstrations (:mod:`.mentor`) it also compares the
robot with the mentor (:mod:`.compare`): conditions too strict or too loose for where the mentor
switched, branches the mentor never took that lead to failure, starved weights, and limits that end
trials the mentor's own timing says were going well.

Only trials that ended as the skill decides are evidence (``EVIDENCE_OUTCOMES``: success, failure,
or the skill's own ``max_duration`` timeout); a trial that ended for a reason outside the net — a
fault, a diverged simulation — says nothing about the net and is left out.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.special import expit

from ..petri.net import APN
from ..runtime.trace import Trace
from .compare import Finding, compare_with_mentor
from .mentor import MentorEvidence

# scores(states (n, d)) -> {place: (n,) scores}; a state belongs to a place when its score >= threshold
RegionScorer = Callable[[np.ndarray], Mapping[str, np.ndarray]]
EVIDENCE_OUTCOMES = ("success", "failure", "timeout")


def is_evidence(outcome: str) -> bool:
    """Whether a trial with this outcome says something about the net."""
    return outcome in EVIDENCE_OUTCOMES


@dataclass
class Exit:
    """The state leaving its place's region in one failed trial."""

    trial: int
    place: str                      # where the token was
    tick: int
    state: list[float]
    scores: dict[str, float]        # region score of every place for that state
    best: str | None                # the best-matching other place, None if no place relates


@dataclass
class Diagnosis:
    """Findings over a window of trials (failed ones unless said otherwise)."""

    trials: int
    failures: int
    never_fired: list[str] = field(default_factory=list)
    never_visited: list[str] = field(default_factory=list)
    never_held: list[str] = field(default_factory=list)          # enabled at some tick, condition never true
    into_failure: Counter = field(default_factory=Counter)        # transition that moved the token into failure
    failed_from: Counter = field(default_factory=Counter)         # place the token left for failure
    active_at_failure: Counter = field(default_factory=Counter)   # maneuver running when the trial failed
    risky_choices: Counter = field(default_factory=Counter)       # chosen over siblings at a choice point, then failed
    safer_siblings: dict[str, Counter] = field(default_factory=dict)
    exits: list[Exit] = field(default_factory=list)
    outcomes: Counter = field(default_factory=Counter)
    findings: list[Finding] = field(default_factory=list)   # where the robot and the mentor disagree
    mentor_fits: dict[str, dict[str, Any]] = field(default_factory=dict)   # conditions vs the mentor's switches
    visited: set[str] = field(default_factory=set)          # places reached in the failed trials

    def to_json(self) -> dict[str, Any]:
        return {"trials": self.trials, "failures": self.failures, "never_fired": self.never_fired,
                "never_visited": self.never_visited, "never_held": self.never_held,
                "into_failure": dict(self.into_failure), "failed_from": dict(self.failed_from),
                "active_at_failure": dict(self.active_at_failure), "risky_choices": dict(self.risky_choices),
                "outcomes": dict(self.outcomes), "findings": [f.to_json() for f in self.findings],
                "exits": [{"trial": e.trial, "place": e.place, "tick": e.tick, "best": e.best,
                           "scores": {k: round(v, 4) for k, v in e.scores.items()}} for e in self.exits]}


def diagnose(apn: APN, traces: Sequence[Trace], region_scores: RegionScorer | None = None,
             region_names: Sequence[str] = (), region_threshold: float = 0.5,
             leave_below: Mapping[str, float] | None = None, mentor: MentorEvidence | None = None,
             succeeded_fired: Sequence[Sequence[str]] = ()) -> Diagnosis:
    """Diagnose the failed trials among ``traces`` (all run on ``apn``).

    ``region_scores`` scores states (columns ``region_names`` of the traces' values) against every
    place's learned region; with it the diagnosis finds where the state left its place (its score
    fell below ``region_threshold``). Such a state counts as lost (no place relates to it) only if
    the state then went below the floor ``leave_below[p]`` of its place p with still no place
    matching — the mentor succeeded from states just outside a region, so a catch that strays a
    little is not a new place. The floors are calibrated logits, as everywhere a floor travels
    (:meth:`~multiform.adapt.learners.ModelLearners.leave_floors`,
    :class:`~multiform.learn.region.RegionCondition`); a place without one uses ``region_threshold``. With ``mentor`` the findings of
    :func:`~.compare.compare_with_mentor` are added; successful trials count there, those among
    ``traces`` and those given only by what they fired (``succeeded_fired``: practice keeps no
    trace of a success).
    """
    traces = [tr for tr in traces if is_evidence(tr.outcome)]
    failed = [(i, tr) for i, tr in enumerate(traces) if not tr.success]
    d = Diagnosis(trials=len(traces), failures=len(failed))
    finals = apn.final_places
    fired: set[str] = set()
    visited: set[str] = set()
    enabled: Counter = Counter()
    held: Counter = Counter()
    for i, tr in failed:
        d.outcomes[tr.outcome] += 1
        fired |= set(tr.fired())
        visited |= {p for k, p in enumerate(tr.place_ids) if (tr.marking[:, k] > 0).any()}
        enabled.update(tr.enabled_ticks)
        held.update(tr.held_ticks)
        law_fired = [f for f in tr.firings if apn.transition_ids and f.transition in apn.transition_ids
                     and apn.transition(f.transition).law]
        if law_fired:
            d.active_at_failure[law_fired[-1].transition] += 1
        last = tr.firings[-1] if tr.firings else None
        if last is not None and last.transition in apn.transition_ids and \
                any(finals.get(p) == "failure" for p in apn.transition(last.transition).outputs):
            d.into_failure[last.transition] += 1
            src = list(apn.transition(last.transition).inputs)
            if src:
                d.failed_from[src[0]] += 1
        for c in tr.choices:
            d.risky_choices[c.chosen] += 1
            d.safer_siblings.setdefault(c.chosen, Counter()).update(x for x in c.candidates if x != c.chosen)
        if region_scores is not None and region_names and last is not None:
            ex = _exit(apn, i, tr, region_scores, region_names, region_threshold, leave_below or {})
            if ex is not None:
                d.exits.append(ex)
    d.never_fired = [t for t in apn.transition_ids if t not in fired]
    d.never_visited = [p for p in apn.place_ids if p not in visited and not apn.place(p).final]
    d.never_held = [t for t in apn.transition_ids if enabled.get(t, 0) > 0 and held.get(t, 0) == 0]
    d.visited = visited - set(apn.final_places)
    if mentor is not None:
        d.findings = compare_with_mentor(apn, traces, mentor, succeeded_fired)
        d.mentor_fits = {t: fit.to_json() for t, fit in mentor.conditions.items()}
    return d


def _exit(apn: APN, trial: int, tr: Trace, region_scores: RegionScorer, names: Sequence[str],
          threshold: float, leave_below: Mapping[str, float], max_lag: float = 2.0) -> Exit | None:
    """Where the state left its place's region for good, shortly before the trial failed from that place
    (a disturbance throwing the state out), or None (the failure had another cause, e.g. a timeout)."""
    last = tr.firings[-1]
    if tr.outcome != "failure" or last.transition not in apn.transition_ids or \
            not apn.leads_to_failure(last.transition):
        return None
    src = list(apn.transition(last.transition).inputs)
    if not src:
        return None
    place = src[0]
    col = tr.place_ids.index(place) if place in tr.place_ids else None
    if col is None:
        return None
    marked = tr.marking[:, col] > 0
    end = last.tick
    start = end
    while start > 0 and marked[start - 1]:
        start -= 1
    if end - start < 2:
        return None
    idx = [tr.value_names.index(n) if n in tr.value_names else None for n in names]
    if None in idx:
        return None
    states = tr.values[start:end][:, idx].astype(np.float64)
    scores = region_scores(states)
    if place not in scores:
        return None
    inside = scores[place] >= threshold
    # The state must have been inside, then left for good shortly before the failure: the last
    # out-of-region stretch runs to the end, began within `max_lag` s of it, and inside came first.
    if inside[-1]:
        return None
    ins = np.flatnonzero(inside)
    if len(ins) == 0:
        return None
    k = int(ins[-1]) + 1
    if (len(states) - k) * tr.dt > max_lag:
        return None
    # the state a little after it left, once the push has shown its direction
    k = min(k + int(round(0.05 / tr.dt)), len(states) - 1)
    best = _best_other(scores, place, k, threshold)
    if best is None:
        # lost only once further out than the mentor's successful stays ever went
        floor = float(expit(leave_below[place])) if place in leave_below else threshold   # no overflow at -inf
        far = np.flatnonzero(scores[place][k:] < floor)
        if len(far) == 0:
            return None
        k += int(far[0])
        best = _best_other(scores, place, k, threshold)
    s = {p: float(v[k]) for p, v in scores.items()}
    return Exit(trial=trial, place=place, tick=start + k, state=states[k].tolist(), scores=s, best=best)


def _best_other(scores: Mapping[str, np.ndarray], place: str, k: int, threshold: float) -> str | None:
    """The best-scoring place other than ``place`` at row ``k``, if it reaches ``threshold``."""
    others = {p: float(v[k]) for p, v in scores.items() if p != place}
    best = max(others, key=others.get) if others else None
    return best if best is not None and others[best] >= threshold else None
