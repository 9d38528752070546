"""The inverse model trained in a forked process beside the laws (``train_model(beside=True)``):
it waits for the laws before using them, its log and errors come back, and a failure on this side
does not leave it waiting."""

from __future__ import annotations

import time
from pathlib import Path
from types import SimpleNamespace

import pytest

import multiform.trainer as trainer


@pytest.fixture(autouse=True)
def _plain_model(monkeypatch):
    # the child opens the model directory itself; a namespace with its path stands in for it here
    monkeypatch.setattr(trainer, "SkillModel", lambda path: SimpleNamespace(path=Path(path)))


def _waits_for_laws(model, seed, log, laws_ready):
    log("babbled without laws")
    laws_ready()
    (model.path / "exercised").write_text("after the laws")
    log("exercised the laws")
    return {"seed": seed}


def _fails(model, seed, log, laws_ready):
    log("babbled without laws")
    raise ValueError("no pendulum mounted")


def test_trainer_waits_for_the_laws_and_its_log_comes_back(tmp_path):
    beside = trainer.Beside(_waits_for_laws, SimpleNamespace(path=tmp_path), seed=7)
    try:
        time.sleep(0.3)
        assert beside.process.is_alive() and not (tmp_path / "exercised").exists()
        beside.laws_ready()
        lines: list[str] = []
        assert beside.result(lines.append) == {"seed": 7}
        assert lines == ["babbled without laws", "exercised the laws"]
        assert (tmp_path / "exercised").exists()
    finally:
        beside.close()
    assert not beside.process.is_alive()


def test_a_failing_trainer_raises_here_with_its_reason(tmp_path):
    beside = trainer.Beside(_fails, SimpleNamespace(path=tmp_path), seed=0)
    lines: list[str] = []
    try:
        with pytest.raises(RuntimeError, match="no pendulum mounted"):
            beside.result(lines.append)
    finally:
        beside.close()
    assert lines == ["babbled without laws"]


def test_a_failure_here_ends_the_waiting_trainer(tmp_path):
    beside = trainer.Beside(_waits_for_laws, SimpleNamespace(path=tmp_path), seed=0)
    time.sleep(0.2)
    t0 = time.perf_counter()
    beside.close()                     # as train_model's finally does when a law fit raised
    assert time.perf_counter() - t0 < 2.0 and not beside.process.is_alive()
    assert not (tmp_path / "exercised").exists()
