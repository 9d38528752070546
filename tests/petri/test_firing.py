import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from multiform.errors import InvalidInput
from multiform.petri.firing import NetRunner
from multiform.petri.net import APN, Condition, Place, Transition
from multiform.petri.revision import add_transition
from multiform.petri.skillfile import load_skill

from .strategies import nets


@settings(max_examples=150, deadline=None)
@given(nets(), st.lists(st.floats(-1.5, 1.5), min_size=1, max_size=40), st.integers(0, 2**31))
def test_firing_obeys_state_equation_and_guards(apn, xs, seed):
    runner = NetRunner(apn, ["x"], rng=seed, max_firings_per_tick=3)
    A = apn.incidence
    pre = apn.pre
    for k, x in enumerate(xs):
        before = np.array(runner.marking)
        # What may fire this tick: enabled by the marking and condition true, judged independently.
        allowed = {t.id for j, t in enumerate(apn.transitions)
                   if (before >= pre[:, j]).all() and t.condition.guard.evaluate({"x": x}) and t.lam > 0}
        fired = runner.tick([x], time=k * 1e-3)
        assert len(fired) == len(set(fired)) <= 3
        m = before.copy()
        for tid in fired:
            j = apn.transition_index(tid)
            assert (m >= pre[:, j]).all(), f"{tid} fired while not enabled"
            assert apn.transition(tid).condition.guard.evaluate({"x": x}), f"{tid} fired with a false condition"
            m = m + A[:, j]                                  # m' = m + A·e_t
        assert (np.array(runner.marking) == m).all()
        if fired:
            assert fired[0] in allowed
        else:
            assert not allowed or runner.outcome is not None or before[apn.place_index("end")] > 0
        assert (np.array(runner.marking) >= 0).all()
        if runner.outcome is not None:
            break


def _choice_net(lams):
    ts = tuple(Transition(f"t{j}", {"P": 1}, {"P": 1}, None, lam, Condition.always()) for j, lam in enumerate(lams))
    return APN(name="choice", places=(Place("P"), Place("end", final="success")), transitions=ts,
               initial_marking={"P": 1})


@settings(max_examples=20, deadline=None, derandomize=True)
@given(st.lists(st.sampled_from([0.0, 0.1, 0.5, 1.0, 2.0, 3.5, 7.0]), min_size=2, max_size=5)
       .filter(lambda ls: sum(ls) > 0))
def test_choice_frequencies_match_normalised_lambda(lams):
    runner = NetRunner(_choice_net(lams), [], rng=np.random.default_rng(12345))
    counts = np.zeros(len(lams))
    cands = list(range(len(lams)))
    for _ in range(10_000):
        counts[runner.choose(cands)] += 1
    freq = counts / counts.sum()
    expected = np.array(lams) / sum(lams)
    assert np.abs(freq - expected).max() <= 0.02
    assert (counts[np.array(lams) == 0] == 0).all()


def test_all_zero_lambda_fires_nothing():
    runner = NetRunner(_choice_net([0.0, 0.0]), [], rng=0)
    assert runner.tick([], 0.0) == []


def test_clocks_counters_and_active_law():
    apn = load_skill("pendulum")
    names = ["theta", "omega", "x", "xdot"]
    r = NetRunner(apn, names, rng=0)
    hanging = [np.pi, 0.0, 0.0, 0.0]
    assert r.tick(hanging, 0.0) == ["t0"]
    assert r.active_laws == {"v_cmd": "swing_up"}
    t = 0.0
    fired = []
    while t < 2.5:
        t += 0.001
        fired += r.tick(hanging, t)
    assert fired == ["t2"]                       # dwell > 2.0 once, then the clock restarts
    assert r.fire_counts()["t2"] == 1
    assert r.values[r.slots["dwell_P1"]] == pytest.approx(t - r.firings[-1].time)
    up = [0.1, 0.5, 0.0, 0.0]
    assert r.tick(up, t + 0.001) == ["t1"]
    assert r.marking_dict() == {"P2": 1}
    assert r.active_laws == {"v_cmd": "balance"}
    r.tick(up, t + 5.2)                          # dwell 5.2 s: not yet
    assert r.outcome is None
    r.tick(up, t + 5.7)                          # no t3 (|theta| < 0.25), dwell > 5.5: success
    assert r.outcome == "success"


