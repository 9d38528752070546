"""The arm-pendulum env: API, physics of the pendulum, reference controller, termination, rendering."""

from __future__ import annotations

import math
import warnings

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import multiform.envs  # noqa: F401  (registers the env ids)
from multiform.envs.arm_pendulum import ArmPendulumEnv, equivalent_length, pendulum_inertia
from multiform.envs.osc import (OBSERVATION_NAMES, TORQUE_LIMITS, ReferenceController, limited_velocity,
                                task_acceleration)

IDX = {n: i for i, n in enumerate(OBSERVATION_NAMES)}


@pytest.fixture(scope="module")
def env():
    e = ArmPendulumEnv()
    yield e
    e.close()


def run(env, v, n, **reset):
    obs, _ = env.reset(seed=reset.pop("seed", 0), options=reset or None)
    rows = [obs]
    for _ in range(n):
        obs, _, term, _, info = env.step(np.array([v(len(rows) * env.dt) if callable(v) else v]))
        rows.append(obs)
        assert not term, info
    return np.array(rows)


def test_check_env_passes_in_both_action_modes():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        check_env(ArmPendulumEnv(render_mode="rgb_array"))
        check_env(ArmPendulumEnv(action_mode="torque"), skip_render_check=True)


def test_registered_and_names():
    env = gym.make("multiform/ArmPendulum-v0")
    base = env.unwrapped
    assert base.observation_names[:4] == ("theta", "omega", "x", "xdot")
    assert base.observation_names == OBSERVATION_NAMES and len(OBSERVATION_NAMES) == 28
    assert base.command_names == ("v_cmd",)
    assert base.dt == 0.001
    obs, _ = env.reset(seed=1)
    assert obs.shape == (28,) and obs.dtype == np.float64
    assert env.spec.max_episode_steps == 60_000             # 60 s, the skills' default max_duration
    env.close()


def test_home_posture_and_default_start(env):
    obs, _ = env.reset(seed=3)
    assert abs(abs(obs[IDX["theta"]]) - math.pi) < 0.1            # hanging, wrapped near ±pi
    assert abs(obs[IDX["omega"]]) <= 0.1
    np.testing.assert_allclose(obs[IDX["ee_x"]:IDX["ee_z"] + 1], env.workspace_centre, atol=1e-8)
    np.testing.assert_allclose(obs[IDX["ee_rx"]:IDX["ee_rz"] + 1], 0.0, atol=1e-8)
    assert obs[IDX["x"]] == pytest.approx(0.0, abs=1e-8)


@pytest.mark.parametrize("x0", [-0.33, 0.2, 0.35])
def test_hand_starts_off_centre_at_rest_and_stays_under_the_servo(env, x0):
    obs, _ = env.reset(seed=3, options={"x0": x0, "theta0": 0.4})
    assert obs[IDX["x"]] == pytest.approx(x0, abs=1e-6)
    np.testing.assert_allclose(obs[IDX["ee_y"]:IDX["ee_z"] + 1], env.workspace_centre[1:], atol=1e-6)
    np.testing.assert_allclose(obs[IDX["ee_rx"]:IDX["ee_rz"] + 1], 0.0, atol=1e-6)   # home orientation
    np.testing.assert_allclose(obs[IDX["qd1"]:IDX["qd6"] + 1], 0.0)                   # at rest
    assert obs[IDX["theta"]] == pytest.approx(0.4, abs=1e-9)
    for _ in range(300):
        obs, *_ = env.step(np.array([0.0]))
    assert obs[IDX["x"]] == pytest.approx(x0, abs=2e-3)
    for bad in (0.5, float("nan")):
        with pytest.raises(ValueError, match="x0"):
            env.reset(seed=0, options={"x0": bad})


def test_theta_convention_tip_towards_plus_x(env):
    for th in (0.3, -0.7, 2.0):
        obs, _ = env.reset(seed=0, options={"theta0": th, "omega0": 0.0})
        assert obs[0] == pytest.approx(th, abs=1e-9)
        d, m = env.data, env.model
        hinge = d.xpos[m.body("pendulum").id]
        tip = d.geom_xpos[m.geom("tip").id]
        L = env.params["length"]
        assert tip[0] - hinge[0] == pytest.approx(L * math.sin(th), abs=1e-9)
        assert tip[2] - hinge[2] == pytest.approx(L * math.cos(th), abs=1e-9)
    obs, _ = env.reset(seed=0, options={"theta0": math.pi})
    assert obs[0] == pytest.approx(math.pi)                       # wrapped to (-pi, pi]


