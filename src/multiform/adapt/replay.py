"""The mentor's successful demonstrations replayed through the net as written, before practice.

A give-up rule (a transition into a failure place) that would have ended one of the mentor's own
successful stays is wrong before the robot has tried anything: the demonstrations show the maneuver
still going well when the rule gives up. Practice only sees such a limit when it ends trials three
times in a row; a limit that ends one trial in ten never makes practice fail constantly, yet costs
the skill a tenth of its trials. So the demonstrations are checked first.

The replay runs at ``1 / slower`` of the mentor's pace: the robot's maneuvers take longer than the
mentor's (:data:`~.compare.SLACK`), so the clocks (``dwell``, ``time``, repeats timed by them) run
``slower`` times faster than the mentor's while the states follow the demonstration sample by
sample. The token follows the mentor's tags, except that a repeat of the running maneuver (a
self-loop the mentor's tags show once however often the robot repeats it) fires by its own
condition, as it would for the robot. Each rule that holds somewhere in a successful stay has the
atoms that held there moved just past what the replay shows: a clock beyond the largest value it
reached over the place's successful stays, a state bound beyond the mentor's range there
(:func:`~.compare.moved_state_bound`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from ..demos.episode import Episode
from ..learn.views import stays, success_mask, value_matrix
from ..petri.guard import parse_guard, to_text
from ..petri.net import APN, is_clock
from ..petri.revision import set_condition
from ..petri.guard_tree import GREATER, atoms, normal, value_at, variables
from .compare import SLACK, Finding, moved_condition, moved_state_bound
from .mentor import MentorEvidence

PASSES = 5            # replays after moving limits: a rule's other atoms may hold later in a stay
MIN_ENDED = 3         # demonstrations a rule must have ended to be moved (one odd one is not the mentor's timing)


def replay_limits(apn: APN, mentor: MentorEvidence, slower: float = SLACK) -> list[Finding]:
    """``limit_too_tight`` findings for the give-up rules of ``apn`` that would have ended a successful
    stay of the mentor's, replayed at ``1 / slower`` of the mentor's pace; each finding holds the
    moved rule (all passes folded into one condition per rule)."""
    moved: dict[str, str] = {}
    ended: dict[str, list[dict[str, Any]]] = {}
    net = apn
    for _ in range(PASSES):
        changes, notes = _one_pass(net, mentor, slower)
        if not changes:
            break
        for fid, change in changes.items():
            moved[fid] = moved_condition(net, fid, change)
            ended.setdefault(fid, []).extend(notes[fid])
            net, _ = set_condition(net, fid, moved[fid], "", {})
    out = []
    for fid, text in moved.items():
        examples = ended[fid]
        episodes = len({e["demonstration"] for e in examples})
        if episodes < MIN_ENDED:
            continue
        out.append(Finding("limit_too_tight", fid,
                           f"the give-up rule '{apn.transition(fid).condition}' would have ended {episodes} of the "
                           f"mentor's successful demonstrations (replayed at 1/{slower:g} of its pace, as slow as the "
                           f"robot may be); moved to '{text}'",
                           {"source": "demonstrations", "demonstrations_ended": episodes, "slower": slower,
                            "examples": examples[:3]}, condition=text))
    return out


def _give_ups(apn: APN, place: str) -> list:
    return [t for t in apn.transitions if place in t.inputs and t.condition.guard is not None
            and apn.leads_to_failure(t.id)]


def _one_pass(apn: APN, mentor: MentorEvidence, slower: float
              ) -> tuple[dict[str, dict[tuple, float]], dict[str, list[dict[str, Any]]]]:
    """One replay of every successful stay: the constants to move per rule and atom path, and notes."""
    clocks: dict[str, list[dict[str, np.ndarray]]] = {}   # per place: each successful stay's columns
    fired: list[tuple[str, Any, int, dict[str, float], int]] = []
    for i, ep in enumerate(mentor.episodes):
        for place, cols in _replay(apn, ep, slower):
            clocks.setdefault(place, []).append(cols)
            for t in _give_ups(apn, place):
                held = np.flatnonzero(t.condition.guard.evaluate_arrays(_columns(t.condition.guard, cols)) > 0)
                if len(held):
                    k = int(held[0])
                    fired.append((place, t, k, {n: float(v[k]) for n, v in cols.items()}, i))
    changes: dict[str, dict[tuple, float]] = {}
    notes: dict[str, list[dict[str, Any]]] = {}
    for place, t, k, env, i in fired:
        live = _live(t.condition.guard.tree, env)
        for path, atom in atoms(t.condition.guard.tree):
            expr, op, c = normal(atom)
            names = variables(expr)
            if not names or path not in live:
                continue
            if all(is_clock(n) for n in names):
                new = _moved_clock(expr, op, clocks[place])
            elif any(is_clock(n) for n in names):
                new = None                  # a clock mixed with state: what to move is unclear
            else:
                bound = moved_state_bound(apn, place, mentor, expr, op, value_at(expr, env))
                new = None if bound is None else float(f"{bound[0]:.4g}")
            if new is None:
                continue
            best = changes.setdefault(t.id, {})
            best[path] = new if path not in best else (max(best[path], new) if op in GREATER else min(best[path], new))
            notes.setdefault(t.id, []).append({"demonstration": i, "place": place, "atom": to_text(atom),
                                               "at_s_of_the_mentors_stay": round(k * mentor.episodes[i].dt, 3)})
    return changes, notes


def _live(tree: tuple, env: dict[str, float], path: tuple = ()) -> set[tuple]:
    """Paths of the atoms that made ``tree`` hold at ``env``: atoms that hold, every ``and`` above them
    holding too (an atom holding in a conjunction that failed ended nothing)."""
    if value_at(tree, env) <= 0:
        return set()
    if tree[0] in ("and", "or"):
        return set().union(*(_live(x, env, path + (i,)) for i, x in enumerate(tree[1])))
    return {path}


def _moved_clock(expr: tuple, op: Any, stays_cols: Sequence[dict[str, np.ndarray]]) -> float | None:
    """A clock bound past the largest value ``expr`` reached over the replayed stays (a count: the next
    whole number), or None if the atom is not an upper limit on a clock."""
    if op not in GREATER:
        return None
    g = parse_guard(to_text(expr))
    top = max(float(np.nanmax(g.evaluate_arrays(_columns(g, cols)))) for cols in stays_cols)
    if all(n.startswith("fires_") for n in g.variables):
        return float(math.floor(top) + 1)
    return _ceil4(top * 1.01 + 1e-3)


def _ceil4(x: float) -> float:
    """``x`` rounded up to four significant digits (the text a condition is written back in)."""
    if x <= 0:
        return float(f"{x:.4g}")
    e = 10.0 ** (math.floor(math.log10(x)) - 3)
    return float(f"{math.ceil(x / e) * e:.4g}")


def _columns(g: Any, cols: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    return {n: cols[n] for n in g.variables}


def _replay(apn: APN, ep: Episode, slower: float) -> list[tuple[str, dict[str, np.ndarray]]]:
    """Each stay of ``ep`` the mentor labelled success throughout, as (place, columns): the state and
    derived variables as demonstrated, the clocks as the net would have kept them at ``1 / slower``
    of the mentor's pace (``time``, ``dwell`` and ``dwell_<place>``, ``fires_<t>`` for every t)."""
    state_names = [*apn.variables, *apn.derived]
    V = value_matrix(apn, ep, state_names)
    ok = success_mask(ep)
    dt = ep.dt * slower
    fires = {t: 0 for t in apn.transition_ids}
    repeat = {t for t in apn.transition_ids if apn.is_repeat(t)}
    segs = ep.segments()
    out = []
    for s, e, place in stays(apn, ep.transitions):
        n = e - s
        counts = {t: np.full(n, fires[t], dtype=float) for t in apn.transition_ids}
        resets = []
        for a, _, tag in segs:
            if s <= a < e and tag in fires and tag not in repeat:
                counts[tag][a - s:] += 1
                fires[tag] += 1
                resets.append(a - s)
        cols = {name: V[s:e, j] for j, name in enumerate(state_names)}
        cols["time"] = np.arange(s, e) * dt
        dwell = _simulate_repeats(apn, place, cols, counts, sorted(set(resets) | {0}), dt, repeat)
        for t in repeat:
            fires[t] = int(counts[t][-1])
        cols.update({f"fires_{t}": c for t, c in counts.items()})
        cols.update({f"dwell_{p}": (dwell if p == place else np.zeros(n)) for p in apn.place_ids})
        cols["dwell"] = dwell
        if ok[s:e].all() and not apn.place(place).final:
            out.append((place, cols))
    return out


