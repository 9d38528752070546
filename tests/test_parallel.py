"""Choosing where work runs: the local pool's start method, and Ray only when asked for."""

from __future__ import annotations

import subprocess
import sys

import pytest

from multiform.cli import main
from multiform.errors import InvalidInput
from multiform.parallel import default_start_method, fitting, mp_context, ray_backend


def test_the_local_pool_forks_on_linux_and_refuses_an_unknown_start_method():
    if sys.platform.startswith("linux"):
        assert default_start_method() == "fork"
    assert mp_context("spawn").get_start_method() == "spawn"
    with pytest.raises(InvalidInput, match="start method 'threads'"):
        mp_context("threads")


def test_laws_are_fitted_with_the_workers_this_machine_has():
    """A job's workers become the law fits' joblib processes, never more than the local cores (with
    Ray, workers may count a whole cluster's)."""
    import os

    from joblib.parallel import get_active_backend
    with fitting(1):
        assert get_active_backend()[1] == 1
    with fitting(10_000):
        assert get_active_backend()[1] == os.cpu_count()


def test_the_core_never_imports_ray():
    code = ("import sys, multiform.cli, multiform.job, multiform.evaluation, multiform.teach.record, "
            "multiform.parallel; print('ray' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


def test_without_ray_installed_a_ray_option_is_a_clear_error(monkeypatch, tmp_path, capsys):
    monkeypatch.delitem(sys.modules, "multiform.cluster", raising=False)
    monkeypatch.setitem(sys.modules, "ray", None)          # what `import ray` finds when it is not installed
    with pytest.raises(InvalidInput, match=r"pip install 'multiform\[ray\]'"):
        ray_backend()
    out = tmp_path / "d.h5"
    assert main(["record", "pendulum", "--demos", "1", "--out", str(out), "--ray", "local"]) == 2
    assert "--ray: Ray is not installed" in capsys.readouterr().err
    assert not out.exists()


@pytest.mark.parametrize("address, says", [("127.0.0.1:1", "cannot reach the Ray cluster at '127.0.0.1:1'"),
                                           ("nonsense", "'nonsense' is not auto, local, HOST:PORT")])
def test_a_ray_address_where_nothing_listens_is_refused_at_once(tmp_path, capsys, address, says):
    out = tmp_path / "d.h5"
    assert main(["record", "pendulum", "--demos", "1", "--out", str(out), "--ray", address]) == 2
    assert says in capsys.readouterr().err
    assert not out.exists()


def test_env_modules_the_caller_allowed_travel_to_spawned_workers(tmp_path, monkeypatch):
    """A model whose env id imports a module (``module:Env-v0``) runs on a spawned pool's workers
    with the modules its caller allowed (``--env-module``), trial for trial as in this process;
    without them every worker refuses it, as this process does."""
    from pathlib import Path

    from multiform.evaluation import Variant, evaluate
    from multiform.demos.dataset import write_dataset
    from multiform.teach.record import record_many
    from multiform.trainer import train_model
    from multiform.model import SkillModel
    from multiform.task import load_task

    example = Path(__file__).resolve().parent.parent / "examples" / "mountain_car"
    monkeypatch.syspath_prepend(str(example))                # spawned workers get this process's sys.path
    spec = "mountain_car:MountainCar"
    task = load_task(spec)
    eps = record_many(task, list(range(4)), task.DEMO_ENV_KWARGS)
    demos = write_dataset(tmp_path / "d.h5", eps, task.SKILL, task.ENV_ID, task.DEMO_ENV_KWARGS)
    model = SkillModel.create(tmp_path / "m", task.SKILL, demos, task.ENV_ID)
    train_model(model, seed=0, log=lambda *a: None)
    model.update_manifest(env=f"mountain_car:{task.ENV_ID}")  # the env id now imports the module
    with pytest.raises(InvalidInput, match="--env-module mountain_car"):
        SkillModel(model.path).verify()
    specs = task.evaluation_specs(4, 0, 0.0)
    allowed = Variant("car", str(model.path), env_modules=("mountain_car",))
    here = evaluate(spec, allowed, specs, workers=1)
    spawned = evaluate(spec, allowed, specs, workers=2, start_method="spawn")
    assert [r["trace_digest"] for r in here["trials_detail"]] == [r["trace_digest"] for r in spawned["trials_detail"]]
    assert spawned["trials"] == 4 and spawned["faults"] == 0
    assert len({r["trace_digest"] for r in here["trials_detail"]}) == 4          # four different trials
    with pytest.raises(InvalidInput, match="--env-module mountain_car"):
        evaluate(spec, Variant("car", str(model.path)), specs, workers=2, start_method="spawn")
    # the command line passes its --env-module on to the workers
    from multiform.cli import main
    assert main(["evaluate", str(model.path), "--task", spec, "--trials", "4", "--push-fraction", "0", "--workers", "2",
                 "--env-module", "mountain_car", "--out", str(tmp_path / "ev")]) == 0
    import json
    ev = json.loads((tmp_path / "ev" / "evaluation.json").read_text())
    assert [r["trace_digest"] for r in ev["trials_detail"]] == [r["trace_digest"] for r in here["trials_detail"]]
