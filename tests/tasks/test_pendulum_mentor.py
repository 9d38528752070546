"""The scripted pendulum mentor: skill, human limits, mistakes, labels, determinism, demo video."""

from __future__ import annotations

import math

import numpy as np
import pytest

from multiform.demos.episode import Episode
from multiform.tasks.pendulum_mentor import PendulumMentor
from multiform.teach.record import PushDuring, record_episode
from multiform.envs.arm_pendulum import ArmPendulumEnv
from multiform.envs.osc import OBSERVATION_NAMES
from multiform.report.video import episode_video, read_mp4, replay

OPTS = {"randomize": True}


@pytest.fixture(scope="module")
def env():
    e = ArmPendulumEnv()
    yield e
    e.close()


def tags_of(ep: Episode) -> list[str]:
    return [t for _, _, t in ep.segments()]


def verdicts(ep: Episode) -> dict[str, bool]:
    return {lab.transition: lab.success for lab in ep.labels}


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_without_mistakes_the_mentor_swings_up_and_balances(env, seed):
    mentor = PendulumMentor(mistake="none")
    ep = record_episode(env, mentor, seed=seed, options=OPTS)
    assert tags_of(ep) == ["t0", "t2", "t1", "t3"]
    assert ep.outcome == "success" and mentor.outcome == "success"
    assert all(verdicts(ep).values())
    segs = {t: (s, e) for s, e, t in ep.segments()}
    s1, e1 = segs["t1"]
    assert (e1 - s1) * ep.dt == pytest.approx(0.5, abs=0.02)
    s3, e3 = segs["t3"]
    assert (e3 - s3) * ep.dt >= 5.0 - 1e-9
    th, om = ep.column("theta"), ep.column("omega")
    assert abs(th[s1]) < 0.5 and abs(om[s1]) < 3.0               # the switching state is in the data
    assert np.abs(th[s3:e3]).max() < 0.3
    assert ep.duration < 20.0


def test_joystick_limits_show_in_the_commands(env):
    mentor = PendulumMentor(mistake="none")
    ep = record_episode(env, mentor, seed=4, options=OPTS)
    a = ep.actions[:, 0]
    assert np.abs(a).max() <= 1.5
    assert np.abs(np.diff(a)).max() <= mentor.stick_accel * ep.dt + 1e-12    # hand speed on the stick
    assert 40 <= mentor.delay_steps <= 80


@pytest.mark.parametrize("kind, seed, bad", [("wrong_phase", 0, "t2"), ("over_pump", 0, "t1"),
                                             ("early_switch", 0, "t1"), ("lapse", 2, "t3")])
def test_each_mistake_ruins_its_segment_and_shows_in_the_commands(env, kind, seed, bad):
    mentor = PendulumMentor(mistake=kind)
    ep = record_episode(env, mentor, seed=seed, options=OPTS)
    assert ep.outcome == "failure"
    v = verdicts(ep)
    assert v[bad] is False
    th, om, a = ep.column("theta"), ep.column("omega"), ep.actions[:, 0]
    segs = {t: (s, e) for s, e, t in ep.segments()}
    if kind == "wrong_phase":
        s, e = segs["t2"]
        assert ep.duration == pytest.approx(20.0, abs=0.01)      # the swing-up timed out
        late = slice(s + 3000, e)                                # after the mistake began (<= 3 s)
        assert np.corrcoef(a[late], -np.sin(th[late]))[0, 1] < -0.5   # moves with the pendulum
    elif kind == "over_pump":
        s, _ = segs["t1"]
        assert abs(om[s]) > mentor.switch_rate + 1.0             # caught while racing over the top
        assert v["t2"] is False
    elif kind == "early_switch":
        s, _ = segs["t1"]
        assert abs(th[s]) > mentor.switch_angle + 0.1
    else:
        s, e = segs["t3"]
        changes = np.flatnonzero(np.diff(a[s:e]) != 0)
        assert np.diff(changes).max() * ep.dt >= 0.4            # the stick froze
        assert v["t1"] and v["t2"]


