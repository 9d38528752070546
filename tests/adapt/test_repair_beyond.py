"""Repair beyond the paper's two scenarios: diagnosis that compares the robot with the mentor, the
operators for what it finds (λ, conditions both ways, limits), trials outside the net ignored, and
the practice loop reverting a repair that did not help before trying the next candidate."""

from __future__ import annotations

import json

import numpy as np
import pytest
import yaml

from multiform.adapt.compare import compare_with_mentor, demonstration_findings
from multiform.adapt.diagnosis import Diagnosis, diagnose
from multiform.adapt.mentor import TIMED_LOOSE, mentor_evidence
from multiform.adapt.practice import Practice, PracticeConfig, PracticeState, RevisionRecord, TrialRecord, Trying
from multiform.adapt.repair import candidates, repair
from multiform.demos.episode import Episode, SegmentLabel
from multiform.model import SkillModel
from multiform.petri.revision import set_condition
from multiform.petri.skillfile import load_skill, skill_from_data, skill_to_data

from .synthetic import make_trace


class FakeLearners:
    def __init__(self, mentor=None):
        self.calls = []
        self._mentor = mentor

    def has_switches(self, apn, t):
        return True

    def switch_condition(self, apn, t):
        self.calls.append(("switch", t))
        return f"{t}_switch", {"mentor_switches": 42}

    def region_condition(self, apn, into, away):
        return f"in_{into}", {}

    def outside_condition(self, apn, place, states):
        return f"outside_{place}", {}

    def mentor(self, apn):
        return self._mentor


def edited(**conditions) -> object:
    """The sound pendulum net with some transitions' fields replaced (or added)."""
    d = skill_to_data(load_skill("pendulum"))
    for tid, spec in conditions.items():
        d["transitions"].setdefault(tid, {}).update(spec)
    return skill_from_data(d, "test")


def vals(n, theta=3.0):
    v = np.zeros((n, 6))
    v[:, 0] = theta
    v[:, 4], v[:, 5] = np.sin(v[:, 0]), np.cos(v[:, 0])
    return v


def mentor_episode(seed: int) -> Episode:
    """A mentor's swing-up (θ from 3 to 0.15 rad) switching into t1 near upright, then balancing."""
    n = 300
    theta = np.concatenate([np.full(10, 3.0), np.linspace(3.0, 0.15, 190), np.full(50, 0.1), np.full(50, 0.05)])
    theta = theta + 0.001 * seed
    obs = np.column_stack([theta, np.zeros(n), np.zeros(n), np.zeros(n)])
    tags = np.array(["t0"] * 10 + ["t2"] * 190 + ["t1"] * 50 + ["t3"] * 50)
    labels = [SegmentLabel(0, 10, "t0", True), SegmentLabel(10, 200, "t2", True), SegmentLabel(200, 250, "t1", True),
              SegmentLabel(250, 300, "t3", True)]
    return Episode(obs=obs, actions=np.zeros((n, 1)), transitions=tags, observation_names=("theta", "omega", "x", "xdot"),
                   command_names=("v_cmd",), dt=0.01, seed=seed, labels=labels, outcome="success")


EPISODES = [mentor_episode(k) for k in range(4)]


@pytest.mark.parametrize("t1, hit, loose", [
    ("abs(theta) < 0.3 and abs(omega) < 2.0 and abs(x) < 0.25", 1.0, 0.0),     # the sound condition
    ("abs(theta) < 2.5", 1.0, 0.74),                                            # fires far from any switch
    ("theta == 0 and omega == 0 and x == 0", 0.0, 0.0)])                        # holds at no switch
def test_conditions_are_held_against_where_the_mentor_switched(t1, hit, loose):
    ev = mentor_evidence(edited(t1={"condition": t1}), EPISODES)
    fit = ev.conditions["t1"]
    assert fit.switches == 4 and fit.hit == hit
    assert fit.loose == pytest.approx(loose, abs=0.02)
    assert ev.took_success == {"t0": 4, "t2": 4, "t1": 4, "t3": 4, "t6": 4} and ev.took_failure == {}
    assert ev.stay_seconds == {"P1": pytest.approx(2.0), "P2": pytest.approx(1.0)}


