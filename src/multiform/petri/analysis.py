"""Structural analysis of a net: reachability/coverability graph, dead transitions, boundedness,
places from which no final place can be reached.

Conditions are continuous guards that the analysis cannot decide, so it treats every condition as
satisfiable: the results say what the *structure* allows. The graph is the Karp–Miller coverability
graph (a place that can grow without bound gets ω), which equals the reachability graph when the
net is bounded. Exploration stops at ``max_states`` and says so. Exploration does not continue from
markings in which a final place holds a token, because a trial ends there.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Iterable
from dataclasses import dataclass, field

from .net import APN

OMEGA = math.inf
Marking = tuple[float, ...]


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

    @property
    def bounded(self) -> bool:
        return not self.unbounded_places

    @property
    def ok(self) -> bool:
        """Structurally sound: a final place reachable, no dead transitions, no stuck places."""
        return (self.final_reachable and not self.dead_transitions and not self.stuck_places
                and not self.truncated)


def analyse(apn: APN, max_states: int = 10_000) -> Analysis:
    """Build the coverability graph of ``apn`` from its initial marking and read properties off it."""
    pre = [[(apn.place_index(p), w) for p, w in t.inputs.items()] for t in apn.transitions]
    delta = apn.incidence.T.tolist()
    finals = [apn.place_index(p) for p in apn.final_places]
    m0: Marking = tuple(float(x) for x in apn.m0)
    states: list[Marking] = [m0]
    index = {m0: 0}
    parent: list[int | None] = [None]
    edges: list[tuple[int, str, int]] = []
    queue = deque([0])
    truncated = False
    fired = [False] * len(apn.transitions)
    while queue:
        k = queue.popleft()
        m = states[k]
        if any(m[i] > 0 for i in finals):
            continue
        for j, t in enumerate(apn.transitions):
            if not all(m[i] >= w for i, w in pre[j]):
                continue
            fired[j] = True
            new = [a + d if a != OMEGA else OMEGA for a, d in zip(m, delta[j])]
            # Karp–Miller acceleration: strictly covering an ancestor means unbounded growth.
            anc = k
            while anc is not None:
                old = states[anc]
                if all(n >= o for n, o in zip(new, old)) and any(n > o for n, o in zip(new, old)):
                    new = [OMEGA if n > o else n for n, o in zip(new, old)]
                anc = parent[anc]
            nm: Marking = tuple(new)
            if nm not in index:
                if len(states) >= max_states:
                    truncated = True
                    continue
                index[nm] = len(states)
                states.append(nm)
                parent.append(k)
                queue.append(index[nm])
            edges.append((k, t.id, index[nm]))

    unbounded = sorted({apn.place_ids[i] for m in states for i, x in enumerate(m) if x == OMEGA})
    dead = [t.id for j, t in enumerate(apn.transitions) if not fired[j]]

    good = _reaching_final(states, edges, finals)
    # With the cap hit, unexplored states would look stuck; only a complete graph decides it.
    bad_states = [] if truncated else [k for k in range(len(states)) if k not in good]
    stuck = sorted({apn.place_ids[i] for k in bad_states for i, x in enumerate(states[k]) if x > 0},
                   key=apn.place_ids.index)
    out_edges = {a for a, _, _ in edges}
    deadlocks = [states[k] for k in bad_states if k not in out_edges]
    return Analysis(states=states, edges=edges, truncated=truncated, max_states=max_states,
                    unbounded_places=unbounded, dead_transitions=dead, stuck_places=stuck,
                    deadlocks=deadlocks, final_reachable=bool(good) and 0 in good)


def _reaching_final(states: list[Marking], edges: list[tuple[int, str, int]], finals: list[int]) -> set[int]:
    """The states from which a state that marks a final place can be reached (a backward search)."""
    preds: dict[int, list[int]] = {}
    for a, _, b in edges:
        preds.setdefault(b, []).append(a)
    good = {k for k, m in enumerate(states) if any(m[i] > 0 for i in finals)}
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
    for p, x in zip(apn.place_ids, m):
        if x == OMEGA:
            parts.append(f"ω·{p}")
        elif x == 1:
            parts.append(p)
        elif x > 1:
            parts.append(f"{int(x)}·{p}")
    return "{" + ", ".join(parts) + "}"


def report(apn: APN, result: Analysis) -> list[str]:
    """Human-readable lines for ``multiform check``."""
    lines = [f"net {apn.name}: {len(apn.places)} places, {len(apn.transitions)} transitions, "
             f"initial marking {format_marking(apn, tuple(float(x) for x in apn.m0))}"]
    n = len(result.states)
    lines.append(f"reachability graph: {n} states, {len(result.edges)} edges"
                 + (f" (stopped at the cap of {result.max_states} states)" if result.truncated else ""))
    lines.append("bounded: yes" if result.bounded else
                 f"bounded: no (unbounded places: {', '.join(result.unbounded_places)})")
    lines.append("final place reachable: " + ("yes" if result.final_reachable else "NO"))
    lines.append("dead transitions: " + (", ".join(result.dead_transitions) or "none"))
    if result.truncated:
        lines.append("places from which no final place can be reached: not decided (state cap hit)")
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
