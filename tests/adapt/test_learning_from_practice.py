"""Learning from practice: own segments with provenance, refits as replayable revisions, exploration,
the mentor's grade of a trial, and the revert of a revision that made things worse."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest

from multiform.adapt.experience import Experience, select_segments
from multiform.adapt.explore import ExploringLaw
from multiform.adapt.practice import Practice, PracticeConfig, PracticeState, RevisionRecord, TrialRecord, Watch
from multiform.demos.episode import Episode, SegmentLabel
from multiform.tasks.pendulum_mentor import PendulumMentor
from multiform.errors import InvalidInput
from multiform.learn.gp import GPLaw
from multiform.learn.judge import SegmentGrade, TrialGrade
from multiform.learn.training import fit_law
from multiform.learn.views import law_data, place_episode
from multiform.model import SkillModel
from multiform.petri.revision import History, add_transition, refit_law
from multiform.petri.skillfile import load_skill

from .synthetic import make_trace


def _values(n: int, theta: float = 0.1) -> np.ndarray:
    """Rows of the pendulum skill's variables (theta, omega, x, xdot, s, c)."""
    rng = np.random.default_rng(n)
    v = np.zeros((n, 6))
    v[:, 0] = theta + 0.01 * rng.standard_normal(n)
    v[:, 1] = rng.standard_normal(n)
    v[:, 2] = 0.1 * rng.standard_normal(n)
    v[:, 4], v[:, 5] = np.sin(v[:, 0]), np.cos(v[:, 0])
    return v


def _trial(apn, outcome="success", seed=7):
    trace = make_trace(apn, [(0, "t0"), (100, "t1"), (250, "t6")], _values(260), outcome)
    trace.seed = seed
    trace.commands[:, 0] = np.linspace(-1, 1, 260)
    grade = TrialGrade(segments=[SegmentGrade("c_3", 0, 100, "P1", "P1", 0.9),
                                 SegmentGrade("c_3", 100, 250, "P2", "P2", 0.6)],
                       places={"P1": 0.9, "P2": 0.6}, score=0.6)
    return trace, grade


def test_own_segments_carry_provenance_and_stay_apart_from_the_mentors(tmp_path):
    apn = load_skill("pendulum")
    trace, grade = _trial(apn)
    own = select_segments(apn, trace, grade, "c_3", "c", 3, margin=0.3)
    # only the stay graded with a margin (0.9 >= 0.8) in a trial graded successful; 0.6 is not sure enough
    assert [(s.place, s.start, s.end) for s in own] == [("P1", 0, 100)]
    s = own[0]
    assert (s.source, s.scenario, s.trial, s.seed, s.judge_score, s.mentor) == ("c_3", "c", 3, 7, 0.9, None)
    assert s.laws == {"swing_up": "swing_up"} and s.transitions == ("t0",)
    # the mentor's verdict on a stay overrides the robot's, both ways
    mentor = {(0, 100): False, (100, 250): True}
    assert [(x.place, x.mentor) for x in select_segments(apn, trace, grade, "c_3", "c", 3, 0.3, mentor)] == [("P2", True)]
    # a trial the robot graded failed gives no own segment, however sure a stay's grade
    failed = TrialGrade(segments=grade.segments, places=grade.places, score=0.2)
    assert select_segments(apn, trace, failed, "c_3", "c", 3, 0.3) == []

    store = Experience(tmp_path)
    store.add(trace, own, "c_3")
    store.add(trace, own, "c_3")                      # a resumed loop adds the same trial again: no duplicate
    assert store.segments() == own
    assert json.loads((tmp_path / "experience" / "segments.jsonl").read_text().splitlines()[0])["source"] == "c_3"
    (ep,) = store.law_episodes("swing_up")
    assert [(lab.start, lab.end, lab.labeller) for lab in ep.labels] == [(0, 100, "robot")]
    assert store.law_episodes("balance") == []
    d = law_data(apn, [ep], "swing_up", lag=0.0)
    assert len(d.X) == 100 and np.allclose(d.Y[:, 0], trace.commands[:100, 0])