def _loose_failures(apn, k=3, tid="t1"):
    fir = [(0, "t0"), (40, tid), (90, "t5")]
    return [make_trace(apn, fir, vals(100, 1.5), "failure") for _ in range(k)]


def test_a_condition_that_fires_where_the_mentor_never_switched_is_relearned():
    apn = edited(t1={"condition": "abs(theta) < 2.5"})
    mentor = mentor_evidence(apn, EPISODES)
    d = diagnose(apn, _loose_failures(apn), mentor=mentor)
    (f,) = [f for f in d.findings if f.transition == "t1"]
    assert f.kind == "too_loose" and "where the mentor chose not to switch" in f.reason
    fake = FakeLearners(mentor)
    r = repair(apn, d, fake)
    assert r.key == "too_loose:t1" and r.apn.transition("t1").condition.model == "t1_switch"
    assert fake.calls == [("switch", "t1")] and r.revisions[0].evidence["holds_where_mentor_did_not_switch"] > 0.5
    # the sound condition fires where the mentor switched: the same failures find nothing wrong with it
    sound = load_skill("pendulum")
    assert not [f for f in diagnose(sound, _loose_failures(sound), mentor=mentor_evidence(sound, EPISODES)).findings
                if f.transition == "t1"]


def test_a_timed_switch_the_mentors_timing_bears_out_is_not_relearned_for_firing_in_failures():
    """``dwell > 1.5`` holds at every mentor switch (after 1.9 s) and along 5.3 % of the clock where the
    mentor held off: a timed maneuver, held to the timed share (20 %), not the state conditions' 5 %.
    Failures after it fired say the maneuver failed, not that its timing is wrong; a clock far too
    short still is."""
    apn = edited(t1={"condition": "dwell > 1.5"})
    mentor = mentor_evidence(apn, EPISODES)
    assert mentor.conditions["t1"].timed and 0.05 < mentor.conditions["t1"].loose < 0.2
    assert not [f for f in diagnose(apn, _loose_failures(apn), mentor=mentor).findings if f.transition == "t1"]
    apn = edited(t1={"condition": "dwell > 1.2"})
    mentor = mentor_evidence(apn, EPISODES)
    assert [f.kind for f in diagnose(apn, _loose_failures(apn), mentor=mentor).findings if f.transition == "t1"] \
        == ["too_loose"]


def test_a_condition_too_strict_for_the_mentors_switches_is_relearned():
    apn = edited(t1={"condition": "abs(theta) < 0.01 and abs(omega) < 0.01"})   # holds now and then, not never
    mentor = mentor_evidence(apn, EPISODES)
    fir = [(0, "t0")] + [(20 * i, "t2") for i in range(1, 13)] + [(260, "t4")]
    tr = [make_trace(apn, fir, vals(300), "failure", enabled={"t1": 259}, held={"t1": 3}) for _ in range(3)]
    d = diagnose(apn, tr, mentor=mentor)
    assert "t1" not in d.never_held
    (f,) = d.findings
    assert f.kind == "too_strict" and f.evidence["holds_at_mentor_switches"] == 0.0
    assert repair(apn, d, FakeLearners(mentor)).apn.transition("t1").condition.model == "t1_switch"


def test_a_branch_that_only_led_to_failure_gets_lambda_zero():
    apn = edited(t8={"label": "balance early", "in": ["P1"], "out": ["P2"], "law": "balance", "lambda": 1.0,
                     "condition": "abs(theta) < 1.5"})
    mentor = mentor_evidence(apn, EPISODES)                     # the mentor never took t8
    d = diagnose(apn, _loose_failures(apn, tid="t8"), mentor=mentor, succeeded_fired=[["t0", "t1", "t6"]])
    (f,) = [f for f in d.findings if f.kind == "dead_branch"]
    assert f.transition == "t8" and f.evidence["fired_in_failed_trials"] == 3
    r = repair(apn, d, FakeLearners(mentor))
    assert r.key == "dead_branch:t8" and r.revisions[0].operator == "set_lambda"
    assert r.apn.transition("t8").lam == 0.0
    assert sum(r.apn.transition(t).lam for t in ("t1", "t2", "t4", "t8")) == pytest.approx(4.0)
    # a branch that also led to a success is not dead
    d = diagnose(apn, _loose_failures(apn, tid="t8"), mentor=mentor, succeeded_fired=[["t0", "t8", "t6"]])
    assert not [f for f in d.findings if f.kind == "dead_branch"]


