"""Structural analysis of a net: reachability/coverability graph, dead transitions, boundedness,
places from which no final place can be reached.

Conditions are continuous guards that the analysis cannot decide, so it treats every condition as
satisfiable: the results say what the *structure* allows. The graph is the Karp–Miller coverability
graph (a place that can grow without bound gets ω), which equals the reachability graph when the
net is bounded. Exploration does not continue from markings in which a final place holds a token,
because a trial ends there.

The analysis is bounded: it stops at ``max_states`` states, after ``max_seconds`` of work, or
when the graph would hold more than ``max_entries`` stored numbers (its memory), and says which;
an unfinished graph decides nothing that needs the whole of it. Markings are stored sparsely (the
marked places only), so a net of 10,000 places in a chain costs what its few marked places cost.
"""

from __future__ import annotations

import math
import time
from collections import deque
from collections.abc import Iterable
from dataclasses import dataclass, field

from .net import APN

OMEGA = math.inf
Marking = tuple[tuple[int, float], ...]        # (place index, tokens or OMEGA) of the marked places, by index


@dataclass
class Analysis:
    """What :func:`analyse` found."""

    states: list[Marking]
    edges: list[tuple[int, str, int]]
    truncated: bool
    max_states: int
    unbounded_places: list[str]
    dead_transitions: list[str]
    stuck_places: list[str]                     # marked in some state from which no final place is reachable
    deadlocks: list[Marking] = field(default_factory=list)   # non-final states with nothing enabled
    final_reachable: bool = True
    stopped_by: str = ""                        # why exploration stopped early: the state cap, time or memory budget

    @property
    def bounded(self) -> bool:
        return not self.unbounded_places

    @property
    def ok(self) -> bool:
        """Structurally sound: a final place reachable, no dead transitions, no stuck places."""
        return (self.final_reachable and not self.dead_transitions and not self.stuck_places
                and not self.truncated)


def analyse(apn: APN, max_states: int = 10_000, max_seconds: float = 5.0,
            max_entries: int = 5_000_000) -> Analysis:
    """Build the coverability graph of ``apn`` from its initial marking and read properties off it,
    within the budgets (see the module docstring)."""
    t_end = time.perf_counter() + max_seconds
    index_of = {p: i for i, p in enumerate(apn.place_ids)}
    pre = [tuple((index_of[p], w) for p, w in t.inputs.items()) for t in apn.transitions]
    delta: list[dict[int, int]] = []
    for t in apn.transitions:
        d = {index_of[p]: -w for p, w in t.inputs.items()}
        for p, w in t.outputs.items():
            d[index_of[p]] = d.get(index_of[p], 0) + w
        delta.append({i: x for i, x in d.items() if x})
    by_place: dict[int, list[int]] = {}
    for j, arcs in enumerate(pre):
        for i, _ in arcs:
            by_place.setdefault(i, []).append(j)
    always = [j for j, arcs in enumerate(pre) if not arcs]
    # Karp–Miller acceleration is needed only where firing can add tokens (a strictly covering marking
    # has more tokens than the one it covers); a net whose every transition keeps or lowers the count
    # is bounded by its initial tokens.
    grows = any(sum(t.outputs.values()) > sum(t.inputs.values()) for t in apn.transitions)
    finals = {index_of[p] for p in apn.final_places}
    m0: Marking = tuple(sorted((index_of[p], int(n)) for p, n in apn.initial_marking.items() if n > 0))
    states: list[Marking] = [m0]
    index = {m0: 0}
    parent: list[int] = [-1]
    edges: list[tuple[int, str, int]] = []
    queue = deque([0])
    stored = len(m0) + 1
    stopped = ""
    fired = [False] * len(apn.transitions)
    while queue and not stopped:
        k = queue.popleft()
        m = states[k]
        if any(i in finals for i, _ in m):
            continue
        have = dict(m)
        candidates = sorted(set(always).union(*(by_place.get(i, ()) for i in have)))
        for j in candidates:
            if not all(have.get(i, 0) >= w for i, w in pre[j]):
                continue
            fired[j] = True
            new = dict(have)
            for i, d in delta[j].items():
                if new.get(i) != OMEGA:
                    v = new.get(i, 0) + d
                    if v:
                        new[i] = v
                    else:
                        new.pop(i, None)
            if grows:
                new = _accelerate(new, k, states, parent)
            nm: Marking = tuple(sorted(new.items()))
            if nm not in index:
                if len(states) >= max_states:
                    stopped = "state cap"
                    continue
                index[nm] = len(states)
                states.append(nm)
                parent.append(k)
                queue.append(index[nm])
                stored += len(nm) + 1
            edges.append((k, apn.transitions[j].id, index[nm]))
            stored += 3
        if stored > max_entries:
            stopped = "memory budget"
        elif time.perf_counter() > t_end:
            stopped = "time budget"
    truncated = bool(stopped)
    unbounded = sorted({apn.place_ids[i] for m in states for i, x in m if x == OMEGA})
    dead = [t.id for j, t in enumerate(apn.transitions) if not fired[j]]

    good = _reaching_final(states, edges, finals)
    # With the graph unfinished, unexplored states would look stuck; only a complete graph decides it.
    bad_states = [] if truncated else [k for k in range(len(states)) if k not in good]
    stuck_idx = {i for k in bad_states for i, x in states[k] if x > 0}
    stuck = [apn.place_ids[i] for i in sorted(stuck_idx)]
    out_edges = {a for a, _, _ in edges}
    deadlocks = [states[k] for k in bad_states if k not in out_edges]
    return Analysis(states=states, edges=edges, truncated=truncated, max_states=max_states,
                    unbounded_places=unbounded, dead_transitions=dead, stuck_places=stuck,
                    deadlocks=deadlocks, final_reachable=bool(good) and 0 in good, stopped_by=stopped)


