"""The mentor takes over a failed practice trial where the robot knew least."""

from __future__ import annotations

import numpy as np

from multiform.adapt.takeover import stuck_tick
from multiform.learn.gp import GPLaw
from multiform.petri.skillfile import load_skill

from .synthetic import make_trace


def test_the_mentor_takes_over_where_the_running_law_was_least_sure():
    apn = load_skill("pendulum")
    rng = np.random.default_rng(0)
    n = 1000                                           # 10 s at 10 ms
    v = np.zeros((n, 6))                               # theta, omega, x, xdot, s, c
    v[:, 0] = np.pi - 0.5 * np.sin(np.linspace(0, 20, n))
    v[:, 1] = rng.normal(0, 1, n)
    v[:, 2] = 0.02 * rng.standard_normal(n)
    v[600:650, 2] = 0.3                                # the hand at the end of its stroke, where no demo went
    v[:, 4], v[:, 5] = np.sin(v[:, 0]), np.cos(v[:, 0])
    X = v[:600][:, [4, 5, 1, 2]]
    law = GPLaw(n_hyper=300, n_restarts=0, random_state=0).fit(X, X[:, 0])
    trace = make_trace(apn, [(0, "t0")], v, "failure")
    tick = stuck_tick(trace, apn, {"swing_up": law})
    assert 600 <= tick < 650
    # only a law that ran is weighed, and not in the trial's first or last second
    assert stuck_tick(trace, apn, {"balance": law}) is None
    short = make_trace(apn, [(0, "t0")], v[:150], "failure")
    assert stuck_tick(short, apn, {"swing_up": law}) is None


def test_a_failed_trial_gets_one_takeover_within_the_budget_kept_apart_with_its_source(tmp_path):
    from multiform.adapt.practice import Practice, PracticeConfig, PracticeState, TrialRecord
    from multiform.adapt.experience import Experience
    from multiform.demos.episode import Episode, SegmentLabel
    from multiform.learn.judge import TrialGrade
    from multiform.model import SkillModel

    model = SkillModel.create(tmp_path / "model", "pendulum")
    rng = np.random.default_rng(0)
    X = rng.standard_normal((60, 4))
    model.save_law("swing_up", GPLaw(n_hyper=60, n_restarts=0, random_state=0).fit(X, X[:, :1]))
    asked = []

    def takeover(trace, tick):
        asked.append(tick)
        n = 300
        return Episode(obs=np.zeros((n, 4)), actions=np.zeros((n, 1)), transitions=np.array(["t2"] * n),
                       observation_names=("theta", "omega", "x", "xdot"), command_names=("v_cmd",), dt=0.01,
                       seed=int(trace.seed), labels=[SegmentLabel(0, n, "t2", True)])

    practice = Practice(model, tmp_path / "p", PracticeConfig(learn=True, mentor_trials=2), name="c",
                        takeover=takeover)
    v = np.zeros((400, 6))
    v[:, 0] = np.linspace(np.pi, 2.0, 400)
    v[:, 4], v[:, 5] = np.sin(v[:, 0]), np.cos(v[:, 0])
    trace = make_trace(model.apn, [(0, "t0")], v, "failure")
    failed = TrialGrade(segments=[], places={}, score=0.1)
    state = PracticeState()
    record = TrialRecord(trial=3, success=False)
    practice.learning.learn_from(state, record, trace, failed, model.apn)
    assert record.takeover.tick == asked[0] and 100 <= asked[0] < 300
    assert [t.trial for t in state.takeovers] == [3]
    kept = Experience(model.path).takeovers()
    assert list(kept) == ["c_3"] and kept["c_3"].num_samples == 300 and kept["c_3"].labels[0].success
    # the budget is spent: the next failed trial is not taken over; a successful one never is
    later = TrialRecord(trial=4, success=False)
    practice.learning.learn_from(state, later, trace, failed, model.apn)
    assert later.takeover is None
    assert len(asked) == 1