def test_a_starved_branch_the_mentor_took_gets_its_weight_back():
    apn = edited(t1={"lambda": 0.0})
    mentor = mentor_evidence(apn, EPISODES)
    fir = [(0, "t0")] + [(20 * i, "t2") for i in range(1, 13)] + [(260, "t4")]
    tr = [make_trace(apn, fir, vals(300, 0.1), "failure", enabled={"t1": 259}, held={"t1": 200}) for _ in range(3)]
    d = diagnose(apn, tr, mentor=mentor)
    assert [f.kind for f in d.findings if f.transition == "t1"] == ["starved"]
    r = repair(apn, d, FakeLearners(mentor))
    assert r.key == "starved:t1" and r.apn.transition("t1").lam == pytest.approx(2.0 / 3.0)


def test_a_repeat_limit_that_ends_trials_the_mentor_kept_going_is_moved():
    apn = edited(t4={"condition": "fires_t2 >= 1"})
    mentor = mentor_evidence(apn, EPISODES)                     # the mentor's swing-ups lasted 2 s
    fir = [(0, "t0"), (50, "t2"), (51, "t4")]                   # the robot gave up after 0.51 s
    tr = [make_trace(apn, fir, vals(60), "failure", enabled={"t1": 50}, held={"t1": 0}) for _ in range(3)]
    d = diagnose(apn, tr, mentor=mentor)
    (f,) = [f for f in d.findings if f.kind == "limit_too_tight"]
    assert f.transition == "t4" and f.condition == "fires_t2 >= 8"       # ceil(1 * 2.0 * 2.0 / 0.51)
    # t1 never held, but it holds where the mentor switched: the trials ended before it could
    assert "t1" in d.never_held and [c.key for c in candidates(apn, d, FakeLearners(mentor))] == ["limit_too_tight:t4"]
    r = repair(apn, d, FakeLearners(mentor))
    assert r.key == "limit_too_tight:t4" and str(r.apn.transition("t4").condition) == "fires_t2 >= 8"


def _fell_once(seed: int) -> Episode:
    """A mentor's demonstration that lost the balance once, went back to swinging up (t7) and succeeded."""
    ep = mentor_episode(seed)
    tags = np.array(["t0"] * 10 + ["t2"] * 90 + ["t1"] * 40 + ["t7"] * 60 + ["t1"] * 50 + ["t3"] * 50)
    labels = [SegmentLabel(s, e, t, True) for s, e, t in ((0, 10, "t0"), (10, 100, "t2"), (100, 140, "t1"),
                                                          (140, 200, "t7"), (200, 250, "t1"), (250, 300, "t3"))]
    return Episode(obs=ep.obs, actions=ep.actions, transitions=tags, observation_names=ep.observation_names,
                   command_names=ep.command_names, dt=ep.dt, seed=seed, labels=labels, outcome="success")


def test_a_limit_on_a_count_of_events_moves_to_the_mentors_count_never_by_a_ratio_of_stays():
    """``fires_t7 >= 1`` (one fall ends the trial) held a moment after the fall's way back: the count is
    compared with how often the mentor's successes fell, not scaled by the short stay since the fall."""
    apn = edited(t7={"label": "way back", "in": ["P2"], "out": ["P1"], "law": "swing_up", "condition": "abs(theta) > 0.8"},
                 t8={"label": "fell once", "in": ["P1"], "out": ["fail"], "condition": "fires_t7 >= 1"})
    fir = [(0, "t0"), (40, "t1"), (60, "t7"), (61, "t8")]
    tr = [make_trace(apn, fir, vals(70), "failure") for _ in range(3)]
    mentor = mentor_evidence(apn, [_fell_once(k) for k in range(2)] + EPISODES[:2])   # it fell at most once
    (f,) = [f for f in diagnose(apn, tr, mentor=mentor).findings if f.kind == "limit_too_tight"]
    assert f.transition == "t8" and f.condition == "fires_t7 >= 2"
    assert f.evidence["examples"][0]["mentor_most_in_a_success"] == 1
    # the mentor never fell and succeeded: one fall is a real failure, the limit stays
    mentor = mentor_evidence(apn, EPISODES)
    assert not [f for f in diagnose(apn, tr, mentor=mentor).findings if f.kind == "limit_too_tight"]


