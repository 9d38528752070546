"""Reading and editing a parsed guard's tree (:attr:`~.guard.Guard.tree`): its comparisons with a
constant, their normal form, and a copy with one constant moved. Repairs that move a limit or a
bound to the mentor's data edit conditions through these."""

from __future__ import annotations

import operator
from typing import Any

import numpy as np

from .guard import parse_guard, to_text

GREATER = (operator.gt, operator.ge)
_FLIP = {operator.lt: operator.gt, operator.le: operator.ge, operator.gt: operator.lt, operator.ge: operator.le}


def atoms(tree: tuple, path: tuple = ()) -> list[tuple[tuple, tuple]]:
    """(path, comparison) for each ``expression op constant`` comparison reachable through and/or."""
    kind = tree[0]
    if kind in ("and", "or"):
        return [a for i, x in enumerate(tree[1]) for a in atoms(x, path + (i,))]
    if kind == "cmp" and len(tree[1]) == 1 and (tree[2][0][0] == "const") != (tree[2][1][0] == "const"):
        return [(path, tree)]
    return []


def normal(atom: tuple) -> tuple[tuple, Any, float]:
    """A comparison as (expression, operator, constant) with the constant on the right."""
    op, (a, b) = atom[1][0], atom[2]
    if a[0] == "const":
        return b, _FLIP.get(op, op), float(a[1])
    return a, op, float(b[1])


def subtree(tree: tuple, path: tuple) -> tuple:
    """The node at ``path`` (indices through and/or)."""
    for i in path:
        tree = tree[1][i]
    return tree


def replace_at(tree: tuple, path: tuple, node: tuple) -> tuple:
    """``tree`` with the node at ``path`` replaced by ``node``."""
    if not path:
        return node
    kind, items = tree[0], list(tree[1])
    items[path[0]] = replace_at(items[path[0]], path[1:], node)
    return (kind, items)


def with_constant(atom: tuple, value: float) -> tuple:
    """A comparison with its constant set to ``value``."""
    op, (a, b) = atom[1], atom[2]
    return ("cmp", op, [("const", value), b] if a[0] == "const" else [a, ("const", value)])


def value_at(tree: tuple, env: dict[str, float]) -> float:
    """A guard subtree's value at one state (``env``: variable -> value)."""
    g = parse_guard(to_text(tree))
    return float(g.evaluate_arrays({k: np.array([env[k]]) for k in g.variables})[0])


def variables(tree: tuple) -> set[str]:
    """The variables a guard subtree reads."""
    kind = tree[0]
    if kind == "var":
        return {tree[1]}
    if kind in ("neg", "not"):
        return variables(tree[1])
    if kind == "bin":
        return variables(tree[2]) | variables(tree[3])
    if kind in ("cmp", "and", "or"):
        items = tree[2] if kind == "cmp" else tree[1]
        return set().union(*(variables(x) for x in items))
    if kind == "call":
        return set().union(set(), *(variables(x) for x in tree[2]))
    return set()
