"""The envs as Gymnasium tooling sees them: check_env in a process with no MUJOCO_GL, the
registered time limit, render_fps, the documented reward and is_success, normalised actions."""

import os
import subprocess
import sys
import textwrap

import gymnasium as gym
import numpy as np
import pytest

import multiform.envs  # noqa: F401
from multiform.envs import rendering
from multiform.envs.arm_pendulum import SUCCESS_HOLD

IDS = ("multiform/ArmPendulum-v0", "multiform/Nunchaku-v0")
# The only warnings check_env may give, and why they stay: the observations are physical quantities
# (velocities, forces) with no hard bound, and in physical units the action box is not [-1, 1]
# (normalize_actions=True gives that).
EXPLAINED = ("observation space minimum value is -infinity", "observation space maximum value is infinity",
             "we recommend using a symmetric and normalized space")

CHECK = textwrap.dedent("""
    import json, os, warnings
    import gymnasium as gym
    from gymnasium.utils.env_checker import check_env
    import multiform.envs
    out = {"gl": os.environ.get("MUJOCO_GL")}
    for env_id in %r:
        for kw in ({}, {"normalize_actions": True}):
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always")
                env = gym.make(env_id, render_mode="rgb_array", width=64, height=48, **kw)
                check_env(env.unwrapped)
                frame = env.unwrapped.render()
                env.close()
            out[env_id + str(kw)] = {"warnings": [str(w.message) for w in caught], "frame": list(frame.shape),
                                     "lit": int(frame.max())}
    print(json.dumps(out))
""") % (IDS,)


def test_check_env_passes_without_mujoco_gl():
    import json
    env = {k: v for k, v in os.environ.items() if k not in ("MUJOCO_GL", "PYOPENGL_PLATFORM")}
    proc = subprocess.run([sys.executable, "-c", CHECK], env=env, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-2000:]
    out = json.loads(proc.stdout.strip().splitlines()[-1])
    assert out.pop("gl") in ("egl", "osmesa")
    for key, res in out.items():
        assert res["frame"] == [48, 64, 3] and res["lit"] > 0, key
        unexplained = [w for w in res["warnings"] if not any(e in w for e in EXPLAINED)]
        assert not unexplained, (key, unexplained)
        if "normalize_actions" in key:
            assert not any("normalized space" in w for w in res["warnings"]), key


def test_renderer_error_says_what_to_install(monkeypatch):
    monkeypatch.delenv("MUJOCO_GL", raising=False)
    monkeypatch.setattr(rendering, "_egl_available", lambda: False)
    monkeypatch.setattr(rendering, "_osmesa_available", lambda: False)
    env = gym.make(IDS[0], render_mode="rgb_array").unwrapped
    env.reset(seed=0)
    with pytest.raises(RuntimeError, match=r"no EGL or OSMesa library found; install EGL \(Debian: libegl1"):
        env.render()


@pytest.mark.parametrize("env_id, steps", [(IDS[0], 60_000), (IDS[1], 15_000)])
def test_time_limit_and_fps_match_the_step(env_id, steps):
    env = gym.make(env_id)
    assert env.spec.max_episode_steps == steps
    assert env.metadata["render_fps"] == round(1.0 / env.unwrapped.dt) == 1000
    assert gym.make(env_id, max_episode_steps=5).spec.max_episode_steps == 5


def test_pendulum_reward_is_time_upright_and_success_after_five_seconds():
    env = gym.make(IDS[0]).unwrapped
    # a heavily damped pendulum started near upright falls too slowly to leave |theta| < 0.5 in 5 s
    obs, info = env.reset(seed=0, options={"theta0": 0.05, "omega0": 0.0, "damping": 5.0})
    assert info["is_success"] is False
    hold = int(np.ceil(SUCCESS_HOLD / env.dt))
    rewards, successes, thetas = [], [], []
    for _ in range(hold + 10):
        obs, r, term, trunc, info = env.step(np.zeros(1))
        rewards.append(r), successes.append(info["is_success"]), thetas.append(obs[0])
    assert np.all(np.abs(thetas) < 0.5) and np.allclose(rewards, env.dt)
    assert not any(successes[: hold - 1]) and all(successes[hold:])
    obs, info = env.reset(seed=0)            # hanging: no reward
    obs, r, *_ , info = env.step(np.zeros(1))
    assert r == 0.0 and info["is_success"] is False


@pytest.mark.parametrize("seed, flipped", [(0, False), (1, True)])
def test_nunchaku_is_success_agrees_with_the_tasks_check(seed, flipped):
    from multiform.task import load_task
    from multiform.tasks import nunchaku
    task = load_task("nunchaku")
    env = gym.make(IDS[1]).unwrapped
    mentor = task.make_mentor()
    obs, info = env.reset(seed=seed, options=task.demo_options(seed))
    mentor.reset(obs, np.random.default_rng([seed, 1]))
    grips, touches, total, success = [], [], 0.0, []
    t = 0.0
    for _ in range(15_000):
        cmd, _tag = mentor.act(obs, info, t)
        obs, r, term, trunc, info = env.step(np.asarray(cmd, dtype=np.float64))
        total += r
        success.append(info["is_success"])
        grips.append(obs[9]), touches.append(obs[10])
        t += env.dt
        if term or trunc or mentor.finished():
            break
    assert total == float(success[-1]) and success == sorted(success)    # one reward, at the flip
    grip = np.array(grips) > 0.5
    released = np.flatnonzero(~grip)
    expected = (info["scene"]["held"] == "b" and len(released) > 0 and grip[-1]
                and (len(grip) - released[-1] - 1) * env.dt >= nunchaku.HOLD_TIME - 1e-9
                and np.any(np.array(touches)[released[0]:released[-1] + 1] > nunchaku.TOUCH))
    assert success[-1] == bool(expected) == flipped


