"""Training sets and fits from real mentor demonstrations (a few recorded pendulum demos)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from multiform.teach.record import record_many
from multiform.errors import InvalidInput
from multiform.learn.labels import LabelStore
from multiform.learn.training import (LawSettings, fit_judge, fit_law, fit_regions, mentor_records,
                                      own_stay_floors, region_floor)
from multiform.tasks.pendulum_mentor import BALANCE_GAINS
from multiform.learn.views import MIRROR_SUFFIX, law_data, mirror_episode, stays, success_mask, value_matrix
from multiform.petri.skillfile import load_skill
from multiform.task import load_task
task = load_task("pendulum")


@pytest.fixture(scope="module")
def demos():
    # 24: with a hand start anywhere in the stroke in 40 % of the demos and a push in 30 %, 16 leave
    # the held-out demos in states no training demo visited (held-out NRMSE 0.53 against 0.29)
    eps = record_many("pendulum", list(range(24)), task.DEMO_ENV_KWARGS, workers=2)
    assert 8 <= sum(e.outcome == "success" for e in eps) < 24
    return load_skill("pendulum"), eps


def test_laws_learn_only_from_successful_segments(demos):
    apn, eps = demos
    dropped = 0
    for law in apn.laws:
        ok = law_data(apn, eps, law, success_only=True, lag=0.0)
        every = law_data(apn, eps, law, success_only=False, lag=0.0)
        assert 0 < len(ok.X) <= len(every.X)
        dropped += len(every.X) - len(ok.X)
        mine = [t.id for t in apn.transitions if t.law == law]
        for i, ep in enumerate(eps):
            in_law = np.isin(ep.transitions, mine)
            assert (ok.episode == i).sum() == (in_law & success_mask(ep)).sum()
            assert (every.episode == i).sum() == in_law.sum()
    assert dropped > 0


def test_swing_up_law_reproduces_the_mentor(demos):
    apn, eps = demos
    law, info = fit_law(apn, eps, "swing_up", settings=LawSettings(n_hyper=500))
    d = law_data(apn, eps, "swing_up")
    pred = law.predict(d.X).reshape(d.Y.shape)
    nrmse = np.sqrt(np.mean((pred - d.Y) ** 2)) / d.Y.std()
    assert nrmse < 0.25 and info["heldout_nrmse"] < 0.35, (nrmse, info["heldout_nrmse"])


def test_region_floor_keeps_the_mentors_catches_inside(demos):
    apn, eps = demos
    regions, _ = fit_regions(apn, eps)
    floor = region_floor(apn, eps, regions, "P2")
    assert floor < 0.0
    back = regions.condition("P1", rather_than="P2", leave_below=floor)
    for ep in eps:
        V = value_matrix(apn, ep, list(regions.input_names))
        ok = success_mask(ep)
        for s, e, p in stays(apn, ep.transitions):
            if p == "P2" and ok[s:e].all():
                assert not back.holds(V[s:e]).any()
    falling = {"theta": [0.9, -1.2], "omega": [4.0, -3.0], "x": [0.0, 0.1]}    # a pushed pendulum
    fallen = np.column_stack([falling[n] for n in regions.input_names])
    assert back.holds(fallen).all()


def _trace(apn, states, names, fired):
    """A trace-like record: ``states`` rows of ``names``; ``fired`` (tick, transition) moves the token."""
    from types import SimpleNamespace
    ids = apn.place_ids
    marking = np.zeros((len(states), len(ids)), np.int16)
    where, k0 = "P1", 0
    for k, t in fired + [(len(states), None)]:
        marking[k0:k, ids.index(where)] = 1
        if t is not None:
            where, k0 = next(iter(apn.transition(t).outputs)), k
    cols = {n: np.asarray(states, float)[:, i] for i, n in enumerate(names)}
    from multiform.runtime.trace import Trace
    tr = SimpleNamespace(value=cols.__getitem__, place_ids=ids, marking=marking,
                         firings=[SimpleNamespace(tick=k, transition=t) for k, t in fired])
    tr.stays = lambda place: Trace.stays(tr, place)
    return tr


def test_own_stays_that_went_on_lower_the_floor_failed_ones_do_not(demos):
    apn, eps = demos
    regions, _ = fit_regions(apn, eps)
    names = list(regions.input_names)
    odd = {"theta": -2.3, "omega": 16.0, "x": 0.3}                # faster than the mentor ever swung
    usual = {n: float(v) for n, v in zip(names, np.median(value_matrix(apn, eps[0], names), axis=0))}
    j = regions.places_.index("P1")
    z_odd = float(regions.logits(np.array([[odd[n] for n in names]]))[0, j])
    assert z_odd < region_floor(apn, eps, regions, "P1") - 0.5           # further out than any mentor stay
    states = [[usual[n] for n in names]] * 5 + [[odd[n] for n in names]] + [[usual[n] for n in names]] * 4
    caught = _trace(apn, states, names, [(8, "t1")])              # P1 → P2: the stay went on
    gave_up = _trace(apn, states, names, [(8, "t4")])             # P1 → failure
    still = _trace(apn, states, names, [])                        # never left P1
    assert own_stay_floors(apn, [caught], regions)["P1"] == pytest.approx(z_odd)
    assert own_stay_floors(apn, [gave_up, still], regions) == {p: 0.0 for p in regions.places_}
    repeat = _trace(apn, states, names, [(3, "t2"), (8, "t1")])   # a repeat inside P1 does not end the stay
    assert own_stay_floors(apn, [repeat], regions)["P1"] == pytest.approx(z_odd)


def test_mirror_image_of_a_demo(demos):
    apn, eps = demos
    ep = eps[0]
    m = mirror_episode(apn, ep)
    names = ["theta", "omega", "x", "xdot", "s", "c"]
    V, M = value_matrix(apn, ep, names), value_matrix(apn, m, names)
    np.testing.assert_allclose(M[:, :5], -V[:, :5], atol=1e-12)      # s = sin(theta) follows the state
    np.testing.assert_allclose(M[:, 5], V[:, 5])
    np.testing.assert_allclose(m.actions, -ep.actions)
    assert (m.transitions == ep.transitions).all() and m.labels == ep.labels
    with pytest.raises(ValueError, match="no mirror"):
        mirror_episode(replace(apn, mirror={}), ep)


def test_a_judge_from_too_few_demonstrations_is_refused_with_the_place_named(demos):
    apn, eps = demos
    store = LabelStore()
    store.add_many(mentor_records(apn, eps[:1]))
    with pytest.raises(InvalidInput, match=r"places\.P1\.judge.*record more demonstrations"):
        fit_judge(apn, eps[:1], store, "P1", mirror=False)


def test_judges_learn_from_mirror_images_but_are_tested_on_real_segments(demos):
    apn, eps = demos
    store = LabelStore()
    store.add_many(mentor_records(apn, eps))
    judge, info = fit_judge(apn, eps, store, "P1", heldout=0.25)
    plain, plain_info = fit_judge(apn, eps, store, "P1", heldout=0.25, mirror=False)
    assert info["mirror_images"] == info["segments"] == plain_info["segments"] == len(plain.y_)
    assert len(judge.y_) == 2 * len(plain.y_)
    assert info["heldout_segments"] == plain_info["heldout_segments"]
    mirrored = [k for k in judge.keys_ if k[0].endswith(MIRROR_SUFFIX)]
    assert len(mirrored) == len(plain.y_)
    rows = {k: i for i, k in enumerate(judge.keys_)}
    names = judge.feature_names_
    for src, a, b in mirrored[:5]:
        orig, img = judge.X_[rows[(src[: -len(MIRROR_SUFFIX)], a, b)]], judge.X_[rows[(src, a, b)]]
        for v in judge.variables:
            assert img[names.index(f"{v}.end")] == pytest.approx(-orig[names.index(f"{v}.end")])
            assert img[names.index(f"{v}.max")] == pytest.approx(-orig[names.index(f"{v}.min")])
        assert img[names.index("duration")] == orig[names.index("duration")]


def test_a_law_learned_across_the_mentors_reaction_time_recovers_its_balance_feedback(demos):
    """While balancing, the mentor's stick noise moves the hand and with it the pendulum: paired with
    the command of the same moment, the state mostly shows the plant's answer to that noise, and the
    fitted feedback on the angle is a fraction of the mentor's. Paired with the command a reaction
    time later (the skill file's ``lag``), it comes within 30 % of it."""
    apn, eps = demos
    mentor_gain = BALANCE_GAINS[0]

    def angle_gain(lag: float) -> float:
        d = law_data(apn, eps, "balance", lag=lag)
        A = np.c_[d.X, np.ones(len(d.X))]
        return float(np.linalg.lstsq(A, d.Y[:, 0], rcond=None)[0][0])

    assert apn.laws["balance"].lag == pytest.approx(0.06)
    same, later = angle_gain(0.0), angle_gain(apn.laws["balance"].lag)
    assert same < 0.4 * mentor_gain < 0.7 * mentor_gain < later < 1.1 * mentor_gain
    d0, d1 = law_data(apn, eps, "balance", lag=0.0), law_data(apn, eps, "balance")
    assert len(d1.X) < len(d0.X)            # the last lag of every kept run has no later command
    ep = eps[0]
    keep = np.flatnonzero(np.isin(ep.transitions, ["t1", "t3"]) & success_mask(ep))
    shift = int(round(apn.laws["balance"].lag / ep.dt))
    first = d1.episode == 0
    np.testing.assert_array_equal(d1.Y[first][:5, 0], ep.actions[keep[:5] + shift, 0])
