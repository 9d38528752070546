"""Repairs of a wrong law, a missing transition the mentor's tags name, and a missing stop: the
diagnosis rules on small hand-made demonstrations, the operators, and the practice loop reverting
such a repair when it does not help."""

from __future__ import annotations

import numpy as np
import pytest
import yaml

from multiform.adapt.diagnosis import diagnose
from multiform.adapt.mentor import law_errors, mentor_evidence
from multiform.adapt.practice import Practice, PracticeConfig, PracticeState, TrialRecord
from multiform.adapt.repair import candidates, repair
from multiform.demos.episode import Episode, SegmentLabel
from multiform.learn.gp import GPLaw
from multiform.learn.views import law_data
from multiform.model import SkillModel
from multiform.petri.guard import parse_guard
from multiform.petri.revision import History
from multiform.petri.skillfile import load_skill, skill_from_data, skill_to_data

from .synthetic import make_trace
from .test_repair_beyond import FakeLearners, vals

DT = 0.01


def _net(drop=(), **changes):
    d = skill_to_data(load_skill("pendulum"))
    for t in drop:
        del d["transitions"][t]
    for tid, spec in changes.items():
        d["transitions"][tid].update(spec)
    return skill_from_data(d, "test")


def _episode(seed: int) -> Episode:
    """A mentor's swing-up (command a function of the swing) switching into t1 near upright, then
    balancing (command a feedback on θ and ω) until the demonstration ends, balanced."""
    rng = np.random.default_rng(seed)
    n_sw, n_c, n_b = 200, 60, 140
    theta = np.concatenate([np.linspace(3.0, 0.3, n_sw) + 0.05 * np.sin(np.arange(n_sw) / 7),
                            0.3 * np.exp(-np.arange(n_c) / 20) * np.cos(np.arange(n_c) / 4),
                            0.03 * np.sin(np.arange(n_b) / 9 + seed)]) + 0.01 * rng.standard_normal(n_sw + n_c + n_b)
    omega = np.gradient(theta, DT)
    x = 0.05 * np.sin(np.arange(len(theta)) / 30 + seed)
    lag = int(round(0.06 / DT))                   # balance answers the state one reaction time before
    fb = np.roll(3.0 * theta + 0.1 * omega, lag)
    v = np.where(np.arange(len(theta)) < n_sw, 0.8 * np.sin(theta) * np.cos(theta), fb)
    obs = np.column_stack([theta, omega, x, np.gradient(x, DT)])
    tags = np.array(["t2"] * n_sw + ["t1"] * n_c + ["t3"] * n_b)
    labels = [SegmentLabel(0, n_sw, "t2", True), SegmentLabel(n_sw, n_sw + n_c, "t1", True),
              SegmentLabel(n_sw + n_c, len(theta), "t3", True)]
    return Episode(obs=obs, actions=v[:, None], transitions=tags, observation_names=("theta", "omega", "x", "xdot"),
                   command_names=("v_cmd",), dt=DT, seed=seed, labels=labels, outcome="success")


EPISODES = [_episode(k) for k in range(5)]


@pytest.fixture(scope="module")
def laws():
    """The two laws fitted on the sound net's segments of the demonstrations."""
    apn = load_skill("pendulum")
    out = {}
    for name, spec in apn.laws.items():
        d = law_data(apn, EPISODES, name)
        out[name] = GPLaw(n_hyper=300, n_restarts=0, max_iter=60, input_names=spec.inputs, output_names=spec.outputs,
                          mean=spec.mean).fit(d.X, d.Y)
    return out


def _evidence(apn, laws):
    ev = mentor_evidence(apn, EPISODES)
    ev.laws = laws
    return ev


def _fell_after(apn, tid="t1", k=3):
    """Failed trials: swung up, fired ``tid`` into P2, then fell there (t5)."""
    return [make_trace(apn, [(0, "t0"), (40, tid), (90, "t5")], vals(100, 0.9), "failure") for _ in range(k)]


def test_the_law_that_explains_the_mentors_segments_is_found_held_out(laws):
    wrong = _net(t1={"law": "swing_up"})
    err = law_errors(wrong, EPISODES, "t1", laws)
    # swing_up is solved without t1's samples (it is trained on them in a net where t1 runs it)
    assert err["balance"] < 0.5 < err["swing_up"]
    # t3's samples are the only ones balance has in this net: it has nothing left to be solved on
    assert set(law_errors(wrong, EPISODES, "t3", laws)) == {"swing_up"}


