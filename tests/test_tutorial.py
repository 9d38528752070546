"""The tutorial is a test: examples/mountain_car teaches a skill on a Gymnasium env multiform does
not ship, in at most 60 lines of Python that use only names ``multiform`` exports, and every
command runs it through ``module:NAME``."""

from __future__ import annotations

import ast
import json
import re
import shlex
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

import multiform

EXAMPLE = Path(__file__).resolve().parent.parent / "examples" / "mountain_car"
PYTHON = sorted(EXAMPLE.glob("*.py"))
TASK = "mountain_car:MountainCar"


def test_the_example_is_at_most_sixty_lines_using_only_exported_names():
    assert sum(len(p.read_text().splitlines()) for p in PYTHON) <= 60
    for path in PYTHON:
        tree = ast.parse(path.read_text())
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom) and node.module:
                assert not node.module.startswith("multiform"), f"{path.name}: from {node.module} import"
            if isinstance(node, ast.Import):
                assert all(a.name == "multiform" or not a.name.startswith("multiform") for a in node.names)
            if isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) and node.value.id == "multiform":
                assert node.attr in multiform.__all__, f"{path.name}: multiform.{node.attr} is not exported"


@pytest.mark.slow
def test_the_tutorial_runs_end_to_end_with_a_repair(tmp_path):
    """Scripted demos -> train -> practice (the over-strict t1 relearned), then practice that learns from
    its own trials -> evaluation (≈ 15 s)."""
    res = subprocess.run([sys.executable, "run.py", str(tmp_path / "run")], cwd=EXAMPLE, capture_output=True,
                         text=True, timeout=600)
    assert res.returncode == 0, res.stderr[-2000:]
    assert re.search(r"revision 1: set_condition t1 — .*condition relearned from the mentor's switches", res.stdout), \
        res.stdout
    # the Task defaults' second scenario learns from practice: it explores and keeps its own graded segments
    keep = re.search(r"keep: (\d+) trials \((\d+) exploring\), (\d+) segments of its own", res.stdout)
    assert keep and int(keep.group(2)) > 0 and int(keep.group(3)) > 0, res.stdout
    ok, n = map(int, re.search(r"success (\d+)/(\d+)", res.stdout).groups())
    assert n == 20 and ok >= 18
    # a mentor that never fails: train says the judges are uninformative, in one line each, no warnings
    assert res.stdout.count("uninformative") == 2 and "Warning" not in res.stdout + res.stderr


def _printed_commands() -> list[list[str]]:
    """The tutorial's command-line section, as printed in docs/your-own-skill.md."""
    text = (EXAMPLE.parent.parent / "docs" / "your-own-skill.md").read_text()
    block = text.split("## 4. The same from the command line", 1)[1].split("```", 2)[1]
    lines = [line.strip() for line in block.splitlines() if line.strip()]
    assert lines[0] == "cd examples/mountain_car"
    return [shlex.split(line) for line in lines[1:]]


@pytest.mark.slow
def test_the_tutorials_commands_run_as_printed_from_the_examples_folder(tmp_path):
    """Each printed command, run by the installed `multiform` program in a copy of
    examples/mountain_car (so the run writes nowhere else), with nothing added to the import path:
    `mountain_car:MountainCar` is found in the current folder (about a minute)."""
    folder = tmp_path / "mountain_car"
    shutil.copytree(EXAMPLE, folder, ignore=shutil.ignore_patterns("__pycache__"))
    program = Path(sys.executable).with_name("multiform")
    outputs = []
    for argv in _printed_commands():
        assert argv[0] == "multiform"
        res = subprocess.run([str(program), *argv[1:]], cwd=folder, capture_output=True, text=True, timeout=600)
        assert res.returncode == 0, f"{' '.join(argv)}: {res.stderr[-2000:]}"
        outputs.append(res.stdout)
    assert any("set_condition t1" in out for out in outputs)              # practice relearned t1
    ev = json.loads((folder / "eval" / "evaluation.json").read_text())
    assert ev["task"] == "mountain_car" and ev["trials"] == 20 and ev["successes"] >= 18
    metrics = json.loads((folder / "run" / "metrics.json").read_text())
    assert metrics["task"] == "mountain_car" and metrics["success_rate"]["successes"] >= 190
    assert [r["name"] for r in metrics["ablation"]] == [metrics["ablation"][0]["name"]]   # --ablation-trials 0
    assert "0.0 % (0.0-100.0 %)" not in outputs[-1]