def test_a_fall_angle_inside_what_the_mentor_balanced_through_is_moved_beyond_it():
    apn = edited(t5={"condition": "abs(theta) > 0.08 or fires_t3 >= 10"})
    mentor = mentor_evidence(apn, EPISODES)                     # the mentor balanced at up to 0.103 rad
    fir = [(0, "t0"), (40, "t1"), (90, "t5")]
    tr = [make_trace(apn, fir, vals(100, 0.09), "failure") for _ in range(3)]
    (f,) = [f for f in diagnose(apn, tr, mentor=mentor).findings if f.kind == "limit_too_tight"]
    assert f.condition == "(abs(theta) > 0.1133) or (fires_t3 >= 10)"
    # a fall far beyond anything the mentor balanced through is a real fall: the limit stays
    tr = [make_trace(apn, fir, vals(100, 0.9), "failure") for _ in range(3)]
    assert not [f for f in diagnose(apn, tr, mentor=mentor).findings if f.kind == "limit_too_tight"]


def test_a_stop_asking_for_longer_than_the_mentor_ever_held_is_moved_to_the_mentors_timing():
    apn = edited(t6={"condition": "dwell > 40 and abs(theta) < 0.25"})
    mentor = mentor_evidence(apn, EPISODES)
    tr = [make_trace(apn, [(0, "t0"), (40, "t1")], vals(400, 0.05), "timeout", enabled={"t6": 360}, held={"t6": 0})
          for _ in range(3)]
    d = diagnose(apn, tr, mentor=mentor)
    (f,) = d.findings
    assert f.kind == "stop_too_late" and f.condition == "(dwell > 1) and (abs(theta) < 0.25)"
    # it never held, but its clock is what is wrong: not relearned from switches (which would stop early)
    assert "t6" in d.never_held and [c.key for c in candidates(apn, d, FakeLearners(mentor))] == ["stop_too_late:t6"]


def test_trials_that_ended_outside_the_net_are_no_evidence():
    apn = edited(t4={"condition": "fires_t2 >= 1"})
    mentor = mentor_evidence(apn, EPISODES)
    fir = [(0, "t0"), (50, "t2"), (51, "t4")]
    tr = [make_trace(apn, fir, vals(60), outcome) for outcome in ("fault", "diverged")]
    d = diagnose(apn, tr, mentor=mentor)
    assert d.trials == 0 and d.failures == 0 and d.findings == []
    assert candidates(apn, d, FakeLearners(mentor)) == []
    state = PracticeState(trials=[TrialRecord(trial=0, success=True), TrialRecord(trial=1, success=False, evidence=False),
                                  TrialRecord(trial=2, success=True)])
    assert state.streak == (2, 0)


def test_a_sound_net_gives_no_finding_on_trials_that_failed_for_other_reasons():
    apn = load_skill("pendulum")
    mentor = mentor_evidence(apn, EPISODES)
    fir = [(0, "t0"), (40, "t1"), (90, "t5")]                 # a real fall (0.9 rad), as after a push
    tr = [make_trace(apn, fir, vals(100, 0.9), "failure") for _ in range(3)]
    assert compare_with_mentor(apn, tr, mentor, [["t0", "t2", "t1", "t6"]]) == []


# -- the practice loop: revert what did not help, then the next candidate --------------------------

