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
  expression over them, so a give-up or stop rule can be held against the mentor's own timing;
* the maneuvers the mentor's tags name that the net lacks (:class:`Missing`: where the mentor's token
  was before and after each), and where and after how long the mentor's successful demonstrations
  ended (:class:`Ending`), so a missing transition or stop can be put back;
* with the fitted laws, how well each of the skill's laws explains the mentor's commands in the
  segments of one transition (:meth:`MentorEvidence.law_errors`), so a transition that runs the
  wrong law can be given the right one.

Clock variables (``dwell``, ``fires_*``, ``time``) follow the mentor's tags, not the robot's firings
(a mentor's swing-up is one segment however long), so conditions reading them are compared through
durations only. A switch condition on its place's clock alone is a timed maneuver (``dwell > 0.15``: a
pull that lasts a moment) where the mentor's own timing bears it out — it holds at most of the
mentor's successful switches (how long the mentor had been in the place then) and at few of the
states where the mentor held off (:data:`TIMED_HIT`, :data:`TIMED_LOOSE`) — and is held against those
durations; otherwise it reads no state and is held as holding everywhere (``dwell > 0.1`` on a
2 s swing-up switches at once).
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from ..demos.episode import Episode
from ..learn.condition import switch_windows
from ..learn.views import law_data, stays, success_mask, switch_data, value_matrix
from ..petri.guard_tree import variables
from ..petri.net import APN

MOMENT = 0.1          # s after a switch in which the mentor's switch counts as one moment
TIMED_HIT = 0.5       # a clock-only switch is a timed maneuver if it holds at this share of the mentor's switches
TIMED_LOOSE = 0.2     # ... and at no more than this share of the clock along the segments where the mentor held off


@dataclass
class ConditionFit:
    """A hand-written condition held against the mentor's switches into its transition."""

    switches: int                 # the mentor's successful switches into the transition
    hit: float                    # fraction of those switch moments at which the condition holds
    loose: float                  # fraction of the mentor's non-switch states at which it holds
    negatives: int
    timed: bool = False           # a clock-only switch the mentor's timing bears out: held against durations

    def to_json(self) -> dict[str, Any]:
        return {"mentor_switches": self.switches, "holds_at_mentor_switches": round(self.hit, 3),
                "holds_where_mentor_did_not_switch": round(self.loose, 3), "non_switch_states": self.negatives,
                **({"timed": True} if self.timed else {})}


@dataclass
class Missing:
    """A maneuver the mentor's tags name that the net has no transition for."""

    tag: str
    inputs: tuple[str, ...]        # where the mentor's token was before it (commonest over successful uses)
    outputs: tuple[str, ...]       # where it was after
    took_success: int
    took_failure: int

    def to_json(self) -> dict[str, Any]:
        return {"tag": self.tag, "from": list(self.inputs), "to": list(self.outputs),
                "mentor_took_successfully": self.took_success, "mentor_took_in_failed_segments": self.took_failure}


@dataclass
class Ending:
    """Where the mentor's successful demonstrations ended (or stopped): the place, how long the mentor
    had held it (its shortest such stay) and the range of the place's judged variables over their
    last second."""

    place: str
    episodes: int
    shortest_stay: float
    ranges: dict[str, tuple[float, float]]

    def stop_condition(self) -> str:
        """A stop where the mentor's demonstrations ended: held as long as the mentor's shortest hold,
        each judged variable in the range the mentor ended in, widened each side by that range's
        width (at least a tenth of its magnitude)."""
        parts = [f"dwell > {self.shortest_stay:.4g}"]
        for v, (lo, hi) in self.ranges.items():
            w = max(hi - lo, 0.1 * max(abs(lo), abs(hi)), 1e-3)
            parts.append(f"{v} > {lo - w:.4g} and {v} < {hi + w:.4g}")
        return " and ".join(parts)