def _accelerate(new: dict[int, float], k: int, states: list[Marking], parent: list[int]) -> dict[int, float]:
    """Karp–Miller: a marking that strictly covers an ancestor (``k`` and up) grows without bound
    in the places where it exceeds it (ω there)."""
    total = sum(new.values())
    anc = k
    while anc >= 0:
        old = states[anc]
        if sum(x for _, x in old) < total or any(v == OMEGA for v in new.values()):
            if all(new.get(i, 0) >= x for i, x in old) and (len(new) > len(old) or any(new.get(i, 0) > x for i, x in old)):
                old_d = dict(old)
                new = {i: (OMEGA if v > old_d.get(i, 0) else v) for i, v in new.items()}
                total = sum(new.values())
        anc = parent[anc]
    return new


def _reaching_final(states: list[Marking], edges: list[tuple[int, str, int]], finals: set[int]) -> set[int]:
    """The states from which a state that marks a final place can be reached (a backward search)."""
    preds: dict[int, list[int]] = {}
    for a, _, b in edges:
        preds.setdefault(b, []).append(a)
    good = {k for k, m in enumerate(states) if any(i in finals for i, _ in m)}
    stack = list(good)
    while stack:
        b = stack.pop()
        for a in preds.get(b, []):
            if a not in good:
                good.add(a)
                stack.append(a)
    return good


def format_marking(apn: APN, m: Marking) -> str:
    """``{P1, 2·P3, ω·P4}`` — the places holding tokens."""
    parts = []
    for i, x in m:
        p = apn.place_ids[i]
        if x == OMEGA:
            parts.append(f"ω·{p}")
        elif x == 1:
            parts.append(p)
        elif x > 1:
            parts.append(f"{int(x)}·{p}")
    return "{" + ", ".join(parts) + "}"


def report(apn: APN, result: Analysis) -> list[str]:
    """Human-readable lines for ``multiform check``."""
    m0 = tuple((apn.place_index(p), float(n)) for p, n in apn.initial_marking.items() if n > 0)
    lines = [f"net {apn.name}: {len(apn.places)} places, {len(apn.transitions)} transitions, "
             f"initial marking {format_marking(apn, tuple(sorted(m0)))}"]
    n = len(result.states)
    stop = {"state cap": f"stopped at the cap of {result.max_states} states (--max-states)",
            "time budget": "stopped at the time budget (--max-seconds)",
            "memory budget": "stopped at the memory budget"}.get(result.stopped_by, "stopped early")
    lines.append(f"reachability graph: {n} states, {len(result.edges)} edges"
                 + (f" ({stop})" if result.truncated else ""))
    lines.append("bounded: yes" if result.bounded else
                 f"bounded: no (unbounded places: {', '.join(result.unbounded_places)})")
    lines.append("final place reachable: " + ("yes" if result.final_reachable else "NO"))
    lines.append("dead transitions: " + (", ".join(result.dead_transitions) or "none"))
    if result.truncated:
        lines.append("places from which no final place can be reached: not decided (the graph is unfinished)")
    else:
        lines.append("places from which no final place can be reached: "
                     + (", ".join(result.stuck_places) or "none"))
    if result.deadlocks:
        shown = ", ".join(format_marking(apn, m) for m in result.deadlocks[:5])
        lines.append(f"deadlocks (non-final markings with nothing enabled): {shown}")
    return lines


def success_reachable(apn: APN, places: Iterable[str]) -> bool:
    """Structurally (ignoring conditions and token counts), a success place is reachable from tokens
    in ``places``: the closure under every transition whose inputs all lie in it."""
    reach = set(places)
    changed = True
    while changed:
        changed = False
        for t in apn.transitions:
            if t.inputs and set(t.inputs) <= reach and not set(t.outputs) <= reach:
                reach |= set(t.outputs)
                changed = True
    return any(apn.place(p).final == "success" for p in reach)
