"""`multiform teleop pendulum` run headless (SDL dummy driver) with scripted key events."""

from __future__ import annotations

import os

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
os.environ.setdefault("SDL_AUDIODRIVER", "dummy")

import numpy as np  # noqa: E402
import pygame  # noqa: E402
import pytest  # noqa: E402

from multiform import cli  # noqa: E402
from multiform.demos.dataset import read_dataset, write_dataset  # noqa: E402
from multiform.task import load_task  # noqa: E402
task = load_task("pendulum")


def key(k: int, down: bool = True) -> None:
    pygame.event.post(pygame.event.Event(pygame.KEYDOWN if down else pygame.KEYUP, key=k, mod=0, unicode="",
                                         scancode=0))


def person(demo: dict[int, list[tuple[int, bool]]], answers: list[int]):
    """A teleop script: key events per demo frame, then one answer per labelling step."""
    def script(stage: str, i: int) -> None:
        if stage == "demo":
            for k, down in demo.get(i, []):
                key(k, down)
        elif i < len(answers):
            key(answers[i])
    return script


SWING = {0: [(pygame.K_RIGHT, True)], 6: [(pygame.K_RIGHT, False), (pygame.K_1, True)],
         12: [(pygame.K_ESCAPE, True)]}
ARGS = ["--keyboard", "--time-scale", "100", "--max-duration", "5"]


def teleop(monkeypatch, out, script, *extra: str) -> int:
    monkeypatch.setattr(cli, "_TELEOP_SCRIPT", script)
    return cli.main(["teleop", "pendulum", "--out", str(out), *ARGS, *extra])


def test_records_labels_and_appends(tmp_path, monkeypatch, capsys):
    out = tmp_path / "demos.h5"
    assert teleop(monkeypatch, out, person(SWING, [pygame.K_s, pygame.K_f]), "--labeller", "zoe") == 0
    assert "wrote" in capsys.readouterr().out
    ds = read_dataset(out)
    assert len(ds) == 1 and ds.env_name == task.ENV_ID and ds.skill == task.SKILL
    assert ds.env_kwargs == task.DEMO_ENV_KWARGS
    first = ds.episodes[0]
    assert first.seed == 0 and first.reset_options == task.demo_options(0)
    assert [t for _, _, t in first.segments()] == ["t0", "t1"]
    assert [(lab.transition, lab.success, lab.labeller) for lab in first.labels] == [("t0", True, "zoe"),
                                                                                     ("t1", False, "zoe")]
    assert first.outcome == "failure"
    assert first.actions[: first.segments()[0][1], 0].max() > 0.5          # the right arrow drove the hand
    assert first.column("x")[first.segments()[0][1]] > 0.02

    # refused without --append; the file stays as it was
    before = out.read_bytes()
    assert teleop(monkeypatch, out, person(SWING, [pygame.K_s, pygame.K_s])) == 2
    assert "--append" in capsys.readouterr().err
    assert out.read_bytes() == before

    again = {0: [(pygame.K_LEFT, True)], 8: [(pygame.K_q, True)]}
    assert teleop(monkeypatch, out, person(again, [pygame.K_s]), "--append", "--labeller", "zoe") == 0
    ds = read_dataset(out)
    assert len(ds) == 2
    old, new = ds.episodes
    assert np.array_equal(old.obs, first.obs) and old.labels == first.labels     # the earlier demo kept
    assert new.seed == 1 and new.outcome == "success" and new.actions[:, 0].min() < -0.5
    assert [t for _, _, t in new.segments()] == ["t0"]


def test_closed_window_and_bad_options_write_nothing(tmp_path, monkeypatch, capsys):
    out = tmp_path / "demos.h5"

    def close(stage: str, i: int) -> None:
        if i == 3:
            pygame.event.post(pygame.event.Event(pygame.QUIT))

    assert teleop(monkeypatch, out, close) == 1
    assert "nothing written" in capsys.readouterr().err and not out.exists()
    monkeypatch.setattr(cli, "_TELEOP_SCRIPT", None)
    assert cli.main(["teleop", "pendulum", "--out", str(out), "--time-scale", "0"]) == 2
    assert "--time-scale" in capsys.readouterr().err and not out.exists()


@pytest.mark.parametrize("env_kwargs", [{"action_mode": "torque"}])
def test_refuses_to_append_to_a_file_of_another_kind(tmp_path, monkeypatch, capsys, env_kwargs):
    out = tmp_path / "demos.h5"
    assert teleop(monkeypatch, out, person({1: [(pygame.K_ESCAPE, True)]}, [pygame.K_s])) == 0
    ep = read_dataset(out).episodes[0]
    write_dataset(out, [ep], task.SKILL, task.ENV_ID, env_kwargs)
    before = out.read_bytes()
    assert teleop(monkeypatch, out, person(SWING, [pygame.K_s, pygame.K_s]), "--append") == 2
    err = capsys.readouterr().err
    assert str(out) in err and "end-effector" in err
    assert out.read_bytes() == before
