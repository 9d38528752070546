"""``state.json``: typed records written as plain JSON, read back checked; older files still load."""

from __future__ import annotations

import json

import pytest

from multiform.adapt.practice import (MentorGrade, PracticeState, RevisionRecord, Takeover, TrialRecord, Watch,
                                      state_from_json, state_to_json)
from multiform.errors import InvalidInput


def _state() -> PracticeState:
    grade = MentorGrade(trial=2, stays=3, agree=2, mentor_success=1, robot_success=2,
                        revised={"P1": {"segments": 12, "cv_score": 0.9, "kernel": "rbf"}})
    trials = [TrialRecord(trial=0, success=False, seed=11, outcome="failure", fired=["t0", "t2"], duration=3.5),
              TrialRecord(trial=1, success=True, explored=True, judge_score=0.8, judge_places={"P1": 0.8}),
              TrialRecord(trial=2, success=False, draw=0, mentor=grade, takeover=Takeover(trial=2, tick=1500, time=1.5,
                                                                                         samples=900, outcome="success"),
                          evidence=False, own_segments=1)]
    return PracticeState(trial=3, trials=trials, failed_since_repair=[0],
                         revisions=[RevisionRecord(version=1, operator="refit_law", target="balance", after_trial=1,
                                                   diagnosis={"refit": {"n": 10}})],
                         mentor_graded=[grade], takeovers=[trials[2].takeover],
                         watch=Watch(before_version=0, version=1, after_trial=1, before=[False, True], draws=[0, 1]),
                         tried=["starved:t6"], last_refit_trial=1, checked=True)


def test_a_state_round_trips_through_json():
    state = _state()
    data = json.loads(json.dumps(state_to_json(state)))
    assert state_from_json(data, "state.json") == state
    # what is at its default is left out of a trial's entry
    assert set(data["trials"][0]) >= {"trial", "success", "seed"} and "draw" not in data["trials"][0]
    assert data["trials"][1]["explored"] is True and "evidence" not in data["trials"][1]


def test_an_older_file_loads_its_derived_and_retired_entries_ignored():
    data = state_to_json(_state())
    data["lambda_exhausted"] = ["t3"]
    data["format_version"] = 1
    data["trials"][1].update(probe=True, held_off=[{"transition": "t7", "stays": []}])
    state = state_from_json(data, "state.json")
    assert state.trials[1].evidence is False          # a trial that held a way back off was no evidence
    assert state.lambda_exhausted == []


@pytest.mark.parametrize("edit, element", [
    (lambda d: d.update(trial=-5), "trial"),
    (lambda d: d.update(trial=7), "trial"),
    (lambda d: d.update(trial="3"), "trial"),
    (lambda d: d["trials"][1].update(success="yes"), "trials[1].success"),
    (lambda d: d["trials"][1].update(trial=4), "trials[1].trial"),
    (lambda d: d["trials"][0].update(duration=float("nan")), "trials[0].duration"),
    (lambda d: d["trials"][0].update(fired="t0"), "trials[0].fired"),
    (lambda d: d["trials"][2]["mentor"].update(stays=[1]), "trials[2].mentor.stays"),
    (lambda d: d.update(watch={"version": 1}), "watch"),
    (lambda d: d.update(revisions=[{"version": "one", "operator": "x"}]), "revisions[0].version"),
    (lambda d: d.update(failed_since_repair=[9]), "failed_since_repair"),
    (lambda d: d.update(done=1), "done"),
])
def test_a_damaged_state_is_refused_naming_the_file_and_the_entry(edit, element):
    data = state_to_json(_state())
    edit(data)
    with pytest.raises(InvalidInput) as err:
        state_from_json(data, "p/state.json")
    (problem,) = err.value.problems
    assert problem.file == "p/state.json" and problem.element == element


def test_a_state_that_is_not_an_object_is_refused():
    with pytest.raises(InvalidInput, match="not a practice state"):
        state_from_json([1, 2], "state.json")
