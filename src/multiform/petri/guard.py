"""The guard language: whitelisted expressions over named variables, compiled once to closures.

A condition in a skill file is text such as ``abs(theta) < 0.3 and fires_t2 < 10``. It is parsed
with :func:`ast.parse` (parsing only, nothing runs), every node is checked against a whitelist, and
the accepted tree is turned into nested Python closures that read variables from a flat list by
slot index. User text is never evaluated as code: the only things that can run are the operators
and functions listed below.

Accepted: numbers, ``true``/``false``, declared variable names, ``+ - * / ** %``, unary ``-``/``+``,
comparisons (chained too), ``and``/``or``/``not``, and the functions ``abs min max sqrt sin cos
atan2 exp wrap_angle``. Everything else (attributes, subscripts, other calls, lambdas,
comprehensions, strings, dunder names, keyword arguments) is refused with the offending text and
its column.
"""

from __future__ import annotations

import ast
import math
import operator
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from ..angles import wrap_angle

Values = Sequence[float]
Compiled = Callable[[Values], float]


# name -> (min args, max args or None for variadic, implementation)
FUNCTIONS: dict[str, tuple[int, int | None, Callable[..., float]]] = {
    "abs": (1, 1, abs),
    "min": (2, None, min),
    "max": (2, None, max),
    "sqrt": (1, 1, math.sqrt),
    "sin": (1, 1, math.sin),
    "cos": (1, 1, math.cos),
    "atan2": (2, 2, math.atan2),
    "exp": (1, 1, math.exp),
    "wrap_angle": (1, 1, wrap_angle),
}
CONSTANTS = {"true": True, "false": False, "pi": math.pi}
MAX_CHARS = 2000        # the bundled skills' longest condition has under 100
MAX_DEPTH = 64          # nesting of the expression tree (the closures it compiles to nest as deep)

_BINOPS = {ast.Add: operator.add, ast.Sub: operator.sub, ast.Mult: operator.mul,
           ast.Div: operator.truediv, ast.Pow: operator.pow, ast.Mod: operator.mod}
_CMPOPS = {ast.Lt: operator.lt, ast.LtE: operator.le, ast.Gt: operator.gt, ast.GtE: operator.ge,
           ast.Eq: operator.eq, ast.NotEq: operator.ne}
_REFUSED = {
    ast.Attribute: "attribute access", ast.Subscript: "subscripts", ast.Lambda: "lambdas",
    ast.ListComp: "comprehensions", ast.SetComp: "comprehensions", ast.DictComp: "comprehensions",
    ast.GeneratorExp: "comprehensions", ast.IfExp: "if-expressions", ast.NamedExpr: "assignment",
    ast.Starred: "starred arguments", ast.List: "lists", ast.Tuple: "tuples", ast.Dict: "dicts",
    ast.Set: "sets", ast.JoinedStr: "strings", ast.Await: "await", ast.Yield: "yield",
}


class GuardError(ValueError):
    """A condition that is not in the guard language; says what and where (1-based column)."""

    def __init__(self, text: str, message: str, col: int | None = None):
        self.text = text
        self.message = message
        self.col = col
        where = f" at column {col}" if col is not None else ""
        shown = repr(text) if len(text) <= 120 else f"{text[:60]!r}... ({len(text)} characters)"
        super().__init__(f"{message}{where} in {shown}")


# The intermediate form: small tuples, so that analysis (variables used) and compilation share one
# checked tree and never go back to Python's AST.
#   ("const", value) ("var", name) ("neg", e) ("not", e) ("bin", op, a, b)
#   ("cmp", [ops], [operands]) ("and", [es]) ("or", [es]) ("call", name, [args])


@dataclass(frozen=True)
class Guard:
    """A parsed condition: its text, the variables it reads, and its checked tree."""

    text: str
    variables: frozenset[str]
    tree: tuple

    def compile(self, slots: Mapping[str, int]) -> Compiled:
        """A callable ``f(values) -> value`` reading each variable at ``values[slots[name]]``."""
        return _compile(self.tree, slots)

    def evaluate(self, env: Mapping[str, float]) -> float:
        """Evaluate once with variables from a mapping (slow path: tests, tools, diagnosis)."""
        names = sorted(self.variables)
        f = self.compile({n: i for i, n in enumerate(names)})
        return f([env[n] for n in names])

    def evaluate_arrays(self, columns: Mapping[str, np.ndarray]) -> np.ndarray:
        """Evaluate over whole columns at once (recorded data, not the 1 kHz path): numpy semantics,
        NaN where a function is undefined (``sqrt`` of a negative number)."""
        n = len(next(iter(columns.values()))) if columns else 1
        with np.errstate(all="ignore"):
            out = _vector(self.tree, columns)
        return np.broadcast_to(np.asarray(out, dtype=np.float64), (n,)).copy()

    @property
    def is_true(self) -> bool:
        """True when the guard is the constant ``true`` (no condition at all)."""
        return self.tree == ("const", True)


