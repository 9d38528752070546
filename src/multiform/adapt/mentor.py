"""What the mentor's demonstrations say about a net, for diagnosis to compare the robot with.

Read off the labelled demonstrations through the net (:mod:`multiform.learn.views`):

* per transition, how often the mentor switched into it in segments it labelled success and in
  segments it labelled failure (a stop into success the mentor never tags counts as taken by each
  successful demonstration that ends in its place);
* per transition with a hand-written condition over state variables (the state part of it; repeats
  of the running maneuver and rules into final places left out), where that condition holds
  against where the mentor switched: at the moments of its successful switches (``hit``; a condition
  true at few of them is too strict) and on the states of the maneuver before, far from any switch
  (``loose``; a condition true at many of those fires where the mentor chose not to switch);
* per place, how long the mentor's successful stays there lasted and the range of each state
  expression over them, so a give-up or stop rule can be held against the mentor's own timing.

Clock variables (``dwell``, ``fires_*``, ``time``) follow the mentor's tags, not the robot's firings
(a mentor's swing-up is one segment however long), so conditions reading them are compared through
durations only.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..demos.episode import Episode
from ..learn.condition import switch_windows
from ..learn.views import stays, success_mask, switch_data, value_matrix
from ..petri.net import APN

CLOCKS = ("time", "dwell")
MOMENT = 0.1          # s after a switch in which the mentor's switch counts as one moment


def is_clock(name: str) -> bool:
    """Whether ``name`` is a clock or count variable of the net (time, dwell, dwell_P, fires_t)."""
    return name in CLOCKS or name.startswith(("dwell_", "fires_"))


@dataclass
class ConditionFit:
    """A hand-written condition held against the mentor's switches into its transition."""

    switches: int                 # the mentor's successful switches into the transition
    hit: float                    # fraction of those switch moments at which the condition holds
    loose: float                  # fraction of the mentor's non-switch states at which it holds
    negatives: int

    def to_json(self) -> dict[str, Any]:
        return {"mentor_switches": self.switches, "holds_at_mentor_switches": round(self.hit, 3),
                "holds_where_mentor_did_not_switch": round(self.loose, 3), "non_switch_states": self.negatives}


@dataclass
class MentorEvidence:
    """The mentor's demonstrations, summarised for the net they are read through."""

    took_success: dict[str, int] = field(default_factory=dict)
    took_failure: dict[str, int] = field(default_factory=dict)
    conditions: dict[str, ConditionFit] = field(default_factory=dict)
    stay_seconds: dict[str, float] = field(default_factory=dict)     # longest successful stay per place
    episodes: Sequence[Episode] = ()

    def took_successfully(self, transition: str) -> bool:
        return self.took_success.get(transition, 0) > 0

    def stay_range(self, apn: APN, place: str, guard_tree: tuple) -> tuple[float, float] | None:
        """The range of a state expression (a guard subtree) over the mentor's successful stays in
        ``place``; None if the mentor never stayed there successfully."""
        from ..petri.guard import parse_guard, to_text
        g = parse_guard(to_text(guard_tree))
        names = sorted(g.variables)
        lo, hi, seen = np.inf, -np.inf, False
        for ep in self.episodes:
            V = value_matrix(apn, ep, names)
            ok = success_mask(ep)
            for s, e, p in stays(apn, ep.transitions):
                if p != place or not ok[s:e].all():
                    continue
                v = g.evaluate_arrays({n: V[s:e, i] for i, n in enumerate(names)})
                v = v[np.isfinite(v)]
                if len(v):
                    lo, hi, seen = min(lo, float(v.min())), max(hi, float(v.max())), True
        return (lo, hi) if seen else None


def _tree_variables(tree: tuple) -> set[str]:
    kind = tree[0]
    if kind == "var":
        return {tree[1]}
    if kind == "const":
        return set()
    if kind in ("neg", "not"):
        return _tree_variables(tree[1])
    if kind == "bin":
        return _tree_variables(tree[2]) | _tree_variables(tree[3])
    if kind in ("cmp", "and", "or"):
        items = tree[2] if kind == "cmp" else tree[1]
        return set().union(*(_tree_variables(x) for x in items))
    if kind == "call":
        return set().union(set(), *(_tree_variables(x) for x in tree[2]))
    return set()


def _is_repeat(apn: APN, tid: str) -> bool:
    """A self-loop that reruns the maneuver its place already runs (a repeat, not a switch): the
    mentor's tags show a maneuver once however often the robot repeats it, so its switches say
    nothing about when to repeat."""
    from .repair import place_law
    t = apn.transition(tid)
    return set(t.outputs) == set(t.inputs) and all(place_law(apn, p) in (None, t.law) for p in t.inputs)


def _state_part(g: Any, state: set[str]) -> Any:
    """The part of a guard over state variables: the guard itself, or the state conjuncts of an
    ``and`` whose other conjuncts read clocks (``fires_t1 >= 1 and phi > 2.3`` → ``phi > 2.3``)."""
    from ..petri.guard import parse_guard, to_text
    if g is None or g.is_true or not g.variables:
        return None
    if g.variables <= state:
        return g
    if g.tree[0] != "and":
        return None
    keep = [x for x in g.tree[1] if _tree_variables(x) and _tree_variables(x) <= state]
    return parse_guard(" and ".join(f"({to_text(x)})" for x in keep)) if keep else None


def mentor_evidence(apn: APN, episodes: Sequence[Episode], min_switches: int = 3) -> MentorEvidence:
    """Summarise ``episodes`` (the mentor's labelled demonstrations) for ``apn``."""
    ev = MentorEvidence(episodes=list(episodes))
    for ep in episodes:
        ok = success_mask(ep)
        for s, _, tag in ep.segments():
            if tag in apn.transition_ids:
                bucket = ev.took_success if ok[s] else ev.took_failure
                bucket[tag] = bucket.get(tag, 0) + 1
        placed = stays(apn, ep.transitions)
        for s, e, p in placed:
            if ok[s:e].all():
                ev.stay_seconds[p] = max(ev.stay_seconds.get(p, 0.0), (e - s) * ep.dt)
        if ep.outcome == "success" and placed:
            # a stop into success the mentor never tags is taken where its successful demonstrations end
            for t in apn.transitions:
                if placed[-1][2] in t.inputs and any(apn.place(q).final == "success" for q in t.outputs) \
                        and not (ep.transitions == t.id).any():
                    ev.took_success[t.id] = ev.took_success.get(t.id, 0) + 1
    state = set(apn.variables) | set(apn.derived)
    for t in apn.transitions:
        if _is_repeat(apn, t.id) or any(apn.place(p).final for p in t.outputs):
            continue                # repeats and stop/give-up rules: held against timing, not switches
        g = _state_part(t.condition.guard, state)
        if g is None or ev.took_success.get(t.id, 0) < min_switches:
            continue
        names = sorted(g.variables)
        cols = lambda X: {n: X[:, i] for i, n in enumerate(names)}  # noqa: E731
        moments = [W for _, _, W in switch_windows(apn, episodes, t.id, names, before=0.0, after=MOMENT) if len(W)]
        if len(moments) < min_switches:
            continue
        hit = float(np.mean([(g.evaluate_arrays(cols(W)) > 0).any() for W in moments]))
        neg = switch_data(apn, episodes, t.id, names).negatives
        loose = float((g.evaluate_arrays(cols(neg)) > 0).mean()) if len(neg) else 0.0
        ev.conditions[t.id] = ConditionFit(len(moments), hit, loose, int(len(neg)))
    return ev
