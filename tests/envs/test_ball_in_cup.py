"""The ball-in-a-cup env: API, the string (slack and taut), the swing's energy, a caught ball, the
hand-guiding mode and the command recovered from a guided motion."""

from __future__ import annotations

import math
import warnings

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import multiform.envs  # noqa: F401  (registers the env ids)
from multiform.envs.ball_in_cup import BALL_RADIUS, OBSERVATION_NAMES, BallInCupEnv

IDX = {n: i for i, n in enumerate(OBSERVATION_NAMES)}
G = 9.81


@pytest.fixture(scope="module")
def env():
    e = BallInCupEnv()
    yield e
    e.close()


def col(rows, name):
    return np.asarray(rows)[:, IDX[name]]


def hold_still(env, n, **options):
    """Reset with ``options`` and command the hand to stay where it is for ``n`` steps."""
    obs, info = env.reset(seed=options.pop("seed", 0), options=options)
    rows, infos = [obs], [info]
    for _ in range(n):
        obs, _, term, _, info = env.step(np.zeros(2))
        assert not term, info
        rows.append(obs)
        infos.append(info)
    return np.array(rows), infos


def test_check_env_passes_in_every_action_mode():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        check_env(BallInCupEnv(render_mode="rgb_array", width=160, height=120))
        for mode in ("kinesthetic", "torque"):
            check_env(BallInCupEnv(action_mode=mode), skip_render_check=True)


def test_registered_and_names():
    env = gym.make("multiform/BallInCup-v0")
    base = env.unwrapped
    assert base.observation_names == OBSERVATION_NAMES
    assert base.command_names == ("vx", "vz") and base.dt == 0.001
    assert env.spec.max_episode_steps == 20_000
    obs, _ = env.reset(seed=1)
    assert obs.shape == (len(OBSERVATION_NAMES),)
    env.close()


def test_string_hangs_taut_and_holds_the_ball(env):
    rows, infos = hold_still(env, 500, length=0.35, phi0=0.0, omega0=0.0)
    assert abs(col(rows, "ball_z")[-1] + 0.35) < 2e-3          # hanging at the string's length
    assert max(abs(col(rows, "ball_x"))) < 1e-3
    assert max(i["scene"]["slack"] for i in infos) < 2e-3


def test_slack_string_lets_the_ball_fall_freely(env):
    """A ball let go 0.15 m inside the string's reach falls as in free flight until the string goes
    taut; then the string stops it."""
    rows, infos = hold_still(env, 400, length=0.35, ball=[0.0, -0.1], ball_v=[0.0, 0.0])
    z = col(rows, "ball_z")
    slack = np.array([i["scene"]["slack"] for i in infos])
    assert slack[0] > 0.2
    free = np.flatnonzero(slack > 0.01)
    t = free[-1] * env.dt
    assert abs(z[free[-1]] - (-0.1 - 0.5 * G * t * t)) < 5e-3    # free fall while slack
    assert slack[-1] < 2e-3 and abs(z[-1]) < 0.35 + 5e-3          # caught by the string, not beyond it


def test_swing_energy_is_conserved_and_period_plausible(env):
    """The hand held still, a ball let go 0.5 rad from hanging swings on: its energy never grows and
    loses less than 8 % of the swing's height in 2 s (the joints' and the string's small damping),
    at the pendulum's period 2 pi sqrt(L / g) with its first large-angle correction."""
    L = 0.35
    rows, _ = hold_still(env, 2000, length=L, mass=0.03, phi0=0.5, omega0=0.0)
    x, z, vx, vz = (col(rows, n) for n in ("ball_x", "ball_z", "ball_vx", "ball_vz"))
    energy = G * z + 0.5 * (vx ** 2 + vz ** 2)                    # per unit mass
    height = G * L * (1 - math.cos(0.5))                         # the swing's, per unit mass
    assert np.max(energy - energy[0]) < 0.01 * height
    assert 0.0 < energy[0] - energy[-1] < 0.08 * height
    crossings = np.flatnonzero(np.diff(np.sign(x)) != 0)
    period = 2 * np.mean(np.diff(crossings)) * env.dt
    expected = 2 * math.pi * math.sqrt(L / G) * (1 + 0.5 ** 2 / 16)   # with the first large-angle correction
    assert abs(period - expected) < 0.03 * expected


