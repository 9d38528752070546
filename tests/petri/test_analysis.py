from multiform.petri.analysis import analyse
from multiform.petri.net import APN, Condition, Place, Transition
from multiform.petri.skillfile import load_skill


def T(tid, ins, outs):
    return Transition(tid, ins, outs, None, 1.0, Condition.always())


def test_pendulum_is_sound():
    r = analyse(load_skill("pendulum"))
    assert r.ok and r.bounded and not r.dead_transitions and not r.stuck_places
    assert len(r.states) == 5


def test_unbounded_place_detected():
    apn = APN("grow", (Place("P"), Place("Q"), Place("end", final="success")),
              (T("gen", {"P": 1}, {"P": 1, "Q": 1}), T("stop", {"P": 1}, {"end": 1})), {"P": 1})
    r = analyse(apn)
    assert r.unbounded_places == ["Q"]
    assert not r.truncated


def test_dead_transition_and_stuck_place():
    apn = APN("dead", (Place("P0"), Place("trap"), Place("never"), Place("end", final="success")),
              (T("go", {"P0": 1}, {"end": 1}), T("fall", {"P0": 1}, {"trap": 1}),
               T("ghost", {"never": 1}, {"end": 1})), {"P0": 1})
    r = analyse(apn)
    assert r.dead_transitions == ["ghost"]
    assert r.stuck_places == ["trap"]
    assert not r.ok


def test_state_cap_is_reported():
    # Two places exchanging tokens with a growing third: many bounded states if capped small.
    apn = APN("big", tuple(Place(f"P{i}") for i in range(6)) + (Place("end", final="success"),),
              tuple(T(f"t{i}", {f"P{i}": 1}, {f"P{(i + 1) % 6}": 1}) for i in range(6)) + (T("e", {"P0": 1}, {"end": 1}),),
              {f"P{i}": 2 for i in range(6)})
    r = analyse(apn, max_states=50)
    assert r.truncated and len(r.states) == 50 and not r.ok
