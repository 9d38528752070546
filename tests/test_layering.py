"""Layering: every import of the package points down the layers the README's layout states, none
closes a cycle, and the method (petri, learn, adapt, runtime) imports no env, task or mentor. An
import inside a function or under TYPE_CHECKING is an import like any other."""

from __future__ import annotations

import ast
import re
from pathlib import Path

import multiform

ROOT = Path(multiform.__file__).parent
README = ROOT.parent.parent / "README.md"
# bottom up; a module may import its own layer or any below it (README "Layout")
LAYERS = [
    ("errors", "_gl", "registry"),
    ("io", "stats", "angles", "lock"),
    ("petri",),
    ("demos",),
    ("learn",),
    ("runtime",),
    ("model", "trainer"),
    ("adapt",),
    ("task",),
    ("parallel", "cluster"),
    ("evaluation",),
    ("envs",),
    ("teach",),
    ("tasks", "skills"),
    ("job", "report", "view"),
    ("api",),
    ("cli", "cli_options", "__main__"),
]
METHOD = ("petri", "learn", "adapt", "runtime")
FORBIDDEN = ("multiform.envs", "multiform.tasks", "multiform.teach", "multiform.job", "multiform.cli")


def module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT.parent).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def imports(path: Path, source: str | None = None) -> dict[str, int]:
    """Modules ``path`` imports anywhere in it (relative imports resolved), with the line of each."""
    tree = ast.parse(path.read_text() if source is None else source)
    here = module_name(path)
    package = here if path.name == "__init__.py" else here.rpartition(".")[0]
    found: dict[str, int] = {}
    for node in ast.walk(tree):
        names: list[str] = []
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                up = package.split(".")
                up = up[: len(up) - node.level + 1]
                base = ".".join(up + ([node.module] if node.module else []))
            names = [base] + [f"{base}.{a.name}" for a in node.names]
        for m in names:
            if m.startswith("multiform"):
                found.setdefault(m, node.lineno)
    return found


def all_modules() -> dict[str, Path]:
    return {module_name(p): p for p in ROOT.rglob("*.py")}


def resolve(name: str, mods: dict[str, Path]) -> str:
    """The module an imported name lives in (``a.b.func`` -> ``a.b``)."""
    while name not in mods and "." in name:
        name = name.rsplit(".", 1)[0]
    return name


def layer_of(module: str) -> int | None:
    unit = module.split(".")[1] if "." in module else ""
    return next((i for i, units in enumerate(LAYERS) if unit in units), None)


def edges(with_packages: bool = False) -> dict[str, dict[str, int]]:
    """module -> {module it imports: line}. For cycles, packages' own ``__init__`` modules are not
    nodes (importing a package's submodule runs it, but it imports only its own submodules); for the
    layers (``with_packages``) they are: importing a package (``import multiform.envs``) is importing
    its layer."""
    mods = all_modules()
    packages = {module_name(p) for p in ROOT.rglob("__init__.py")}
    out: dict[str, dict[str, int]] = {}
    for name, path in mods.items():
        if name in packages and not with_packages:
            continue
        for imported, line in imports(path).items():
            target = resolve(imported, mods)
            if target != name and (with_packages or target not in packages) and target != "multiform" \
                    and not name.startswith(target + "."):
                out.setdefault(name, {}).setdefault(target, line)
    return out


def test_every_module_has_a_layer():
    stray = [m for m in all_modules() if m != "multiform" and layer_of(m) is None]
    assert not stray, f"place these in LAYERS and the README's layout: {stray}"


def test_every_import_points_down_or_sideways():
    up = [f"{a} -> {b} (line {line})" for a, targets in edges(with_packages=True).items()
          for b, line in targets.items() if a != "multiform" and layer_of(b) > layer_of(a)]
    assert not up, "\n".join(up)


def test_no_import_cycle():
    graph = edges()
    state: dict[str, int] = {}
    stack: list[str] = []

    def visit(n: str) -> list[str] | None:
        state[n] = 1
        stack.append(n)
        for m in sorted(graph.get(n, {})):
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


def test_the_method_imports_no_env_task_or_mentor():
    bad = [f"{name} imports {m}" for name, path in all_modules().items()
           if name.split(".")[1:2] and name.split(".")[1] in METHOD
           for m in imports(path) if any(m == f or m.startswith(f + ".") for f in FORBIDDEN)]
    assert not bad, "\n".join(bad)


def test_the_readme_states_these_layers():
    text = README.read_text()
    m = re.search(r"Layers, bottom up:(.*?)\n\n", text, re.S)
    assert m, "the README's layout section states the layers"
    stated = [tuple(u.strip(" `.\n") for u in group.split(",")) for group in re.sub(r"\s+", " ", m.group(1)).split("→")]
    assert stated == [tuple(u for u in layer if not u.startswith("_") and u != "__main__") for layer in LAYERS]


def test_the_checks_see_a_violation():
    """The checks are not vacuous: a relative import of an env from learn resolves, also inside a
    function, and it points up."""
    probe = ROOT / "learn" / "probe.py"
    assert "multiform.envs.osc" in imports(probe, "from ..envs import osc\n")
    inside = "def f():\n    from ...multiform.tasks import pendulum\n"
    assert "multiform.tasks.pendulum" in imports(probe, inside)
    assert layer_of("multiform.envs.osc") > layer_of("multiform.learn.probe")
