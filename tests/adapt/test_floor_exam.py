"""The ways back's floor, examined deeper once at the end of practice and kept only if it wins."""

from __future__ import annotations

import numpy as np
import pytest

from multiform.adapt.practice import Practice, PracticeConfig, PracticeState, TrialRecord
from multiform.adapt.practice.floors import ways_back
from multiform.learn.region import PlaceRegions, RegionCondition
from multiform.model import SkillModel
from multiform.petri.revision import History, add_transition


def _regions() -> PlaceRegions:
    rng = np.random.default_rng(0)
    p1 = np.column_stack([rng.uniform(-3, 3, 800), rng.uniform(-6, 6, 800)])
    p2 = np.column_stack([0.05 * rng.standard_normal(800), 0.2 * rng.standard_normal(800)])
    return PlaceRegions(("theta", "omega")).fit({"P1": p1, "P2": p2})


def _model_with_way_back(tmp_path, floor: float = -0.5) -> SkillModel:
    """The pendulum skill with a way back t7 (P2 -> P1 once the state has left P2's region)."""
    model = SkillModel.create(tmp_path / "model", "pendulum")
    regions = _regions()
    model.save_regions(regions)
    model.save_condition("in_P1", RegionCondition(regions, "into", "P1", "P2", floor))
    _, rev = add_transition(model.apn, "t7", {"in": ["P2"], "out": ["P1"], "law": "swing_up",
                                              "condition": {"model": "in_P1", "unless": ["t1"]}}, "way back")
    model.history.record(rev)
    return model


def test_a_way_back_is_a_learned_region_condition_that_leaves_its_place(tmp_path):
    model = _model_with_way_back(tmp_path)
    (w,) = ways_back(model.apn, model.conditions())
    assert (w.transition, w.condition, w.place, w.floor) == ("t7", "in_P1", "P2", -0.5)
    assert ways_back(model.history.version(0), model.conditions()) == []


@pytest.mark.parametrize("bad", [0.5, float("nan"), True, "deep"])
def test_an_examined_floor_must_be_a_logit_at_or_below_zero(bad):
    from multiform.errors import InvalidInput
    with pytest.raises(InvalidInput, match="floor_exam"):
        PracticeConfig(floor_exam=bad)


def _ended_practice(tmp_path, **config) -> tuple[Practice, PracticeState]:
    """Eight plain trials of the net with its way back t7, the last four successes (the target
    reached); t7 fired in trials 0, 1, 3 and 5, two of which failed."""
    model = _model_with_way_back(tmp_path)
    cfg = PracticeConfig(**{"learn": True, "exam": True, "floor_exam": -4.0, "target_rate": 0.9, "target_window": 4,
                            "success_streak": 10**6, "max_trials": 100, "revert_window": 10, **config})
    back, plain = ["t0", "t1", "t7", "t1", "t6"], ["t0", "t1", "t6"]
    trials = [TrialRecord(trial=k, success=k not in (0, 3), net_version=1, fired=back if k in (0, 1, 3, 5) else plain)
              for k in range(8)]
    return Practice(model, tmp_path / "p", cfg, name="c"), PracticeState(trial=8, trials=trials)


def _replay(practice: Practice, state: PracticeState, outcomes: list[bool]) -> None:
    for ok in outcomes:
        draw = practice.watch.exam_draw(state)
        state.trials.append(TrialRecord(trial=state.trial, draw=draw, success=ok, net_version=practice.model.version,
                                        fired=["t0", "t1", "t7", "t1", "t6"]))
        state.trial += 1
        practice.after_trial(state)


def test_at_its_target_practice_examines_a_deeper_floor_on_the_trials_that_took_the_way_back(tmp_path):
    practice, state = _ended_practice(tmp_path)
    model = practice.model
    practice.after_trial(state)
    assert not state.done and state.floor_examined
    rev = model.history.revisions()[-1]
    assert (rev.operator, rev.target, model.version) == ("set_condition", "t7", 2)
    assert rev.evidence["floor_before"] == -0.5 and rev.evidence["leave_below_logit"] == -4.0
    assert rev.evidence["replayed_trials"] == [0, 1, 3, 5]          # only these can change: t7 fired in them
    assert state.watch.draws == [0, 1, 3, 5] and state.watch.before == [False, True, False, True]
    # replayable: the revision's condition is the way back with the deeper floor, yielding to t1 as before
    cond = History(model.path / "skill.yaml").versions()[2].transition("t7").condition
    assert cond.unless == ("t1",) and model.conditions()[cond.model].leave_below == -4.0
    # a killed practice resumes the exam where it was
    _replay(practice, state, [True])
    practice.save_state(state)
    state = practice.load_state()
    assert state.floor_examined and state.watch.must_win and practice.watch.exam_draw(state) == 1
    # the deeper floor saves both trials that failed: kept, and practice stops as it would have
    _replay(practice, state, [True, True, True])
    assert state.done and state.watch is None and model.version == 2
    assert state.stop_reason.startswith("own success rate") and state.stop_reason.endswith("floor examined")


@pytest.mark.parametrize("outcomes, kept", [
    ([False, True, False, True], False),     # the same trials: nothing won, so nothing for a change no failure asked for
    ([True, False, True, True], False),      # won two, lost one
    ([True, True, False, True], True),       # won one, lost none
    ([True, False, True, False], False),     # won two, lost two
])
def test_a_deeper_floor_is_kept_only_if_it_wins_its_exam(tmp_path, outcomes, kept):
    practice, state = _ended_practice(tmp_path)
    practice.after_trial(state)
    _replay(practice, state, outcomes)
    rev = practice.model.history.revisions()[-1]
    assert state.done and (rev.operator == "set_condition") == kept
    if not kept:
        assert rev.operator == "revert" and rev.evidence["reverted"] == 2
    t7 = practice.model.apn.transition("t7").condition.model
    assert practice.model.conditions()[t7].leave_below == (-4.0 if kept else -0.5)


def test_failures_during_the_floor_exam_set_off_no_repair(tmp_path):
    practice, state = _ended_practice(tmp_path)
    practice.after_trial(state)
    _replay(practice, state, [False, False, False])
    assert state.watch is not None and [r.operator for r in practice.model.history.revisions()][-1] == "set_condition"


def test_no_floor_exam_where_no_way_back_fired_or_it_is_off(tmp_path):
    practice, state = _ended_practice(tmp_path / "a")
    for t in state.trials:
        t.fired = ["t0", "t1", "t6"]
    practice.after_trial(state)
    assert state.done and practice.model.version == 1 and state.stop_reason.startswith("own success rate")
    practice, state = _ended_practice(tmp_path / "b", floor_exam=0.0)
    practice.after_trial(state)
    assert state.done and practice.model.version == 1 and not state.floor_examined


def test_with_no_room_left_for_another_revision_the_floor_is_examined_in_the_trials_that_remain(tmp_path):
    practice, state = _ended_practice(tmp_path, target_rate=0.0, max_trials=11)
    state.trials[5].success = False
    practice.after_trial(state)                 # three trials left: the last three that took the way back
    assert state.watch.draws == [1, 3, 5] and state.watch.then_stop is None
    _replay(practice, state, [True, True, True])
    assert practice.model.version == 2 and not state.done     # kept (won two); the budget ends practice