def parse_guard(text: str, allowed: set[str] | frozenset[str] | None = None) -> Guard:
    """Parse and check ``text``; with ``allowed`` given, any other variable name is an error."""
    if not isinstance(text, str):
        raise GuardError(str(text), f"a condition must be text, got {type(text).__name__}")
    src = text.strip()
    if not src:
        raise GuardError(text, "empty condition")
    if len(src) > MAX_CHARS:
        raise GuardError(src, f"condition of {len(src)} characters, more than {MAX_CHARS}")
    try:
        node = ast.parse(src, mode="eval").body
    except SyntaxError as exc:
        raise GuardError(text, f"malformed expression ({exc.msg})", exc.offset or len(src) + 1) from None
    except (RecursionError, MemoryError):
        raise GuardError(src, f"expression nested more than {MAX_DEPTH} levels deep") from None
    depth = _depth(node)
    if depth > MAX_DEPTH:
        raise GuardError(src, f"expression nested {depth} levels deep, more than {MAX_DEPTH}")
    used: set[str] = set()
    tree = _check(node, src, used, allowed)
    return Guard(text=src, variables=frozenset(used), tree=_fold(tree))


def _depth(node: ast.AST) -> int:
    """Nesting depth of an expression tree, found without recursion."""
    deepest, stack = 0, [(node, 1)]
    while stack:
        n, d = stack.pop()
        deepest = max(deepest, d)
        stack.extend((c, d + 1) for c in ast.iter_child_nodes(n) if isinstance(c, ast.expr))
    return deepest


def _col(node: ast.AST) -> int:
    return getattr(node, "col_offset", 0) + 1


# One function on purpose: a dispatch over the node types the guard language admits, each branch a
# few lines; read together they are the whitelist.
def _check(node: ast.AST, src: str, used: set[str], allowed) -> tuple:
    def fail(n: ast.AST, what: str) -> GuardError:
        seg = ast.get_source_segment(src, n) or ""
        seg = seg if len(seg) <= 60 else seg[:40] + "..."
        return GuardError(src, f"{what} not allowed: {seg!r}" if seg else f"{what} not allowed", _col(n))

    rec = lambda n: _check(n, src, used, allowed)  # noqa: E731
    if isinstance(node, ast.Constant):
        v = node.value
        if isinstance(v, bool):
            return ("const", v)
        if isinstance(v, (int, float)) and not isinstance(v, complex):
            try:
                f = float(v)
            except OverflowError:
                f = math.inf
            if not math.isfinite(f):
                raise GuardError(src, "number out of range", _col(node))
            return ("const", f)
        raise fail(node, f"constant of type {type(v).__name__}")
    if isinstance(node, ast.Name):
        name = node.id
        if name.startswith("__"):
            raise fail(node, "dunder name")
        if name in CONSTANTS:
            return ("const", CONSTANTS[name])
        if name in FUNCTIONS:
            raise GuardError(src, f"function {name!r} used without a call", _col(node))
        if allowed is not None and name not in allowed:
            raise GuardError(src, f"undeclared variable {name!r}", _col(node))
        used.add(name)
        return ("var", name)
    if isinstance(node, ast.UnaryOp):
        if isinstance(node.op, ast.USub):
            return ("neg", rec(node.operand))
        if isinstance(node.op, ast.UAdd):
            return rec(node.operand)
        if isinstance(node.op, ast.Not):
            return ("not", rec(node.operand))
        raise fail(node, "operator " + type(node.op).__name__)
    if isinstance(node, ast.BinOp):
        op = _BINOPS.get(type(node.op))
        if op is None:
            raise fail(node, "operator " + type(node.op).__name__)
        return ("bin", op, rec(node.left), rec(node.right))
    if isinstance(node, ast.BoolOp):
        kind = "and" if isinstance(node.op, ast.And) else "or"
        return (kind, [rec(v) for v in node.values])
    if isinstance(node, ast.Compare):
        ops = []
        for o in node.ops:
            f = _CMPOPS.get(type(o))
            if f is None:
                raise fail(node, "comparison " + type(o).__name__)
            ops.append(f)
        return ("cmp", ops, [rec(node.left)] + [rec(c) for c in node.comparators])
    if isinstance(node, ast.Call):
        if not isinstance(node.func, ast.Name):
            if type(node.func) in _REFUSED:
                rec(node.func)
            raise fail(node.func, "calling anything but a listed function")
        name = node.func.id
        if name not in FUNCTIONS:
            raise GuardError(src, f"unknown function {name!r}", _col(node))
        if node.keywords:
            raise fail(node, "keyword arguments")
        args = [rec(a) for a in node.args]
        lo, hi, _ = FUNCTIONS[name]
        n = len(args)
        if n < lo or (hi is not None and n > hi):
            want = f"{lo}" if lo == hi else (f"at least {lo}" if hi is None else f"{lo}-{hi}")
            raise GuardError(src, f"{name}() takes {want} argument(s), got {n}", _col(node))
        return ("call", name, args)
    what = _REFUSED.get(type(node), type(node).__name__)
    raise fail(node, what)