def _mentor_episode(n: int = 400, seed: int = 0) -> Episode:
    v = _values(n)
    rng = np.random.default_rng(seed)
    obs = np.column_stack([v[:, :4]])
    tags = np.array(["t0"] * 200 + ["t1"] * (n - 200))
    return Episode(obs=obs, actions=rng.standard_normal((n, 1)), transitions=tags,
                   observation_names=("theta", "omega", "x", "xdot"), command_names=("v_cmd",), dt=0.01,
                   seed=seed, labels=[SegmentLabel(0, 200, "t0", True), SegmentLabel(200, n, "t1", True)])


def test_a_refit_reports_mentor_and_own_samples_apart_with_error_before_and_after(tmp_path):
    apn = load_skill("pendulum")
    mentor = [_mentor_episode(seed=i) for i in range(3)]
    first, _ = fit_law(apn, mentor, "swing_up", seed=0)
    trace, grade = _trial(apn)
    store = Experience(tmp_path)
    store.add(trace, select_segments(apn, trace, grade, "c_3", "c", 3), "c_3")
    law, info = fit_law(apn, mentor, "swing_up", seed=0, own=store.law_episodes("swing_up"), current=first)
    # every episode also gives its mirror image (the pendulum skill declares one), of both kinds
    assert (info["n_mentor"], info["n_own"], info["own_episodes"], info["demos"]) == (1200, 200, 1, 3)
    assert info["n"] == 1400 and np.isfinite(info["heldout_nrmse"]) and np.isfinite(info["heldout_nrmse_current"])
    # the robot's own samples never outweigh the mentor's beyond the set ratio
    from multiform.learn.training import LawSettings
    _, capped = fit_law(apn, mentor, "swing_up", seed=0, own=store.law_episodes("swing_up"),
                        settings=LawSettings(own_ratio=0.1))
    assert (capped["n_mentor"], capped["n_own"]) == (1200, 120)
    # own samples that are none of them new to the mentor's law give no refit, when one is asked for
    none, info = fit_law(apn, mentor, "swing_up", seed=0, own=store.law_episodes("swing_up"), mentor_law=first,
                         settings=LawSettings(own_novelty=1e9), own_required=True)
    assert none is None and info["n_own"] == 0 and "heldout_nrmse" not in info
    # with the earlier law's hyperparameters only the posterior is solved: the same kernel, the new data in it
    kept, info = fit_law(apn, mentor, "swing_up", seed=0, own=store.law_episodes("swing_up"), theta=first.theta_)
    assert np.allclose(kept.theta_, first.theta_) and info["n_own"] == 200
    X = law_data(apn, store.law_episodes("swing_up"), "swing_up", lag=0.0).X
    assert not np.allclose(kept.predict(X), first.predict(X))


def test_a_skill_at_its_target_is_not_refitted(tmp_path):
    model = _model(tmp_path)
    practice = Practice(model, tmp_path / "p", PracticeConfig(learn=True, target_rate=0.9), name="c")
    state = PracticeState(trial=10, trials=[TrialRecord(trial=i, success=True) for i in range(10)])
    practice.learning.refit(state)
    assert model.version == 0 and state.last_refit_trial == 9


@pytest.mark.parametrize("outcomes, short", [([True] * 17 + [False], False), ([True] * 6 + [False] * 4, True),
                                              ([True] * 4 + [False], False), ([True] * 3 + [False] * 2, True)])
