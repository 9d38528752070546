"""Ways back held off in practice: what a probe records, and the floor the robot lowers from it;
a deeper floor examined at the end of practice."""

from __future__ import annotations

import numpy as np
import pytest

from multiform.adapt.hold_off import choose_floor, held_off, probe_stays, ways_back
from multiform.adapt.practice import Practice, PracticeConfig, PracticeState
from multiform.learn.region import PlaceRegions, RegionCondition
from multiform.model import SkillModel
from multiform.petri.revision import History, add_transition, revert

from .synthetic import make_trace


@pytest.mark.parametrize("stays, rate, expected", [
    # two stays the way back would have ended went on; it saves half the trials it fires in
    ([(-1.5, True), (-1.2, True), (-3.0, False), (-0.5, True), (None, False)], 0.5, (-1.5, 1.0)),
    # a way back that saves nearly every trial is worth more than the law going on
    ([(-1.5, True), (-1.2, True)], 0.9, None),
    # a lost stay between two that went on costs what the way back would have saved
    ([(-1.2, True), (-1.4, False), (-1.5, True)], 0.2, (-1.5, 1.4)),
    ([(-1.2, True), (-1.4, False), (-1.5, True)], 0.5, None),
    # stays at or above the floor say nothing about it
    ([(-0.97, True), (-0.5, True)], 0.0, None),
])
def test_the_floor_goes_only_as_low_as_the_stays_that_went_on_pay_for(stays, rate, expected):
    got = choose_floor(stays, -0.97, rate)
    assert got == (None if expected is None else pytest.approx(expected))


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


def _values(theta: np.ndarray) -> np.ndarray:
    v = np.zeros((len(theta), 6))
    v[:, 0] = theta
    v[:, 4], v[:, 5] = np.sin(theta), np.cos(theta)
    return v


def test_a_way_back_held_off_once_taken_and_what_a_probe_records_after_it(tmp_path):
    model = _model_with_way_back(tmp_path)
    conditions = model.conditions()
    (w,) = ways_back(model.apn, conditions)
    assert (w.transition, w.condition, w.place, w.floor) == ("t7", "in_P1", "P2", -0.5)
    once = held_off(conditions, [w], -10.0)["in_P1"]
    assert once.input_names == ("theta", "omega", "fires_t7")
    near, far = np.array([0.25, 0.0]), np.array([1.0, 0.0])       # P2's logit about -5 and -130, both in P1
    assert conditions["in_P1"](near) and conditions["in_P1"](far)
    # before its first firing the way back is as written; after it, it waits down to the probe floor
    assert once(np.append(near, 0.0)) and not once(np.append(near, 1.0)) and once(np.append(far, 1.0))
    assert conditions["in_P1"] is once.condition and conditions["in_P1"].leave_below == -0.5   # untouched

    # swing-up, catch, a push out of P2 (the way back fires), swing-up, a catch that goes out to
    # 0.25 rad and back with the way back held off, then the success stop (t6)
    theta = np.concatenate([np.linspace(-3, -0.1, 100), np.zeros(30), np.linspace(0, 1.2, 20),
                            np.linspace(1.2, 0.1, 30), np.linspace(0.1, 0.25, 10), np.linspace(0.25, 0, 25),
                            np.zeros(60)])
    fired = [(0, "t0"), (100, "t1"), (140, "t7"), (180, "t1"), (270, "t6")]
    trace = make_trace(model.apn, fired, _values(theta), "success")
    apn0 = model.history.version(0)
    (stay,) = probe_stays(apn0, trace, w, conditions["in_P1"])    # the stay before the way back is no probe
    m, went_on = stay
    z = conditions["in_P1"].regions.logits(np.array([[0.25, 0.0]]))[0, 1]
    assert went_on and m == pytest.approx(z, abs=1e-3) and m < w.floor

    practice = Practice(model, tmp_path / "p", PracticeConfig(learn=True, hold_off_every=1), name="c")
    out = practice._probed(trace, model.apn)
    assert out["probe"] and out["held_off"][0]["stays"] == [stay] and out["held_off"][0]["towards"] == "P1"
    # a catch lost to the give-up rule (t5) did not go on; a trial the way back never fired in has no probe
    lost = make_trace(model.apn, fired[:4] + [(200, "t5")], _values(theta[:210]), "failure")
    assert probe_stays(apn0, lost, w, conditions["in_P1"])[0][1] is False
    plain = make_trace(model.apn, [(0, "t0"), (100, "t1"), (250, "t6")], _values(theta[:260]), "success")
    assert probe_stays(apn0, plain, w, conditions["in_P1"]) == []
    assert not practice._probed(plain, model.apn)["probe"]