def _practice(tmp_path, helped: bool):
    d = skill_to_data(load_skill("pendulum"))
    d["transitions"]["t8"] = {"label": "balance early", "in": ["P1"], "out": ["P2"], "law": "balance",
                              "lambda": 1.0, "condition": "abs(theta) < 1.5"}
    skill = tmp_path / "faulty.yaml"
    skill.write_text(yaml.safe_dump(d))
    model = SkillModel.create(tmp_path / "model", skill)
    apn = model.apn
    mentor = mentor_evidence(apn, EPISODES)
    practice = Practice(model, tmp_path / "p", PracticeConfig(), name="a")
    practice.ctx.learners = FakeLearners(mentor)
    # an earlier candidate (a limit move on t5) is on trial since trial 2
    new, rev = set_condition(apn, "t5", "abs(theta) > 0.9 or fires_t3 >= 10", "test", {"candidate": "limit_too_tight:t5"})
    model.history.record(rev)
    trials = []
    for k in range(6):
        ok = helped and k == 3
        fir = [(0, "t0"), (40, "t1"), (90, "t6")] if ok else [(0, "t0"), (40, "t8"), (90, "t5")]
        tr = make_trace(apn, fir, vals(100, 1.0), "success" if ok else "failure")
        if not ok:
            tr.save(practice.trace_path(k))
        trials.append(TrialRecord(trial=k, success=ok, fired=tr.fired()))
    state = PracticeState(trial=6, trials=trials, failed_since_repair=[k for k in (3, 4, 5) if not trials[k].success],
                          tried=["limit_too_tight:t5"],
                          revisions=[RevisionRecord(version=1, operator="set_condition", target="t5", after_trial=2)],
                          trying=Trying(key="limit_too_tight:t5", before_version=0, version=1, after_trial=2,
                                        visited=["P0", "P1", "P2"], failed=[0, 1, 2]))
    return model, practice, state


def test_a_repair_that_did_not_help_is_reverted_and_the_next_candidate_tried(tmp_path):
    model, practice, state = _practice(tmp_path, helped=False)
    practice.repairs.repair(state)
    ops = [(r.operator, r.target) for r in model.history.revisions()]
    assert ops == [("set_condition", "t5"), ("revert", "version 0"), ("set_lambda", "t8")]
    assert "limit_too_tight:t5 did not help" in model.history.revisions()[1].reason
    net = model.apn
    assert str(net.transition("t5").condition) == "abs(theta) > 0.8 or fires_t3 >= 10"    # back as written
    assert net.transition("t8").lam == 0.0
    assert state.tried == ["limit_too_tight:t5", "dead_branch:t8"] and state.trying.key == "dead_branch:t8"
    assert state.trying.before_version == 2 and state.trying.version == 3


def test_a_repair_that_helped_stays_and_the_next_one_builds_on_it(tmp_path):
    model, practice, state = _practice(tmp_path, helped=True)
    practice.repairs.repair(state)
    ops = [r.operator for r in model.history.revisions()]
    assert ops == ["set_condition", "set_lambda"]
    assert str(model.apn.transition("t5").condition) == "abs(theta) > 0.9 or fires_t3 >= 10"


def test_a_candidate_is_never_tried_twice(tmp_path):
    model, practice, state = _practice(tmp_path, helped=False)
    state.tried.append("dead_branch:t8")
    practice.repairs.repair(state)
    assert [r.operator for r in model.history.revisions()] == ["set_condition", "revert"]
    assert state.revisions[-1].operator == "none" and "dead_branch:t8" in state.revisions[-1].reason


def test_a_stop_with_no_weight_is_starved_though_the_mentor_never_tagged_it():
    """The mentor's demonstrations end balanced without tagging the stop t6: each successful one that
    ends in P2 counts as taking it."""
    apn = edited(t6={"lambda": 0.0})
    mentor = mentor_evidence(apn, EPISODES)
    tr = [make_trace(apn, [(0, "t0"), (40, "t1")], vals(400, 0.05), "timeout", enabled={"t6": 360}, held={"t6": 300})
          for _ in range(3)]
    d = diagnose(apn, tr, mentor=mentor)
    assert ("starved", "t6") in [(f.kind, f.transition) for f in d.findings]
    # λ first: the least change to the mentor's definition (the stop's 5.5 s also exceeds these
    # short demonstrations' 1 s, a limit candidate for later)
    assert [c.key for c in candidates(apn, d, FakeLearners(mentor))] == ["starved:t6", "stop_too_late:t6"]
    assert repair(apn, d, FakeLearners(mentor)).apn.transition("t6").lam == pytest.approx(2.0 / 3.0)   # t3, t5, t6