@dataclass
class MentorEvidence:
    """The mentor's demonstrations, summarised for the net they are read through."""

    took_success: dict[str, int] = field(default_factory=dict)
    took_failure: dict[str, int] = field(default_factory=dict)
    conditions: dict[str, ConditionFit] = field(default_factory=dict)
    stay_seconds: dict[str, float] = field(default_factory=dict)     # longest successful stay per place
    episodes: Sequence[Episode] = ()
    missing: dict[str, Missing] = field(default_factory=dict)         # tags the net has no transition for
    endings: dict[str, Ending] = field(default_factory=dict)          # by place
    laws: Mapping[str, Any] = field(default_factory=dict)            # the fitted laws, by law name
    _law_errors: dict[tuple, dict[str, float]] = field(default_factory=dict, repr=False)

    def law_errors(self, apn: APN, transition: str) -> dict[str, float]:
        """Held-out NRMSE of each fitted law (writing the commands ``transition``'s law writes) on the
        mentor's successful samples of ``transition``; {} without fitted laws or samples. Computed
        once per net (laws as assigned)."""
        key = (transition, tuple((t.id, t.law) for t in apn.transitions))
        if key not in self._law_errors:
            self._law_errors[key] = law_errors(apn, self.episodes, transition, self.laws) if self.laws else {}
        return self._law_errors[key]

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
    keep = [x for x in g.tree[1] if variables(x) and variables(x) <= state]
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
    ev.missing = _missing(apn, episodes, min_switches)
    ev.endings = _endings(apn, episodes)
    state = set(apn.variables) | set(apn.derived)
    for t in apn.transitions:
        if apn.is_repeat(t.id) or any(apn.place(p).final for p in t.outputs):
            continue                # repeats and stop/give-up rules: held against timing, not switches
        if ev.took_success.get(t.id, 0) < min_switches:
            continue
        g = _state_part(t.condition.guard, state)
        timed = _duration_fit(apn, episodes, t.id, min_switches) if g is None else None
        if timed is not None and timed.hit >= TIMED_HIT and timed.loose <= TIMED_LOOSE:
            ev.conditions[t.id] = timed
            continue
        # a condition that reads no state ("true", or clocks alone) holds wherever the mentor was: it
        # is held against the mentor's switches as holding everywhere, read off the place's judged
        # variables (or the state's)
        names = sorted(g.variables) if g is not None else \
            sorted({v for p in t.inputs for v in apn.place(p).judge} or set(apn.variables))
        if not names:
            continue
        cols = lambda X: {n: X[:, i] for i, n in enumerate(names)}  # noqa: E731
        moments = [W for _, _, W in switch_windows(apn, episodes, t.id, names, before=0.0, after=MOMENT) if len(W)]
        if len(moments) < min_switches:
            continue
        neg = switch_data(apn, episodes, t.id, names).negatives
        if g is None:
            if len(neg):
                ev.conditions[t.id] = ConditionFit(len(moments), 1.0, 1.0, int(len(neg)))
            continue
        hit = float(np.mean([(g.evaluate_arrays(cols(W)) > 0).any() for W in moments]))
        loose = float((g.evaluate_arrays(cols(neg)) > 0).mean()) if len(neg) else 0.0
        ev.conditions[t.id] = ConditionFit(len(moments), hit, loose, int(len(neg)))
    return ev


def _duration_fit(apn: APN, episodes: Sequence[Episode], tid: str, min_switches: int) -> ConditionFit | None:
    """:class:`ConditionFit` of a switch condition that reads only its input place's clock
    (``dwell``), through durations: the clock at each of the mentor's successful switches (the time
    since the segment before it began in that place) and along the mentor's segments there far from
    any switch (:func:`~multiform.learn.views.switch_data`'s negatives). None for any other condition,
    or with fewer than ``min_switches`` switches."""
    t = apn.transition(tid)
    g = t.condition.guard
    if g is None or set(g.variables) != {"dwell"} or len(t.inputs) != 1:
        return None
    clock = f"dwell_{next(iter(t.inputs))}"
    place = next(iter(t.inputs))
    at_switch = []
    for ep in episodes:
        ok = success_mask(ep)
        D = value_matrix(apn, ep, [clock])[:, 0]
        segs = ep.segments()
        for i, (s, _, tag) in enumerate(segs):
            if tag == tid and ok[s] and i and segs[i - 1][2] in apn.transition_ids \
                    and place in apn.transition(segs[i - 1][2]).outputs:
                at_switch.append(D[s - 1] + ep.dt)
    if len(at_switch) < min_switches:
        return None
    neg = switch_data(apn, episodes, tid, [clock]).negatives[:, 0]
    hit = float(np.mean(g.evaluate_arrays({"dwell": np.asarray(at_switch)}) > 0))
    loose = float(np.mean(g.evaluate_arrays({"dwell": neg}) > 0)) if len(neg) else 0.0
    return ConditionFit(len(at_switch), hit, loose, int(len(neg)), timed=True)


def _missing(apn: APN, episodes: Sequence[Episode], min_uses: int) -> dict[str, Missing]:
    """The tags naming no transition of ``apn`` that the mentor used successfully ``min_uses`` times,
    with where its token was before (the places the maneuver before put it in; the initial marking
    for the first) and after (the places the next maneuver needs; the final place the demonstration
    reached for the last)."""
    known = set(apn.transition_ids)
    final = {k: next((p for p, f in apn.final_places.items() if f == k), None) for k in ("success", "failure")}
    arcs: dict[str, Counter] = {}
    took: dict[str, list[int]] = {}
    for ep in episodes:
        ok = success_mask(ep)
        segs = ep.segments()
        for i, (s, _, tag) in enumerate(segs):
            if not tag or tag in known:
                continue
            counts = took.setdefault(tag, [0, 0])
            counts[0 if ok[s] else 1] += 1
            prev = segs[i - 1][2] if i else None
            before = tuple(sorted(apn.initial_marking)) if prev is None else \
                tuple(sorted(apn.transition(prev).outputs)) if prev in known else None
            if i + 1 < len(segs):
                nxt = segs[i + 1][2]
                after = tuple(sorted(apn.transition(nxt).inputs)) if nxt in known else None
            else:
                end = final.get(ep.outcome)
                after = (end,) if end else None
            if ok[s] and before and after:
                arcs.setdefault(tag, Counter())[(before, after)] += 1
    out = {}
    for tag, (good, bad) in sorted(took.items()):
        if good >= min_uses and tag in arcs:
            (ins, outs), _ = arcs[tag].most_common(1)[0]
            out[tag] = Missing(tag, ins, outs, good, bad)
    return out


