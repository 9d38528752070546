"""With learning from practice, the job evaluates the skill as the repair scenarios left it beside
the final one (the report's "practice repairs the net only" row), at the net version just before
learning's first revision; without learning, or when learning revised nothing, no such row."""

from __future__ import annotations

import shutil

import pytest

import multiform
from multiform.job import Job, JobConfig
from multiform.petri.revision import set_lambda


@pytest.fixture()
def car(trained_car):
    task, _ = trained_car                   # the Task defaults: a repair scenario, then one that learns
    assert [s.learn for s in task.scenarios()] == [False, True]
    return trained_car


class Queue:
    """An evaluator that only notes what was submitted (and collects nothing)."""

    def __init__(self):
        self.submitted = []

    def submit(self, variant, specs, done=None):
        self.submitted.append((variant, len(specs)))
        return []

    def collect(self, variant, futures):
        return {"name": variant.name, "notes": variant.notes, "successes": 0, "trials": 0, "rate": 0.0,
                "low": 0.0, "high": 0.0}


def _revise(model, scenario: str) -> int:
    t = model.apn.transition_ids[0]
    _, rev = set_lambda(model.apn, t, 1.0, "test", {"scenario": scenario})
    return model.history.record(rev).version


@pytest.mark.parametrize("learn", [True, False])
def test_the_repair_only_skill_is_evaluated_beside_the_learned_one(car, tmp_path, learn):
    task, model_dir = car
    shutil.copytree(model_dir, tmp_path / "model")
    model = multiform.open_model(tmp_path / "model")
    job = Job(task, tmp_path / "run", JobConfig(learn=learn, ablation_trials=7), log=lambda *a: None, progress=False)
    repaired = _revise(model, "practice")
    ev = Queue()
    assert job.repair_only(model, ev) == []          # learning has revised nothing yet: the same skill
    main, _ = job.evaluate(model, Queue(), queued=[])
    assert ("learning from practice revised nothing" in main["notes"]) is learn     # and the table says so
    _revise(model, "keep")
    _revise(model, "keep")
    rows = job.repair_only(model, ev)
    if not learn:
        assert rows == [] and ev.submitted == []
        return
    (variant, _, bar), = rows
    bar.close()
    assert variant.net_version == repaired and variant.model_dir == str(model.path)
    assert "repairs the net only" in variant.name
    assert ev.submitted == [(variant, 7)]


@pytest.mark.parametrize("task, demos, learn", [("pendulum", 10, True), ("nunchaku", 10, True)])
def test_the_main_job_takes_its_size_and_learning_from_the_task(tmp_path, task, demos, learn):
    """`multiform demo pendulum` and `multiform demo nunchaku` learn from practice from 10
    demonstrations (the fewest from which every job seed measured reaches the target); a config
    that says otherwise wins."""
    job = Job(task, tmp_path / "run", JobConfig(), log=lambda *a: None, progress=False)
    assert (job.cfg.demos, job.cfg.learn) == (demos, learn)
    told = Job(task, tmp_path / "run", JobConfig(demos=3, learn=not learn), log=lambda *a: None, progress=False)
    assert (told.cfg.demos, told.cfg.learn) == (3, not learn)


@pytest.mark.parametrize("flags, learn", [([], True), (["--learn-from-practice"], True),
                                          (["--no-learn-from-practice"], False)])
def test_demo_learns_from_practice_as_the_task_says_unless_told(flags, learn):
    from multiform.cli import build_parser
    assert build_parser().parse_args(["demo", "pendulum", "-o", "run", *flags]).learn_from_practice is learn