def _fold(t: tuple) -> tuple:
    """Constant-fold subtrees without variables (keeps closures short on the hot path)."""
    kind = t[0]
    if kind in ("const", "var"):
        return t
    if kind in ("neg", "not"):
        a = _fold(t[1])
        if a[0] == "const":
            return ("const", -a[1] if kind == "neg" else (not a[1]))
        return (kind, a)
    if kind == "bin":
        a, b = _fold(t[2]), _fold(t[3])
        if a[0] == "const" and b[0] == "const":
            try:
                return ("const", t[1](a[1], b[1]))
            except (ArithmeticError, ValueError):
                pass
        return ("bin", t[1], a, b)
    if kind == "cmp":
        xs = [_fold(x) for x in t[2]]
        if all(x[0] == "const" for x in xs):
            return ("const", all(op(a[1], b[1]) for op, a, b in zip(t[1], xs, xs[1:])))
        return ("cmp", t[1], xs)
    if kind in ("and", "or"):
        xs = [_fold(x) for x in t[1]]
        if all(x[0] == "const" for x in xs):
            vals = [bool(x[1]) for x in xs]
            return ("const", all(vals) if kind == "and" else any(vals))
        return (kind, xs)
    if kind == "call":
        args = [_fold(x) for x in t[2]]
        if all(a[0] == "const" for a in args):
            try:
                return ("const", FUNCTIONS[t[1]][2](*[a[1] for a in args]))
            except (ArithmeticError, ValueError):
                pass
        return ("call", t[1], args)
    raise AssertionError(kind)


# One function on purpose: a dispatch over the checked tree's node kinds, each with the closures
# specialised for the shapes conditions usually have (variable vs constant), since one Python call
# per node is the cost that matters at 1 kHz.
def _compile(t: tuple, slots: Mapping[str, int]) -> Compiled:
    kind = t[0]
    if kind == "const":
        c = t[1]
        return lambda v: c
    if kind == "var":
        i = slots[t[1]]
        return lambda v: v[i]
    if kind == "neg":
        a = t[1]
        if a[0] == "var":
            i = slots[a[1]]
            return lambda v: -v[i]
        f = _compile(a, slots)
        return lambda v: -f(v)
    if kind == "not":
        f = _compile(t[1], slots)
        return lambda v: not f(v)
    if kind == "bin":
        op, a, b = t[1], t[2], t[3]
        if a[0] == "var" and b[0] == "const":
            i, c = slots[a[1]], b[1]
            return lambda v: op(v[i], c)
        fa, fb = _compile(a, slots), _compile(b, slots)
        return lambda v: op(fa(v), fb(v))
    if kind == "cmp":
        ops, xs = t[1], t[2]
        if len(ops) == 1:
            op, a, b = ops[0], xs[0], xs[1]
            if b[0] == "const":
                c = b[1]
                if a[0] == "var":
                    i = slots[a[1]]
                    return lambda v: op(v[i], c)
                if a[0] == "call" and a[1] == "abs" and a[2][0][0] == "var":
                    i = slots[a[2][0][1]]
                    return lambda v: op(abs(v[i]), c)
                fa = _compile(a, slots)
                return lambda v: op(fa(v), c)
            fa, fb = _compile(a, slots), _compile(b, slots)
            return lambda v: op(fa(v), fb(v))
        fs = [_compile(x, slots) for x in xs]
        pairs = list(zip(ops, range(len(ops))))

        def chained(v: Values) -> bool:
            vals = [f(v) for f in fs]
            return all(op(vals[k], vals[k + 1]) for op, k in pairs)
        return chained
    if kind == "and":
        fs = [_compile(x, slots) for x in t[1]]
        if len(fs) == 2:
            f1, f2 = fs
            return lambda v: f1(v) and f2(v)
        return lambda v: all(f(v) for f in fs)
    if kind == "or":
        fs = [_compile(x, slots) for x in t[1]]
        if len(fs) == 2:
            f1, f2 = fs
            return lambda v: f1(v) or f2(v)
        return lambda v: any(f(v) for f in fs)
    if kind == "call":
        name, args = t[1], t[2]
        impl = FUNCTIONS[name][2]
        if len(args) == 1:
            a = args[0]
            if a[0] == "var":
                i = slots[a[1]]
                return lambda v: impl(v[i])
            f = _compile(a, slots)
            return lambda v: impl(f(v))
        fs = [_compile(x, slots) for x in args]
        if len(fs) == 2:
            f1, f2 = fs
            return lambda v: impl(f1(v), f2(v))
        return lambda v: impl(*[f(v) for f in fs])
    raise AssertionError(kind)