def test_only_a_skill_that_clearly_falls_short_of_its_target_is_refitted(tmp_path, outcomes, short):
    # one failure in 18 is what a 95 % skill shows now and then; four in ten it is not
    model = _model(tmp_path)
    practice = Practice(model, tmp_path / "p", PracticeConfig(learn=True, target_rate=0.95), name="c")
    trials = [TrialRecord(trial=i, success=ok, net_version=0) for i, ok in enumerate(outcomes)]
    trials += [TrialRecord(trial=len(trials), success=False, net_version=0, explored=True),
               TrialRecord(trial=len(trials) + 1, success=False, net_version=-1)]    # not plain, another net
    state = PracticeState(trial=len(trials), trials=trials)
    assert practice.learning.falls_short(state) is short
    if not short:
        practice.learning.refit(state)
        assert model.version == 0 and state.last_refit_trial == len(trials) - 1


def test_a_shortfall_needs_enough_plain_trials_of_the_net_as_it_is_now(tmp_path):
    """One failure in five plain trials is clearly short of 98 %, read off five trials; with
    ``shortfall_after`` 20 it is no evidence yet, and two failures in twenty are."""
    model = _model(tmp_path)

    def short(outcomes, after):
        practice = Practice(model, tmp_path / "p", PracticeConfig(learn=True, target_rate=0.98,
                                                                  shortfall_after=after), name="c")
        trials = [TrialRecord(trial=i, success=ok, net_version=0) for i, ok in enumerate(outcomes)]
        return practice.learning.falls_short(PracticeState(trial=len(trials), trials=trials))

    few, many = [True] * 4 + [False], [True] * 9 + [False] + [True] * 9 + [False]
    assert short(few, 0) and not short(few, 20)
    assert short(many, 20)
    with pytest.raises(InvalidInput, match="shortfall_after"):
        PracticeConfig(shortfall_after=-1)


def _model(tmp_path) -> SkillModel:
    model = SkillModel.create(tmp_path / "model", "pendulum")
    rng = np.random.default_rng(0)
    X = rng.standard_normal((60, 4))
    for name, shift in (("swing_up", 0.0), ("swing_up_r1", 5.0)):
        model.save_law(name, GPLaw(n_hyper=60, n_restarts=0, random_state=0).fit(X, X[:, :1] + shift))
    return model


def test_a_refit_is_replayed_from_the_history(tmp_path):
    model = _model(tmp_path)
    v0 = model.apn
    v1, rev = refit_law(v0, "swing_up", "swing_up_r1", "own data", {"own_segments": 12})
    model.history.record(rev)
    replayed = History(model.path / "skill.yaml").versions()
    assert replayed == [v0, v1]
    assert replayed[1].laws["swing_up"].fit_name == "swing_up_r1" and replayed[0].laws["swing_up"].fit_name == "swing_up"
    x = np.zeros(4)
    # the model runs the fit its net version names: version 0 the mentor-only law, version 1 the refit
    assert model.laws(replayed[0])["swing_up"].predict_one(x)[0] == pytest.approx(
        GPLaw.load(model.path / "laws" / "swing_up.npz").predict_one(x)[0])
    assert model.laws()["swing_up"].predict_one(x)[0] == pytest.approx(
        GPLaw.load(model.path / "laws" / "swing_up_r1.npz").predict_one(x)[0])
    assert model.laws()["swing_up"].predict_one(x)[0] > model.laws(replayed[0])["swing_up"].predict_one(x)[0] + 3


def _state(before: list[bool], after: list[bool], watch_version: int) -> PracticeState:
    trials = [TrialRecord(trial=i, success=ok) for i, ok in enumerate(before + after)]
    return PracticeState(trial=len(trials), trials=trials,
                         watch=Watch(before_version=watch_version - 1, version=watch_version,
                                     after_trial=len(before) - 1, before=before))


