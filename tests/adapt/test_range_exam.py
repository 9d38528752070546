"""A learned switch held to where the mentor switched, where its own firings outside that range fail
(``range_exam``): examined on replayed trials at a shortfall, kept only if it wins."""

from __future__ import annotations

import numpy as np
import pytest

from multiform.adapt.practice import Practice, PracticeConfig, PracticeState, TrialRecord
from multiform.adapt.practice import ranges
from multiform.adapt.practice.ranges import SPREAD, firing_outcomes, range_evidence
from multiform.learn.views import switch_data
from multiform.model import SkillModel

FAILED = (2, 5, 8, 12, 15, 18)


@pytest.fixture()
def model(relearned_model, monkeypatch) -> SkillModel:
    """The four-demonstration pendulum model, t1 relearned from its mentor's four switches (the
    range is taken from three and up here)."""
    monkeypatch.setattr(ranges, "MIN_SWITCHES", 3)
    return relearned_model


def _mentor(model: SkillModel) -> dict[str, tuple[float, float]]:
    names = ("theta", "omega", "x", "xdot", "s", "c")
    sw = switch_data(model.apn, model.episodes, "t1", names).switch_states
    return {n: (float(sw[:, j].mean()), float(sw[:, j].std(ddof=1))) for j, n in enumerate(names)}


def _falling_short(model: SkillModel, tmp_path, far: str | None) -> tuple[Practice, PracticeState]:
    """Twenty trials, each firing t1 once at the mentor's mean switch state; the six that failed
    (four of them plain: a shortfall at a 95 % target) fired it with ``far`` ten standard
    deviations off (None: where the others did)."""
    cfg = PracticeConfig(max_trials=100, switch_exam=False)
    mentor = _mentor(model)
    trials = []
    for k in range(20):
        row = {n: mu for n, (mu, sd) in mentor.items()}
        if far is not None and k in FAILED:
            row[far] = mentor[far][0] + 10 * mentor[far][1]
        trials.append(TrialRecord(trial=k, success=k not in FAILED, net_version=model.version,
                                  explored=cfg.explores(k), fired=["t0", "t1"], switch_states={"t1": [row]}))
    return Practice(model, tmp_path / "p", cfg, name="c"), PracticeState(trial=20, trials=trials)


def test_firings_outside_the_mentors_range_that_fail_hold_the_switch_to_it_and_a_loss_reverts_it(model, tmp_path):
    practice, state = _falling_short(model, tmp_path, "xdot")
    version = model.version
    practice.after_trial(state)
    assert state.ranges_examined == ["t1:xdot"] and model.version == version + 1
    rev = model.history.revisions()[-1]
    assert (rev.operator, rev.target) == ("set_condition", "t1")
    mu, sd = _mentor(model)["xdot"]
    cond = model.apn.transition("t1").condition
    assert cond.model == rev.before["condition"]["model"] and "xdot" in cond.within.variables
    assert rev.evidence["low"] == pytest.approx(mu - SPREAD * sd, rel=1e-4)
    assert rev.evidence["outside"] == [0, 6] and rev.evidence["inside"] == [14, 0]
    assert state.watch is not None and state.watch.must_win and state.watch.by_margin
    # replayed: it wins one of the plain trials it replays and loses none, not the two it must -> back, and the
    # refit it stood in for is made at once
    before = state.watch.before
    won = before.index(False)
    outcomes = [b or i == won for i, b in enumerate(before)]
    for ok in outcomes:
        draw = practice.watch.exam_draw(state)
        state.trials.append(TrialRecord(trial=state.trial, draw=draw, success=ok, net_version=model.version,
                                        fired=["t0", "t1"]))
        state.trial += 1
        practice.after_trial(state)
    assert model.history.revisions()[-1].operator in ("revert", "refit_law")
    assert model.apn.transition("t1").condition.within is None
    assert any(r.operator == "revert" for r in model.history.revisions())


def test_no_range_exam_where_inside_and_outside_fare_alike(model, tmp_path):
    practice, state = _falling_short(model, tmp_path, None)
    assert practice.ranges.evidence(state) is None
    practice.after_trial(state)
    assert state.ranges_examined == [] and model.apn.transition("t1").condition.within is None


def test_range_evidence_counts_firings_inside_and_outside_the_mentors_mean_plus_minus_three_sd():
    mentor = np.array([0.0, 0.1, -0.1, 0.05, -0.05])
    x = np.array([0.0] * 10 + [1.0] * 6)
    ok = np.array([True] * 9 + [False] + [False] * 5 + [True])
    got = range_evidence(mentor, x, ok)
    assert got["inside"] == [9, 1] and got["outside"] == [1, 5] and got["p"] < 0.01
    assert got["high"] == pytest.approx(3 * np.std(mentor, ddof=1))
    assert range_evidence(mentor[:2], x, ok) is None            # too few switches for a range
    assert range_evidence(mentor, x[:14], ok[:14]) is None      # four firings outside: too few to judge


def test_firing_outcomes_count_only_a_successful_trials_last_firing_as_success():
    trials = [TrialRecord(trial=0, success=True, switch_states={"t2": [{"a": 1.0}, {"a": 2.0}]}),
              TrialRecord(trial=1, success=False, switch_states={"t2": [{"a": 3.0}]}),
              TrialRecord(trial=2, success=True)]
    states, ok = firing_outcomes(trials, "t2")
    assert [s["a"] for s in states] == [1.0, 2.0, 3.0] and ok.tolist() == [False, True, False]


def test_a_switch_held_to_the_mentors_range_that_wins_its_exam_by_the_margin_is_kept(model, tmp_path):
    practice, state = _falling_short(model, tmp_path, "xdot")
    practice.after_trial(state)
    version = model.version
    before = state.watch.before
    won = [i for i, b in enumerate(before) if not b][:2]
    for ok in [b or i in won for i, b in enumerate(before)]:
        draw = practice.watch.exam_draw(state)
        state.trials.append(TrialRecord(trial=state.trial, draw=draw, success=ok, net_version=model.version,
                                        fired=["t0", "t1"]))
        state.trial += 1
        practice.after_trial(state)
    assert state.watch is None and not any(r.operator == "revert" for r in model.history.revisions())
    assert model.history.version(version).transition("t1").condition.within is not None
