"""The job's practice draws: from the job's seed, or from a practice seed of their own, all else the
same (how much a result owes to the trials practice happened to draw)."""

from __future__ import annotations

import shutil

import pytest

import multiform
from multiform.adapt.practice import PracticeConfig
from multiform.io import read_json
from multiform.job import Job, JobConfig


def _practise(trained_car, folder, **config) -> dict[str, list[int]]:
    """The trial seeds each scenario drew, practising a copy of the model for two trials a scenario."""
    task, model_dir = trained_car
    shutil.copytree(model_dir, folder / "model")
    job = Job(task, folder / "run", JobConfig(seed=3, practice_max_trials=2, practice_budget=4, **config),
              log=lambda *a: None, progress=False)
    job.practise(multiform.open_model(folder / "model"))
    return {sc.name: [t["seed"] for t in read_json(folder / "run" / "practice" / sc.name / "state.json", "state")["trials"]]
            for sc in task.scenarios()}


def test_practice_draws_from_the_job_seed_unless_given_its_own(trained_car, tmp_path):
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    default = _practise(trained_car, tmp_path / "a")
    own = _practise(trained_car, tmp_path / "b", practice_seed=40)
    for i, name in enumerate(default):            # scenario i draws from the seed plus its place in the list
        assert default[name] == [PracticeConfig(seed=3 + i).trial_seed(k) for k in range(len(default[name]))]
        assert own[name] == [PracticeConfig(seed=40 + i).trial_seed(k) for k in range(len(own[name]))]
        assert default[name] and own[name]


def test_a_run_folder_practised_on_other_draws_is_refused(trained_car, tmp_path):
    """A finished practice is reused when a run folder is resumed; on another practice seed it would
    stand for draws it never saw, so the job refuses it and leaves it as it was."""
    from multiform.errors import InvalidInput
    (tmp_path / "a").mkdir()
    _practise(trained_car, tmp_path / "a")
    task, _ = trained_car
    state = tmp_path / "a" / "run" / "practice" / task.scenarios()[0].name / "state.json"
    before = state.read_bytes()
    job = Job(task, tmp_path / "a" / "run", JobConfig(seed=3, practice_max_trials=2, practice_budget=4, practice_seed=40),
              log=lambda *a: None, progress=False)
    with pytest.raises(InvalidInput, match="other draws") as err:
        job.practise(multiform.open_model(tmp_path / "a" / "model"))
    assert str(state) in str(err.value) and state.read_bytes() == before


def test_demo_takes_a_practice_seed():
    from multiform.cli import build_parser
    parse = build_parser().parse_args
    assert parse(["demo", "pendulum", "-o", "run"]).practice_seed is None
    assert parse(["demo", "pendulum", "-o", "run", "--practice-seed", "7"]).practice_seed == 7
    with pytest.raises(SystemExit):
        parse(["demo", "pendulum", "-o", "run", "--practice-seed", "-1"])