def test_a_probe_is_no_evidence_for_repair():
    trials = [{"trial": 0, "success": True}, {"trial": 1, "success": False},
              {"trial": 2, "success": False, "probe": True}, {"trial": 3, "success": False}]
    assert PracticeState(trial=4, trials=trials).streak == (0, 2)


def _probes(stays: list) -> dict:
    return {"held_off": [{"transition": "t7", "place": "P2", "towards": "P1", "floor": -0.5, "stays": stays}],
            "probe": True, "explored": True}


def test_the_probes_lower_the_way_backs_floor_in_a_watched_replayable_revision(tmp_path):
    model = _model_with_way_back(tmp_path)
    cfg = PracticeConfig(learn=True, hold_off_every=2, max_trials=100, revert_window=10, exam=True)
    practice = Practice(model, tmp_path / "p", cfg, name="c")
    fired = ["t0", "t1", "t7", "t1", "t7", "t1", "t5"]            # the way back fired again
    trials = [{"trial": i, "success": i == 0, "net_version": 1, "fired": fired} for i in range(4)]
    trials.append({"trial": 9, "success": True, "net_version": 1, "fired": ["t0", "t1", "t7", "t1", "t6"]})
    trials += [{"trial": 4, "success": True, "net_version": 1, "fired": ["t0", "t1", "t6"],
                **_probes([[-2.0, True], [-0.2, True]])},
               {"trial": 5, "success": True, "net_version": 1, "fired": ["t0", "t1", "t6"], **_probes([[-1.5, True]])}]
    state = PracticeState(trial=6, trials=trials)
    practice._lower_floors(state)
    rev = model.history.revisions()[-1]
    assert (rev.operator, rev.target, model.version) == ("set_condition", "t7", 2)
    assert rev.evidence["floor_before"] == -0.5 and rev.evidence["leave_below_logit"] == -2.0
    assert (rev.evidence["stays_below"], rev.evidence["went_on"], rev.evidence["way_success"]) == (2, 2, 1)
    assert state.watch["version"] == 2 and state.tried == ["floor:t7:-2.000"]
    # replayed from the history: the new condition, the same yield to t1, the new floor
    cond = History(model.path / "skill.yaml").versions()[2].transition("t7").condition
    assert cond.unless == ("t1",) and model.conditions()[cond.model].leave_below == -2.0
    assert model.conditions()["in_P1"].leave_below == -0.5            # the old version's condition is kept
    # at -2.0 nothing below the floor went on; and after a revert the same floor is not proposed again
    state.watch = None
    n = len(model.history.revisions())
    practice._lower_floors(state)
    assert len(model.history.revisions()) == n
    _, back = revert(model.apn, 1, model.history.version(1), "the exam lost two trials")
    model.history.record(back)
    practice._lower_floors(state)
    assert model.version == 3 and model.conditions()[model.apn.transition("t7").condition.model].leave_below == -0.5


def test_no_floor_is_lowered_without_enough_trials_that_fired_the_way_back(tmp_path):
    model = _model_with_way_back(tmp_path)
    practice = Practice(model, tmp_path / "p", PracticeConfig(learn=True, hold_off_every=2), name="c")
    trials = [{"trial": i, "success": False, "net_version": 1, "fired": ["t0", "t1", "t7", "t1", "t7"]}
              for i in range(2)]
    trials += [{"trial": 2 + i, "success": False, "net_version": 1, "fired": ["t0", "t1", "t7"]} for i in range(3)]
    trials.append({"trial": 5, "success": True, "net_version": 1, "fired": ["t0", "t1", "t6"],
                   **_probes([[-2.0, True], [-1.5, True], [-1.8, True]])})
    practice._lower_floors(PracticeState(trial=6, trials=trials))
    assert model.version == 1


@pytest.mark.parametrize("name", ["hold_off_floor", "floor_exam"])
@pytest.mark.parametrize("bad", [0.5, float("nan"), True, "deep"])
def test_a_probe_or_examined_floor_must_be_a_logit_at_or_below_zero(name, bad):
    from multiform.errors import InvalidInput
    with pytest.raises(InvalidInput, match=name):
        PracticeConfig(**{name: bad})


def _ended_practice(tmp_path, **config) -> tuple[Practice, PracticeState]:
    """Eight plain trials of the net with its way back t7, the last four successes (the target
    reached); t7 fired in trials 0, 1, 3 and 5, two of which failed."""
    model = _model_with_way_back(tmp_path)
    cfg = PracticeConfig(**{"learn": True, "exam": True, "floor_exam": -4.0, "target_rate": 0.9, "target_window": 4,
                            "success_streak": 10**6, "max_trials": 100, "revert_window": 10, **config})
    back, plain = ["t0", "t1", "t7", "t1", "t6"], ["t0", "t1", "t6"]
    trials = [{"trial": k, "success": k not in (0, 3), "net_version": 1, "fired": back if k in (0, 1, 3, 5) else plain}
              for k in range(8)]
    return Practice(model, tmp_path / "p", cfg, name="c"), PracticeState(trial=8, trials=trials)