def test_reset_options_set_pendulum_and_validate(env):
    env.reset(seed=0, options={"length": 0.5, "mass": 0.2, "damping": 1e-3})
    m, b = env.model, env.model.body("pendulum").id
    lc, it, ia = pendulum_inertia(0.5, 0.2)
    assert m.body_mass[b] == pytest.approx(0.2)
    assert m.body_ipos[b, 2] == pytest.approx(lc)
    np.testing.assert_allclose(m.body_inertia[b], [it, it, ia])
    assert m.dof_damping[m.joint("pendulum").dofadr[0]] == pytest.approx(1e-3)
    assert m.geom_pos[m.geom("tip").id, 2] == pytest.approx(0.5)
    # randomize: ±20 % on what was not given, reproducible from the seed
    seen = set()
    for s in range(8):
        env.reset(seed=s, options={"randomize": True})
        p = env.params
        assert 0.32 <= p["length"] <= 0.48 and 0.08 <= p["mass"] <= 0.12
        seen.add(round(p["length"], 6))
    assert len(seen) == 8
    env.reset(seed=5, options={"randomize": True})
    a = dict(env.params)
    env.reset(seed=5, options={"randomize": True})
    assert env.params == a
    with pytest.raises(ValueError, match="unknown reset option"):
        env.reset(seed=0, options={"lenght": 0.4})
    with pytest.raises(ValueError, match="disturbances"):
        env.reset(seed=0, options={"disturbances": [{"time": 1.0}]})
    env.reset(seed=0)
    assert env.params == {"length": 0.4, "mass": 0.1, "damping": 2e-4}


@pytest.mark.parametrize("length", [0.32, 0.4, 0.48])
def test_small_swing_period_matches_pendulum_theory(env, length):
    rows = run(env, 0.0, 5000, theta0=math.pi - 0.05, omega0=0.0, length=length)
    phi = np.unwrap(rows[:, 0]) - math.pi
    up = np.flatnonzero((phi[1:] > 0) & (phi[:-1] <= 0))
    period = np.diff(up).mean() * env.dt
    assert period == pytest.approx(2 * math.pi * math.sqrt(equivalent_length(length) / 9.81), rel=0.005)


def test_disturbance_pulse_gives_the_angular_impulse(env):
    tau, dur = 0.2, 0.02
    rows = run(env, 0.0, 200, theta0=math.pi, omega0=0.0,
               disturbances=[{"time": 0.1, "duration": dur, "torque": tau}])
    lc, it, _ = pendulum_inertia(0.4, 0.1)
    j = it + 0.1 * lc * lc
    before, after = rows[100, 1], rows[121, 1]
    assert before == pytest.approx(0.0, abs=1e-6)
    assert after - before == pytest.approx(tau * dur / j, rel=0.05)
    # push(): the same pulse now
    env.reset(seed=0, options={"theta0": math.pi, "omega0": 0.0})
    env.push(-tau, dur)
    for _ in range(20):
        obs, _, _, _, info = env.step(np.array([0.0]))
    assert info["disturbance"] == pytest.approx(-tau)
    assert obs[1] == pytest.approx(-tau * dur / j, rel=0.05)


def test_velocity_servo_tracks_with_30_rad_s_bandwidth(env):
    rows = run(env, 0.5, 400)
    xd = rows[:, IDX["xdot"]]
    t63 = np.argmax(xd >= 0.5 * (1 - math.exp(-1))) * env.dt
    assert 0.025 <= t63 <= 0.045                       # 1/30 s
    assert xd[-100:].mean() == pytest.approx(0.5, rel=0.01)
    assert xd.max() < 0.51


def test_servo_holds_pose_while_carrying_a_swinging_pendulum(env):
    rows = run(env, lambda t: 1.0 * math.sin(2 * math.pi * 0.8 * t), 5000, theta0=0.5, omega0=3.0)
    c = env.workspace_centre
    assert np.abs(rows[:, IDX["ee_y"]] - c[1]).max() < 0.002
    assert np.abs(rows[:, IDX["ee_z"]] - c[2]).max() < 0.002
    assert np.abs(rows[:, IDX["ee_rx"]:IDX["ee_rz"] + 1]).max() < 0.01
    err = rows[1:, IDX["xdot"]] - np.sin(2 * math.pi * 0.8 * np.arange(1, 5001) * env.dt)
    w = 2 * math.pi * 0.8 / 30.0                       # a first-order lag of bandwidth 30 rad/s
    expected = w / math.sqrt(1 + w * w) / math.sqrt(2)
    assert np.sqrt(np.mean(err[500:] ** 2)) == pytest.approx(expected, rel=0.1)


