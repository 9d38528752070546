from pathlib import Path

import pytest

from multiform.cli import main
from multiform.errors import InvalidInput
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
    if name not in bundled_skills():
        pytest.skip(f"{name} not bundled yet")
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


def test_incidence_matrix():
    apn = load_skill("pendulum")
    A = apn.incidence
    assert A.shape == (5, 7)
    assert (A == apn.post - apn.pre).all()
    assert A[apn.place_index("P1"), apn.transition_index("t2")] == 0      # self-loop
    assert A[apn.place_index("P0"), apn.transition_index("t0")] == -1