@pytest.mark.parametrize("after, reverted", [([True] * 2 + [False] * 8, True), ([True] * 7 + [False] * 3, False)])
def test_a_revision_that_made_things_clearly_worse_is_reverted(tmp_path, after, reverted):
    model = _model(tmp_path)
    _, rev = refit_law(model.apn, "swing_up", "swing_up_r1", "own data")
    model.history.record(rev)
    practice = Practice(model, tmp_path / "p", PracticeConfig(learn=True, revert_window=10), name="c")
    state = _state([True] * 9 + [False], after, watch_version=1)
    practice.watch.check(state)
    assert state.watch is None
    if reverted:
        assert model.version == 2 and model.history.revisions()[-1].operator == "revert"
        assert model.apn == model.history.version(0) and model.apn.laws["swing_up"].fit_name == "swing_up"
        assert state.revisions[-1].operator == "revert" and "9/10 to 2/10" in state.revisions[-1].reason
    else:
        assert model.version == 1 and model.apn.laws["swing_up"].fit_name == "swing_up_r1"


def test_the_mentor_grades_a_trial_from_its_trace_alone():
    """The trace seen by place holds nothing of the simulator: the pendulum's angle and the places."""
    dt = 0.01
    theta = np.concatenate([np.linspace(3.0, 0.2, 300), 0.1 * np.ones(600)])
    tags = np.array(["P1"] * 300 + ["P2"] * 560 + ["done"] * 40)
    ep = Episode(obs=theta[:, None], actions=np.zeros((900, 1)), transitions=tags, observation_names=("theta",),
                 command_names=("v_cmd",), dt=dt, seed=0)
    mentor = PendulumMentor()
    labels = mentor.grade_trial(ep)
    assert [(lab.transition, lab.start, lab.end, lab.success) for lab in labels] == [("P1", 0, 300, True),
                                                                                    ("P2", 300, 860, True)]
    fell = theta.copy()
    fell[500:] = 1.2                                   # the catch held a second, then the pendulum fell
    labels = mentor.grade_trial(Episode(obs=fell[:, None], actions=ep.actions, transitions=tags,
                                        observation_names=("theta",), command_names=("v_cmd",), dt=dt, seed=0))
    assert [lab.success for lab in labels] == [True, False]


def test_the_mentor_labels_only_the_stays_the_judges_graded(tmp_path, monkeypatch):
    """A way back and the way in firing within a few ticks leave stays of milliseconds that the
    judges do not grade (:func:`~multiform.learn.judge.grade_episode`); the mentor's word on them
    is not asked for, so no judge learns what a few milliseconds of a place look like."""
    import multiform.adapt.practice.learning as learning
    model = SkillModel.create(tmp_path / "model", "pendulum")
    apn, _ = add_transition(model.apn, "t7", {"in": ["P2"], "out": ["P1"], "law": "swing_up",
                                              "condition": {"model": "back", "unless": "t1"}}, "test")
    trace = make_trace(apn, [(0, "t0"), (100, "t1"), (103, "t7"), (105, "t1"), (250, "t6")], _values(260), "success")
    grade = TrialGrade(segments=[SegmentGrade("c_3", 0, 100, "P1", "P1", 0.9),
                                 SegmentGrade("c_3", 105, 250, "P2", "P2", 0.9)], places={"P1": 0.9, "P2": 0.9}, score=0.9)
    revised = []
    monkeypatch.setattr(learning, "refit_judges", lambda model, places, episodes, seed=0: revised.append(places) or {})

    def mentor(placed, net):
        return [SegmentLabel(s, e, p, True, "mentor") for s, e, p in placed.segments() if p in ("P1", "P2")]
    assert len(mentor(place_episode(apn, trace.to_episode()), apn)) == 4           # it would label all four
    practice = Practice(model, tmp_path / "practice", PracticeConfig(learn=True), name="c", mentor=mentor)
    verdicts, account = practice.learning.mentor_grades(3, trace, grade, apn)
    assert sorted(verdicts) == [(0, 100), (105, 250)]
    assert sorted((r.start, r.end) for r in model.labels) == [(0, 100), (105, 250)]
    assert {r.source for r in model.labels} == {"c_3"}
    assert account.stays == account.agree == 2 and revised == [["P1", "P2"]]


