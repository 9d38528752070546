"""Pictures of nets through graphviz: places with their tokens, transitions with λ and conditions,
final places marked, and what a revision changed drawn in another colour (the paper's Fig. 8).
"""

from __future__ import annotations

import os
from collections.abc import Iterable, Mapping
from pathlib import Path

import graphviz

from ..errors import InvalidInput
from ..io import atomic_path
from .net import APN

FORMATS = ("svg", "png", "pdf", "dot")      # what a picture of a net is written as, by its file's suffix

CHANGED = "#d95f02"      # what a revision added or changed
SUCCESS = "#1b9e77"
FAILURE = "#c0392b"


def changed_elements(old: APN, new: APN) -> set[str]:
    """Ids of places and transitions that are new in ``new`` or differ from ``old``."""
    out = {p.id for p in new.places if p.id not in old.place_ids or old.place(p.id) != p}
    out |= {t.id for t in new.transitions if t.id not in old.transition_ids or old.transition(t.id) != t}
    return out


def _wrap(text: str, width: int = 28) -> str:
    words, lines, cur = text.split(), [], ""
    for w in words:
        if cur and len(cur) + 1 + len(w) > width:
            lines.append(cur)
            cur = w
        else:
            cur = f"{cur} {w}" if cur else w
    if cur:
        lines.append(cur)
    return "\\n".join(lines)


def to_graph(apn: APN, marking: Mapping[str, int] | None = None, changed: Iterable[str] = (),
             title: str | None = None) -> graphviz.Digraph:
    """A graphviz digraph of ``apn``; ``marking`` defaults to the initial marking."""
    marking = dict(apn.initial_marking if marking is None else marking)
    changed = set(changed)
    g = graphviz.Digraph(apn.name, graph_attr={"rankdir": "LR", "fontname": "Helvetica", "fontsize": "11",
                                               "label": title or apn.name, "labelloc": "t", "nodesep": "0.4"},
                         node_attr={"fontname": "Helvetica", "fontsize": "10"},
                         edge_attr={"fontname": "Helvetica", "fontsize": "9", "arrowsize": "0.7"})
    for p in apn.places:
        n = marking.get(p.id, 0)
        tokens = "●" * n if n <= 3 else f"{n}●"
        label = f"{p.id}\\n{_wrap(p.label, 14)}" + (f"\\n{tokens}" if n else "")
        attrs = {"shape": "doublecircle" if p.final else "circle", "label": label, "width": "0.9", "fixedsize": "false"}
        if p.final == "success":
            attrs.update(color=SUCCESS, fontcolor=SUCCESS)
        elif p.final == "failure":
            attrs.update(color=FAILURE, fontcolor=FAILURE)
        if p.id in changed:
            attrs.update(style="filled", fillcolor="#fde0c5", color=CHANGED, penwidth="2")
        g.node(p.id, **attrs)
    for t in apn.transitions:
        lines = [f"{t.id}: {_wrap(t.label, 24)}" if t.label else t.id]
        if t.law:
            lines.append(f"law: {t.law}")
        lines.append(f"λ = {t.lam:.3g}")
        if not (t.condition.guard is not None and t.condition.guard.is_true):
            lines.append(_wrap(f"if {t.condition}", 30))
        attrs = {"shape": "box", "label": "\\n".join(lines), "style": "filled", "fillcolor": "#eeeeee"}
        if t.id in changed:
            attrs.update(fillcolor="#fde0c5", color=CHANGED, penwidth="2", fontcolor=CHANGED)
        g.node(t.id, **attrs)
        for p, w in t.inputs.items():
            g.edge(p, t.id, label=str(w) if w != 1 else "",
                   **({"color": CHANGED, "penwidth": "2"} if t.id in changed else {}))
        for p, w in t.outputs.items():
            g.edge(t.id, p, label=str(w) if w != 1 else "",
                   **({"color": CHANGED, "penwidth": "2"} if t.id in changed else {}))
    return g


def draw(apn: APN, path: str | os.PathLike, marking: Mapping[str, int] | None = None,
         changed: Iterable[str] = (), title: str | None = None) -> Path:
    """Render ``apn`` to ``path``; the suffix (one of :data:`FORMATS`, none: SVG) picks the format."""
    path = Path(path)
    fmt = path.suffix.lstrip(".").lower() or "svg"
    if fmt not in FORMATS:
        raise InvalidInput(f"unknown picture format {path.suffix!r}; give a file ending in "
                           + ", ".join(f".{f}" for f in FORMATS), file=str(path))
    data = to_graph(apn, marking, changed, title).pipe(format=fmt)
    with atomic_path(path) as tmp:
        tmp.write_bytes(data)
    return path
