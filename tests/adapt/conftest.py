"""Fixtures shared by the practice tests."""

from __future__ import annotations

import shutil

import pytest

from multiform.adapt.learners import ModelLearners
from multiform.model import SkillModel
from multiform.petri.revision import set_condition


@pytest.fixture()
def relearned_model(hostile_lab, tmp_path) -> SkillModel:
    """The four-demonstration pendulum model, its t1 relearned from the mentor's switches (as the
    repair does), with the setting cross-validation picks."""
    shutil.copytree(hostile_lab / "model", tmp_path / "model")
    model = SkillModel(tmp_path / "model")
    name, evidence = ModelLearners(model, seed=0).switch_condition(model.apn, "t1")
    _, rev = set_condition(model.apn, "t1", {"model": name}, "relearned", evidence)
    model.history.record(rev)
    return model
