"""The practice loop as a whole, fast, on the tutorial's mountain car (Gymnasium's
MountainCarContinuous-v0 with a scripted mentor and an over-strict switch condition): constant
failure leads to a repair that then succeeds, every trial is saved as it ends, and a loop stopped
midway resumes to exactly where an uninterrupted one ends."""

from __future__ import annotations

import json
import shutil
from dataclasses import replace
from pathlib import Path

import pytest

import multiform
from multiform.adapt.practice import Practice, state_from_json


def _practice(task, model_dir: Path, folder: Path, max_trials: int = 8) -> Practice:
    sc = task.scenarios()[0]
    return Practice(multiform.open_model(model_dir), folder, sc.practice_config(max_trials=max_trials, seed=1),
                    options=sc.options, name=sc.name)


def test_constant_failure_is_repaired_and_the_repair_then_succeeds(trained_car, tmp_path):
    task, model_dir = trained_car
    model = tmp_path / "model"
    shutil.copytree(model_dir, model)
    state = _practice(task, model, tmp_path / "p").run()
    outcomes = [t.success for t in state.trials]
    # the mentor's t1 never holds: three failures in a row, then the repair ...
    assert outcomes[:3] == [False] * 3
    repair = state.revisions[0]
    assert (repair.operator, repair.target, repair.after_trial) == ("set_condition", "t1", 2)
    # ... after which the robot succeeds on every trial, with the revised net
    after = state.trials[3:]
    assert after and all(t.success and t.net_version == repair.version for t in after)
    assert state.done and "successes in a row" in state.stop_reason
    # the failed trials are kept for the diagnosis, the state on disk is the state returned
    assert sorted(p.name for p in (tmp_path / "p" / "traces").iterdir()) == [f"trial_000{k}.npz" for k in range(3)]
    assert state_from_json(json.loads((tmp_path / "p" / "state.json").read_text()), "state.json") == state


def test_a_loop_stopped_midway_resumes_to_where_an_uninterrupted_one_ends(trained_car, tmp_path):
    task, model_dir = trained_car
    ends = []
    for stop in (None, 2, 4):
        model = tmp_path / f"model_{stop}"
        shutil.copytree(model_dir, model)
        folder = tmp_path / f"p_{stop}"
        if stop is not None:
            first = _practice(task, model, folder).run(stop_after=stop)
            assert len(first.trials) == stop and not first.done
        state = _practice(task, model, folder).run()
        history = (model / "skill.history.jsonl").read_text().splitlines()
        ends.append(([replace(t, wall=0.0, time="") for t in state.trials],
                     [(json.loads(r)["operator"], json.loads(r)["target"], json.loads(r)["version"]) for r in history]))
    assert ends[0] == ends[1] == ends[2]


def test_each_trial_starts_as_evaluation_draws_a_trial_of_its_seed(trained_car, tmp_path):
    """A practice trial's reset options come from its own seed (as an evaluation trial's do), so two
    job seeds practise from different starts, not from one sequence indexed by the trial number."""
    task, model_dir = trained_car
    asked: dict[int, list[int]] = {}
    for job_seed in (1, 2):
        model = tmp_path / f"model_{job_seed}"
        shutil.copytree(model_dir, model)
        sc = task.scenarios()[0]
        seeds = asked.setdefault(job_seed, [])
        practice = Practice(multiform.open_model(model), tmp_path / f"p_{job_seed}",
                            sc.practice_config(max_trials=8, seed=job_seed),
                            options=lambda s, seeds=seeds: seeds.append(s) or sc.options(s), name=sc.name)
        state = practice.run(stop_after=3)
        assert seeds == [t.seed for t in state.trials]
    assert set(asked[1]).isdisjoint(asked[2])