def test_exploration_is_seeded_smooth_and_of_the_asked_size():
    class Zero:
        def predict_one(self, x):
            return np.zeros(1)

    law = ExploringLaw(Zero(), np.array([0.2]), tau=0.1, dt=0.001, seed=3)
    a = np.array([law.predict_one(None)[0] for _ in range(20000)])
    law.reseed(3)
    b = np.array([law.predict_one(None)[0] for _ in range(20000)])
    assert np.array_equal(a, b)
    assert 0.1 < a.std() < 0.3
    assert np.corrcoef(a[:-1], a[1:])[0, 1] > 0.98          # smooth over 0.1 s, not white noise per tick


def test_a_scenario_adopts_only_its_own_revisions_after_a_kill(tmp_path):
    """A revision recorded after a scenario's last saved trial is its own only if it says so: another
    scenario's refits (or a finished scenario) are never adopted on resume."""
    from multiform.io import write_json
    model = _model(tmp_path)
    folder = tmp_path / "a"
    write_json(folder / "state.json", {"trial": 3, "trials": [{"trial": i, "success": False, "time": "2000-01-01T00:00:00"}
                                                              for i in range(3)], "revisions": [], "done": False})
    _, rev = refit_law(model.apn, "swing_up", "swing_up_r1", "own data", {"scenario": "c"})
    model.history.record(rev)
    assert Practice(model, folder, name="a").load_state().revisions == []
    assert [r.version for r in Practice(model, folder, name="c").load_state().revisions] == [1]


def test_a_law_learned_with_mirror_images_is_symmetric():
    """A skill that declares its mirror symmetry can give its laws each episode's mirror image: the
    law then commands the mirror of its command in the mirror of a state (no drift to one side)."""
    from multiform.learn.training import LawSettings
    apn = load_skill("pendulum")
    mentor = [_mentor_episode(seed=i) for i in range(3)]
    for ep in mentor:
        ep.actions[:, 0] = 0.5 + ep.obs[:, 1]          # a bias to one side, a gain on omega
    plain, p_info = fit_law(apn, mentor, "swing_up", seed=0, settings=LawSettings(mirror=False))
    both, m_info = fit_law(apn, mentor, "swing_up", seed=0, settings=LawSettings(mirror=True))
    assert m_info["n"] == 2 * p_info["n"]
    x = np.array([0.1, 1.0, 0.5, 0.05])                 # s, c, omega, x
    mx = x * np.array([-1, 1, -1, -1])
    assert both.predict_one(x)[0] == pytest.approx(-both.predict_one(mx)[0], abs=0.05)
    assert abs(plain.predict_one(x)[0] + plain.predict_one(mx)[0]) > 0.5   # the one-sided law keeps its bias


def test_the_target_counts_only_trials_of_the_net_as_it_is_now(tmp_path):
    model = _model(tmp_path)
    practice = Practice(model, tmp_path / "p", PracticeConfig(learn=True, target_rate=0.9, target_window=4), name="c")
    trials = [TrialRecord(trial=i, success=True, net_version=0) for i in range(6)]
    assert practice.reached_target(PracticeState(trial=6, trials=trials))
    _, rev = refit_law(model.apn, "swing_up", "swing_up_r1", "own data")
    model.history.record(rev)
    later = trials + [TrialRecord(trial=6 + i, success=True, net_version=1) for i in range(3)]
    assert not practice.reached_target(PracticeState(trial=9, trials=later))
    assert practice.reached_target(PracticeState(trial=10, trials=later + [TrialRecord(trial=9, success=True,
                                                                                        net_version=1)]))


def _exam_state(before: list[bool], after: list[bool], draws: list[int]) -> PracticeState:
    trials = [TrialRecord(trial=i, success=ok) for i, ok in enumerate(before)]
    trials += [TrialRecord(trial=len(before) + i, success=ok, draw=d) for i, (ok, d) in enumerate(zip(after, draws))]
    return PracticeState(trial=len(trials), trials=trials,
                         watch=Watch(before_version=0, version=1, after_trial=len(before) - 1, before=before,
                                     draws=draws))


