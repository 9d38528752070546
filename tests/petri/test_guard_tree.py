"""Reading and editing a parsed guard's tree: comparisons with a constant found through and/or, their
normal form, one constant moved, a subtree's value and variables."""

from __future__ import annotations

import operator

import pytest

from multiform.petri.guard import parse_guard, to_text
from multiform.petri.guard_tree import (GREATER, atoms, normal, replace_at, subtree, value_at, variables,
                                        with_constant)


def test_atoms_are_the_comparisons_with_a_constant_reachable_through_and_or():
    tree = parse_guard("abs(theta) < 0.3 and (fires_t2 >= 12 or 2.0 < dwell) and x < y").tree
    found = [(path, to_text(a)) for path, a in atoms(tree)]
    assert found == [((0,), "abs(theta) < 0.3"), ((1, 0), "fires_t2 >= 12"), ((1, 1), "2 < dwell")]
    assert atoms(parse_guard("not (theta > 1)").tree) == []        # under a not: no constant to move


def test_normal_puts_the_constant_on_the_right_and_flips_the_operator():
    tree = parse_guard("2.0 < dwell").tree
    expr, op, c = normal(tree)
    assert (to_text(expr), op, c) == ("dwell", operator.gt, 2.0) and op in GREATER
    expr, op, c = normal(parse_guard("abs(omega) <= 5").tree)
    assert (to_text(expr), op, c) == ("abs(omega)", operator.le, 5.0) and op not in GREATER


def test_a_constant_moved_in_place_leaves_the_rest_of_the_guard_as_written():
    tree = parse_guard("abs(theta) > 0.8 or fires_t3 >= 10").tree
    (path, atom), _ = atoms(tree)
    moved = replace_at(tree, path, with_constant(subtree(tree, path), 0.9))
    same = lambda text: to_text(parse_guard(text).tree)  # noqa: E731
    assert to_text(moved) == same("abs(theta) > 0.9 or fires_t3 >= 10")
    assert to_text(tree) == same("abs(theta) > 0.8 or fires_t3 >= 10")     # the original is untouched
    flipped = with_constant(parse_guard("2.0 < dwell").tree, 3.5)
    assert to_text(flipped) == "3.5 < dwell"


@pytest.mark.parametrize("text, env, value", [("abs(theta) - 0.3", {"theta": -0.5}, 0.2),
                                               ("wrap_angle(phi + 7)", {"phi": 0.0}, 7 - 2 * 3.141592653589793)])
def test_a_subtree_is_evaluated_at_one_state(text, env, value):
    assert value_at(parse_guard(text).tree, env) == pytest.approx(value)


def test_the_variables_a_subtree_reads():
    tree = parse_guard("abs(theta) < 0.3 and max(omega, -x) < sqrt(c) and not done > 0").tree
    assert variables(tree) == {"theta", "omega", "x", "c", "done"}
    assert variables(parse_guard("1 < 2").tree) == set()
