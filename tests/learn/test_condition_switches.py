"""The learned switch condition on recorded pendulum demos: windows around the mentor's switches."""

import numpy as np
import pytest

from multiform.teach.record import record_many
from multiform.learn.condition import switch_windows, window_hits
from multiform.learn.training import fit_switch_condition
from multiform.learn.views import switch_data
from multiform.petri.skillfile import load_skill
from multiform.task import load_task
task = load_task("pendulum")

NAMES = ["theta", "omega", "x"]


@pytest.fixture(scope="module")
def demos():
    return record_many("pendulum", list(range(100, 116)), task.DEMO_ENV_KWARGS, workers=2)


def test_switch_windows_hold_the_states_around_each_successful_switch(demos):
    apn = load_skill("pendulum")
    d = switch_data(apn, demos, "t1", NAMES)
    wins = switch_windows(apn, demos, "t1", NAMES, before=0.0, after=0.0)
    assert len(wins) == len(d.switch_states) > 0
    assert np.allclose(np.stack([W[0] for _, _, W in wins]), d.switch_states)
    near = switch_windows(apn, demos, "t1", NAMES, before=0.3, after=0.3, near=("theta", 0.15))
    assert len(near) == len(wins)
    assert all(np.all(np.abs(W[:, 0]) <= 0.15) for _, _, W in near)
    assert all(len(W) <= 601 for _, _, W in near)


def test_window_hits_counts_an_empty_window_as_a_miss():
    class Always:
        def holds(self, X):
            return np.ones(len(X), bool)

    wins = [(0, 5, np.zeros((3, 2))), (1, 7, np.zeros((0, 2)))]
    assert window_hits(Always(), wins).tolist() == [True, False]


def test_switch_condition_holds_at_held_out_switches_not_far_from_them(demos):
    apn = load_skill("pendulum")
    cond, info = fit_switch_condition(apn, demos[:10], "t1", NAMES, windows=(0.02, 0.1), folds=3)
    assert info["window"] in (0.02, 0.1)
    assert cond.n_support_ <= 500
    test = demos[10:]
    d = switch_data(apn, test, "t1", NAMES)
    assert cond.holds(d.negatives).mean() <= 0.05
    hits = window_hits(cond, switch_windows(apn, test, "t1", NAMES, before=0.3, after=0.3, near=("theta", 0.15)))
    assert hits.mean() >= 0.5
