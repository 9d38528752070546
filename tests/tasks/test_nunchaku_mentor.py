"""The scripted nunchaku mentor flips the nunchaku, tags the bundled skill's transitions, labels honestly."""

import numpy as np
import pytest

from multiform.tasks.nunchaku_mentor import FlipParameters, NunchakuMentor
from multiform.teach.record import record_episode
from multiform.envs.nunchaku import NunchakuEnv
from multiform.petri.skillfile import load_skill

ORDER = ["t0", "t1", "t2", "t3", "t4", "t5"]


@pytest.fixture(scope="module")
def env():
    return NunchakuEnv()


def test_skill_file_names_what_the_env_provides(env):
    apn = load_skill("nunchaku")
    assert set(apn.variables) <= set(env.observation_names)
    assert tuple(apn.commands) == env.command_names
    assert {"t0", "t1", "t2", "t3", "t4", "t5", "t6", "t7", "t8"} == set(apn.transition_ids)
    for law in apn.laws.values():
        assert law.inputs


def test_mentor_flips_and_tags_every_sub_procedure(env):
    mentor = NunchakuMentor(failure_rate=0.0)
    results = [record_episode(env, mentor, seed=s) for s in (11, 12, 13)]
    wins = [ep for ep in results if ep.outcome == "success"]
    assert len(wins) >= 2
    for ep in wins:
        tags = [tag for _, _, tag in ep.segments()]
        assert tags == ORDER
        assert all(lab.success for lab in ep.labels)
        assert [lab.transition for lab in ep.labels] == tags
        assert ep.observation_names == env.observation_names and ep.command_names == env.command_names
        # the command is smooth: the mentor's hand accelerates at most 40 m/s^2
        dv = np.abs(np.diff(ep.actions[:, 0])) / ep.dt
        assert dv.max() <= 40.0 + 1e-6
        # the magnet lets go at the release and holds again at the regrasp
        seg = {tag: (s, e) for s, e, tag in ep.segments()}
        assert ep.actions[seg["t2"][0], 3] == 0.0 and ep.actions[seg["t4"][0], 3] == 1.0
        grip = ep.column("grip")
        assert grip[seg["t1"][0]] == 1.0 and grip[seg["t2"][0] + 5] == 0.0 and grip[-1] == 1.0


def test_fumbles_fail_and_are_labelled_so(env):
    mentor = NunchakuMentor(failure_rate=1.0)
    eps = [record_episode(env, mentor, seed=s) for s in range(20, 26)]
    failed = [ep for ep in eps if ep.outcome == "failure"]
    assert len(failed) >= 3
    for ep in failed:
        assert any(not lab.success for lab in ep.labels)
        assert ep.labels[0].transition == "t0"


def test_demos_are_reproducible_from_the_seed(env):
    mentor = NunchakuMentor()
    a = record_episode(env, mentor, seed=7)
    b = record_episode(env, mentor, seed=7)
    assert np.array_equal(a.obs, b.obs) and np.array_equal(a.actions, b.actions)
    assert [(l.start, l.end, l.success) for l in a.labels] == [(l.start, l.end, l.success) for l in b.labels]


def test_noise_free_mentor_is_repeatable_and_parameters_are_committed():
    p = FlipParameters()
    assert p.vector().shape == (16,)
    m = NunchakuMentor(noise=0.0, failure_rate=0.0)
    m.reset(np.zeros(15), np.random.default_rng(0))
    assert m.p == p and m.reaction == 0.0 and m.fumble == ""


def test_the_mentor_grades_a_robot_trial_from_what_it_shows():
    """The trial seen by place: the magnet's grip and the touch on the back of the hand, nothing of the
    simulator. A flip (let go, chain over the back, a rod caught and held 0.5 s) passes every stay; a
    catch that did not last, or a release without the chain rolling over, fails the later stays."""
    from multiform.demos.episode import Episode
    dt, n = 0.01, 300
    grip = np.ones(n)
    grip[100:180] = 0.0                                 # let go at 1 s, caught at 1.8 s, held 1.2 s
    touch = np.zeros(n)
    touch[130:150] = 2.0                                # the chain on the back of the hand
    tags = np.array(["P1"] * 100 + ["P2"] * 85 + ["P3"] * 60 + ["done"] * 55)

    def grade(grip, touch):
        ep = Episode(obs=np.stack([grip, touch], axis=1), actions=np.zeros((n, 1)), transitions=tags,
                     observation_names=("grip", "touch"), command_names=("vx",), dt=dt, seed=0)
        return [(lab.transition, lab.success) for lab in NunchakuMentor().grade_trial(ep)]

    assert grade(grip, touch) == [("P1", True), ("P2", True), ("P3", True)]
    short = grip.copy()
    short[220:] = 0.0                                   # the catch held 0.4 s, then the rod fell out
    assert grade(short, touch) == [("P1", True), ("P2", False), ("P3", False)]
    assert grade(grip, np.zeros(n)) == [("P1", False), ("P2", False), ("P3", False)]


def test_the_grade_from_the_trace_matches_what_the_flipping_mentor_saw(env):
    """On recorded flips, fumbles included, the trace-only grade of the last stay says what the
    mentor who did the flip saw (it knew which rod ended in its palm)."""
    from multiform.learn.views import place_episode
    apn = load_skill("nunchaku")
    mentor = NunchakuMentor(failure_rate=0.6)
    grader = NunchakuMentor()
    seen = set()
    for s in range(30, 36):
        ep = record_episode(env, mentor, seed=s)
        last = grader.grade_trial(place_episode(apn, ep))[-1]
        assert last.success == (ep.outcome == "success"), s
        seen.add(last.success)
    assert seen == {True, False}
