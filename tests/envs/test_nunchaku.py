"""The nunchaku env: API, magnet, estimation from load, stability at 1 ms."""

import math

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import multiform.envs  # noqa: F401  (registers the ids)
from multiform.envs.load_estimator import LoadEstimator
from multiform.envs.nunchaku import COMMAND_NAMES, OBSERVATION_NAMES, NunchakuEnv

HOLD = np.array([0.0, 0.0, 0.0, 1.0])


def obs_of(obs, name):
    return obs[OBSERVATION_NAMES.index(name)]


def test_registered_and_passes_check_env():
    env = gym.make("multiform/Nunchaku-v0")
    base = env.unwrapped
    assert isinstance(base, NunchakuEnv)
    assert base.dt == pytest.approx(0.001)
    assert len(base.observation_names) == base.observation_space.shape[0]
    assert len(base.command_names) == base.action_space.shape[0] == len(COMMAND_NAMES)
    with pytest.warns(UserWarning):      # gymnasium's advice on unbounded/asymmetric boxes
        check_env(base)
    env.close()


def test_seeded_reset_is_reproducible_and_options_fix_values():
    env = NunchakuEnv()
    o1, i1 = env.reset(seed=3)
    p1 = dict(env.params)
    o2, i2 = env.reset(seed=3)
    assert np.array_equal(o1, o2) and p1 == env.params
    env.reset(seed=4)
    assert env.params != p1
    env.reset(seed=4, options={"rod_mass": 1.1, "rod_length": 0.95, "hand_q": 0.05})
    assert env.params["rod_mass"] == 1.1 and env.params["rod_length"] == 0.95
    rod_b = env.model.body("rod_b").id
    assert env.model.body_mass[rod_b] == pytest.approx(0.22)
    env.reset(seed=4, options={"randomize": False})
    assert env.params["rod_mass"] == 1.0 and env.params["swing"] == 0.0
    assert env.model.body_mass[rod_b] == pytest.approx(0.2)
    with pytest.raises(ValueError, match="unknown reset option"):
        env.reset(options={"rod_colour": 1})


def test_holds_the_rod_and_weighs_the_nunchaku():
    env = NunchakuEnv()
    obs, info = env.reset(seed=0, options={"rod_mass": 1.1})
    assert obs_of(obs, "grip") == 1.0 and info["scene"]["held"] == "a"
    assert env.estimator.m_rod == pytest.approx(0.22, rel=0.03)
    x0, z0 = obs_of(obs, "hand_x"), obs_of(obs, "hand_z")
    for _ in range(1000):
        obs, r, term, trunc, info = env.step(HOLD)
    assert not term and obs_of(obs, "grip") == 1.0
    assert abs(obs_of(obs, "hand_x") - x0) < 0.005 and abs(obs_of(obs, "hand_z") - z0) < 0.005
    # the pull of a hanging nunchaku is the weight of its free part
    assert obs_of(obs, "load") == pytest.approx((0.03 + 0.22 + 0.03) * 9.81, rel=0.1)
    assert abs(math.remainder(obs_of(obs, "phi") - info["truth"]["phi"], 2 * math.pi)) < 0.05


def test_hand_tracks_velocity_commands():
    env = NunchakuEnv()
    env.reset(seed=1)
    for _ in range(300):
        obs, *_ = env.step(np.array([0.5, -0.2, 2.0, 1.0]))
    assert obs_of(obs, "hand_vx") == pytest.approx(0.5, abs=0.05)
    assert obs_of(obs, "hand_vz") == pytest.approx(-0.2, abs=0.05)
    assert obs_of(obs, "hand_wq") == pytest.approx(2.0, abs=0.2)


def test_magnet_releases_and_captures_only_within_reach():
    env = NunchakuEnv()
    env.reset(seed=2)
    obs, r, term, trunc, info = env.step(np.array([0.0, 0.0, 0.0, 0.0]))
    assert obs_of(obs, "grip") == 0.0 and info["scene"]["held"] == ""
    # switching the magnet on again at once catches rod A, still on the palm
    obs, r, term, trunc, info = env.step(HOLD)
    obs, r, term, trunc, info = env.step(HOLD)
    assert info["scene"]["held"] == "a"
    # let go and jerk the hand up and away, then arm the magnet: nothing within reach, nothing caught
    for k in range(3000):
        obs, r, term, trunc, info = env.step(np.array([0.0, 2.0 if k < 100 else 0.0, 0.0, float(k >= 100)]))
        if term:
            break
    assert term and info["dropped"] and not info["diverged"]
    assert obs_of(obs, "grip") == 0.0


def test_non_finite_state_terminates_without_exception():
    env = NunchakuEnv()
    env.reset(seed=0)
    env.data.qvel[10] = np.nan
    obs, r, term, trunc, info = env.step(HOLD)
    assert term and info["diverged"]
    assert np.all(np.isfinite(obs))


def test_truncates_after_max_duration():
    env = NunchakuEnv(max_duration=0.05)
    env.reset(seed=0)
    for k in range(50):
        obs, r, term, trunc, info = env.step(HOLD)
    assert trunc and not term


