import numpy as np
from scipy.special import logit

from multiform.adapt.diagnosis import diagnose
from multiform.adapt.repair import adjust_lambda, repair
from multiform.petri.skillfile import load_skill

from .synthetic import make_trace


class FakeLearners:
    """Stands in for a model's learners: records what the repair asked for."""

    def __init__(self, switches=True):
        self.calls = []
        self.switches = switches

    def has_switches(self, apn, t):
        return self.switches

    def switch_condition(self, apn, t):
        self.calls.append(("switch", t))
        return f"{t}_switch", {"mentor_switches": 20}

    def region_condition(self, apn, into, away):
        self.calls.append(("region", into, away))
        return f"in_{into}", {}

    def outside_condition(self, apn, place, states):
        self.calls.append(("outside", place))
        return f"outside_{place}", {}


def vals(n, theta=3.0):
    v = np.zeros((n, 6))
    v[:, 0] = theta
    v[:, 4], v[:, 5] = np.sin(theta), np.cos(theta)
    return v


def strict_failures(apn, k=3):
    n = 300
    fir = [(0, "t0")] + [(20 * i, "t2") for i in range(1, 13)] + [(260, "t4")]
    return [make_trace(apn, fir, vals(n), "failure", enabled={"t1": 259, "t2": 259, "t4": 259},
                       held={"t1": 0, "t2": 12, "t4": 1}) for _ in range(k)]


def test_strict_t1_diagnosed_and_relearned():
    apn = load_skill("pendulum_strict")
    d = diagnose(apn, strict_failures(apn))
    assert d.failures == 3 and "t1" in d.never_fired and "t1" in d.never_held
    assert "P2" in d.never_visited and d.into_failure == {"t4": 3}
    assert not d.risky_choices                         # λ had no choice to make
    fake = FakeLearners()
    r = repair(apn, d, fake)
    assert [rev.operator for rev in r.revisions] == ["set_condition"]
    assert r.apn.transition("t1").condition.model == "t1_switch"
    assert fake.calls == [("switch", "t1")]
    assert "only way" in r.revisions[0].reason and r.revisions[0].evidence["mentor_switches"] == 20


def test_no_demonstrated_switches_no_relearning():
    apn = load_skill("pendulum_strict")
    assert repair(apn, diagnose(apn, strict_failures(apn)), FakeLearners(switches=False)) is None


def test_lambda_lowered_where_a_choice_led_to_failure():
    apn = load_skill("pendulum")
    n = 100
    fir = [(0, "t0"), (30, "t1"), (80, "t5")]
    tr = [make_trace(apn, fir, vals(n, 0.1), "failure", choices=[(80, "t5", ("t3", "t5"))]) for _ in range(3)]
    d = diagnose(apn, tr)
    assert d.risky_choices == {"t5": 3}
    r = adjust_lambda(apn, d)
    assert r.revisions[0].operator == "set_lambda" and r.apn.transition("t5").lam == 0.5
    assert sum(r.apn.transition(t).lam for t in ("t3", "t5", "t6")) == 3.0      # siblings share the rest
    assert adjust_lambda(apn, d, exhausted=frozenset({"t5"})) is None


def _pushed(apn, belongs_to_p1=True):
    n = 200
    v = vals(n, 0.05)
    v[150:, 0] = np.linspace(0.3, 0.9, 50)          # thrown out of P2 at tick 150, fails at 199
    fir = [(0, "t0"), (50, "t1"), (199, "t5")]
    tr = [make_trace(apn, fir, v, "failure") for _ in range(3)]

    def scores(states):
        th = np.abs(states[:, 0])
        p2 = (th < 0.25).astype(float) * 0.9 + 0.05
        p1 = np.where(th >= 0.25, 0.8 if belongs_to_p1 else 0.01, 0.3)
        return {"P1": p1, "P2": p2}
    return tr, scores


def test_transition_back_added_when_the_state_matches_another_place():
    apn = load_skill("pendulum")
    tr, scores = _pushed(apn)
    d = diagnose(apn, tr, scores, ("theta", "omega", "x"))
    assert [(e.place, e.best) for e in d.exits] == [("P2", "P1")] * 3
    fake = FakeLearners()
    r = repair(apn, d, fake)
    rev = r.revisions[0]
    assert rev.operator == "add_transition" and rev.target == "t7"
    t7 = r.apn.transition("t7")
    assert dict(t7.inputs) == {"P2": 1} and dict(t7.outputs) == {"P1": 1}
    assert t7.law == "swing_up" and t7.condition.model == "in_P1"      # P1's law, P1's region
    assert t7.condition.unless == ("t1",)                               # yields to the way in
    assert fake.calls == [("region", "P1", "P2")]