def test_a_clock_limit_is_read_as_the_net_saw_it_before_firing():
    """The recorded row of a firing tick holds the clocks after the firing; the limit is judged on
    the clock the condition read."""
    apn = edited(t5={"condition": "dwell > 0.15"})
    mentor = mentor_evidence(apn, EPISODES)                      # the mentor's balance lasted 1 s
    tr = []
    for _ in range(3):
        t = make_trace(apn, [(0, "t0"), (40, "t1"), (70, "t5")], vals(71, 0.05), "failure")
        t.dwell[40:70, apn.place_ids.index("P2")] = np.arange(30) * t.dt
        tr.append(t)
    (f,) = [f for f in diagnose(apn, tr, mentor=mentor).findings if f.kind == "limit_too_tight"]
    assert f.condition == "dwell > 1"                            # 0.15 * 2.0 * 1.0 s / 0.3 s


def test_which_lambdas_are_exhausted_is_read_off_the_revisions():
    def rev(operator: str, target: str) -> RevisionRecord:
        return RevisionRecord(version=1, operator=operator, target=target, after_trial=0)
    state = PracticeState(revisions=[rev("set_lambda", "t3"), rev("refit_law", "balance"), rev("set_lambda", "t4")])
    assert state.lambda_exhausted == []                        # each lowered once
    state.revisions.append(rev("set_lambda", "t3"))
    assert state.lambda_exhausted == ["t3"]                    # lowered again: Λ did not cure it
    state.revisions += [rev("revert", "version 2"), rev("none", "")]
    assert state.lambda_exhausted == ["t3"]                    # reverts and repairs that found nothing change nothing
    state.revisions.append(rev("set_condition", "t1"))
    assert state.lambda_exhausted == []                        # another kind of repair: Λ may help again
    state.revisions.append(rev("set_lambda", "t4"))
    assert state.lambda_exhausted == ["t4"]                    # its earlier lowering still counts


def test_a_practice_state_saved_with_lambda_exhausted_still_loads(tmp_path):
    model, practice, state = _practice(tmp_path, helped=False)
    practice.repairs.repair(state)                                    # a revert, then λ(t8) set to 0
    practice.save_state(state)
    data = json.loads(practice.state_path.read_text())
    assert "lambda_exhausted" not in data
    data["lambda_exhausted"] = ["t3"]                          # a file written when the state kept the list
    practice.state_path.write_text(json.dumps(data))
    loaded = practice.load_state()
    assert loaded.revisions == state.revisions and loaded.tried == state.tried
    assert loaded.lambda_exhausted == []                       # read off the revisions, not the file


# -- before the first trial: what the demonstrations alone show --------------------------------------

def test_a_switch_on_a_clock_the_mentors_timing_bears_out_is_a_timed_maneuver():
    """t1 on its place's clock alone, a little before the mentor switched (its swing-ups last 1.9 s):
    held against the durations of the mentor's segments, it holds at every switch and where the
    mentor held off only near the end of its swing-ups, so nothing is found before a trial; a clock
    far earlier than the mentor's switches still switches at once (the test below)."""
    apn = edited(t1={"condition": "dwell > 1.5"})
    ev = mentor_evidence(apn, EPISODES)
    fit = ev.conditions["t1"]
    assert fit.switches == 4 and fit.hit == 1.0 and 0.0 < fit.loose < TIMED_LOOSE and fit.negatives > 0
    assert not [f for f in demonstration_findings(apn, ev) if f.transition == "t1"]


@pytest.mark.parametrize("t1", ["true", "dwell > 0.1", "abs(theta) >= 0"])
def test_a_switch_condition_that_holds_wherever_the_mentor_held_off_is_found_before_any_trial(t1):
    """Written with no bound to move (true, a clock alone, a bound nothing crosses), it switches at
    once; the mentor's switches show where it should."""
    apn = edited(t1={"condition": t1})
    ev = mentor_evidence(apn, EPISODES)
    fit = ev.conditions["t1"]
    assert fit.loose == pytest.approx(1.0) and fit.negatives > 0
    (f,) = demonstration_findings(apn, ev)
    assert (f.kind, f.transition) == ("too_loose", "t1") and "would switch at once" in f.reason
    fake = FakeLearners(ev)
    assert repair(apn, Diagnosis(trials=0, failures=0, findings=[f]), fake).apn.transition("t1").condition.model \
        == "t1_switch"
    # the same condition found from failures too: the robot fired it in every failed trial
    d = diagnose(apn, _loose_failures(apn), mentor=ev)
    assert ("too_loose", "t1") in [(x.kind, x.transition) for x in d.findings]


