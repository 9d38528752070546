"""The definition held against the mentor's demonstrations before practice: give-up rules that would
have ended the mentor's own successful stays are moved, a sound net is left alone."""

from __future__ import annotations

import yaml

from multiform.adapt.mentor import mentor_evidence
from multiform.adapt.practice import Practice, PracticeConfig, PracticeState
from multiform.adapt.replay import replay_limits
from multiform.demos.episode import Episode, SegmentLabel
from multiform.model import SkillModel
from multiform.petri.skillfile import load_skill, skill_to_data

from .test_repair_beyond import EPISODES, FakeLearners, edited


def test_a_sound_net_would_have_ended_no_demonstration():
    apn = load_skill("pendulum")
    assert replay_limits(apn, mentor_evidence(apn, EPISODES)) == []


def test_a_repeat_limit_is_counted_with_the_repeats_the_net_makes_not_the_mentors_tags():
    # The mentor tags its 2 s swing-up once; the net repeats it whenever dwell > 2 s, which at half the
    # mentor's pace is once (at 1 s of the mentor's time): 'fires_t2 >= 1' gives up in every demonstration.
    apn = edited(t4={"condition": "fires_t2 >= 1"})
    (f,) = replay_limits(apn, mentor_evidence(apn, EPISODES))
    assert (f.kind, f.transition, f.condition) == ("limit_too_tight", "t4", "fires_t2 >= 2")
    assert f.evidence["source"] == "demonstrations" and f.evidence["demonstrations_ended"] == 4
    assert f.evidence["examples"][0]["at_s_of_the_mentors_stay"] == 1.01
    # played at the mentor's own pace the repeat never fires within the swing-up: nothing to move
    assert replay_limits(apn, mentor_evidence(apn, EPISODES), slower=1.0) == []


def test_a_time_limit_leaves_the_robot_twice_the_mentors_longest_stay():
    apn = edited(t5={"condition": "abs(theta) > 0.8 or dwell > 0.3"})
    (f,) = replay_limits(apn, mentor_evidence(apn, EPISODES))
    # the mentor balanced 1 s after its switch (t1 resets the dwell; its t3 tag is a repeat): 1.98 s at half pace
    assert f.transition == "t5" and f.condition == "(abs(theta) > 0.8) or (dwell > 2.001)"
    assert replay_limits(edited(t5={"condition": f.condition}), mentor_evidence(apn, EPISODES)) == []


def test_only_the_atoms_that_gave_up_are_moved():
    # 'theta > 5' never holds, so its conjunction ended nothing: its 'dwell > 0.1' stays as written
    apn = edited(t5={"condition": "(theta > 5 and dwell > 0.1) or abs(theta) > 0.08"})
    (f,) = replay_limits(apn, mentor_evidence(apn, EPISODES))
    assert f.condition == "((theta > 5) and (dwell > 0.1)) or (abs(theta) > 0.1133)"


def _odd_episode() -> Episode:
    """A successful demonstration whose balance swayed to 0.5 rad once, unlike every other."""
    ep = EPISODES[0]
    obs = ep.obs.copy()
    obs[260:270, 0] = 0.5
    return Episode(obs=obs, actions=ep.actions, transitions=ep.transitions, observation_names=ep.observation_names,
                   command_names=ep.command_names, dt=ep.dt, seed=9, labels=ep.labels, outcome="success")


def test_one_odd_demonstration_is_not_the_mentors_timing():
    apn = edited(t5={"condition": "abs(theta) > 0.4 or fires_t3 >= 10"})
    assert replay_limits(apn, mentor_evidence(apn, [*EPISODES, _odd_episode()])) == []
    three = [_odd_episode() for _ in range(3)]
    (f,) = replay_limits(apn, mentor_evidence(apn, [*EPISODES, *three]))
    assert f.condition == "(abs(theta) > 0.55) or (fires_t3 >= 10)"


def test_stays_the_mentor_labelled_failed_are_no_evidence():
    apn = edited(t5={"condition": "abs(theta) > 0.4 or fires_t3 >= 10"})
    bad = []
    for _ in range(3):
        ep = _odd_episode()
        labels = [lab if lab.transition != "t3" else SegmentLabel(lab.start, lab.end, "t3", False) for lab in ep.labels]
        bad.append(Episode(obs=ep.obs, actions=ep.actions, transitions=ep.transitions,
                           observation_names=ep.observation_names, command_names=ep.command_names, dt=ep.dt, seed=9,
                           labels=labels, outcome="failure"))
    assert replay_limits(apn, mentor_evidence(apn, [*EPISODES, *bad])) == []


def _model(tmp_path, **conditions) -> SkillModel:
    d = skill_to_data(load_skill("pendulum"))
    for tid, cond in conditions.items():
        d["transitions"][tid]["condition"] = cond
    skill = tmp_path / "skill.yaml"
    skill.write_text(yaml.safe_dump(d))
    return SkillModel.create(tmp_path / "model", skill)


def test_practice_moves_such_a_limit_before_its_first_trial_once(tmp_path):
    model = _model(tmp_path, t4="fires_t2 >= 1")
    practice = Practice(model, tmp_path / "p", PracticeConfig(), name="a")
    practice.ctx.learners = FakeLearners(mentor_evidence(model.apn, EPISODES))
    state = PracticeState()
    practice.repairs.check_definition(state)
    practice.save_state(state)
    (rev,) = model.history.revisions()
    assert (rev.operator, rev.target, str(model.apn.transition("t4").condition)) == \
        ("set_condition", "t4", "fires_t2 >= 2")
    assert rev.evidence["candidate"] == "demonstrations:t4" and rev.evidence["source"] == "demonstrations"
    assert state.checked and state.revisions[0].after_trial == -1 and state.tried == []
    saved = practice.load_state()
    assert saved.checked and saved.revisions == state.revisions
    # checking again (a resumed loop) finds the moved limit sound
    practice.ctx.learners = FakeLearners(mentor_evidence(model.apn, EPISODES))
    practice.repairs.check_definition(PracticeState())
    assert len(model.history.revisions()) == 1


def test_practice_leaves_a_sound_definition_as_written(tmp_path):
    model = _model(tmp_path)
    practice = Practice(model, tmp_path / "p", PracticeConfig(), name="a")
    practice.ctx.learners = FakeLearners(mentor_evidence(model.apn, EPISODES))
    practice.repairs.check_definition(state := PracticeState())
    assert model.history.revisions() == [] and state.checked and model.version == 0
