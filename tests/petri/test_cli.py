import shutil

import pytest

from multiform.cli import main
from multiform.petri.revision import History, add_transition
from multiform.petri.skillfile import bundled_skills


def test_check_reports_analysis(capsys):
    assert main(["check", "pendulum"]) == 0
    out = capsys.readouterr().out
    assert "reachability graph: 5 states" in out and "dead transitions: none" in out


def test_check_fails_on_stuck_net(tmp_path, capsys):
    path = tmp_path / "stuck.yaml"
    text = bundled_skills()["pendulum"].read_text().replace(
        "  fail: {label: failure, final: failure}", "  fail: {label: failure, final: failure}\n  trap: {label: lost}")
    text += '  t9: {in: [P1], out: [trap], condition: "abs(theta) > 3"}\n'
    path.write_text(text)
    assert main(["check", str(path)]) == 2
    captured = capsys.readouterr()
    assert "check: FAILED" in captured.err
    assert "places from which no final place can be reached: trap" in captured.out


def test_draw_and_diff_and_export(tmp_path, capsys):
    skill = tmp_path / "pendulum.yaml"
    shutil.copy(bundled_skills()["pendulum"], skill)
    hist = History(skill)
    apn, rev = add_transition(hist.latest(), "t7", {"in": ["P2"], "out": ["P1"], "law": "swing_up"}, "push")
    hist.record(rev)
    assert main(["draw", str(skill), "--net-version", "1", "-o", str(tmp_path / "v1.svg")]) == 0
    svg = (tmp_path / "v1.svg").read_text()
    assert "<svg" in svg and "t7" in svg and "#d95f02" in svg      # the change in its own colour
    assert main(["net", "diff", str(skill), "0", "1"]) == 0
    out = capsys.readouterr().out
    assert "t7" in out and "1 change(s)" in out
    assert main(["net", "export", str(skill), "--net-version", "1", "-o", str(tmp_path / "n.pnml")]) == 0
    assert main(["net", "import", str(tmp_path / "n.pnml"), "-o", str(tmp_path / "back.yaml")]) == 0
    assert "t7" in (tmp_path / "back.yaml").read_text()
    assert main(["net", "history", str(skill)]) == 0
    assert "version 1: add_transition t7" in capsys.readouterr().out


def test_output_into_a_closed_pipe_ends_quietly():
    """`multiform check pendulum | head -0`: the reader has gone before anything is written; the
    command ends with the shell's SIGPIPE status, without a traceback."""
    import os
    import subprocess
    import sys
    read, write = os.pipe()
    os.close(read)
    try:
        proc = subprocess.run([sys.executable, "-m", "multiform.cli", "check", "pendulum"], stdout=write,
                              stderr=subprocess.PIPE, text=True, timeout=60)
    finally:
        os.close(write)
    assert proc.returncode == 141, proc.stderr
    assert "Traceback" not in proc.stderr and "BrokenPipeError" not in proc.stderr


def test_export_and_draw_use_the_latest_version_and_say_so(tmp_path, capsys):
    from multiform.petri.pnml import read_pnml
    model = tmp_path / "model"
    model.mkdir()
    shutil.copy(bundled_skills()["pendulum"], model / "skill.yaml")
    hist = History(model / "skill.yaml")
    apn, rev = add_transition(hist.latest(), "t7", {"in": ["P2"], "out": ["P1"], "law": "swing_up"}, "push")
    hist.record(rev)
    assert main(["net", "export", str(model), "-o", str(tmp_path / "latest.pnml")]) == 0
    captured = capsys.readouterr()
    assert "version 1, the latest of the history" in captured.err and "(version 1)" in captured.out
    assert "t7" in read_pnml(tmp_path / "latest.pnml").transition_ids
    assert main(["net", "export", str(model), "--net-version", "0", "-o", str(tmp_path / "v0.pnml")]) == 0
    assert "t7" not in read_pnml(tmp_path / "v0.pnml").transition_ids
    assert "latest" not in capsys.readouterr().err
    assert main(["draw", str(model / "skill.yaml"), "-o", str(tmp_path / "latest.svg")]) == 0
    assert "drawing version 1" in capsys.readouterr().err
    assert "t7" in (tmp_path / "latest.svg").read_text()


@pytest.mark.parametrize("command", [[], ["net"], ["demos"], ["check"], ["draw"], ["net", "diff"], ["net", "history"],
                                     ["net", "export"], ["net", "import"], ["record"], ["demos", "info"],
                                     ["demos", "export"], ["demos", "import"], ["teleop"], ["label"], ["train"],
                                     ["practice"], ["evaluate"], ["demo"], ["replay"], ["report"]])
def test_every_help_page_prints(command, capsys):
    with pytest.raises(SystemExit) as info:
        main([*command, "--help"])
    assert info.value.code == 0
    assert "usage: multiform" in capsys.readouterr().out