def _endings(apn: APN, episodes: Sequence[Episode], last: float = 1.0) -> dict[str, Ending]:
    """Per non-final place in which successful demonstrations ended: their last stay in a non-final
    place, labelled success, followed by nothing but a stop (a tag into a final place, or one the net
    lacks). How many, the shortest such stay, and the range of the place's judged variables over
    the last ``last`` s of them."""
    known = set(apn.transition_ids)
    found: dict[str, list] = {}
    for ep in episodes:
        if ep.outcome != "success":
            continue
        placed = [x for x in stays(apn, ep.transitions) if not apn.place(x[2]).final]
        if not placed:
            continue
        s, e, p = placed[-1]
        after = set(np.unique(ep.transitions[e:]).tolist())
        if any(t in known and not any(apn.place(q).final for q in apn.transition(t).outputs) for t in after) \
                or not success_mask(ep)[s:e].all():
            continue
        names = list(apn.place(p).judge) or list(apn.variables)
        V = value_matrix(apn, ep, names)[max(s, e - int(round(last / ep.dt))):e]
        found.setdefault(p, []).append(((e - s) * ep.dt, names, V))
    out = {}
    for p, items in found.items():
        names = items[0][1]
        V = np.concatenate([v for _, _, v in items])
        out[p] = Ending(p, len(items), float(min(d for d, _, _ in items)),
                        {n: (float(V[:, i].min()), float(V[:, i].max())) for i, n in enumerate(names)})
    return out


def law_errors(apn: APN, episodes: Sequence[Episode], transition: str, laws: Mapping[str, Any],
               max_samples: int = 2000, seed: int = 0) -> dict[str, float]:
    """How well each law explains the mentor's commands in the successful segments of ``transition``.

    Each law of the skill that writes the same commands as ``transition``'s law (any law, if it runs
    none) is solved again, with the hyperparameters it learned, on at most ``max_samples`` of its own
    training samples *without* those of ``transition`` (a law trained on them would explain them
    by heart), then predicts the mentor's commands from the states of ``transition``'s segments (at
    most twice ``max_samples`` of them),
    paired across the law's own reaction time. Returns NRMSE per law (1 = no better than the mean
    command; the worst output counts).
    """
    from sklearn.base import clone
    t = apn.transition(transition)
    outputs = apn.laws[t.law].outputs if t.law in apn.laws else None
    without = apn.with_transition(replace(t, law=None))
    only = apn                      # the net with no law but on ``transition``: its samples alone
    for other in apn.transitions:
        if other.id != transition and other.law is not None:
            only = only.with_transition(replace(other, law=None))
    rng = np.random.default_rng(seed)
    out: dict[str, float] = {}
    for name, spec in apn.laws.items():
        fitted = laws.get(name)
        if fitted is None or (outputs is not None and tuple(spec.outputs) != tuple(outputs)):
            continue
        target = law_data(only.with_transition(replace(t, law=name)), episodes, name)
        train = law_data(without, episodes, name)
        if len(target.X) < 20 or len(train.X) < 20:
            continue
        idx = np.sort(rng.choice(len(train.X), min(max_samples, len(train.X)), replace=False))
        X, Y = train.X[idx], train.Y[idx]
        xs, ys = np.maximum(X.std(axis=0), 1e-12), np.maximum(Y.std(axis=0), 1e-12)
        # the learned hyperparameters, in the units of this subset's standardisation
        y_ratio = np.max(fitted.y_scale_ / ys)
        theta = np.r_[np.log(fitted.length_scale_ * fitted.x_scale_ / xs), np.log(fitted.sigma_f_ * y_ratio),
                      np.log(fitted.noise_ * y_ratio)]
        probe = clone(fitted).set_params(sparse_threshold=None, exact_var_max_n=None, ard=True, theta=theta).fit(X, Y)
        rows = np.sort(rng.choice(len(target.X), min(2 * max_samples, len(target.X)), replace=False))
        pred = probe.predict(target.X[rows]).reshape(len(rows), -1)
        Yt = target.Y[rows].reshape(len(rows), -1)
        out[name] = float((np.sqrt(np.mean((pred - Yt) ** 2, axis=0)) / np.maximum(Yt.std(axis=0), 1e-12)).max())
    return out