@pytest.mark.parametrize("env_id, kwargs", [(IDS[0], {}), (IDS[0], {"action_mode": "torque"}), (IDS[1], {})])
def test_normalised_actions_are_the_same_physics(env_id, kwargs):
    plain = gym.make(env_id, **kwargs).unwrapped
    norm = gym.make(env_id, normalize_actions=True, **kwargs).unwrapped
    assert np.all(norm.action_space.low == -1) and np.all(norm.action_space.high == 1)
    lo, hi = plain.action_space.low, plain.action_space.high
    rng = np.random.default_rng(1)
    a, b = plain.reset(seed=4)[0], norm.reset(seed=4)[0]
    assert np.array_equal(a, b)
    for _ in range(300):
        u = rng.uniform(-1, 1, lo.shape)
        a = plain.step(lo + (u + 1) / 2 * (hi - lo))[0]
        b = norm.step(u)[0]
    np.testing.assert_allclose(a, b, rtol=1e-9, atol=1e-9)


def test_gymnasium_makes_the_envs_in_a_fresh_interpreter_without_importing_multiform():
    """Gymnasium 1.x loads no plugins: the id names the module that registers it; and
    `import multiform` alone registers nothing and imports neither Gymnasium nor MuJoCo."""
    code = textwrap.dedent("""
        import sys, gymnasium
        env = gymnasium.make("multiform.envs:multiform/ArmPendulum-v0")
        obs, _ = env.reset(seed=0)
        print(obs.shape[0], env.unwrapped.dt, "multiform/Nunchaku-v0" in gymnasium.registry)
    """)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.split() == ["28", "0.001", "True"]
    code = ("import sys, multiform; print(sorted(m for m in ('gymnasium', 'mujoco', 'multiform.envs') "
            "if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=True)
    assert out.stdout.strip() == "[]"


@pytest.mark.parametrize("env_id", IDS)
def test_frame_skip_holds_the_action_over_that_many_physics_steps(env_id):
    fine = gym.make(env_id, disable_env_checker=True)
    coarse = gym.make(env_id, disable_env_checker=True, frame_skip=20)
    assert coarse.unwrapped.dt == pytest.approx(0.02) and coarse.metadata["render_fps"] == 50
    assert fine.metadata["render_fps"] == 1000
    fine.reset(seed=3)
    coarse.reset(seed=3)
    action = 0.3 * coarse.action_space.high
    total = 0.0
    for _ in range(3):
        for _ in range(20):
            obs_fine, r, *_ = fine.step(action)
            total += r
        obs_coarse, r_coarse, *_ = coarse.step(action)
        assert np.array_equal(obs_fine, obs_coarse)
    with pytest.raises(ValueError, match="frame_skip"):
        gym.make(env_id, frame_skip=0)


@pytest.mark.slow
def test_record_video_of_a_full_pendulum_episode_stays_under_500_mb(tmp_path):
    """60 s of the arm (the registered time limit) recorded by Gymnasium's RecordVideo at 25 frames
    per second (frame_skip 40, 320x240): the memory the recording takes (the process's peak, video
    written, above what it held before the episode: the interpreter, MuJoCo and its GL context,
    about 300 MB) stays under 500 MB; at 1 kHz it would be about 14 GB."""
    code = textwrap.dedent(f"""
        import resource, gymnasium, numpy as np
        from gymnasium.wrappers import RecordVideo
        env = gymnasium.make("multiform.envs:multiform/ArmPendulum-v0", render_mode="rgb_array", frame_skip=40,
                             width=320, height=240, shadows=False, max_episode_steps=1500)
        env = RecordVideo(env, {str(tmp_path)!r}, episode_trigger=lambda e: True)
        env.reset(seed=0)
        before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss // 1024
        steps, done = 0, False
        while not done:
            _, _, term, trunc, _ = env.step(np.zeros(1))
            steps, done = steps + 1, term or trunc
        env.close()
        print(steps, env.unwrapped.data.time, resource.getrusage(resource.RUSAGE_SELF).ru_maxrss // 1024 - before)
    """)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=900)
    assert out.returncode == 0, out.stderr[-3000:]
    steps, sim_time, peak_mb = out.stdout.split()[-3:]
    assert int(steps) == 1500 and float(sim_time) == pytest.approx(60.0)
    assert int(peak_mb) < 500, peak_mb
    videos = list(tmp_path.glob("*.mp4"))
    assert len(videos) == 1 and videos[0].stat().st_size > 10_000
