"""Layering: the method (petri, learn, adapt, runtime) never imports an environment, a task or a
mentor, and the package has no import cycle among the imports a module runs when it is imported."""

from __future__ import annotations

import ast
from pathlib import Path

import multiform

ROOT = Path(multiform.__file__).parent
METHOD = ("petri", "learn", "adapt", "runtime")
FORBIDDEN = ("multiform.envs", "multiform.tasks", "multiform.teach.record", "multiform.teach.teleop",
             "multiform.tasks.pendulum_mentor", "multiform.tasks.nunchaku_mentor", "multiform.job", "multiform.cli")


def module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT.parent).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def imports(path: Path, top_level_only: bool, source: str | None = None) -> set[str]:
    """Modules ``path`` imports (relative imports resolved); with ``top_level_only`` only those run
    on import (not inside functions)."""
    tree = ast.parse(path.read_text() if source is None else source)
    here = module_name(path)
    package = here if path.name == "__init__.py" else here.rpartition(".")[0]
    nodes = ast.iter_child_nodes(tree) if top_level_only else ast.walk(tree)
    found: set[str] = set()
    for node in nodes:
        if isinstance(node, ast.Import):
            found |= {a.name for a in node.names}
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                up = package.split(".")
                up = up[: len(up) - node.level + 1]
                base = ".".join(up + ([node.module] if node.module else []))
            found.add(base)
            found |= {f"{base}.{a.name}" for a in node.names}
    return {m for m in found if m.startswith("multiform")}


def all_modules() -> dict[str, Path]:
    return {module_name(p): p for p in ROOT.rglob("*.py")}


def test_the_method_imports_no_env_task_or_mentor():
    bad = []
    for name, path in all_modules().items():
        if name.split(".")[1:2] and name.split(".")[1] in METHOD:
            for m in imports(path, top_level_only=False):
                if any(m == f or m.startswith(f + ".") for f in FORBIDDEN):
                    bad.append(f"{name} imports {m}")
    assert not bad, "\n".join(bad)


def test_no_import_cycle():
    mods = all_modules()
    graph = {name: {m for m in imports(path, top_level_only=True) if m in mods and m != name}
             for name, path in mods.items()}
    # importing a package's submodule runs the package first: an edge to each enclosing package
    for name in mods:
        for deps in (graph[name],):
            for m in list(deps):
                parts = m.split(".")
                deps |= {".".join(parts[:i]) for i in range(2, len(parts)) if ".".join(parts[:i]) in mods} - {name}
            # a package's __init__ that imports its own submodules closes no cycle: its submodules
            # import siblings, never the package they belong to
            deps -= {name.rsplit(".", i)[0] for i in range(1, name.count("."))}
    state: dict[str, int] = {}
    stack: list[str] = []

    def visit(n: str) -> list[str] | None:
        state[n] = 1
        stack.append(n)
        for m in sorted(graph[n]):
            if state.get(m) == 1:
                return stack[stack.index(m):] + [m]
            if m not in state:
                cycle = visit(m)
                if cycle:
                    return cycle
        stack.pop()
        state[n] = 2
        return None

    for n in sorted(graph):
        if n not in state:
            cycle = visit(n)
            assert cycle is None, " -> ".join(cycle)


def test_the_checks_see_a_violation():
    """The layering check is not vacuous: it resolves a relative import of an env from learn, and
    one inside a function."""
    probe = ROOT / "learn" / "probe.py"
    assert "multiform.envs.osc" in imports(probe, True, "from ..envs import osc\n")
    inside = "def f():\n    from ...multiform.tasks import pendulum\n"
    assert imports(probe, True, inside) == set() and "multiform.tasks.pendulum" in imports(probe, False, inside)
