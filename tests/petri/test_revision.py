import shutil

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from multiform.errors import InvalidInput
from multiform.petri.revision import (History, Revision, add_place, add_transition, apply, set_condition,
                                      set_lambda)
from multiform.petri.skillfile import bundled_skills, load_skill


@pytest.fixture
def skill_copy(tmp_path):
    path = tmp_path / "pendulum.yaml"
    shutil.copy(bundled_skills()["pendulum"], path)
    return path


def test_set_lambda_renormalises_siblings():
    apn = load_skill("pendulum")
    # P2's choice group: t3, t5, t6 (λ = 1 each, total 3).
    new, rev = set_lambda(apn, "t5", 0.3, "failed 5 times in a row", {"failures": 5})
    lam = {t: new.transition(t).lam for t in ("t3", "t5", "t6")}
    assert lam["t5"] == pytest.approx(0.3)
    assert lam["t3"] == pytest.approx(1.35) and lam["t6"] == pytest.approx(1.35)
    assert sum(lam.values()) == pytest.approx(3.0)
    assert new.transition("t1").lam == 1.0                     # other groups untouched
    assert rev.operator == "set_lambda" and rev.before["lambda"]["t5"] == 1.0
    assert rev.evidence == {"failures": 5}


def test_set_lambda_refuses_bad_values():
    apn = load_skill("pendulum")
    for bad in (-1.0, float("nan"), 10.0):
        with pytest.raises(InvalidInput):
            set_lambda(apn, "t5", bad, "x")
    with pytest.raises(InvalidInput, match="unknown transition"):
        set_lambda(apn, "t99", 0.5, "x")


def test_set_condition_checks_variables():
    apn = load_skill("pendulum_strict")
    new, rev = set_condition(apn, "t1", "abs(theta) < 0.2 and abs(omega) < 1.5", "never fired")
    assert str(new.transition("t1").condition) == "abs(theta) < 0.2 and abs(omega) < 1.5"
    assert rev.before == {"condition": "theta == 0 and omega == 0 and x == 0"}
    with pytest.raises(InvalidInput, match="undeclared variable 'phi'"):
        set_condition(apn, "t1", "phi < 1", "x")
    new, _ = set_condition(apn, "t1", {"model": "t1_learned"}, "relearned")
    assert new.transition("t1").condition.model == "t1_learned"


def test_add_transition_and_place():
    apn = load_skill("pendulum")
    new, rev = add_transition(apn, "t7", {"in": ["P2"], "out": ["P1"], "law": "swing_up",
                                         "condition": "abs(theta) > 0.5"}, "disturbance")
    assert new.transition("t7").inputs == {"P2": 1} and rev.before is None
    with pytest.raises(InvalidInput, match="already used"):
        add_transition(new, "t7", {"in": ["P2"], "out": ["P1"]}, "again")
    with pytest.raises(InvalidInput, match="unknown place 'P9'"):
        add_transition(apn, "t8", {"in": ["P9"], "out": ["P1"]}, "x")
    new2, _ = add_place(new, "P3", {"label": "tumbling"}, "no place relates")
    assert new2.place("P3").label == "tumbling"
    new3, _ = add_transition(new2, "t8", {"in": ["P3"], "out": ["P1"], "law": "swing_up"}, "new place")
    assert new3.transition_ids[-1] == "t8"


def test_history_replays_and_never_touches_original(skill_copy):
    original_bytes = skill_copy.read_bytes()
    hist = History(skill_copy)
    apn = hist.latest()
    apn, r1 = set_condition(apn, "t1", "abs(theta) < 0.25", "relearn")
    hist.record(r1)
    apn, r2 = add_transition(apn, "t7", {"in": ["P2"], "out": ["P1"], "law": "swing_up"}, "disturbance")
    hist.record(r2)
    versions = hist.versions()
    assert len(versions) == 3
    assert versions[-1] == apn
    assert versions[0] == load_skill(skill_copy)
    assert skill_copy.read_bytes() == original_bytes
    assert hist.path.name == "pendulum.history.jsonl"
    assert [r.version for r in hist.revisions()] == [1, 2]


def test_corrupt_history_is_refused(skill_copy):
    hist = History(skill_copy)
    hist.path.write_text('{"version": 1, "operator": "explode", "target": "t1", "reason": "", "params": {}}\n')
    with pytest.raises(InvalidInput, match="unknown revision operator"):
        hist.versions()
    hist.path.write_text("not json\n")
    with pytest.raises(InvalidInput, match="line 1"):
        hist.versions()


ops = st.sampled_from(["lambda", "condition", "transition", "place"])


@settings(max_examples=40, deadline=None)
@given(st.lists(st.tuples(ops, st.integers(0, 6), st.floats(0.0, 1.0)), min_size=1, max_size=8))
def test_replaying_history_rebuilds_every_version(tmp_path_factory, steps):
    path = tmp_path_factory.mktemp("h") / "pendulum.yaml"
    shutil.copy(bundled_skills()["pendulum"], path)
    hist = History(path)
    apn = hist.latest()
    built = [apn]
    for op, k, u in steps:
        tids = apn.transition_ids
        tid = tids[k % len(tids)]
        if op == "lambda":
            group_total = sum(apn.transition(t).lam for t in (tid, *apn.siblings(tid)))
            apn, rev = set_lambda(apn, tid, u * group_total, "random")
        elif op == "condition":
            apn, rev = set_condition(apn, tid, f"abs(theta) < {u:.4f}", "random")
        elif op == "transition":
            new = apn.fresh_id("t")
            src, dst = apn.place_ids[k % len(apn.place_ids)], apn.place_ids[(k + 1) % len(apn.place_ids)]
            apn, rev = add_transition(apn, new, {"in": [src], "out": [dst], "lambda": u}, "random")
        else:
            apn, rev = add_place(apn, apn.fresh_id("P"), {"label": f"p{u:.3f}"}, "random")
        hist.record(rev)
        built.append(apn)
    replayed = hist.versions()
    assert len(replayed) == len(built)
    for a, b in zip(built, replayed):
        assert a == b
    # and from the JSON records alone
    again = [built[0]]
    for rev in hist.revisions():
        again.append(apply(again[-1], Revision.from_json(rev.to_json())))
    assert again == built


def test_set_law_is_recorded_and_replayed(skill_copy):
    from multiform.petri.revision import set_law
    apn = load_skill(skill_copy)
    new, rev = set_law(apn, "t1", "swing_up", "the mentor's t1 segments say so", {"heldout_nrmse": {"swing_up": 0.2}})
    assert new.transition("t1").law == "swing_up" and apn.transition("t1").law == "balance"
    assert rev.operator == "set_law" and rev.before == {"law": "balance"} and rev.after == {"law": "swing_up"}
    h = History(skill_copy)
    h.record(rev)
    assert h.latest().transition("t1").law == "swing_up" and h.version(0).transition("t1").law == "balance"
    with pytest.raises(InvalidInput, match="unknown law 'kick'"):
        set_law(apn, "t1", "kick", "x")
    with pytest.raises(InvalidInput, match="unknown transition"):
        set_law(apn, "t9", "balance", "x")