def test_no_weight_on_a_maneuver_the_mentor_took_is_found_before_any_trial():
    apn = edited(t1={"lambda": 0.0})
    (f,) = demonstration_findings(apn, mentor_evidence(apn, EPISODES))
    assert (f.kind, f.transition) == ("starved", "t1")
    fixed = repair(apn, Diagnosis(trials=0, failures=0, findings=[f]), FakeLearners()).apn
    assert fixed.transition("t1").lam > 0


def test_the_sound_definition_shows_nothing_wrong_before_any_trial():
    for name in ("pendulum", "pendulum_strict"):
        apn = load_skill(name)
        assert demonstration_findings(apn, mentor_evidence(apn, EPISODES)) == []


def test_practice_fixes_what_the_demonstrations_show_before_its_first_trial(tmp_path):
    d = skill_to_data(load_skill("pendulum"))
    d["transitions"]["t1"]["condition"] = "true"
    skill = tmp_path / "loose.yaml"
    skill.write_text(yaml.safe_dump(d))
    model = SkillModel.create(tmp_path / "model", skill)
    practice = Practice(model, tmp_path / "p", PracticeConfig(), name="a")
    practice.ctx.learners = FakeLearners(mentor_evidence(model.apn, EPISODES))
    state = PracticeState()
    practice.repairs.check_definition(state)
    (rev,) = model.history.revisions()
    assert (rev.operator, rev.target, rev.evidence["candidate"]) == ("set_condition", "t1", "demonstrations:too_loose:t1")
    assert state.checked and state.revisions[0].after_trial == -1 and state.tried == []


# -- a way back is judged by the failures that reached the place it leaves --------------------------

def _way_back_on_trial(tmp_path, since):
    """The sound net with a way back t7 (P2 -> P1) added after three falls from P2 (t5), and three
    failures since it, each fired as ``since``."""
    from multiform.petri.revision import add_transition
    skill = tmp_path / "sound.yaml"
    skill.write_text(yaml.safe_dump(skill_to_data(load_skill("pendulum"))))
    model = SkillModel.create(tmp_path / "model", skill)
    apn = model.apn
    practice = Practice(model, tmp_path / "p", PracticeConfig(), name="b")
    practice.ctx.learners = FakeLearners(mentor_evidence(apn, EPISODES))
    spec = {"label": "back to swung up", "in": ["P2"], "out": ["P1"], "law": "swing_up", "lambda": 1.0,
            "condition": "abs(theta) > 1.0"}
    _, rev = add_transition(apn, "t7", spec, "test", {"candidate": "back:P2>P1"})
    model.history.record(rev)
    fell = [(0, "t0"), (40, "t1"), (90, "t5")]
    trials = []
    for k in range(6):
        fir = fell if k < 3 else since
        tr = make_trace(model.apn if k >= 3 else apn, fir, vals(300, 0.02), "failure")
        tr.save(practice.trace_path(k))
        trials.append(TrialRecord(trial=k, success=False, fired=tr.fired()))
    state = PracticeState(trial=6, trials=trials, failed_since_repair=[3, 4, 5], tried=["back:P2>P1"],
                          revisions=[RevisionRecord(version=1, operator="add_transition", target="t7", after_trial=2)],
                          trying=Trying(key="back:P2>P1", before_version=0, version=1, after_trial=2,
                                        visited=["P0", "P1", "P2"], failed=[0, 1, 2]))
    practice.repairs.repair(state)
    return model


@pytest.mark.parametrize("since, stays", [
    ([(0, "t0")] + [(20 * (k + 1), "t2") for k in range(12)] + [(290, "t4")], True),   # never caught: no evidence
    ([(0, "t0"), (40, "t1"), (90, "t7")] + [(100 + 10 * k, "t2") for k in range(12)] + [(290, "t4")], True),  # took it
    ([(0, "t0"), (40, "t1"), (90, "t5")], False),                                       # fell from P2 as before
])
def test_a_way_back_is_refuted_only_by_failures_that_reached_its_place_and_ended_as_before(tmp_path, since, stays):
    model = _way_back_on_trial(tmp_path, since)
    ops = [(r.operator, r.target) for r in model.history.revisions()]
    assert ops[0] == ("add_transition", "t7")
    assert (("revert", "version 0") not in ops) == stays
    assert ("t7" in model.apn.transition_ids) == stays