def test_a_caught_ball_stays_caught(env):
    """A ball set in the cup stays there while the hand holds still and then moves gently; the env
    reports it resting, and is_success after a second."""
    obs, info = env.reset(seed=0, options={"ball": [0.0, 0.06], "ball_v": [0.0, 0.0]})
    resting, success = [], []
    for k in range(2500):
        v = 0.0 if k < 1000 else 0.3 * math.sin(2 * math.pi * (k - 1000) * env.dt)    # a slow sway
        obs, _, term, _, info = env.step(np.array([v, 0.0]))
        assert not term
        resting.append(info["scene"]["in_cup"])
        success.append(info["is_success"])
    assert all(resting[200:])
    assert not success[900] and success[1300]
    assert abs(obs[IDX["ball_z"]] - (0.010 + 0.008 + BALL_RADIUS)) < 0.01    # on the cup's bottom


def test_reset_options_checked(env):
    with pytest.raises(ValueError, match="unknown reset option"):
        env.reset(options={"lenght": 0.3})
    with pytest.raises(ValueError, match="reach"):
        env.reset(options={"ball": [0.0, -1.0]})
    with pytest.raises(ValueError, match="wall"):
        env.reset(options={"ball": [0.056, 0.06]})
    with pytest.raises(ValueError, match="x0"):
        env.reset(options={"x0": 1.0})
    env.reset(seed=3, options={"randomize": True})
    assert 0.315 <= env.params["length"] <= 0.385 and 0.027 <= env.params["mass"] <= 0.033


def test_hand_guiding_mode_is_compliant():
    """Without a hand on it the arm in hand-guiding mode stays where it is (gravity compensated); a
    person's push of 20 N along x moves it along x only."""
    env = BallInCupEnv(action_mode="kinesthetic")
    obs, _ = env.reset(seed=0, options={"phi0": 0.0, "omega0": 0.0})
    for _ in range(300):
        obs, _, term, _, _ = env.step(np.zeros(2))
    assert abs(obs[IDX["hand_x"]]) < 2e-3 and abs(obs[IDX["hand_z"]]) < 2e-3
    for _ in range(100):
        obs, _, term, _, _ = env.step(np.array([20.0, 0.0]))
    assert obs[IDX["hand_vx"]] > 0.2 and abs(obs[IDX["hand_vz"]]) < 0.05
    assert abs(obs[IDX["ee_y"]] + 0.55) < 2e-3
    env.close()


def test_recovered_command_reproduces_a_guided_motion():
    """The hand motion of a person guiding the arm, replayed as velocity commands recovered from the
    motion alone, is reproduced by the arm's own servo to within a few millimetres."""
    from multiform.teach.kinesthetic import GuidingHand

    class Sway:
        name = "sway"

        def reset(self, obs, rng):
            pass

        def act(self, obs, info, t):
            return np.array([0.6 * math.sin(2 * math.pi * 1.2 * t), 0.2 * math.sin(2 * math.pi * 0.7 * t)]), "t0"

    guided = BallInCupEnv(action_mode="kinesthetic")
    hand = GuidingHand(Sway(), [IDX["hand_vx"], IDX["hand_vz"]])
    obs, _ = guided.reset(seed=4, options={"phi0": 0.0, "omega0": 0.0})
    hand.reset(obs, np.random.default_rng(0))
    rows = [obs]
    for k in range(1500):
        force, _ = hand.act(obs, {}, k * guided.dt)
        obs, *_ = guided.step(force)
        rows.append(obs)
    rows = np.array(rows)
    cmd = guided.command_from_motion(rows[:-1])
    servo = BallInCupEnv()
    obs, _ = servo.reset(seed=4, options={"phi0": 0.0, "omega0": 0.0})
    replay = [obs]
    for c in cmd:
        obs, *_ = servo.step(c)
        replay.append(obs)
    replay = np.array(replay)
    for n in ("hand_x", "hand_z"):
        assert np.ptp(col(rows, n)) > 0.05                        # it moved
        assert np.max(np.abs(col(replay, n) - col(rows, n))) < 5e-3, n