@pytest.mark.parametrize("after, reverted", [
    ([True] * 7 + [False] * 3, True),                        # lost 2 of the same trials, won none
    ([True] * 8 + [False] * 2, False),                       # lost 1: within what chaos gives
    ([False] + [True] * 7 + [False, True], False),           # lost 2, won 1
])
def test_an_examined_revision_is_judged_on_the_same_trials_replayed(tmp_path, after, reverted):
    model = _model(tmp_path)
    _, rev = refit_law(model.apn, "swing_up", "swing_up_r1", "own data")
    model.history.record(rev)
    practice = Practice(model, tmp_path / "p", PracticeConfig(learn=True, revert_window=10, exam=True), name="c")
    before = [True] * 9 + [False]
    state = _exam_state(before, after, draws=list(range(10)))
    practice.watch.check(state)
    assert state.watch is None and state.last_refit_trial == state.trial - 1
    if reverted:
        assert model.version == 2 and model.apn.laws["swing_up"].fit_name == "swing_up"
        ev = model.history.revisions()[-1].evidence
        assert (ev["lost"], ev["won"], ev["reverted"]) == (2, 0, 1)
    else:
        assert model.version == 1


@pytest.mark.parametrize("operator, after, retried", [
    ("refit_law", [True] * 9 + [False], True),               # new laws kept: the old verdicts are void
    ("refit_law", [True] * 7 + [False] * 3, False),          # the refit reverted: the old laws, the old verdicts
    ("add_transition", [True] * 9 + [False], False),         # the laws did not change
])
def test_repair_candidates_get_a_new_chance_after_new_laws_pass_their_exam(tmp_path, operator, after, retried):
    model = _model(tmp_path)
    _, rev = refit_law(model.apn, "swing_up", "swing_up_r1", "own data")
    model.history.record(rev)
    practice = Practice(model, tmp_path / "p", PracticeConfig(learn=True, revert_window=10, exam=True), name="c")
    state = _exam_state([True] * 9 + [False], after, draws=list(range(10)))
    state.tried = ["back:P2>P1"]
    state.revisions = [RevisionRecord(version=1, operator=operator, target="swing_up", after_trial=9)]
    practice.watch.check(state)
    assert state.tried == ([] if retried else ["back:P2>P1"])


def test_the_exam_replays_the_draws_of_the_plain_trials_before_the_revision(tmp_path):
    model = _model(tmp_path)
    cfg = PracticeConfig(learn=True, revert_window=3, exam=True, explore=0.5, explore_every=2)
    practice = Practice(model, tmp_path / "p", cfg, name="c")
    # trials 0..5, the odd ones explored; the last three plain ones are 0, 2, 4 (trial 4 itself a replay of 1)
    trials = [TrialRecord(trial=i, success=True, explored=i % 2 == 1) for i in range(6)]
    trials[4].draw = 1
    state = PracticeState(trial=6, trials=trials)
    practice.watch.start(state, 0, 1)
    assert state.watch.draws == [0, 2, 1]
    assert [practice.watch.exam_draw(PracticeState(trial=6 + i, trials=trials, watch=state.watch))
            for i in range(4)] == [0, 2, 1, None]
    # without an exam nothing is replayed
    plain = Practice(model, tmp_path / "q", PracticeConfig(learn=True, exam=False), name="c")
    fresh = PracticeState(trial=6, trials=trials)
    plain.watch.start(fresh, 0, 1)
    assert fresh.watch.draws is None and plain.watch.exam_draw(fresh) is None