def test_strict_condition_never_holds_and_is_counted():
    r = NetRunner(load_skill("pendulum_strict"), ["theta", "omega", "x", "xdot"], rng=0)
    for k in range(100):
        r.tick([0.01, 0.02, 0.0, 0.0], k * 1e-3)
    t1 = r.apn.transition_index("t1")
    assert r.enabled_ticks[t1] == 99 and r.held_ticks[t1] == 0


def test_missing_state_variable_is_refused():
    with pytest.raises(InvalidInput, match="no variable"):
        NetRunner(load_skill("pendulum"), ["theta", "omega"])


def test_learned_condition_model_is_called():
    class Model:
        input_names = ("theta", "omega")
        def __call__(self, x):
            return x[0] ** 2 + x[1] ** 2 < 0.01

    from multiform.petri.revision import set_condition
    apn, _ = set_condition(load_skill("pendulum_strict"), "t1", {"model": "t1_learned"}, "test")
    with pytest.raises(InvalidInput, match="t1_learned"):
        NetRunner(apn, ["theta", "omega", "x", "xdot"])
    r = NetRunner(apn, ["theta", "omega", "x", "xdot"], learned={"t1_learned": Model()}, rng=0)
    r.tick([3.0, 0.0, 0, 0], 0.0)
    assert r.tick([0.05, 0.05, 0, 0], 0.001) == ["t1"]


class _Bump:
    """A learned switch condition whose decision peaks at theta = 0 and holds for |theta| < 0.3."""

    input_names = ("theta",)
    threshold = 0.0

    def __init__(self, at_peak):
        self.at_peak = at_peak

    def decision(self, x):
        return 0.3 - abs(float(x[0]))

    def __call__(self, x):
        return self.decision(x) > self.threshold


def _switch_tick(at_peak, thetas):
    from multiform.petri.revision import set_condition
    apn, _ = set_condition(load_skill("pendulum_strict"), "t1", {"model": "sw"}, "test")
    r = NetRunner(apn, ["theta", "omega", "x", "xdot"], learned={"sw": _Bump(at_peak)}, rng=0)
    assert r.tick([3.0, 0.0, 0, 0], 0.0) == ["t0"]
    for k, th in enumerate(thetas, start=1):
        if r.tick([th, 0.0, 0, 0], k * 1e-3) == ["t1"]:
            return k
    return None


def test_a_learned_switch_fires_at_the_peak_of_its_decision_not_on_entering_its_region():
    approach = [0.5, 0.25, 0.1, 0.02, -0.05, -0.2, -0.5]          # through the region, peak at 0.02
    assert _switch_tick(False, approach) == 2                       # entering: |theta| = 0.25
    assert _switch_tick(True, approach) == 5                        # the tick after the peak
    assert _switch_tick(True, [0.5, 0.25, 0.1, 0.1, 0.1]) == 4      # a state that stays: no longer rising
    # a passage still rising when it left fires on the tick after, as entering would have fired on it
    assert _switch_tick(True, [0.5, 0.28, 0.25, 0.5, 0.6]) == 4
    # a passage broken by a reset starts again
    assert _switch_tick(True, [0.5]) is None


def test_a_learned_switch_fires_on_each_passage_after_a_reset():
    from multiform.petri.revision import set_condition
    apn, _ = set_condition(load_skill("pendulum_strict"), "t1", {"model": "sw"}, "test")
    r = NetRunner(apn, ["theta", "omega", "x", "xdot"], learned={"sw": _Bump(True)}, rng=0)
    for _ in range(2):
        r.reset()
        fired = [r.tick([th, 0.0, 0, 0], k * 1e-3) for k, th in enumerate([3.0, 0.2, 0.1, 0.15])]
        assert fired == [["t0"], [], [], ["t1"]]


def test_concurrent_tokens():
    # Two tokens in P0 feed two branches that join; a P/T net, not a state machine.
    ps = (Place("P0"), Place("A"), Place("B"), Place("end", final="success"))
    ts = (Transition("ta", {"P0": 1}, {"A": 1}, None, 1.0, Condition.always()),
          Transition("tb", {"P0": 1}, {"B": 1}, None, 1.0, Condition.always()),
          Transition("join", {"A": 1, "B": 1}, {"end": 1}, None, 1.0, Condition.always()))
    apn = APN(name="fork", places=ps, transitions=ts, initial_marking={"P0": 2})
    outcomes = set()
    for seed in range(20):
        r = NetRunner(apn, [], rng=seed)
        for k in range(5):
            r.tick([], k * 1e-3)
        outcomes.add(r.outcome)
    assert "success" in outcomes