def test_new_place_when_no_place_relates():
    apn = load_skill("pendulum")
    tr, scores = _pushed(apn, belongs_to_p1=False)
    d = diagnose(apn, tr, scores, ("theta", "omega", "x"))
    assert all(e.best is None for e in d.exits) and len(d.exits) == 3
    r = repair(apn, d, FakeLearners())
    ops = [rev.operator for rev in r.revisions]
    assert ops == ["add_place", "add_transition", "add_transition"]
    new_place = r.revisions[0].target
    into = r.apn.transition(r.revisions[1].target)
    back = r.apn.transition(r.revisions[2].target)
    assert dict(into.inputs) == {"P2": 1} and dict(into.outputs) == {new_place: 1}
    assert dict(back.inputs) == {new_place: 1} and set(back.outputs) <= {"P1", "P2"}


def test_way_back_from_a_new_place_leads_where_the_lost_states_are_nearest():
    from multiform.adapt.diagnosis import Diagnosis, Exit
    from multiform.adapt.repair import add_new_place
    apn = load_skill("pendulum")
    for scores, home in (({"P1": 0.06, "P2": 1e-12}, "P1"),     # a spin thrown out of the swing-up
                         ({"P1": 1e-9, "P2": 1e-3}, "P2")):
        d = Diagnosis(trials=3, failures=3,
                      exits=[Exit(k, "P1", 100, [-2.1, 11.8], scores, None) for k in range(3)])
        fake = FakeLearners()
        r = add_new_place(apn, d, fake)
        new_place = r.revisions[0].target
        back = r.apn.transition(r.revisions[2].target)
        assert dict(back.inputs) == {new_place: 1} and dict(back.outputs) == {home: 1}
        assert ("region", home, new_place) in fake.calls
        assert back.law == {"P1": "swing_up", "P2": "balance"}[home]   # the law of where it goes back


def test_one_lost_trial_is_not_enough_for_a_new_place():
    apn = load_skill("pendulum")
    tr, scores = _pushed(apn, belongs_to_p1=False)
    d = diagnose(apn, tr[:1], scores, ("theta", "omega", "x"))
    assert len(d.exits) == 1 and d.exits[0].best is None
    assert repair(apn, d, FakeLearners()) is None
    d = diagnose(apn, tr[:2], scores, ("theta", "omega", "x"))
    assert repair(apn, d, FakeLearners()).revisions[0].operator == "add_place"


def test_timeouts_are_not_disturbances():
    apn = load_skill("pendulum")
    tr = strict_failures(apn)

    def scores(states):
        return {"P1": np.full(len(states), 0.1), "P2": np.full(len(states), 0.1)}
    assert diagnose(apn, tr, scores, ("theta", "omega", "x")).exits == []


def test_a_stray_just_outside_is_not_lost():
    """A state just outside P2's region, no further out than the mentor's successful stays went
    (P2 score above its floor), is not evidence for a new place; once it goes further, it is."""
    apn = load_skill("pendulum")
    n = 200
    v = vals(n, 0.05)
    v[150:, 0] = 0.3                                   # leaves P2's region, but only just
    fir = [(0, "t0"), (50, "t1"), (199, "t5")]
    tr = [make_trace(apn, fir, v, "failure") for _ in range(3)]

    def scores(states):
        th = np.abs(states[:, 0])
        return {"P1": np.full(len(states), 0.01), "P2": np.where(th < 0.25, 0.95, np.where(th < 0.5, 0.2, 1e-9))}
    assert diagnose(apn, tr, scores, ("theta", "omega", "x"), leave_below={"P2": float(logit(1e-6))}).exits == []
    # without floors, or with a state beyond them, the same trials show a lost state
    assert len(diagnose(apn, tr, scores, ("theta", "omega", "x")).exits) == 3
    v[180:, 0] = 0.9
    tr = [make_trace(apn, fir, v, "failure") for _ in range(3)]
    d = diagnose(apn, tr, scores, ("theta", "omega", "x"), leave_below={"P2": float(logit(1e-6))})
    assert [(e.best, round(e.state[0], 2)) for e in d.exits] == [(None, 0.9)] * 3
