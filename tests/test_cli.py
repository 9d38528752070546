"""The command's conventions, the same for every sub-command: help text and a shown default for
every option, one set of defaults shared with the API, `python -m multiform`, shell completion,
one overwrite policy, distinct exit statuses for a wrong and a missing input."""

from __future__ import annotations

import argparse
import dataclasses
import inspect
import subprocess
import sys
from pathlib import Path

import pytest

from multiform import api
from multiform.cli import EXIT_MISSING, JOB_DEFAULTS, build_parser, main

TERMINAL = (argparse._HelpAction, argparse._VersionAction)


def _verbs(parser: argparse.ArgumentParser, prefix: tuple[str, ...] = ()):
    """Every (command path, parser) of the command, nested sub-commands included."""
    yield prefix, parser
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                yield from _verbs(sub, prefix + (name,))


def _is_completion(action: argparse.Action) -> bool:
    return "--print-completion" in action.option_strings


def test_every_verbs_help_gives_every_option_help_text_and_its_default(capsys):
    verbs = list(_verbs(build_parser()))
    assert len(verbs) >= 22
    for path, parser in verbs:
        with pytest.raises(SystemExit) as info:
            main([*path, "--help"])
        assert info.value.code == 0
        page = " ".join(capsys.readouterr().out.split())
        for action in parser._actions:
            if isinstance(action, (*TERMINAL, argparse._SubParsersAction)) or _is_completion(action):
                continue
            where = f"multiform {' '.join(path)} {'/'.join(action.option_strings) or action.dest}"
            assert (action.help or "").strip(), f"{where} has no help text"
            if action.option_strings and not action.required:
                text = " ".join(parser.formatter_class("x")._get_help_string(action).split()) % vars(action)
                assert "default" in text and text in page, f"{where} shows no default"


def test_one_set_of_defaults_shared_with_the_api_and_the_job():
    from multiform.job import JobConfig
    job = {f.name: f.default for f in dataclasses.fields(JobConfig)}
    assert {k: job[k] for k in JOB_DEFAULTS} == JOB_DEFAULTS
    parser = build_parser()
    verbs = dict(_verbs(parser))

    def default(path, dest):
        return next(a.default for a in verbs[path]._actions if a.dest == dest)

    for path, fn, names in ((("record",), api.record, ("demos", "workers", "seed")),
                            (("evaluate",), api.evaluate, ("trials", "seed", "push_fraction", "workers")),
                            (("practice",), api.practise, ("max_trials", "seed", "scenario", "workers")),
                            (("train",), api.train, ("seed", "workers")),
                            (("mentor",), api.mentor_rate, ("trials", "seed", "workers"))):
        for name in names:
            assert default(path, name) == inspect.signature(fn).parameters[name].default, (path, name)
    assert default(("practice",), "scenario") is None          # the task's own first scenario


def test_python_dash_m_multiform_and_version():
    out = subprocess.run([sys.executable, "-m", "multiform", "--version"], capture_output=True, text=True, timeout=60)
    assert out.returncode == 0 and out.stdout.startswith("multiform ")


def test_shell_completion_script_names_every_verb():
    out = subprocess.run([sys.executable, "-m", "multiform", "--print-completion", "bash"], capture_output=True,
                         text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    for verb in ("record", "train", "practice", "evaluate", "demo", "--overwrite", "--net-version"):
        assert verb in out.stdout
    assert "complete" in out.stdout


def test_version_of_a_net_is_net_version_and_version_is_the_programs(capsys):
    for path in (["draw", "pendulum"], ["net", "export", "pendulum"], ["evaluate", "model"]):
        with pytest.raises(SystemExit) as info:
            main([*path, "-v", "1"])
        assert info.value.code == 2
    assert "unrecognized arguments: -v" in capsys.readouterr().err


def test_every_command_that_writes_an_output_refuses_it_unless_overwrite(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    Path("n.pnml").write_text("old")
    assert main(["net", "export", "pendulum", "-o", "n.pnml"]) == 2
    assert "n.pnml: exists; pass --overwrite" in capsys.readouterr().err and Path("n.pnml").read_text() == "old"
    assert main(["net", "export", "pendulum", "-o", "n.pnml", "--overwrite"]) == 0
    assert "<pnml" in Path("n.pnml").read_text()
    Path("s.yaml").write_text("old")
    assert main(["net", "import", "n.pnml", "-o", "s.yaml"]) == 2
    assert main(["net", "import", "n.pnml", "-o", "s.yaml", "--overwrite"]) == 0 and "places" in Path("s.yaml").read_text()
    Path("d.svg").write_text("old")
    assert main(["draw", "pendulum", "-o", "d.svg"]) == 2
    assert main(["draw", "pendulum", "-o", "d.svg", "--overwrite"]) == 0 and "<svg" in Path("d.svg").read_text()
    writers = [a.dest for _, p in _verbs(build_parser()) for a in p._actions if a.dest == "overwrite"]
    assert len(writers) >= 10


def test_a_missing_input_has_its_own_exit_status_and_a_wrong_one_two(tmp_path, capsys):
    assert main(["check", str(tmp_path / "nope.yaml")]) == EXIT_MISSING
    (tmp_path / "bad.yaml").write_text("skill: [")
    assert main(["check", str(tmp_path / "bad.yaml")]) == 2
    assert main(["demos", "info", str(tmp_path / "none.h5")]) == EXIT_MISSING
    assert main(["practice", str(tmp_path / "no_model")]) == EXIT_MISSING
    err = capsys.readouterr().err
    assert "nope.yaml" in err and "none.h5" in err and "no_model: no such model directory" in err