def test_a_way_back_yields_to_the_way_in():
    """t7 (P2 -> P1) written to yield to t1 (P1 -> P2): where both conditions hold, t1 fires and
    t7 does not, so the token does not flip between the places every tick."""
    class Holds:
        input_names = ("theta",)

        def __call__(self, x):
            return abs(float(x[0])) > 0.2                 # "in P1's region" by the angle alone

    apn, _ = add_transition(load_skill("pendulum"), "t7", {"in": ["P2"], "out": ["P1"], "law": "swing_up",
                                                            "condition": {"model": "back", "unless": "t1"}}, "test")
    assert apn.transition("t7").condition.to_data() == {"model": "back", "unless": ["t1"]}
    runner = NetRunner(apn, ["theta", "omega", "x", "xdot"], learned={"back": Holds()}, rng=0)
    assert runner.tick([3.0, 0.0, 0.0, 0.0], 0.0) == ["t0"]
    assert runner.tick([0.25, 0.5, 0.0, 0.0], 0.1) == ["t1"]         # t1 holds (|θ| < 0.3, |ω| < 2)
    assert runner.tick([0.25, 0.5, 0.0, 0.0], 0.101) == []           # back holds too, but yields to t1
    assert runner.tick([0.6, 3.0, 0.0, 0.0], 0.2) == ["t7"]          # fallen: only the way back holds
    without, _ = add_transition(load_skill("pendulum"), "t7", {"in": ["P2"], "out": ["P1"], "law": "swing_up",
                                                               "condition": {"model": "back"}}, "test")
    runner = NetRunner(without, ["theta", "omega", "x", "xdot"], learned={"back": Holds()}, rng=0)
    runner.tick([3.0, 0.0, 0.0, 0.0], 0.0), runner.tick([0.25, 0.5, 0.0, 0.0], 0.1)
    assert runner.tick([0.25, 0.5, 0.0, 0.0], 0.101) == ["t7"]       # the flip the yield prevents


def test_unless_names_a_transition_of_the_net():
    with pytest.raises(InvalidInput, match="unless"):
        add_transition(load_skill("pendulum"), "t7", {"in": ["P2"], "out": ["P1"],
                                                      "condition": {"model": "back", "unless": ["t99"]}}, "test")


def test_a_learned_switch_held_within_a_region_fires_only_inside_it():
    """``within`` holds a learned condition to a region of the state: outside it the switch does not
    fire, however high its decision; a peak guard's passage is one through both."""
    from multiform.petri.revision import set_condition
    apn, rev = set_condition(load_skill("pendulum_strict"), "t1", {"model": "sw", "within": "x > -0.1 and x < 0.1"},
                             "test")
    assert apn.transition("t1").condition.to_data() == {"model": "sw", "within": "x > -0.1 and x < 0.1"}
    assert "x" in apn.transition("t1").condition.variables
    for at_peak, expect in ((False, 3), (True, 4)):
        r = NetRunner(apn, ["theta", "omega", "x", "xdot"], learned={"sw": _Bump(at_peak)}, rng=0)
        assert r.tick([3.0, 0.0, 0.0, 0], 0.0) == ["t0"]
        fired = [r.tick([th, 0.0, x, 0], k * 1e-3)
                 for k, (th, x) in enumerate([(0.1, 0.3), (0.0, 0.3), (0.1, 0.05), (0.15, 0.05), (0.2, 0.05)], 1)]
        assert [k for k, f in enumerate(fired, 1) if f == ["t1"]] == [expect]     # not at the peak outside (k = 2)


def test_within_must_be_an_expression_over_the_skills_variables():
    from multiform.petri.revision import set_condition
    for bad in ({"model": "sw", "within": 3}, {"model": "sw", "within": "nonsense_var > 1"},
                {"model": "sw", "within": "x >"}):
        with pytest.raises(InvalidInput, match="within"):
            set_condition(load_skill("pendulum_strict"), "t1", bad, "test")