def _replay(practice: Practice, state: PracticeState, outcomes: list[bool]) -> None:
    for ok in outcomes:
        draw = practice._exam_draw(state)
        state.trials.append({"trial": state.trial, "draw": draw, "success": ok, "net_version": practice.model.version,
                             "fired": ["t0", "t1", "t7", "t1", "t6"]})
        state.trial += 1
        practice._after_trial(state)


def test_at_its_target_practice_examines_a_deeper_floor_on_the_trials_that_took_the_way_back(tmp_path):
    practice, state = _ended_practice(tmp_path)
    model = practice.model
    practice._after_trial(state)
    assert not state.done and state.floor_examined
    rev = model.history.revisions()[-1]
    assert (rev.operator, rev.target, model.version) == ("set_condition", "t7", 2)
    assert rev.evidence["floor_before"] == -0.5 and rev.evidence["leave_below_logit"] == -4.0
    assert rev.evidence["replayed_trials"] == [0, 1, 3, 5]          # only these can change: t7 fired in them
    assert state.watch["draws"] == [0, 1, 3, 5] and state.watch["before"] == [False, True, False, True]
    # replayable: the revision's condition is the way back with the deeper floor, yielding to t1 as before
    cond = History(model.path / "skill.yaml").versions()[2].transition("t7").condition
    assert cond.unless == ("t1",) and model.conditions()[cond.model].leave_below == -4.0
    # a killed practice resumes the exam where it was
    _replay(practice, state, [True])
    practice.save_state(state)
    state = practice.load_state()
    assert state.floor_examined and state.watch["must_win"] and practice._exam_draw(state) == 1
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
    practice._after_trial(state)
    _replay(practice, state, outcomes)
    rev = practice.model.history.revisions()[-1]
    assert state.done and (rev.operator == "set_condition") == kept
    if not kept:
        assert rev.operator == "revert" and rev.evidence["reverted"] == 2
    t7 = practice.model.apn.transition("t7").condition.model
    assert practice.model.conditions()[t7].leave_below == (-4.0 if kept else -0.5)


def test_failures_during_the_floor_exam_set_off_no_repair(tmp_path):
    practice, state = _ended_practice(tmp_path)
    practice._after_trial(state)
    _replay(practice, state, [False, False, False])
    assert state.watch is not None and [r.operator for r in practice.model.history.revisions()][-1] == "set_condition"


def test_no_floor_exam_where_no_way_back_fired_or_it_is_off(tmp_path):
    practice, state = _ended_practice(tmp_path / "a")
    for t in state.trials:
        t["fired"] = ["t0", "t1", "t6"]
    practice._after_trial(state)
    assert state.done and practice.model.version == 1 and state.stop_reason.startswith("own success rate")
    practice, state = _ended_practice(tmp_path / "b", floor_exam=0.0)
    practice._after_trial(state)
    assert state.done and practice.model.version == 1 and not state.floor_examined


def test_with_no_room_left_for_another_revision_the_floor_is_examined_in_the_trials_that_remain(tmp_path):
    practice, state = _ended_practice(tmp_path, target_rate=0.0, max_trials=11)
    state.trials[5]["success"] = False
    practice._after_trial(state)                 # three trials left: the last three that took the way back
    assert state.watch["draws"] == [1, 3, 5] and state.watch["then_stop"] is None
    _replay(practice, state, [True, True, True])
    assert practice.model.version == 2 and not state.done     # kept (won two); the budget ends practice


def test_the_net_takes_a_held_off_way_back_once_then_only_below_the_probe_floor(tmp_path):
    from multiform.petri.firing import NetRunner
    model = _model_with_way_back(tmp_path)
    conditions = model.conditions()
    held = held_off(conditions, ways_back(model.apn, conditions), -30.0)
    runner = NetRunner(model.apn, ["theta", "omega", "x", "xdot"], held, rng=0)
    t = iter(np.arange(1, 100) * 0.001)
    up, out, far = [0.0, 0.0, 0.0, 0.0], [0.35, 0.0, 0.0, 0.0], [0.6, 0.0, 0.0, 0.0]   # P2 logit ~-13 and -45
    assert runner.tick([np.pi, 0.0, 0.0, 0.0], 0.0) == ["t0"] and runner.tick(up, next(t)) == ["t1"]
    assert runner.tick(out, next(t)) == ["t7"]                   # the first time, as written (floor -0.5)
    assert runner.tick(up, next(t)) == ["t1"]
    assert runner.tick(out, next(t)) == []                       # then held off down to -30
    assert runner.tick(far, next(t)) == ["t7"]
