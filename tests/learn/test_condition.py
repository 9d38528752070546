"""Learned firing conditions: hold where the mentor switched, rarely elsewhere, at numpy speed."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from multiform.errors import InvalidInput
from multiform.learn.condition import LearnedCondition, load_condition
from multiform.petri.firing import NetRunner
from multiform.petri.revision import set_condition
from multiform.petri.skillfile import load_skill

from .synthetic import switch_data

NAMES = ("theta", "omega")


@pytest.fixture(scope="module")
def fitted():
    train, test = switch_data(0), switch_data(1)
    cond = LearnedCondition(NAMES).fit_switches(train.positives, train.negatives)
    return cond, train, test


def test_holds_near_switches_and_rarely_far(fitted):
    cond, _, test = fitted
    near = cond.holds(test.near).mean()           # held-out switch-like states, |theta| < 0.15
    far = cond.holds(test.negatives).mean()       # held-out swing states far from any switch
    print(f"\nlearned condition: holds at {near:.1%} of held-out near-upright switch states, "
          f"{far:.2%} of held-out far swing states; {cond.n_support_} support vectors")
    assert near >= 0.90
    assert far <= 0.02
    assert cond.n_support_ <= 500


def test_decision_equals_sklearn(fitted):
    cond, _, test = fitted
    X = np.concatenate([test.near, test.negatives[:500], test.positives])
    ref = cond.estimator_.decision_function(X)
    np.testing.assert_allclose(cond.decision(X), ref, rtol=0, atol=1e-8)
    one = np.array([cond.decision(x) for x in X[:200]])
    np.testing.assert_allclose(one, ref[:200], rtol=0, atol=1e-8)
    calls = np.array([cond(x) for x in X[:200]])
    assert calls.dtype == bool and np.array_equal(calls, ref[:200] > 0)


def test_support_vectors_capped_on_overlapping_classes():
    rng = np.random.default_rng(3)
    X = rng.normal(size=(3000, 2))
    y = X[:, 0] + rng.normal(0, 1.0, 3000) > 0.5         # heavy overlap: most points become SVs
    cond = LearnedCondition(NAMES, max_support=120).fit(X, y)
    assert cond.n_support_ <= 120
    assert len(cond.fit_rounds_) > 1 and cond.fit_rounds_[0][1] > 120
    assert cond.rates(X, y)["hit"] > 0.6                    # still a useful separator


def test_threshold_trades_false_positives_against_misses(fitted):
    cond, _, test = fitted
    X = np.concatenate([test.positives, test.negatives])
    y = np.r_[np.ones(len(test.positives), bool), np.zeros(len(test.negatives), bool)]
    rates = []
    for thr in (-1.0, 0.0, 1.0):
        c = LearnedCondition(**{**cond.get_params(), "threshold": thr})
        c.decision_ = cond.decision_
        rates.append(c.rates(X, y))
    hits = [r["hit"] for r in rates]
    fps = [r["false_positive"] for r in rates]
    assert hits == sorted(hits, reverse=True) and fps == sorted(fps, reverse=True)
    thr = cond.threshold_for(test.negatives, 0.001)
    assert (np.asarray(cond.decision(test.negatives)) > thr).mean() <= 0.001


def test_needs_both_kinds_of_states():
    with pytest.raises(ValueError, match="need states"):
        LearnedCondition(NAMES).fit(np.zeros((5, 2)), np.ones(5, bool))


def test_save_load_and_net_wiring(tmp_path, fitted):
    cond, _, test = fitted
    path = tmp_path / "t1_learned.npz"
    cond.save(path)
    back = load_condition(path, input_names=NAMES)
    assert isinstance(back, LearnedCondition) and back.input_names == NAMES
    X = np.concatenate([test.near[:50], test.negatives[:50]])
    np.testing.assert_array_equal(back.decision(X), cond.decision(X))

    apn, _ = set_condition(load_skill("pendulum"), "t1", {"model": "t1_learned"}, "test")
    runner = NetRunner(apn, ["theta", "omega", "x", "xdot"], learned={"t1_learned": back}, rng=0)
    assert runner.tick([np.pi, 0.0, 0.0, 0.0], 0.0) == ["t0"]            # token into P1
    assert runner.tick([1.5, 4.0, 0.0, 0.0], 0.1) == []                 # far from upright: no switch
    assert runner.tick([0.03, 0.2, 0.0, 0.0], 0.2) == ["t1"]            # near upright: switch
    cond.at_peak = True
    cond.save(path)
    peak = load_condition(path, input_names=NAMES)
    assert peak.at_peak
    runner = NetRunner(apn, ["theta", "omega", "x", "xdot"], learned={"t1_learned": peak}, rng=0)
    runner.tick([np.pi, 0.0, 0.0, 0.0], 0.0)
    assert runner.tick([0.03, 0.2, 0.0, 0.0], 0.2) == []                # its decision rises
    assert runner.tick([0.03, 0.2, 0.0, 0.0], 0.201) == ["t1"]          # ... and no longer: switch
    cond.at_peak = False


def test_a_condition_saved_without_the_peak_setting_fires_on_entering(tmp_path, fitted):
    """Files written before conditions fired at their peak run as they did when they were written."""
    import json
    cond, _, _ = fitted
    path = tmp_path / "old.npz"
    cond.save(path)
    with np.load(path, allow_pickle=False) as z:
        arrays = {k: z[k] for k in z.files}
    header = json.loads(str(arrays["__format__"]))
    header["meta"]["at_peak"] = True
    arrays["__format__"] = np.array(json.dumps(header))
    np.savez(path, **arrays)
    assert load_condition(path, input_names=NAMES).at_peak
    del header["meta"]["at_peak"]
    arrays["__format__"] = np.array(json.dumps(header))
    np.savez(path, **arrays)
    old = load_condition(path, input_names=NAMES)
    assert not old.at_peak
    apn, _ = set_condition(load_skill("pendulum"), "t1", {"model": "t1_learned"}, "test")
    runner = NetRunner(apn, ["theta", "omega", "x", "xdot"], learned={"t1_learned": old}, rng=0)
    runner.tick([np.pi, 0.0, 0.0, 0.0], 0.0)
    assert runner.tick([0.03, 0.2, 0.0, 0.0], 0.2) == ["t1"]            # on entering


def test_corrupt_or_mismatched_condition_file(tmp_path, fitted):
    cond, _, _ = fitted
    path = tmp_path / "c.npz"
    cond.save(path)
    good = path.read_bytes()
    with pytest.raises(InvalidInput, match="input_names") as e:
        LearnedCondition.load(path, input_names=("theta", "omega", "x"))
    assert "c.npz" in str(e.value)
    path.write_bytes(good[:100])
    with pytest.raises(InvalidInput, match="c.npz"):
        load_condition(path)
    assert path.read_bytes() == good[:100]
    path.write_bytes(b"not a zip at all")
    with pytest.raises(InvalidInput, match="c.npz"):
        LearnedCondition.load(path)
    assert path.read_bytes() == b"not a zip at all"


class _Bump:
    """A condition on theta alone whose decision peaks at theta = 0 and is positive for |theta| < 0.3005."""

    input_names = ("theta",)
    threshold = 0.0

    def decision(self, X):
        X = np.asarray(X, dtype=float)
        return 0.3005 - np.abs(X[..., 0]) if X.ndim > 1 else 0.3005 - abs(float(X[0]))


def _approach(switch):
    """theta from 1 to -0.5 rad, one mrad per 1 ms tick; the mentor swings up (t0) and switches into
    balancing (t1) at sample ``switch``, both labelled successful."""
    from multiform.demos.episode import Episode, SegmentLabel
    theta = np.linspace(1.0, -0.5, 1501)
    n = len(theta)
    obs = np.zeros((n, 4))
    obs[:, 0] = theta
    return Episode(obs=obs, actions=np.zeros((n, 1)), transitions=np.array(["t0"] * switch + ["t1"] * (n - switch)),
                   observation_names=("theta", "omega", "x", "xdot"), command_names=("v_cmd",), dt=0.001, seed=0,
                   labels=[SegmentLabel(0, switch, "t0", True), SegmentLabel(switch, n, "t1", True)])


def test_switch_lags_measure_each_rule_against_the_mentors_decision():
    """Entering fires at theta = 0.3 (sample 700), the peak one tick after theta = 0 (1001); the
    mentor decided its reaction time (t1's law, balance: 0.06 s) before its recorded switch."""
    from multiform.learn.condition import switch_lags
    apn = load_skill("pendulum")
    early = [_approach(900)]                                   # switched at theta = 0.1
    np.testing.assert_allclose(switch_lags(_Bump(), apn, early, "t1", ("theta",), False), [-0.2 + 0.06])
    np.testing.assert_allclose(switch_lags(_Bump(), apn, early, "t1", ("theta",), True), [0.101 + 0.06])
    late = [_approach(1060)]                                   # decided at theta = 0
    np.testing.assert_allclose(switch_lags(_Bump(), apn, late, "t1", ("theta",), True), [0.001], atol=1e-9)


@settings(max_examples=60, deadline=None)
@given(st.lists(st.floats(-1.0, 1.0), min_size=2, max_size=30))
def test_first_firing_is_the_nets_rule(decisions):
    """The rule run on a recorded sequence fires where the net, ticking through it, fires."""
    from multiform.learn.condition import first_firing

    class Seq:
        input_names = ("theta",)
        threshold = 0.0
        at_peak = True

        def decision(self, x):
            return float(x[0])

        def __call__(self, x):
            return float(x[0]) > 0.0

    apn, _ = set_condition(load_skill("pendulum_strict"), "t1", {"model": "seq"}, "test")
    runner = NetRunner(apn, ["theta", "omega", "x", "xdot"], learned={"seq": Seq()}, rng=0)
    runner.tick([3.0, 0.0, 0.0, 0.0], 0.0)                        # t0: the token into P1
    fired = -1
    for k, d in enumerate(decisions):
        if runner.tick([d, 0.0, 0.0, 0.0], (k + 1) * 1e-3) == ["t1"]:
            fired = k
            break
    assert fired == first_firing(np.array(decisions), 0.0, True)
