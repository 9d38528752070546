"""A model directory cannot lie: every artifact is listed with its SHA-256 and checked before a trial
runs; the net's versions run the fits they name; a shared directory never imports code."""

from __future__ import annotations

import json

import numpy as np
import pytest

from multiform.errors import InvalidInput
from multiform.learn.gp import GPLaw
from multiform.model import SkillModel, needs_inverse_model
from multiform.petri.revision import refit_law


def _law(shift: float = 0.0) -> GPLaw:
    X = np.random.default_rng(0).standard_normal((40, 4))
    return GPLaw(n_hyper=40, n_restarts=0, random_state=0).fit(X, X[:, :1] + shift)


@pytest.fixture
def model(tmp_path) -> SkillModel:
    m = SkillModel.create(tmp_path / "model", "pendulum")
    m.save_law("swing_up", _law())
    m.save_law("balance", _law(1.0))
    return m


def _problems(model: SkillModel, to_run: bool = True) -> list[str]:
    return [f"{p.file}|{p.element}|{p.message}" for p in SkillModel(model.path).problems(to_run)]


def test_a_trained_model_lists_each_artifact_with_its_hash_and_verifies(model):
    listed = model.manifest["artifacts"]
    assert set(listed) == {"skill.yaml", "laws/swing_up.npz", "laws/balance.npz"}
    assert listed["laws/balance.npz"]["kind"] == "law" and len(listed["laws/balance.npz"]["sha256"]) == 64
    model.verify()
    assert _problems(model) == []


def test_a_changed_an_unlisted_or_a_missing_artifact_is_named(model):
    law = model.path / "laws" / "balance.npz"
    law.write_bytes(law.read_bytes() + b"\0")
    (model.path / "judges").mkdir()
    np.savez(model.path / "judges" / "P9.npz", a=np.zeros(1))
    found = _problems(model)
    assert any(str(law) in p and "changed since multiform wrote it" in p for p in found)
    assert any("P9.npz" in p and "not listed" in p for p in found)
    law.unlink()
    assert any(str(law) in p and "missing" in p for p in _problems(model))
    with pytest.raises(InvalidInput):
        SkillModel(model.path).verify()


def test_the_net_needs_a_fit_for_every_law_it_runs(tmp_path):
    m = SkillModel.create(tmp_path / "m", "pendulum")
    m.save_law("swing_up", _law())
    (p,) = _problems(m)
    assert "laws/balance.npz" in p and "laws.balance" in p and "train first" in p
    assert _problems(m, to_run=False) == []          # the directory itself is sound


def test_each_net_version_runs_the_fit_it_names(model):
    model.save_law("swing_up_r1", _law(5.0))
    _, rev = refit_law(model.apn, "swing_up", "swing_up_r1", "own data")
    model.history.record(rev)
    x = np.zeros(4)
    v0, v1 = model.history.version(0), model.history.version(1)
    assert model.laws(v1)["swing_up"].predict_one(x)[0] == pytest.approx(model.laws(v0)["swing_up"].predict_one(x)[0] + 5.0,
                                                                          abs=0.5)
    assert model.laws()["balance"] is not None and model.version == 1


def test_a_model_directory_never_imports_the_module_its_env_names(model):
    manifest = json.loads((model.path / "model.json").read_text())
    manifest["env"] = "os:Evil-v0"
    (model.path / "model.json").write_text(json.dumps(manifest))
    assert any("would import the module 'os'" in p for p in _problems(model))
    allowed = SkillModel(model.path, env_modules=("os",))
    assert not any("would import" in p.message for p in allowed.problems())


def test_a_torque_driven_env_needs_the_inverse_model(model):
    assert needs_inverse_model({"env_kwargs": {"action_mode": "torque"}})
    assert not needs_inverse_model({"env_kwargs": {"action_mode": "ee"}}) and not needs_inverse_model({})
    manifest = json.loads((model.path / "model.json").read_text())
    manifest["env_kwargs"] = {"action_mode": "torque"}
    (model.path / "model.json").write_text(json.dumps(manifest))
    assert any("inverse_model.npz" in p and "joint torques" in p for p in _problems(model))


def test_a_skill_file_for_another_env_than_the_demonstrations_is_refused(tmp_path):
    with pytest.raises(InvalidInput, match="the model runs the demonstrations' env"):
        SkillModel.create(tmp_path / "m", "pendulum", env_id="multiform/Nunchaku-v0")
    assert not (tmp_path / "m").exists()
