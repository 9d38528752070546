"""Training sets and fits from real mentor demonstrations (a few recorded pendulum demos)."""

from __future__ import annotations

import numpy as np
import pytest

from multiform.demos.record import record_many
from multiform.learn.training import LawSettings, fit_law, fit_regions, region_floor
from multiform.learn.views import law_data, stays, success_mask, value_matrix
from multiform.petri.skillfile import load_skill
from multiform.tasks import pendulum as task


@pytest.fixture(scope="module")
def demos():
    eps = record_many("pendulum", list(range(8)), task.DEMO_ENV_KWARGS, workers=2)
    assert 3 <= sum(e.outcome == "success" for e in eps) < 8
    return load_skill("pendulum"), eps


def test_laws_learn_only_from_successful_segments(demos):
    apn, eps = demos
    dropped = 0
    for law in apn.laws:
        ok = law_data(apn, eps, law, success_only=True)
        every = law_data(apn, eps, law, success_only=False)
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
    fallen = np.array([[0.9, 4.0, 0.0], [-1.2, -3.0, 0.1]])      # a pushed pendulum falling
    assert back.holds(fallen).all()
