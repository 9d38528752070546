from pathlib import Path

import numpy as np
import pytest

from multiform.cli import main
from multiform.errors import InvalidInput
from multiform.petri.firing import NetRunner
from multiform.petri.net import APN, Condition, Place, Transition
from multiform.petri.skillfile import bundled_skills, dump_skill, load_skill, parse_skill

MALFORMED = sorted((Path(__file__).parent / "malformed").glob("*.yaml"))


def test_there_are_enough_malformed_files():
    assert len(MALFORMED) >= 25


@pytest.mark.parametrize("path", MALFORMED, ids=[p.stem for p in MALFORMED])
def test_malformed_file_fails_check_with_named_element(path, capsys, tmp_path, monkeypatch):
    expect = path.read_text().splitlines()[0].removeprefix("# expect: ")
    before = path.read_bytes()
    monkeypatch.chdir(tmp_path)
    assert main(["check", str(path)]) == 2
    err = capsys.readouterr().err
    assert expect in err
    assert str(path) in err
    assert path.read_bytes() == before
    assert list(tmp_path.iterdir()) == []      # nothing written


@pytest.mark.parametrize("name", ["pendulum", "pendulum_strict", "nunchaku"])
def test_bundled_skills_pass_check(name, capsys):
    assert name in bundled_skills(), f"the bundled skill {name} is missing"
    assert main(["check", name]) == 0
    assert "check: ok" in capsys.readouterr().out


def test_all_problems_reported_at_once():
    text = (Path(__file__).parent / "malformed" / "lambda_negative.yaml").read_text()
    text = text.replace("abs(theta) < 0.1", "abs(phi) < 0.1").replace("law: go", "law: run")
    with pytest.raises(InvalidInput) as info:
        parse_skill(text, "multi.yaml")
    msgs = [str(p) for p in info.value.problems]
    assert len(msgs) == 3
    assert any("transitions.t1.lambda" in m for m in msgs)
    assert any("undeclared variable 'phi'" in m for m in msgs)
    assert any("unknown law 'run'" in m for m in msgs)
    assert all(m.startswith("multi.yaml: ") for m in msgs)


def test_dump_then_load_is_identity():
    for name in ("pendulum", "pendulum_strict"):
        apn = load_skill(name)
        assert parse_skill(dump_skill(apn)) == apn


def test_pendulum_structure_matches_paper_fig5():
    apn = load_skill("pendulum")
    assert apn.transition_ids == ("t0", "t1", "t2", "t3", "t4", "t5", "t6")
    t = {tid: apn.transition(tid) for tid in apn.transition_ids}
    assert dict(t["t0"].inputs) == {"P0": 1} and dict(t["t0"].outputs) == {"P1": 1}
    assert dict(t["t1"].inputs) == {"P1": 1} and dict(t["t1"].outputs) == {"P2": 1}
    assert dict(t["t2"].outputs) == {"P1": 1} and dict(t["t3"].outputs) == {"P2": 1}
    assert apn.final_places == {"done": "success", "fail": "failure"}
    assert dict(t["t6"].outputs) == {"done": 1}
    assert set(t["t4"].outputs) == set(t["t5"].outputs) == {"fail"}
    strict = load_skill("pendulum_strict")
    assert strict.transition("t1").condition.guard.text == "theta == 0 and omega == 0 and x == 0"


def test_incidence_matrix_of_the_pendulum_net():
    apn = load_skill("pendulum")
    assert apn.place_ids == ("P0", "P1", "P2", "done", "fail")
    #                        t0  t1  t2  t3  t4  t5  t6     (t2, t3: self-loops)
    expected = np.array([[-1,  0,  0,  0,  0,  0,  0],    # P0
                         [ 1, -1,  0,  0, -1,  0,  0],    # P1
                         [ 0,  1,  0,  0,  0, -1, -1],    # P2
                         [ 0,  0,  0,  0,  0,  0,  1],    # done
                         [ 0,  0,  0,  0,  1,  1,  0]])   # fail
    assert (apn.incidence == expected).all()


def test_firing_moves_the_marking_by_its_column_of_a_weighted_net():
    t = lambda tid, i, o: Transition(tid, i, o, None, 1.0, Condition.always())  # noqa: E731
    apn = APN(name="weighted", places=(Place("A"), Place("B"), Place("C"), Place("end", final="success")),
              transitions=(t("t0", {"A": 2}, {"B": 1, "C": 3}), t("t1", {"B": 1, "C": 1}, {"A": 1}),
                           t("t2", {"C": 2}, {"end": 1})),
              initial_marking={"A": 4})
    columns = {"t0": [-2, 1, 3, 0], "t1": [1, -1, -1, 0], "t2": [0, 0, -2, 1]}
    assert (apn.incidence == np.array([columns[k] for k in ("t0", "t1", "t2")]).T).all()
    runner = NetRunner(apn, [])
    assert runner.marking_dict() == {"A": 4}
    with pytest.raises(RuntimeError, match="t1 fired while not enabled"):
        runner.fire(apn.transition_index("t1"))
    runner.reset()
    for tid in ("t0", "t1", "t0", "t2"):
        before = np.array(runner.marking)
        runner.fire(apn.transition_index(tid))
        assert (np.array(runner.marking) - before == columns[tid]).all(), tid
    assert runner.marking_dict() == {"A": 1, "B": 1, "C": 3, "end": 1} and runner.outcome == "success"