def test_soft_wall_keeps_x_inside_the_workspace(env):
    rows = run(env, 1.5, 1500)
    assert rows[:, IDX["x"]].max() < env.x_limit + 0.005
    rows = run(env, -1.5, 1500)
    assert rows[:, IDX["x"]].min() > -env.x_limit - 0.005
    assert limited_velocity(9.0, 0.0) == 1.5
    assert limited_velocity(1.0, 0.35) == 0.0
    assert limited_velocity(0.0, 0.4) < 0.0


def test_reference_controller_from_observations_matches_the_env(env):
    rc = ReferenceController()
    envt = ArmPendulumEnv(action_mode="torque")
    o1, _ = env.reset(seed=5)
    o2, _ = envt.reset(seed=5)
    for k in range(2000):
        v = np.array([0.6 * math.sin(2 * math.pi * k / 800)])
        tau = rc.torques(o2, v)
        o1, *_ = env.step(v)
        assert np.abs(tau - env.last_torques).max() < 1e-3
        o2, *_ = envt.step(tau)
    assert np.abs(o1 - o2).max() < 1e-5
    a6 = task_acceleration(o1, 0.0)
    assert a6.shape == (6,)
    envt.close()


def test_torque_mode_clips_and_terminates_when_the_arm_falls():
    envt = ArmPendulumEnv(action_mode="torque")
    envt.reset(seed=0)
    envt.step(np.full(6, 1e4))
    np.testing.assert_allclose(envt.last_torques, TORQUE_LIMITS)
    envt.reset(seed=0)
    for k in range(3000):
        _, _, term, trunc, info = envt.step(np.zeros(6))
        if term:
            break
    assert term and info["out_of_workspace"] and not info["diverged"] and not trunc
    envt.close()


def test_non_finite_state_terminates_as_diverged(env):
    env.reset(seed=1)
    env.data.qvel[6] = np.nan
    obs, _, term, _, info = env.step(np.array([0.0]))
    assert term and info["diverged"]
    assert np.all(np.isfinite(obs))


def test_same_seed_and_actions_give_identical_trajectories(env):
    a = run(env, lambda t: 0.7 * math.sin(7 * t), 1500, seed=11, randomize=True)
    b = run(env, lambda t: 0.7 * math.sin(7 * t), 1500, seed=11, randomize=True)
    assert np.array_equal(a, b)


def test_rgb_array_frames_render_headless():
    e = ArmPendulumEnv(render_mode="rgb_array", width=320, height=240)
    e.reset(seed=0, options={"theta0": 0.0})
    frame = e.render()
    assert frame.shape == (240, 320, 3) and frame.dtype == np.uint8
    assert frame.std() > 10                                        # a scene, not a blank image
    assert ArmPendulumEnv().render() is None
    e.close()


def test_frames_without_shadows_show_the_same_scene_less_shaded():
    frames = {}
    for shadows in (True, False):
        e = ArmPendulumEnv(render_mode="rgb_array", width=320, height=240, shadows=shadows)
        e.reset(seed=0, options={"theta0": 0.0})
        frames[shadows] = e.render().astype(float)
        e.close()
    lit, plain = frames[True], frames[False]
    assert lit.shape == plain.shape and plain.std() > 10
    diff = np.abs(lit - plain).max(axis=2)
    assert 0.0 < (diff > 30).mean() < 0.25                         # the shadows only, not another scene
    assert plain.mean() > lit.mean()                               # without them the floor is brighter


@pytest.mark.parametrize("options", [{"length": float("inf")}, {"mass": float("nan")}, {"damping": float("inf")},
                                     {"length": 1e9}, {"theta0": float("nan")}, {"omega0": float("inf")}])
def test_non_finite_or_absurd_reset_options_are_refused(options):
    import gymnasium as gym
    env = gym.make("multiform/ArmPendulum-v0")
    with pytest.raises(ValueError):
        env.reset(seed=0, options=options)
    env.close()


def test_named_accessors_read_the_entries_they_name(env):
    obs, _ = env.reset(seed=3, options={"theta0": 0.2, "omega0": -0.7, "x0": 0.1})
    obs, *_ = env.step(np.array([0.3]))
    assert env.pendulum_angle() == obs[IDX["theta"]] and env.pendulum_angular_velocity() == obs[IDX["omega"]]
    centre = env.workspace_centre
    assert env.flange_offset() == (obs[IDX["x"]], obs[IDX["ee_y"]] - centre[1], obs[IDX["ee_z"]] - centre[2])
    assert env.flange_offset()[0] == pytest.approx(obs[IDX["ee_x"]] - centre[0])
    tilt = obs[[IDX["ee_rx"], IDX["ee_ry"], IDX["ee_rz"]]]
    assert env.flange_tilt_squared() == pytest.approx(float(tilt @ tilt))
