"""The public API: ``import multiform`` is cheap and gives every documented name, each with a
docstring, and docs/api.md is the page the docstrings generate."""

from __future__ import annotations

import importlib.util
import subprocess
import sys
from pathlib import Path

import multiform

ROOT = Path(__file__).resolve().parent.parent


def test_every_exported_name_resolves_and_has_a_docstring():
    for name in multiform.__all__:
        obj = getattr(multiform, name)
        assert (obj.__doc__ or "").strip(), f"{name} has no docstring"
    assert "Task" in dir(multiform)


def test_import_multiform_loads_no_learner():
    code = "import sys, multiform; print(sorted(m for m in ('sklearn', 'multiform.learn.gp', 'multiform.job') if m in sys.modules))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"


def test_the_api_page_is_up_to_date():
    spec = importlib.util.spec_from_file_location("api_docs", ROOT / "scripts" / "api_docs.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    assert (ROOT / "docs" / "api.md").read_text() == mod.render(), "run python scripts/api_docs.py"


def test_mentor_rate_runs_the_mentor_from_the_evaluation_starts():
    task = str(ROOT / "examples" / "mountain_car" / "mountain_car.py") + ":MountainCar"
    r = multiform.mentor_rate(task, trials=4, seed=1, workers=1)
    assert r["seeds"] == [50_100_000, 50_100_001, 50_100_002, 50_100_003]
    assert r["trials"] == 4 and r["successes"] == r["outcomes"].count("success") and 0 <= r["low"] <= r["rate"]
    assert [s.seed for s in multiform.load_task(task).evaluation_specs(4, 1, 0.5)] == r["seeds"]


def test_import_multiform_imports_neither_gymnasium_nor_mujoco_and_registers_nothing():
    code = "import sys, multiform; print(sorted(m for m in ('gymnasium', 'mujoco') if m in sys.modules))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"
