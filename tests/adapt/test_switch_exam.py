"""A learned switch's smoothest setting, examined on replayed trials at the skill's first shortfall
(``switch_exam``) and kept only if it wins."""

from __future__ import annotations

import pytest

from multiform.adapt.practice import Practice, PracticeConfig, PracticeState, TrialRecord
from multiform.adapt.practice.switches import learned_switches
from multiform.model import SkillModel


@pytest.fixture()
def model(relearned_model) -> SkillModel:
    return relearned_model


def _falling_short(model: SkillModel, tmp_path, **config) -> tuple[Practice, PracticeState]:
    """Twenty trials, every other one plain; four of the ten plain ones failed (a shortfall at a
    95 % target), and a refit is due."""
    cfg = PracticeConfig(**{"max_trials": 100, **config})
    trials = [TrialRecord(trial=k, success=k not in (2, 8, 12, 18), net_version=model.version,
                          explored=cfg.explores(k), fired=["t0", "t1"]) for k in range(20)]
    return Practice(model, tmp_path / "p", cfg, name="c"), PracticeState(trial=20, trials=trials)


def _replay(practice: Practice, state: PracticeState, outcomes: list[bool]) -> None:
    for ok in outcomes:
        draw = practice.watch.exam_draw(state)
        state.trials.append(TrialRecord(trial=state.trial, draw=draw, success=ok, net_version=practice.model.version,
                                        fired=["t0", "t1"]))
        state.trial += 1
        practice.after_trial(state)


def test_at_the_first_shortfall_the_smoothest_setting_of_a_learned_switch_is_examined(model, tmp_path):
    practice, state = _falling_short(model, tmp_path)
    before = learned_switches(practice.ctx)["t1"]
    practice.after_trial(state)
    assert state.switch_examined and model.version == 2
    rev = model.history.revisions()[-1]
    assert (rev.operator, rev.target) == ("set_condition", "t1")
    assert rev.evidence["prefer"] == "smooth" and rev.evidence["before"]["window"] == before["window"]
    assert (rev.evidence["window"], rev.evidence["params"]) != (before["window"], before["params"])
    # the smoothest of the settings that hold at as many held-out switches as any
    best = max(s["hit_in_moment"] for s in rev.evidence["cv"])
    tied = [s for s in rev.evidence["cv"] if s["hit_in_moment"] == best]
    assert rev.evidence["window"] == max(s["window"] for s in tied)
    assert rev.evidence["params"]["gamma"] == min(s["params"]["gamma"] for s in tied if s["window"] == rev.evidence["window"])
    # the last ten plain trials are replayed; the change must win (no failure pointed at it)
    plain = [t.trial for t in state.trials if not t.explored][-10:]
    assert state.watch.draws == plain and state.watch.must_win and state.watch.by_margin
    assert model.conditions()[model.apn.transition("t1").condition.model] is not None
    # a killed practice resumes the exam where it was
    practice.save_state(state)
    state = practice.load_state()
    assert state.switch_examined and state.watch.must_win and practice.watch.exam_draw(state) == plain[0]


BEFORE = [True, False, True, True, False, True, False, True, True, False]     # the ten plain trials replayed


@pytest.mark.parametrize("outcomes, kept", [
    ([True] * 10, True),                    # won all four that failed
    ([False] + [True] * 9, True),           # won four, lost one
    ([False] * 10, False),                  # lost six
    (BEFORE, False),                        # the same trials: nothing won
    ([False, True] + BEFORE[2:], False),    # won one, lost one
    (BEFORE[:1] + [True] + BEFORE[2:], False),                       # won one, lost none: chance
    (BEFORE[:1] + [True] + BEFORE[2:4] + [True] + BEFORE[5:], True),  # won two, lost none
])
def test_the_smoother_switch_is_kept_only_if_it_wins_its_exam(model, tmp_path, outcomes, kept):
    practice, state = _falling_short(model, tmp_path)
    old = model.apn.transition("t1").condition.model
    practice.after_trial(state)
    new = model.apn.transition("t1").condition.model
    _replay(practice, state, outcomes)
    assert state.watch is None
    ops = [r.operator for r in model.history.revisions()]
    assert ops[-1] == ("set_condition" if kept else "revert")
    assert model.apn.transition("t1").condition.model == (new if kept else old)


@pytest.mark.parametrize("outcomes, refitted", [([False] * 10, True), ([True] * 10, False)])
def test_a_reverted_exam_lets_the_laws_refit_at_once(model, tmp_path, monkeypatch, outcomes, refitted):
    """The shortfall that called the exam holds for the net a revert returns to: the refit the exam
    stood in for is made on the trial the exam ends, without waiting for new plain trials to show it
    again; a kept switch is watched as any revision and waits its turn."""
    practice, state = _falling_short(model, tmp_path)
    practice.after_trial(state)
    reached = []
    segments = practice.ctx.experience.segments
    monkeypatch.setattr(practice.ctx.experience, "segments", lambda: reached.append(state.trial) or segments())
    _replay(practice, state, outcomes)
    assert model.history.revisions()[-1].operator == ("revert" if refitted else "set_condition")
    assert reached == ([state.trial] if refitted else []) and not state.refit_now


def test_the_switch_is_examined_once_by_default_and_never_when_off(model, tmp_path):
    practice, state = _falling_short(model, tmp_path, switch_exam=False)
    practice.after_trial(state)
    assert not state.switch_examined and model.version == 1
    practice, state = _falling_short(model, tmp_path / "b")
    practice.after_trial(state)
    _replay(practice, state, [False] * 10)                 # reverted
    assert state.switch_examined and model.version == 3
    for ok in BEFORE * 2:                                  # the skill as it was falls short again
        state.trials.append(TrialRecord(trial=state.trial, success=ok, net_version=3, fired=["t0", "t1"]))
        state.trial += 1
    practice.after_trial(state)
    assert practice.learning.falls_short(state) and model.version == 3


def test_no_exam_while_the_trials_it_would_replay_all_succeed(model, tmp_path):
    practice, state = _falling_short(model, tmp_path)
    state.trials += [TrialRecord(trial=k, success=True, net_version=model.version, explored=k % 2 == 1,
                                 fired=["t0", "t1"]) for k in range(20, 30)]
    state.trial = 30
    for k, ok in ((0, False), (4, False), (12, True), (18, True)):   # the failures older than the last ten plain trials
        state.trials[k].success = ok
    assert practice.learning.falls_short(state)
    practice.after_trial(state)
    assert not state.switch_examined and model.version == 1


@pytest.mark.parametrize("bad", [1, "yes", None])
def test_switch_exam_must_be_true_or_false(bad):
    from multiform.errors import InvalidInput
    with pytest.raises(InvalidInput, match="switch_exam"):
        PracticeConfig(switch_exam=bad)