def test_a_transition_whose_stays_fail_and_whose_segments_another_law_explains_gets_that_law(tmp_path, laws):
    wrong = _net(t1={"law": "swing_up"})
    mentor = _evidence(wrong, laws)
    d = diagnose(wrong, _fell_after(wrong), mentor=mentor)
    (f,) = [f for f in d.findings if f.kind == "wrong_law"]
    assert f.transition == "t1" and f.law == "balance" and f.evidence["ended_after_it"] == 3
    keys = [c.key for c in candidates(wrong, d, FakeLearners(mentor))]
    assert "wrong_law:t1>balance" in keys
    stages = [c.stage for c in candidates(wrong, d, FakeLearners(mentor))]
    assert stages == sorted(stages, key=("lambda", "condition", "limit", "law", "structure").index)
    r = repair(wrong, d, FakeLearners(mentor), skip=frozenset(k for k in keys if k != "wrong_law:t1>balance"))
    (rev,) = r.revisions
    assert rev.operator == "set_law" and r.apn.transition("t1").law == "balance"
    assert rev.evidence["heldout_nrmse"]["balance"] < rev.evidence["heldout_nrmse"]["swing_up"]
    # recorded, the revision replays from the definition as written
    skill = tmp_path / "wrong.yaml"
    skill.write_text(yaml.safe_dump(skill_to_data(wrong)))
    h = History(skill)
    h.record(rev)
    assert h.latest().transition("t1").law == "balance" and h.version(0).transition("t1").law == "swing_up"
    # the sound net fails the same way (a push) with nothing wrong with its laws
    sound = load_skill("pendulum")
    assert not [f for f in diagnose(sound, _fell_after(sound), mentor=_evidence(sound, laws)).findings
                if f.kind == "wrong_law"]


def test_a_transition_the_mentors_tags_name_and_the_net_lacks_is_put_back(laws):
    apn = _net(drop=("t1",))
    mentor = _evidence(apn, laws)
    (m,) = mentor.missing.values()
    assert (m.tag, m.inputs, m.outputs, m.took_success) == ("t1", ("P1",), ("P2",), 5)
    # the robot swung up and gave up in P1 every time: it had no way on
    fir = [(0, "t0")] + [(20 * i, "t2") for i in range(1, 13)] + [(260, "t4")]
    d = diagnose(apn, [make_trace(apn, fir, vals(300, 0.1), "failure") for _ in range(3)], mentor=mentor)
    (f,) = [f for f in d.findings if f.kind == "missing_transition"]
    assert f.transition == "t1" and f.spec == {"in": ["P1"], "out": ["P2"]}
    cands = candidates(apn, d, FakeLearners(mentor))
    assert cands[-1].key == "missing_transition:t1" and cands[-1].stage == "structure"
    fake = FakeLearners(mentor)
    r = repair(apn, d, fake, skip=frozenset(c.key for c in cands[:-1]))
    (rev,) = r.revisions
    t1 = r.apn.transition("t1")
    assert rev.operator == "add_transition" and set(t1.inputs) == {"P1"} and set(t1.outputs) == {"P2"}
    assert t1.law == "balance" and t1.condition.model == "t1_switch" and fake.calls == [("switch", "t1")]
    assert rev.evidence["heldout_nrmse"]["balance"] < rev.evidence["heldout_nrmse"]["swing_up"]
    # trials that ended elsewhere (a fall in P2) do not call for it
    d = diagnose(apn, _fell_after(apn, tid="t2"), mentor=mentor)
    assert not [f for f in d.findings if f.kind == "missing_transition"]


def test_a_missing_stop_is_put_back_where_and_when_the_mentors_demonstrations_ended():
    apn = _net(drop=("t6",))
    mentor = mentor_evidence(apn, EPISODES)
    end = mentor.endings["P2"]
    assert end.episodes == 5 and end.shortest_stay == pytest.approx(2.0)
    balanced = vals(400, 0.02)
    trials = [make_trace(apn, [(0, "t0"), (40, "t1")], balanced, "timeout") for _ in range(3)]
    d = diagnose(apn, trials, mentor=mentor)
    (f,) = [f for f in d.findings if f.kind == "missing_stop"]
    assert f.spec == {"in": ["P2"], "out": ["done"]} and f.condition.startswith("dwell > 2 and theta > ")
    r = repair(apn, d, FakeLearners(mentor))
    assert r.key == "missing_stop:P2"
    (stop,) = [t for t in r.apn.transitions if "done" in t.outputs]
    assert set(stop.inputs) == {"P2"} and stop.id == f.transition
    g = parse_guard(f.condition)
    held = {"dwell": np.array([2.5, 1.0, 2.5]), "theta": np.array([0.02, 0.02, 0.9]), "omega": np.zeros(3)}
    assert g.evaluate_arrays(held).astype(bool).tolist() == [True, False, False]   # held long enough, upright
    # trials that ended in P2 before holding it as long as the mentor did: not a missing stop
    short = [make_trace(apn, [(0, "t0"), (40, "t1")], vals(100, 0.02), "timeout") for _ in range(3)]
    assert not [f for f in diagnose(apn, short, mentor=mentor).findings if f.kind == "missing_stop"]
    # a net with its stop has nothing missing
    sound = load_skill("pendulum")
    assert not [f for f in diagnose(sound, trials, mentor=mentor_evidence(sound, EPISODES)).findings
                if f.kind in ("missing_stop", "missing_transition")]