def test_renders_rgb_frames():
    env = NunchakuEnv(render_mode="rgb_array", width=160, height=120)
    env.reset(seed=0)
    frame = env.render()
    assert frame.shape == (120, 160, 3) and frame.dtype == np.uint8 and frame.std() > 5
    env.close()


def test_estimator_at_rest_reads_the_weight():
    est = LoadEstimator()
    est.reset(angle=0.0)
    # a hanging free part at rest: the wrist carries hand + held rod + free part
    total = (0.35 + 0.2 + 0.26) * 9.81
    for _ in range(200):
        phi, omega = est.update((0.0, total), 0.0, 0.0, 0.0, 0.0, 0.0, 0.001)
    assert abs(phi) < 1e-3 and abs(omega) < 1e-2
    assert est.pull[1] == pytest.approx(-0.26 * 9.81, rel=1e-6)


def _swing_errors(seeds):
    """Angle errors of the estimate while the scripted mentor swings the nunchaku (before release)."""
    from multiform.tasks.nunchaku_mentor import NunchakuMentor
    env = NunchakuEnv()
    mentor = NunchakuMentor(failure_rate=0.0)
    errors = []
    for seed in seeds:
        obs, info = env.reset(seed=seed)
        mentor.reset(obs, np.random.default_rng([seed, 1]))
        t = 0.0
        while True:
            cmd, tag = mentor.act(obs, info, t)
            obs, r, term, trunc, info = env.step(cmd)
            t += env.dt
            if tag not in ("t0", "t1") or term or mentor.finished():
                break
            if t > 0.3:
                errors.append(math.remainder(obs_of(obs, "phi") - info["truth"]["phi"], 2 * math.pi))
    return np.array(errors)


def test_free_rod_angle_from_load_is_accurate_during_the_swing():
    err = _swing_errors([100, 101, 102, 103])
    rms = float(np.sqrt(np.mean(err ** 2)))
    print(f"free-rod angle RMS error during the swing: {rms:.3f} rad over {len(err)} samples")
    assert len(err) > 1000
    assert rms <= 0.1


def _random_trials(n, duration=1.5, seed0=0):
    """Randomised nunchakus, alternately under random hand/wrist motion with magnet switching and
    under the scripted flip with doubled noise and frequent fumbles; counts divergences."""
    from multiform.tasks.nunchaku_mentor import NunchakuMentor
    env = NunchakuEnv(settle=0.0)
    mentor = NunchakuMentor(failure_rate=0.5, noise=2.0)
    diverged = 0
    for k in range(n):
        seed = seed0 + k
        rng = np.random.default_rng(seed)
        obs, info = env.reset(seed=seed)
        if k % 2:
            mentor.reset(obs, rng)
            t = 0.0
            while not mentor.finished() and t < 8.0:
                cmd, _ = mentor.act(obs, info, t)
                obs, r, term, trunc, info = env.step(cmd)
                t += env.dt
                if term:
                    diverged += bool(info["diverged"])
                    break
            continue
        amp = rng.uniform(0, 1, 3) * np.array([3.0, 3.0, 20.0])
        freq = rng.uniform(0.5, 4.0, 3)
        phase = rng.uniform(0, 2 * np.pi, 3)
        toggles = np.sort(rng.uniform(0, duration, 4))
        for i in range(int(duration / env.dt)):
            t = i * env.dt
            v = amp * np.sin(2 * np.pi * freq * t + phase)
            magnet = float(np.searchsorted(toggles, t) % 2 == 0)
            obs, r, term, trunc, info = env.step(np.array([v[0], v[1], v[2], magnet]))
            if term:
                diverged += bool(info["diverged"])
                break
            if not np.all(np.isfinite(obs)):
                diverged += 1
                break
    return diverged


def test_stable_over_randomised_trials_fast():
    assert _random_trials(8) == 0


@pytest.mark.slow
def test_stable_over_1000_randomised_trials():
    assert _random_trials(1000, seed0=10_000) == 0


@pytest.mark.parametrize("options", [{"rod_mass": float("nan")}, {"rod_length": -1.0}, {"swing": float("inf")},
                                     {"ft_noise": float("nan")}])
def test_non_finite_or_absurd_reset_options_are_refused(options):
    import gymnasium as gym

    env = gym.make("multiform/Nunchaku-v0")
    with pytest.raises(ValueError):
        env.reset(seed=0, options=options)
    env.close()


def test_named_accessors_read_the_entries_they_name():
    env = NunchakuEnv()
    env.reset(seed=0)
    obs, *_ = env.step(HOLD)
    q = obs_of(obs, "hand_q")
    assert env.wrist_vertical_load() == pytest.approx(obs_of(obs, "ft_fz") * math.cos(q) + obs_of(obs, "ft_fx") * math.sin(q))
    assert env.back_of_hand_touch() == obs_of(obs, "touch")
    # held still, the wrist carries the weight of the whole nunchaku and nothing touches the back of the hand
    assert abs(env.wrist_vertical_load()) > 0.4 * 9.81 and env.back_of_hand_touch() == 0.0
