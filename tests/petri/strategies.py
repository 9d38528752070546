"""Hypothesis strategies for random P/T nets."""

from hypothesis import strategies as st

from multiform.petri.net import APN, Condition, Place, Transition


@st.composite
def nets(draw, max_places: int = 5, max_transitions: int = 6, conditions: bool = True) -> APN:
    n_p = draw(st.integers(2, max_places))
    n_t = draw(st.integers(1, max_transitions))
    places = [Place(f"P{i}") for i in range(n_p - 1)] + [Place("end", final="success")]
    pids = [p.id for p in places]
    transitions = []
    for j in range(n_t):
        ins = draw(st.dictionaries(st.sampled_from(pids[:-1]), st.integers(1, 2), min_size=0, max_size=2))
        outs = draw(st.dictionaries(st.sampled_from(pids), st.integers(1, 2), min_size=0, max_size=2))
        if not ins and not outs:
            outs = {pids[0]: 1}
        cond = Condition.always()
        if conditions and draw(st.booleans()):
            cond = Condition.expression(f"x > {draw(st.floats(-1, 1)):.3f}", {"x"})
        lam = draw(st.sampled_from([0.0, 0.5, 1.0, 2.0, 3.0]))
        transitions.append(Transition(f"t{j}", ins, outs, None, lam, cond))
    m0 = draw(st.dictionaries(st.sampled_from(pids[:-1]), st.integers(1, 3), min_size=1, max_size=3))
    return APN(name="random", places=tuple(places), transitions=tuple(transitions), initial_marking=m0,
               variables={"x": ""})