_VECTOR_FUNCS: dict[str, Callable[..., np.ndarray]] = {
    "abs": np.abs, "min": lambda *a: np.minimum.reduce(np.broadcast_arrays(*a)),
    "max": lambda *a: np.maximum.reduce(np.broadcast_arrays(*a)), "sqrt": np.sqrt, "sin": np.sin, "cos": np.cos,
    "atan2": np.arctan2, "exp": np.exp,
    "wrap_angle": lambda a: np.where((w := np.mod(a + np.pi, 2 * np.pi)) <= 0, w + 2 * np.pi, w) - np.pi,
}


def _vector(t: tuple, cols: Mapping[str, np.ndarray]):
    kind = t[0]
    if kind == "const":
        return np.float64(t[1])
    if kind == "var":
        return np.asarray(cols[t[1]], dtype=np.float64)
    if kind == "neg":
        return -_vector(t[1], cols)
    if kind == "not":
        return np.logical_not(_vector(t[1], cols))
    if kind == "bin":
        return t[1](_vector(t[2], cols), _vector(t[3], cols))
    if kind == "cmp":
        vals = [_vector(x, cols) for x in t[2]]
        return np.logical_and.reduce([op(a, b) for op, a, b in zip(t[1], vals, vals[1:])])
    if kind == "and":
        return np.logical_and.reduce([_vector(x, cols) for x in t[1]])
    if kind == "or":
        return np.logical_or.reduce([_vector(x, cols) for x in t[1]])
    if kind == "call":
        return _VECTOR_FUNCS[t[1]](*[_vector(x, cols) for x in t[2]])
    raise AssertionError(kind)


def to_text(tree: tuple) -> str:
    """Render a checked tree back to guard-language text (used for diagrams and diffs)."""
    kind = tree[0]
    if kind == "const":
        v = tree[1]
        return ("true" if v else "false") if isinstance(v, bool) else f"{v:g}"
    if kind == "var":
        return tree[1]
    if kind == "neg":
        return f"-{_paren(tree[1])}"
    if kind == "not":
        return f"not {_paren(tree[1])}"
    if kind == "bin":
        sym = {operator.add: "+", operator.sub: "-", operator.mul: "*", operator.truediv: "/",
               operator.pow: "**", operator.mod: "%"}[tree[1]]
        return f"{_paren(tree[2])} {sym} {_paren(tree[3])}"
    if kind == "cmp":
        syms = {operator.lt: "<", operator.le: "<=", operator.gt: ">", operator.ge: ">=",
                operator.eq: "==", operator.ne: "!="}
        out = _paren(tree[2][0])
        for op, x in zip(tree[1], tree[2][1:]):
            out += f" {syms[op]} {_paren(x)}"
        return out
    if kind in ("and", "or"):
        return f" {kind} ".join(_paren(x) for x in tree[1])
    if kind == "call":
        return f"{tree[1]}({', '.join(to_text(a) for a in tree[2])})"
    raise AssertionError(kind)


def _paren(t: tuple) -> str:
    s = to_text(t)
    return s if t[0] in ("const", "var", "call") else f"({s})"