def test_own_samples_join_only_where_the_mentors_law_is_unsure():
    from multiform.learn.training import novel_samples
    from multiform.learn.views import LawData
    rng = np.random.default_rng(0)
    X = rng.uniform(-1, 1, (300, 2))
    law = GPLaw(n_hyper=300, n_restarts=0, random_state=0).fit(X, np.sin(3 * X[:, 0]))
    near = rng.uniform(-0.9, 0.9, (50, 2))               # inside the mentor's data
    far = rng.uniform(3.0, 4.0, (50, 2))                 # where the mentor never went
    own = LawData(np.vstack([near, far]), np.zeros((100, 1)), np.arange(100))
    kept = novel_samples(own, law, 0.5)
    assert set(kept.episode.tolist()) == set(range(50, 100))


def test_no_repair_is_made_with_too_few_trials_left_to_check_it(tmp_path):
    """Like a refit, a repair made while practice learns must leave room for its watch: with fewer
    trials left than the watch needs, constant failure changes nothing and says why."""
    model = _model(tmp_path)
    practice = Practice(model, tmp_path / "p", PracticeConfig(learn=True, max_trials=20, revert_window=10,
                                                              exam=True), name="c")
    state = PracticeState(trial=12, trials=[TrialRecord(trial=i, success=False) for i in range(12)],
                          failed_since_repair=list(range(12)))
    practice.repairs.repair(state)
    (none,) = state.revisions
    assert none.operator == "none" and "8 trials are left, fewer than the 10" in none.reason
    assert model.version == 0 and state.failed_since_repair == [] and state.trying is None
    early = PracticeState(trial=5, trials=state.trials[:5], failed_since_repair=list(range(5)))
    practice.repairs.repair(early)                                # room left: the repair loop runs as ever
    assert "trials are left" not in early.revisions[-1].reason


def test_deliberate_practice_pushes_its_exploring_trials_where_it_fails_more(tmp_path):
    """Plain trials keep the scenario's mix; exploring ones go where the robot is weaker."""
    model = _model(tmp_path)
    pushes = []
    practice = Practice(model, tmp_path / "p", PracticeConfig(learn=True, deliberate=True), name="c",
                        perturb=lambda k: "scheduled" if k % 4 < 2 else None, push=lambda k: pushes.append(k) or "push")

    def state(pushed_ok: list[bool], unpushed_ok: list[bool]) -> PracticeState:
        trials = [TrialRecord(trial=i, success=ok, pushed=True) for i, ok in enumerate(pushed_ok)]
        trials += [TrialRecord(trial=len(trials) + i, success=ok) for i, ok in enumerate(unpushed_ok)]
        return PracticeState(trial=len(trials), trials=trials)

    weak_pushed = state([False, False, True], [True, True, True])
    assert practice.perturbation(weak_pushed, 7, explores=True) == "push" and pushes == [7]
    assert practice.perturbation(weak_pushed, 7, explores=False) is None           # plain: as scheduled
    assert practice.perturbation(weak_pushed, 8, explores=False) == "scheduled"
    weak_unpushed = state([True, True], [False, True, False])
    assert practice.perturbation(weak_unpushed, 8, explores=True) is None
    assert practice.perturbation(state([True], [True]), 8, explores=True) == "scheduled"   # a tie: as scheduled
    off = Practice(model, tmp_path / "q", PracticeConfig(learn=True), name="c",
                   perturb=lambda k: None, push=lambda k: "push")
    assert off.perturbation(weak_pushed, 7, explores=True) is None


def test_practice_stops_at_its_robot_time_budget(tmp_path, mountain_car_class):
    import multiform
    task = mountain_car_class()
    demos = multiform.record(task, tmp_path / "demos.h5", demos=4, workers=1)
    model = multiform.train(task.SKILL, demos, tmp_path / "model", task=task, log=lambda s: None)
    sc = task.scenarios()[0]
    cfg = replace(sc.practice_config(max_trials=50, seed=0), max_robot_seconds=300.0, success_streak=0)
    state = Practice(model, tmp_path / "p", cfg, options=sc.options, name=sc.name).run()
    assert state.stop_reason.startswith("used") and state.robot_seconds() >= 300.0
    assert state.robot_seconds() - state.trials[-1].duration < 300.0