def _simulate_repeats(apn: APN, place: str, cols: dict[str, np.ndarray], counts: dict[str, np.ndarray],
                      resets: list[int], dt: float, repeat: set[str], most: int = 10_000) -> np.ndarray:
    """The place's dwell over one stay, restarting at the tagged firings (``resets``) and at every
    firing of a repeat of the running maneuver, which fires (first in the net's order) as soon as its
    condition holds; ``counts`` are updated with those firings."""
    n = len(cols["time"])
    own = [apn.transition(t) for t in apn.transition_ids if t in repeat and place in apn.transition(t).inputs
           and apn.transition(t).condition.guard is not None]
    starts = list(resets)
    k = 0
    for _ in range(most):
        dwell = _dwell(n, starts, dt)
        if not own or k >= n:
            return dwell
        hit = None
        env = {**cols, **{f"fires_{x}": c for x, c in counts.items()}, "dwell": dwell, f"dwell_{place}": dwell}
        for t in own:
            g = t.condition.guard
            held = np.flatnonzero(g.evaluate_arrays({v: env[v][k:] for v in g.variables}) > 0)
            if len(held) and (hit is None or held[0] < hit[1]):
                hit = (t.id, int(held[0]))
        if hit is None:
            return dwell
        tid, j = hit
        at = k + j
        counts[tid][at:] += 1
        starts = sorted(set(starts) | {at})
        k = at + 1
    return _dwell(n, starts, dt)


def _dwell(n: int, starts: list[int], dt: float) -> np.ndarray:
    """Seconds since the last of ``starts`` (ticks) at every tick of a stay ``n`` ticks long."""
    last = np.zeros(n, dtype=int)
    last[np.asarray(starts, dtype=int)] = np.asarray(starts, dtype=int)
    return (np.arange(n) - np.maximum.accumulate(last)) * dt
