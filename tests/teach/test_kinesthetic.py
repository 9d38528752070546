"""Kinesthetic teaching: the mentor guides the compliant arm by hand; the recording keeps only what
the robot sensed, and the commands are recovered from the arm's own motion."""

from __future__ import annotations

import h5py
import numpy as np
import pytest

import multiform.envs  # noqa: F401  (registers the env ids)
from multiform import api
from multiform.demos.dataset import read_dataset
from multiform.errors import InvalidInput
from multiform.teach.kinesthetic import GuidingHand, guided
from multiform.teach.record import record_episode


class Spy(GuidingHand):
    """A guiding hand that remembers every force it applied (what must never reach the data)."""

    def act(self, obs, info, t):
        force, tag = super().act(obs, info, t)
        self.forces.append(np.array(force))
        return force, tag

    def reset(self, obs, rng, seed=None):
        self.forces = []
        super().reset(obs, rng, seed=seed)


@pytest.mark.parametrize("task", ["ball_in_cup", "pendulum"])
def test_recording_holds_no_mentor_force(task, tmp_path):
    """The episode's commands are what the env recovers from the recorded observations alone; they
    are velocities (within the servo's range), never the forces the hand applied, and the file holds
    no force anywhere."""
    import gymnasium as gym

    from multiform.task import load_task
    t = load_task(task)
    env = gym.make(t.ENV_ID, action_mode="kinesthetic")
    base = env.unwrapped
    hand = Spy(t.make_mentor(), [base.observation_names.index(n) for n in base.guided_velocity_names])
    ep = record_episode(env, hand, seed=3, options=t.demo_options(3), max_steps=3000)
    forces = np.array(hand.forces)
    assert len(forces) == ep.num_samples and np.max(np.abs(forces)) > 5.0      # the person did push
    np.testing.assert_allclose(ep.actions, base.command_from_motion(ep.obs))
    assert np.max(np.abs(ep.actions)) < 4.0                                      # m/s, not N
    for j in range(forces.shape[1]):
        assert not np.allclose(ep.actions[:, j], forces[:, j], atol=1.0)
    path = tmp_path / "d.h5"
    from multiform.demos.dataset import write_dataset
    write_dataset(path, [ep], t.SKILL, t.ENV_ID, t.DEMO_ENV_KWARGS, teaching="kinesthetic")
    stored = []
    with h5py.File(path, "r") as f:
        f.visititems(lambda name, obj: stored.append(obj[()]) if isinstance(obj, h5py.Dataset) and obj.dtype.kind == "f"
                     else None)
        assert f["data"].attrs["teaching"] == "kinesthetic"
    for arr in stored:
        arr = np.asarray(arr, dtype=np.float64).reshape(len(arr), -1) if np.ndim(arr) else None
        if arr is None or len(arr) != len(forces):
            continue
        for j in range(forces.shape[1]):
            for k in range(arr.shape[1]):
                assert not np.allclose(arr[:, k], forces[:, j], atol=0.5)
    env.close()


def test_record_kinesthetic_pendulum_through_the_api(tmp_path):
    """``record(..., kinesthetic=True)`` (``multiform record pendulum --kinesthetic``) marks the file
    and its demos succeed as often as the joystick ones do here."""
    out = api.record("pendulum", tmp_path / "k.h5", demos=3, workers=1, kinesthetic=True)
    ds = read_dataset(out)
    assert ds.meta["teaching"] == "kinesthetic" and ds.summary()["teaching"] == "kinesthetic"
    assert ds.episodes[0].command_names == ("v_cmd",)
    assert sum(e.outcome == "success" for e in ds.episodes) >= 2
    joystick = read_dataset(api.record("pendulum", tmp_path / "j.h5", demos=1, workers=1))
    assert joystick.meta["teaching"] == ""


def test_an_env_without_a_hand_guiding_mode_is_refused_before_anything_is_written(tmp_path):
    with pytest.raises(InvalidInput, match="hand-guiding"):
        api.record("nunchaku", tmp_path / "n.h5", demos=1, workers=1, kinesthetic=True)
    assert not (tmp_path / "n.h5").exists()


def test_guided_wraps_only_on_a_guided_arm():
    import gymnasium as gym

    from multiform.task import load_task
    mentor = load_task("pendulum").make_mentor()
    assert guided(mentor, gym.make("multiform/ArmPendulum-v0")) is mentor
    hand = guided(mentor, gym.make("multiform/ArmPendulum-v0", action_mode="kinesthetic"))
    assert isinstance(hand, GuidingHand) and hand.mentor is mentor and hand.name == mentor.name
    assert guided(hand, gym.make("multiform/ArmPendulum-v0", action_mode="kinesthetic")) is hand


def test_replay_refuses_a_guided_demonstration_saying_why(tmp_path):
    from multiform.view.replay import replay_demo
    out = api.record("pendulum", tmp_path / "k.h5", demos=1, workers=1, kinesthetic=True)
    with pytest.raises(InvalidInput, match="guided the arm"):
        replay_demo(out)
