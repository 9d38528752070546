"""The Task API: bundled tasks satisfy it, a user's task is found by entry point, module or file,
defaults fill what a task leaves out, and a bad spec is refused naming it."""

from __future__ import annotations

import sys
import textwrap

import pytest

from multiform.errors import InvalidInput
from multiform.task import Task, load_task, task_for_env

TASK_SOURCE = textwrap.dedent('''
    from multiform.task import Task

    class Mine(Task):
        TASK = "mine"
        SKILL = "pendulum"
        ENV_ID = "multiform/ArmPendulum-v0"

        def physical_success(self, trace):
            return trace.success

    instance = Mine()
''')


@pytest.mark.parametrize("name", ["pendulum", "nunchaku"])
def test_bundled_tasks_satisfy_the_protocol(name):
    task = load_task(name)
    assert isinstance(task, Task) and task.TASK == name and task.spec == name
    assert callable(task.physical_success) and task.scenarios()
    specs = task.evaluation_specs(4, 0, 0.5)
    assert len({s.seed for s in specs}) == 4
    assert task_for_env(task.ENV_ID).TASK == name


def test_evaluation_trials_are_drawn_as_documented():
    pendulum, nunchaku = load_task("pendulum"), load_task("nunchaku")
    specs = pendulum.evaluation_specs(6, 3, 0.5)
    assert [s.seed for s in specs] == [50_300_000 + i for i in range(6)]
    assert [s.push is not None for s in specs] == [True, False] * 3
    assert specs[2].push == pendulum.push(50_300_002)
    assert [s.seed for s in nunchaku.evaluation_specs(2, 3, 0.5)] == [70_300_000, 70_300_001]


def test_a_file_task_gets_the_defaults(tmp_path):
    (tmp_path / "mine.py").write_text(TASK_SOURCE)
    task = load_task(f"{tmp_path / 'mine.py'}:Mine")
    assert task.TASK == "mine" and task.demo_options(3) == {} and task.train_inverse_model is None
    specs = task.evaluation_specs(3, 1, 0.5)
    assert [s.seed for s in specs] == [50_100_000, 50_100_001, 50_100_002] and all(s.push is None for s in specs)
    repair, learn = task.scenarios()
    assert (repair.name, repair.learn, learn.name, learn.learn) == ("practice", False, "keep", True)
    cfg = learn.practice_config(max_trials=50, seed=1)
    assert cfg.learn and cfg.exam and cfg.check_demonstrations and cfg.max_trials == 50
    assert not repair.practice_config(30, 0).learn
    assert list(task.ablations(None, tmp_path, None)) == []
    with pytest.raises(InvalidInput, match="no inverse model"):
        task.robot_env_kwargs(True)
    with pytest.raises(InvalidInput, match="no scripted mentor"):
        task.make_mentor()
    assert not list(tmp_path.glob("__pycache__")), "reading a task file wrote bytecode beside it"


def test_a_module_task_and_an_installed_entry_point(tmp_path, monkeypatch):
    (tmp_path / "mytasks_pkg.py").write_text(TASK_SOURCE)
    dist = tmp_path / "mytasks-0.1.dist-info"
    dist.mkdir()
    (dist / "METADATA").write_text("Metadata-Version: 2.1\nName: mytasks\nVersion: 0.1\n")
    (dist / "entry_points.txt").write_text("[multiform.tasks]\nmine = mytasks_pkg:instance\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    try:
        assert load_task("mytasks_pkg:Mine").TASK == "mine"
        by_entry_point = load_task("mine")
        assert by_entry_point.TASK == "mine" and by_entry_point.spec == "mine"
    finally:
        sys.modules.pop("mytasks_pkg", None)


@pytest.mark.parametrize("spec, words", [
    ("juggling", "unknown task"), ("no_such_pkg_xyz:T", "no module"), ("json:nothing", "has no nothing"),
    ("json:dumps", "not a multiform.Task"), ("json", "unknown task"), ("/no/such/file.py:T", "no such file"), (":T", "package.module:NAME")])
def test_a_bad_spec_is_refused_naming_it(spec, words):
    with pytest.raises(InvalidInput, match=words) as info:
        load_task(spec)
    assert spec in str(info.value)


def test_a_scenario_on_a_changed_object_overrides_its_reset_options():
    sc = load_task("pendulum").scenarios()[2]
    changed = sc.with_options({"length": 0.24})
    assert changed.options(5) == {"randomize": True, "length": 0.24} and sc.options(5) == {"randomize": True}
    assert (changed.name, changed.learn, changed.push) == (sc.name, sc.learn, sc.push)


@pytest.mark.parametrize("text", ['{"length": 1e999}', '[0.24]', '{"length": '])
def test_options_for_a_changed_object_are_checked_as_plain_data(text):
    from multiform.cli import build_parser
    assert build_parser().parse_args(["practice", "m", "--options", '{"length": 0.24}']).options == {"length": 0.24}
    with pytest.raises(SystemExit) as info:
        build_parser().parse_args(["practice", "m", "--options", text])
    assert info.value.code == 2


def test_a_job_overrides_every_scenarios_practice_settings_and_refuses_what_it_may_not_change(tmp_path):
    from multiform.job import Job, JobConfig
    for sc in load_task("pendulum").scenarios():
        cfg = sc.with_config({"deliberate": True, "success_streak": 7}).practice_config(30, 1)
        assert (cfg.deliberate, cfg.success_streak, cfg.learn, cfg.max_trials) == (True, 7, sc.learn, 30)
    for bad, element in [({"bogus": 1}, "practice.bogus"), ({"seed": 3}, "practice.seed"),
                         ({"deliberate": 3}, "practice.deliberate")]:
        with pytest.raises(InvalidInput) as info:
            Job("pendulum", tmp_path / "run", JobConfig(practice=bad))
        assert info.value.problems[0].element == element
    assert not (tmp_path / "run").exists()
