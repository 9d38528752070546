import math

import pytest
from hypothesis import given
from hypothesis import strategies as st

from multiform.petri.guard import GuardError, parse_guard, to_text, wrap_angle

finite = st.floats(min_value=-100, max_value=100, allow_nan=False)


@pytest.mark.parametrize("text, env, expected", [
    ("true", {}, True),
    ("false or true", {}, True),
    ("abs(theta) < 0.3 and abs(omega) < 2", {"theta": -0.2, "omega": 1.0}, True),
    ("abs(theta) < 0.3 and abs(omega) < 2", {"theta": -0.2, "omega": 3.0}, False),
    ("0 < x <= 1 < y", {"x": 1.0, "y": 2.0}, True),
    ("0 < x <= 1 < y", {"x": 1.0, "y": 0.5}, False),
    ("not (x > 1)", {"x": 0.0}, True),
    ("x ** 2 + y % 3", {"x": 2.0, "y": 7.0}, 5.0),
    ("-x * 2 / 4", {"x": 2.0}, -1.0),
    ("min(x, y, 3) + max(x, y)", {"x": 1.0, "y": 2.0}, 3.0),
    ("sqrt(x) + exp(0) + sin(0) + cos(0)", {"x": 4.0}, 4.0),
    ("atan2(1, 1)", {}, math.pi / 4),
    ("wrap_angle(x)", {"x": 3 * math.pi / 2}, -math.pi / 2),
    ("x == 0 and y != 0", {"x": 0.0, "y": 1.0}, True),
    ("pi", {}, math.pi),
])
def test_semantics(text, env, expected):
    assert parse_guard(text).evaluate(env) == pytest.approx(expected)


@pytest.mark.parametrize("text, fragment", [
    ("x.real > 0", "attribute access not allowed"),
    ("x[0] > 0", "subscripts not allowed"),
    ("open('f')", "unknown function 'open'"),
    ("__import__('os')", "unknown function '__import__'"),
    ("__class__", "dunder name not allowed"),
    ("(lambda: 1)()", "lambdas not allowed"),
    ("[a for a in b]", "comprehensions not allowed"),
    ("max(a for a in b)", "comprehensions not allowed"),
    ("x if y else z", "if-expressions not allowed"),
    ("'text'", "constant of type str not allowed"),
    ("abs(x, 2)", "abs() takes 1 argument(s), got 2"),
    ("max(x)", "max() takes at least 2 argument(s)"),
    ("min(x, key=y)", "keyword arguments not allowed"),
    ("(x := 3)", "assignment not allowed"),
    ("x & y", "operator BitAnd not allowed"),
    ("x in y", "comparison In not allowed"),
    ("x is y", "comparison Is not allowed"),
    ("x +", "malformed expression"),
    ("", "empty condition"),
    ("abs", "used without a call"),
    ("f(x)(y)", "calling anything but a listed function"),
])
def test_refused(text, fragment):
    with pytest.raises(GuardError) as info:
        parse_guard(text, {"x", "y", "z", "a", "b"})
    assert fragment in str(info.value)


def test_error_names_position():
    with pytest.raises(GuardError) as info:
        parse_guard("abs(theta) < 1 and omega.imag > 0", {"theta", "omega"})
    assert info.value.col == 20
    assert "omega.imag" in str(info.value)


def test_undeclared_variable_refused():
    with pytest.raises(GuardError, match="undeclared variable 'phi'"):
        parse_guard("phi > 1", {"theta"})


def test_variables_collected():
    assert parse_guard("abs(theta) < 0.1 and dwell > 2 or pi > x").variables == {"theta", "dwell", "x"}


def test_constant_folding_leaves_no_variables():
    g = parse_guard("2 * 3 > 5")
    assert g.tree == ("const", True) and g.is_true


@given(finite, finite, finite)
def test_compiled_matches_python_arithmetic(x, y, z):
    g = parse_guard("x * y - z / (abs(y) + 1) + max(x, z) ** 2")
    expected = x * y - z / (abs(y) + 1) + max(x, z) ** 2
    assert g.evaluate({"x": x, "y": y, "z": z}) == pytest.approx(expected, rel=1e-12, abs=1e-12)


@given(finite, finite)
def test_chained_comparison_matches_python(x, y):
    assert parse_guard("x < y <= 2 * y").evaluate({"x": x, "y": y}) == (x < y <= 2 * y)


@given(st.floats(min_value=-50, max_value=50, allow_nan=False))
def test_wrap_angle_range_and_equivalence(a):
    w = wrap_angle(a)
    assert -math.pi < w <= math.pi
    assert math.cos(w) == pytest.approx(math.cos(a), abs=1e-9)
    assert math.sin(w) == pytest.approx(math.sin(a), abs=1e-9)


@pytest.mark.parametrize("text", ["abs(theta) < 0.3 and abs(omega) < 2", "0 < x <= 1", "not (x > 1) or y == 2",
                                  "-x * 2 + max(x, y, 1)"])
def test_to_text_round_trips(text):
    g = parse_guard(text)
    assert parse_guard(to_text(g.tree)).tree == g.tree


@pytest.mark.parametrize("text, fragment", [
    ("x < " + "1" * 400, "number out of range at column 5"),
    ("x < 1e999", "number out of range"),
    ("-" * 100_000 + "x", "condition of 100001 characters, more than 2000"),
    ("x" + " + x" * 400, "expression nested 401 levels deep, more than 64"),
    ("(" * 250 + "x" + ")" * 250 + " < 1", "malformed expression (too many nested parentheses)"),
    ("not " * 300 + "x", "nested 301 levels deep"),
    ("abs(" * 70 + "x" + ")" * 70, "nested 71 levels deep"),
])
def test_long_deep_or_huge_refused(text, fragment):
    with pytest.raises(GuardError) as info:
        parse_guard(text)
    assert fragment in str(info.value)
    assert len(str(info.value)) < 300


def test_deepest_allowed_guard_compiles_and_runs():
    g = parse_guard("x" + " + x" * 60 + " > 0")
    assert g.evaluate({"x": 1.0}) is True