def test_a_law_change_that_did_not_help_is_reverted_and_the_next_candidate_tried(tmp_path, laws):
    d = skill_to_data(load_skill("pendulum"))
    d["transitions"]["t1"]["law"] = "swing_up"
    del d["transitions"]["t6"]
    skill = tmp_path / "faulty.yaml"
    skill.write_text(yaml.safe_dump(d))
    model = SkillModel.create(tmp_path / "model", skill)
    apn = model.apn
    mentor = _evidence(apn, laws)
    practice = Practice(model, tmp_path / "p", PracticeConfig(), name="a")
    practice.ctx.learners = FakeLearners(mentor)
    fell = [(0, "t0"), (40, "t1"), (290, "t5")]
    trials = []
    for k in range(3):
        tr = make_trace(apn, fell, vals(300, 0.02), "failure")
        tr.save(practice.trace_path(k))
        trials.append(TrialRecord(trial=k, success=False, fired=tr.fired()))
    # the condition candidates before it (least change first) were tried already
    keys = [c.key for c in candidates(apn, diagnose(apn, [make_trace(apn, fell, vals(300, 0.02), "failure")] * 3,
                                                    mentor=mentor), practice.ctx.learners)]
    earlier = keys[:keys.index("wrong_law:t1>balance")]
    state = PracticeState(trial=3, trials=trials, failed_since_repair=[0, 1, 2], tried=list(earlier))
    practice.repairs.repair(state)
    assert state.trying.key == "wrong_law:t1>balance" and model.apn.transition("t1").law == "balance"
    for k in range(3, 6):                         # it did not help: the same falls
        tr = make_trace(model.apn, fell, vals(300, 0.02), "failure")
        tr.save(practice.trace_path(k))
        trials.append(TrialRecord(trial=k, success=False, fired=tr.fired()))
    state.trial, state.failed_since_repair = 6, [3, 4, 5]
    practice.repairs.repair(state)
    ops = [(r.operator, r.target) for r in model.history.revisions()]
    assert ops[0] == ("set_law", "t1") and ops[1] == ("revert", "version 0") and ops[2][0] == "add_transition"
    assert "wrong_law:t1>balance did not help" in model.history.revisions()[1].reason
    assert model.apn.transition("t1").law == "swing_up"                 # back as written
    assert state.tried == earlier + ["wrong_law:t1>balance", "missing_stop:P2"]



def test_a_tagged_stop_the_net_lacks_is_put_back_timed_by_the_mentors_holds():
    """A stop ends the trial: the mentor stopped once the place had been held long enough, which a
    condition learned from states alone cannot see, so the stop the tags name is timed."""
    from dataclasses import replace
    eps = []
    for ep in EPISODES:
        n = ep.num_samples
        tags = ep.transitions.copy()
        tags[n - 10:] = "t6"                                  # the mentor's stop, tagged
        eps.append(replace(ep, transitions=tags, labels=ep.labels[:-1] + [
            SegmentLabel(ep.labels[-1].start, n - 10, "t3", True), SegmentLabel(n - 10, n, "t6", True)]))
    apn = _net(drop=("t6",))
    mentor = mentor_evidence(apn, eps)
    assert mentor.missing["t6"].outputs == ("done",) and mentor.endings["P2"].shortest_stay == pytest.approx(1.9)
    trials = [make_trace(apn, [(0, "t0"), (40, "t1")], vals(400, 0.02), "timeout") for _ in range(3)]
    d = diagnose(apn, trials, mentor=mentor)
    (f,) = [f for f in d.findings if f.kind in ("missing_transition", "missing_stop")]
    assert f.kind == "missing_transition" and f.condition.startswith("dwell > 1.9 and theta > ")
    fake = FakeLearners(mentor)
    r = repair(apn, d, fake)
    assert r.key == "missing_transition:t6" and fake.calls == []          # nothing learned from states
    t6 = r.apn.transition("t6")
    assert set(t6.outputs) == {"done"} and t6.law is None and str(t6.condition) == f.condition