def test_mistakes_are_drawn_at_the_configured_rate():
    m = PendulumMentor(mistake_rate=0.3)
    kinds = []
    for seed in range(400):
        m.reset(np.zeros(28), np.random.default_rng([seed, 1]))
        kinds.append(m.mistake_kind)
    frac = np.mean([k != "none" for k in kinds])
    assert 0.24 < frac < 0.36
    assert {"wrong_phase", "over_pump", "early_switch", "lapse"} <= set(kinds)
    m = PendulumMentor(mistake_rate=0.0)
    m.reset(np.zeros(28), np.random.default_rng(0))
    assert m.mistake_kind == "none"
    with pytest.raises(ValueError):
        PendulumMentor(mistake="sneezing")


def success_rate(env, seeds) -> tuple[float, list[tuple[int, str, str]]]:
    mentor = PendulumMentor()
    rows = []
    for seed in seeds:
        ep = record_episode(env, mentor, seed=seed, options=OPTS)
        rows.append((seed, mentor.mistake_kind, ep.outcome))
    return float(np.mean([o == "success" for _, _, o in rows])), rows


def test_failures_come_from_mistakes_fast(env):
    rate, rows = success_rate(env, range(8))
    print(f"\nscripted mentor over {len(rows)} demos: success rate {rate:.0%}")
    for seed, kind, outcome in rows:
        if kind == "none":
            assert outcome == "success", seed
        elif kind in ("wrong_phase", "over_pump"):
            assert outcome == "failure", seed
    assert any(kind != "none" for _, kind, _ in rows)
    assert 0.5 <= rate < 1.0


@pytest.mark.slow
def test_success_rate_over_50_demos_is_60_to_80_percent(env):
    rate, rows = success_rate(env, range(50))
    kinds = {}
    for _, kind, outcome in rows:
        kinds.setdefault(kind, []).append(outcome == "success")
    print(f"\nscripted mentor over 50 demos: success rate {rate:.0%}; "
          + ", ".join(f"{k}: {sum(v)}/{len(v)}" for k, v in sorted(kinds.items())))
    assert 0.60 <= rate <= 0.80
    assert all(kinds["none"])
    assert not any(kinds.get("wrong_phase", [])) and not any(kinds.get("over_pump", []))


def test_replaying_a_demo_from_its_seed_reproduces_it(env):
    mentor = PendulumMentor()
    a = record_episode(env, mentor, seed=1, options=OPTS)
    b = record_episode(env, mentor, seed=1, options=OPTS)
    assert np.array_equal(a.obs, b.obs) and np.array_equal(a.actions, b.actions)
    assert np.array_equal(a.transitions, b.transitions) and a.labels == b.labels
    obs, _ = replay(env, a)
    assert np.array_equal(obs, a.obs)
    other = record_episode(env, mentor, seed=2, options=OPTS)
    assert not np.array_equal(other.obs[:100], a.obs[:100])


def test_pushed_while_balancing_the_mentor_swings_up_again_and_the_replay_reproduces_it(env):
    """A push the mentor's balance cannot absorb: the pendulum falls, the mentor swings it up again
    (tagged t2, after t3: its own definition has no such transition), catches and holds it."""
    push = PushDuring(tags=("t1", "t3"), after=2.0, size=0.5, duration=0.1)
    ep = record_episode(env, PendulumMentor(mistake="none"), seed=3, options=OPTS, push=push)
    assert tags_of(ep) == ["t0", "t2", "t1", "t3", "t2", "t1", "t3"]
    assert [lab.success for lab in ep.labels] == [True, True, True, False, True, True, True]
    (pulse,) = ep.reset_options["disturbances"]
    t1_start = next(s for s, _, t in ep.segments() if t == "t1")
    assert pulse["time"] == pytest.approx(t1_start * ep.dt + 2.0, abs=2e-3) and pulse["torque"] == 0.5
    obs, _ = replay(env, ep)
    assert np.array_equal(obs, ep.obs)
    without = record_episode(env, PendulumMentor(mistake="none"), seed=3, options=OPTS)
    assert tags_of(without) == ["t0", "t2", "t1", "t3"] and "disturbances" not in without.reset_options


def test_a_mentor_without_recoveries_gives_up_when_the_pendulum_falls(env):
    push = PushDuring(tags=("t1", "t3"), after=2.0, size=0.5, duration=0.1)
    ep = record_episode(env, PendulumMentor(mistake="none", recover=0), seed=3, options=OPTS, push=push)
    assert tags_of(ep) == ["t0", "t2", "t1", "t3"] and ep.outcome == "failure"
    assert [lab.success for lab in ep.labels] == [True, True, True, False]


def test_the_mentor_decides_from_observations_alone(env):
    """Fed the recorded observations (no info, no env), a fresh mentor issues the same commands."""
    rec = PendulumMentor()
    ep = record_episode(env, rec, seed=8, options=OPTS)
    m = PendulumMentor()
    m.reset(ep.obs[0], np.random.default_rng([8, 1]))
    for k in range(ep.num_samples):
        cmd, tag = m.act(ep.obs[k], {}, k * ep.dt)
        assert cmd[0] == ep.actions[k, 0] and tag == ep.transitions[k]


def synthetic(theta: np.ndarray, omega: np.ndarray, tags: list[str]) -> Episode:
    n = len(theta)
    obs = np.zeros((n, len(OBSERVATION_NAMES)))
    obs[:, 0], obs[:, 1] = theta, omega
    return Episode(obs=obs, actions=np.zeros((n, 1)), transitions=np.array(tags), observation_names=OBSERVATION_NAMES,
                   command_names=("v_cmd",), dt=0.001, seed=0)


def test_labels_follow_what_the_mentor_saw():
    m = PendulumMentor()
    # swing-up that ends near upright and slow, a catch that holds, 5 s of balance
    th = np.concatenate([np.linspace(math.pi, 0.3, 3000), 0.3 * np.exp(-np.arange(500) / 200), np.full(5000, 0.02)])
    om = np.concatenate([np.full(2999, 1.0), [-1.0], np.zeros(5500)])
    tags = ["t2"] * 3000 + ["t1"] * 500 + ["t3"] * 5000
    assert [lab.success for lab in m.label(synthetic(th, om, tags))] == [True, True, True]
    # the same but the pendulum falls 2 s into the balancing
    th2 = th.copy()
    th2[5500:] = 1.2
    labels = m.label(synthetic(th2, om, tags))
    assert [lab.success for lab in labels] == [True, True, False]
    assert (labels[2].start, labels[2].end, labels[2].transition, labels[2].labeller) == (3500, 8500, "t3", m.name)
    # a swing-up that ended fast and a catch that failed
    om3 = om.copy()
    om3[2999] = -6.0
    th3 = th.copy()
    th3[3200:] = 1.0
    assert [lab.success for lab in m.label(synthetic(th3, om3, tags))] == [False, False, False]
    # a catch the demo does not outlast by a second is no success, however upright it was
    assert [lab.success for lab in m.label(synthetic(th[:3400], om[:3400], tags[:3400]))] == [True, False]


def test_a_10_second_demo_is_written_to_mp4(env, tmp_path):
    ep = record_episode(env, PendulumMentor(mistake="none"), seed=0, options=OPTS)
    assert ep.duration >= 10.0
    rv = ArmPendulumEnv(width=320, height=240)
    path = episode_video(rv, ep, tmp_path / "demo.mp4", fps=10, camera="front", width=320, height=240)
    assert path.exists() and path.stat().st_size > 10_000
    frames = read_mp4(path)
    assert len(frames) == pytest.approx(ep.duration * 10, abs=1.5)
    assert frames[0].shape == (240, 320, 3)
    assert [p.name for p in tmp_path.iterdir()] == ["demo.mp4"]       # no temporary file left
