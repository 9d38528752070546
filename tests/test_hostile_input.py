"""Every command on hostile input: exit status 2 (66 for an input that does not exist), one error line naming the culprit (a file with
several problems lists the others below it), no traceback, nothing written or changed on disk, no
module imported from data."""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import sys
from collections.abc import Callable
from pathlib import Path

import h5py
import numpy as np
import pytest

from multiform.cli import EXIT_MISSING, main
from multiform.model import SkillModel
from multiform.petri.skillfile import resolve_skill
from multiform.task import load_task
task = load_task("pendulum")

EVIL = "multiform_evil_module"          # a module that leaves a mark when imported


@pytest.fixture(scope="module")
def lab(hostile_lab) -> Path:
    """Four mentor demos and a model trained from them (see conftest's ``hostile_lab``)."""
    return hostile_lab


@pytest.fixture()
def work(lab, tmp_path, monkeypatch) -> Path:
    w = tmp_path / "w"
    shutil.copytree(lab, w)
    manifest = w / "model" / "model.json"
    manifest.write_text(manifest.read_text().replace(str((lab / "demos.h5").resolve()), str((w / "demos.h5").resolve())))
    (w / "cwd").mkdir()
    monkeypatch.chdir(w / "cwd")
    # a module on the path that leaves a mark if anything imports it
    (w / "mods").mkdir()
    (w / "mods" / f"{EVIL}.py").write_text(f"open({str(w / 'imported')!r}, 'w').write('x')\n")
    monkeypatch.syspath_prepend(str(w / "mods"))
    return w


def snapshot(root: Path) -> dict[str, str]:
    return {str(p.relative_to(root)): hashlib.sha256(p.read_bytes()).hexdigest() if p.is_file() else "dir"
            for p in sorted(root.rglob("*"))}


def edit_json(path: Path, fn: Callable[[dict], object]) -> None:
    d = json.loads(path.read_text())
    out = fn(d)
    path.write_text(json.dumps(d if out is None else out))


def with_nan(path: Path) -> None:
    """Put a NaN into the first float array of an .npz, keeping everything else (pickle-free)."""
    with np.load(path, allow_pickle=False) as npz:
        arrays = {k: npz[k] for k in npz.files}
    key = next(k for k, v in arrays.items() if v.dtype.kind == "f" and v.size)
    arrays[key] = arrays[key].copy()
    arrays[key].flat[0] = np.nan
    with open(path, "wb") as fh:
        np.savez(fh, **arrays)


def rehash(model: Path, rel: str) -> None:
    """What a careful forger does: update the manifest's hash after changing the file."""
    digest = hashlib.sha256((model / rel).read_bytes()).hexdigest()
    edit_json(model / "model.json", lambda d: d["artifacts"][rel].update(sha256=digest))


def skill_file(w: Path, text: str, name: str = "bad.yaml") -> str:
    (w / name).write_text(text)
    return str(w / name)


def _env_name(path: Path, env_id: str) -> None:
    with h5py.File(path, "r+") as f:
        d = f["data"].attrs
        args = json.loads(d["env_args"])
        args["env_name"] = env_id
        d["env_args"] = json.dumps(args)


def _history(w: Path, line: str) -> None:
    (w / "model" / "skill.history.jsonl").write_text(line + "\n")


def do(*steps):
    """Side effects evaluated in order, then ``(argv, culprit)``: the last two values."""
    return steps[-2], steps[-1]


M = ["practice"]                    # practice runs the model: it checks everything first

# Each case: (id, setup) where setup(work) prepares the hostile input and returns (argv, culprit):
# the text the error line must contain.
CASES: list[tuple[str, Callable[[Path], tuple[list[str], str]]]] = [
    # -- argument parsing ---------------------------------------------------------------------------
    ("no_command", lambda w: do([], "required")),
    ("unknown_command", lambda w: do(["fly"], "fly")),
    ("check_max_states_zero", lambda w: do(["check", "pendulum", "--max-states", "0"], "--max-states")),
    ("check_max_states_huge", lambda w: do(["check", "pendulum", "--max-states", str(10**12)], "--max-states")),
    ("check_max_states_text", lambda w: do(["check", "pendulum", "--max-states", "many"], "--max-states")),
    ("record_demos_zero", lambda w: do(["record", "pendulum", "--demos", "0", "-o", "d.h5"], "--demos")),
    ("record_demos_million", lambda w: do(["record", "pendulum", "--demos", "1000000", "-o", "d.h5"], "--demos")),
    ("record_seed_negative", lambda w: do(["record", "pendulum", "--seed", "-1", "-o", "d.h5"], "--seed")),
    ("record_workers_zero", lambda w: do(["record", "pendulum", "--workers", "0", "-o", "d.h5"], "--workers")),
    ("record_unknown_task", lambda w: do(["record", "juggling", "-o", "d.h5"], "juggling")),
    ("record_task_no_module", lambda w: do(["record", "no_such_pkg_xyz.tasks:Mine", "-o", "d.h5"], "no_such_pkg_xyz")),
    ("record_task_no_file", lambda w: do(["record", str(w / "mine.py") + ":Mine", "-o", "d.h5"], "mine.py")),
    ("record_task_no_name", lambda w: do(["record", "multiform.tasks.pendulum:Nope", "-o", "d.h5"], "Nope")),
    ("record_task_not_a_task", lambda w: do(["record", "json:dumps", "-o", "d.h5"], "json:dumps")),
    ("record_task_import_fails", lambda w: do((w / "broken.py").write_text("1/0\n"),
                                              ["record", str(w / "broken.py") + ":T", "-o", "d.h5"], "broken.py")),
    ("demo_unknown_task", lambda w: do(["demo", "juggling", "-o", "run2"], "juggling")),
    ("train_unknown_task", lambda w: do(["train", "pendulum", str(w / "demos.h5"), "-o", "m", "--task", "juggling"],
                                        "juggling")),
    ("practice_unknown_task", lambda w: do([*M, str(w / "model"), "--task", "juggling"], "juggling")),
    ("evaluate_unknown_task", lambda w: do(["evaluate", str(w / "model"), "--task", "no_such_pkg_xyz:T"],
                                           "no_such_pkg_xyz")),
    ("demo_demos_zero", lambda w: do(["demo", "pendulum", "--demos", "0", "-o", "run2"], "--demos")),
    ("demo_demos_million", lambda w: do(["demo", "pendulum", "--demos", "1000000", "-o", "run2"], "--demos")),
    ("demo_seed_negative", lambda w: do(["demo", "pendulum", "--seed", "-1", "-o", "run2"], "--seed")),
    ("demo_eval_trials_zero", lambda w: do(["demo", "pendulum", "--eval-trials", "0", "-o", "run2"], "--eval-trials")),
    ("demo_workers_zero", lambda w: do(["demo", "pendulum", "--workers", "0", "-o", "run2"], "--workers")),
    ("demo_budget_negative", lambda w: do(["demo", "pendulum", "--practice-budget", "-3", "-o", "r"],
                                          "--practice-budget")),
    ("practice_max_trials_negative", lambda w: do([*M, str(w / "model"), "--max-trials", "-5"], "--max-trials")),
    ("practice_max_trials_zero", lambda w: do([*M, str(w / "model"), "--max-trials", "0"], "--max-trials")),
    ("practice_seed_negative", lambda w: do([*M, str(w / "model"), "--seed", "-1"], "--seed")),
    ("practice_stop_after_zero", lambda w: do([*M, str(w / "model"), "--stop-after", "0"], "--stop-after")),
    ("train_seed_negative", lambda w: do(["train", "pendulum", str(w / "demos.h5"), "-o", "m", "--seed", "-1"],
                                         "--seed")),
    ("teleop_seed_negative", lambda w: do(["teleop", "pendulum", "-o", "t.h5", "--seed", "-2"], "--seed")),
    ("train_workers_zero", lambda w: do(["train", "pendulum", str(w / "demos.h5"), "-o", "m", "--workers", "0"],
                                        "--workers")),
    ("practice_workers_zero", lambda w: do(["practice", str(w / "model"), "--workers", "0"], "--workers")),
    ("net_diff_width_tiny", lambda w: do(["net", "diff", "pendulum", "0", "0", "--width", "3"], "--width")),
    ("label_seed_text", lambda w: do(["label", str(w / "demos.h5"), "-m", str(w / "model"), "--seed", "x"], "--seed")),
    # -- skill files and nets -----------------------------------------------------------------------
    ("check_missing_file", lambda w: do(["check", str(w / "nope.yaml")], "nope.yaml")),
    ("check_folder", lambda w: do(["check", str(w / "run")], "run")),
    ("check_binary", lambda w: do((w / "b.yaml").write_bytes(bytes(range(256)) * 4), ["check", str(w / "b.yaml")],
                                  "b.yaml")),
    ("check_not_yaml", lambda w: do(["check", skill_file(w, "skill: [unclosed")], "bad.yaml")),
    ("check_yaml_list", lambda w: do(["check", skill_file(w, "- a\n- b\n")], "bad.yaml")),
    ("check_deep_yaml", lambda w: do(["check", skill_file(w, "a: " + "[" * 20000 + "]" * 20000)], "bad.yaml")),
    ("draw_missing_version", lambda w: do(["draw", "pendulum", "--net-version", "5"], "version 5")),
    ("draw_history_not_object", lambda w: do((w / "h.jsonl").write_text("[1, 2]\n"),
                                             ["draw", "pendulum", "--history", str(w / "h.jsonl"), "--net-version", "1"],
                                             "h.jsonl")),
    ("net_history_bad_json", lambda w: do((w / "h.jsonl").write_text("{nope\n"),
                                          ["net", "history", "pendulum", "--history", str(w / "h.jsonl")], "h.jsonl")),
    ("net_history_missing_params", lambda w: do(
        (w / "h.jsonl").write_text(json.dumps({"version": 1, "operator": "set_lambda", "target": "t1", "reason": "x"})),
        ["net", "history", "pendulum", "--history", str(w / "h.jsonl")], "params")),
    ("net_diff_replay_fails", lambda w: do(
        (w / "h.jsonl").write_text(json.dumps({"version": 1, "operator": "set_lambda", "target": "t99", "reason": "x",
                                               "params": {"transition": "t99", "lambda": 0.5}})),
        ["net", "diff", "pendulum", "0", "1", "--history", str(w / "h.jsonl")], "record 1")),
    ("net_export_missing_version", lambda w: do(["net", "export", "pendulum", "--net-version", "3"], "version 3")),
    ("net_import_missing", lambda w: do(["net", "import", str(w / "none.pnml")], "none.pnml")),
    ("net_import_not_xml", lambda w: do((w / "x.pnml").write_text("not xml at all"), ["net", "import", str(w / "x.pnml")],
                                        "x.pnml")),
    ("net_import_entities", lambda w: do(
        (w / "e.pnml").write_text('<?xml version="1.0"?><!DOCTYPE lolz [<!ENTITY lol "lol"><!ENTITY lol2 '
                                  '"&lol;&lol;&lol;">]><pnml><net id="n">&lol2;</net></pnml>'),
        ["net", "import", str(w / "e.pnml")], "e.pnml")),
    # -- demonstration files ------------------------------------------------------------------------
    ("demos_info_missing", lambda w: do(["demos", "info", str(w / "none.h5")], "none.h5")),
    ("demos_info_text", lambda w: do((w / "t.h5").write_text("hello"), ["demos", "info", str(w / "t.h5")], "t.h5")),
    ("demos_info_empty_h5", lambda w: do(h5py.File(w / "e.h5", "w").close(), ["demos", "info", str(w / "e.h5")],
                                         "e.h5")),
    ("demos_info_truncated", lambda w: do((w / "tr.h5").write_bytes((w / "demos.h5").read_bytes()[:5000]),
                                          ["demos", "info", str(w / "tr.h5")], "tr.h5")),
    ("record_existing_file", lambda w: do(["record", "pendulum", "--demos", "1", "-o", str(w / "demos.h5")],
                                          "demos.h5")),
    ("record_folder_missing", lambda w: do(["record", "pendulum", "--demos", "1", "-o", str(w / "no" / "d.h5")],
                                           "d.h5")),
    ("record_under_a_file", lambda w: do(["record", "pendulum", "--demos", "1", "-o", str(w / "demos.h5" / "d.h5")],
                                         "d.h5")),
    ("record_onto_folder", lambda w: do(["record", "pendulum", "--demos", "1", "--overwrite", "-o", str(w / "model")],
                                        "model")),
    ("teleop_existing_without_append", lambda w: do(["teleop", "pendulum", "-o", str(w / "demos.h5")], "demos.h5")),
    ("teleop_time_scale_zero", lambda w: do(["teleop", "pendulum", "-o", "t.h5", "--time-scale", "0"],
                                            "--time-scale")),
    ("teleop_max_duration_nan", lambda w: do(["teleop", "pendulum", "-o", "t.h5", "--max-duration", "nan"],
                                             "--max-duration")),
    ("teleop_no_display", lambda w: do(["teleop", "pendulum", "-o", "t.h5"], "display")),
    # -- training -----------------------------------------------------------------------------------
    ("train_into_existing_model", lambda w: do(["train", "pendulum", str(w / "demos.h5"), "-o", str(w / "model")],
                                               "model")),
    ("train_missing_skill", lambda w: do(["train", str(w / "s.yaml"), str(w / "demos.h5"), "-o", "m"], "s.yaml")),
    ("train_demos_not_h5", lambda w: do((w / "d.txt").write_text("x"), ["train", "pendulum", str(w / "d.txt"), "-o", "m"],
                                        "d.txt")),
    ("train_inverse_without_trainer", lambda w: do(
        shutil.copy(w / "demos.h5", w / "n.h5"), _env_name(w / "n.h5", "Other-v0"),
        ["train", "pendulum", str(w / "n.h5"), "-o", "m", "--inverse-model"], "--inverse-model")),
    # -- model directories --------------------------------------------------------------------------
    ("practice_not_a_model", lambda w: do([*M, str(w / "cwd")], "skill.yaml")),
    ("practice_unknown_scenario", lambda w: do([*M, str(w / "model"), "--scenario", "zz"], "zz")),
    ("draw_unknown_picture_format", lambda w: do(["draw", "pendulum", "-o", "net.txt"], "net.txt")),
    # reset options the env refuses: refused before the first trial writes a practice state
    ("practice_unknown_reset_option", lambda w: do([*M, str(w / "model"), "--options", '{"lenght": 0.3}'], "lenght")),
    ("practice_reset_option_out_of_range", lambda w: do([*M, str(w / "model"), "--options", '{"length": -1}'],
                                                        "options")),
    ("evaluate_unknown_reset_option", lambda w: do(["evaluate", str(w / "model"), "--trials", "2", "--options",
                                                    '{"lenght": 0.3}', "-o", "ev"], "lenght")),
    ("model_json_not_json", lambda w: do((w / "model" / "model.json").write_text("{"), [*M, str(w / "model")],
                                         "model.json")),
    ("model_json_list", lambda w: do((w / "model" / "model.json").write_text("[]"), [*M, str(w / "model")],
                                     "model.json")),
    ("model_json_old_version", lambda w: do(edit_json(w / "model" / "model.json", lambda d: d.update(format_version=1)),
                                            [*M, str(w / "model")], "manifest version")),
    ("model_env_wrong_type", lambda w: do(edit_json(w / "model" / "model.json", lambda d: d.update(env=42)),
                                          [*M, str(w / "model")], "env")),
    ("model_env_kwargs_wrong_type", lambda w: do(edit_json(w / "model" / "model.json", lambda d: d.update(env_kwargs=[1])),
                                                 [*M, str(w / "model")], "env_kwargs")),
    ("model_env_imports_module", lambda w: do(
        edit_json(w / "model" / "model.json", lambda d: d.update(env=f"{EVIL}:Foo-v0")), [*M, str(w / "model")], EVIL)),
    ("model_env_unregistered", lambda w: do(edit_json(w / "model" / "model.json", lambda d: d.update(env="Nope-v9")),
                                            [*M, str(w / "model")], "Nope-v9")),
    ("model_torque_without_inverse", lambda w: do(
        edit_json(w / "model" / "model.json", lambda d: d["env_kwargs"].update(action_mode="torque")),
        [*M, str(w / "model")], "inverse_model.npz")),
    ("model_listed_artifact_deleted", lambda w: do((w / "model" / "judges" / "P1.npz").unlink(),
                                                   [*M, str(w / "model")], "P1.npz")),
    ("model_law_deleted", lambda w: do((w / "model" / "laws" / "balance.npz").unlink(), [*M, str(w / "model")],
                                       "balance.npz")),
    ("model_law_nan_hash_stale", lambda w: do(with_nan(w / "model" / "laws" / "balance.npz"), [*M, str(w / "model")],
                                              "balance.npz")),
    ("model_law_nan_forged_hash", lambda w: do(with_nan(w / "model" / "laws" / "balance.npz"),
                                               rehash(w / "model", "laws/balance.npz"), [*M, str(w / "model")],
                                               "non-finite")),
    ("model_judge_nan_forged_hash", lambda w: do(with_nan(w / "model" / "judges" / "P2.npz"),
                                                 rehash(w / "model", "judges/P2.npz"), [*M, str(w / "model")],
                                                 "P2.npz")),
    ("model_regions_nan_forged_hash", lambda w: do(with_nan(w / "model" / "regions.npz"),
                                                   rehash(w / "model", "regions.npz"), [*M, str(w / "model")],
                                                   "regions.npz")),
    ("model_regions_bitflip", lambda w: do(
        (w / "model" / "regions.npz").write_bytes((w / "model" / "regions.npz").read_bytes()[:-40] + b"\x00" * 40),
        [*M, str(w / "model")], "regions.npz")),
    ("model_unlisted_law", lambda w: do(shutil.copy(w / "model" / "laws" / "balance.npz", w / "model" / "laws" / "x.npz"),
                                        [*M, str(w / "model")], "x.npz")),
    ("model_artifact_path_escapes", lambda w: do(
        edit_json(w / "model" / "model.json",
                  lambda d: d["artifacts"].update({"../../etc/passwd": {"kind": "law", "sha256": "0" * 64}})),
        [*M, str(w / "model")], "passwd")),
    ("model_skill_changed", lambda w: do(
        (w / "model" / "skill.yaml").write_text((w / "model" / "skill.yaml").read_text() + "\n# edited\n"),
        [*M, str(w / "model")], "skill.yaml")),
    ("model_history_not_object", lambda w: do(_history(w, "7"), [*M, str(w / "model")], "record 1")),
    ("model_history_unknown_operator", lambda w: do(
        _history(w, json.dumps({"version": 1, "operator": "rm_rf", "target": "/", "reason": "", "params": {}})),
        [*M, str(w / "model")], "rm_rf")),
    ("label_not_a_model", lambda w: do(["label", str(w / "demos.h5"), "-m", str(w / "cwd"), "--script", "s"],
                                       "skill.yaml")),
    ("label_model_tampered", lambda w: do((w / "model" / "judges" / "P1.npz").write_bytes(b"PK\x03\x04junk"),
                                          ["label", str(w / "demos.h5"), "-m", str(w / "model"), "--script", "s"],
                                          "P1.npz")),
    # -- run folders --------------------------------------------------------------------------------
    ("report_no_metrics", lambda w: do(["report", str(w / "run")], "metrics.json")),
    ("report_metrics_broken", lambda w: do((w / "run" / "metrics.json").write_text('{"skill": '),
                                           ["report", str(w / "run")], "metrics.json")),
    ("report_metrics_list", lambda w: do((w / "run" / "metrics.json").write_text("[1]"), ["report", str(w / "run")],
                                         "metrics.json")),
    ("report_metrics_wrong_types", lambda w: do(
        (w / "run" / "metrics.json").write_text(json.dumps({"skill": "pendulum", "success_rate": 5, "demos": 3})),
        ["report", str(w / "run")], "metrics.json")),
    ("evaluate_not_a_model", lambda w: do(["evaluate", str(w / "cwd")], "skill.yaml")),
    ("evaluate_trials_zero", lambda w: do(["evaluate", str(w / "model"), "--trials", "0"], "--trials")),
    ("evaluate_push_fraction", lambda w: do(["evaluate", str(w / "model"), "--push-fraction", "2"], "--push-fraction")),
    ("evaluate_missing_version", lambda w: do(["evaluate", str(w / "model"), "--net-version", "4"], "version 4")),
    ("evaluate_tampered_law", lambda w: do((w / "model" / "laws" / "swing_up.npz").write_bytes(b"x"),
                                           ["evaluate", str(w / "model")], "swing_up.npz")),
    ("evaluate_out_is_a_file", lambda w: do(["evaluate", str(w / "model"), "--out", str(w / "demos.h5")], "demos.h5")),
    ("replay_missing_source", lambda w: do(["replay", str(w / "none.h5")], "none.h5")),
    ("replay_demo_out_of_range", lambda w: do(["replay", str(w / "demos.h5"), "--demo", "99"], "99")),
    ("replay_fps_zero", lambda w: do(["replay", str(w / "demos.h5"), "--fps", "0"], "--fps")),
    ("replay_not_a_trace", lambda w: do((w / "t.npz").write_bytes(b"junk"), ["replay", str(w / "t.npz")], "t.npz")),
    ("demos_export_missing", lambda w: do(["demos", "export", str(w / "none.h5"), "-o", "lr"], "none.h5")),
    # --overwrite replaces a folder of what the command writes, never a folder of something else
    ("demos_export_overwrite_a_foreign_folder", lambda w: do((w / "mine").mkdir(), (w / "mine" / "notes.txt").write_text("x"),
                                                             ["demos", "export", str(w / "demos.h5"), "-o", str(w / "mine"),
                                                              "--overwrite"], "meta/info.json")),
    ("train_overwrite_a_foreign_folder", lambda w: do((w / "mine").mkdir(), (w / "mine" / "notes.txt").write_text("x"),
                                                      ["train", "pendulum", str(w / "demos.h5"), "-o", str(w / "mine"),
                                                       "--overwrite"], "model.json")),
    ("demos_import_not_a_dataset", lambda w: do(["demos", "import", str(w / "run"), "-o", "d.h5"], "run")),
    ("demo_out_under_a_file", lambda w: do(["demo", "pendulum", "--demos", "2", "-o", str(w / "demos.h5" / "run")],
                                           "run")),
]


# -- a run folder is data, numbers are bounded where they enter, no input blocks or forges a line --

def _run_folder(w: Path, task_name: str = "pendulum", config: dict | None = None, trials: int = 2,
                **metrics) -> Path:
    """A finished run's metrics.json and evaluation_trials.json (its model is not needed to refuse it)."""
    seeds = [s.seed for s in task.evaluation_specs(trials, 0, 0.5)]
    cfg = {"eval_trials": trials, "seed": 0, "push_fraction": 0.5, "videos": False, "inverse_model": False,
           **(config or {})}
    (w / "run" / "metrics.json").write_text(json.dumps({"skill": "pendulum", "task": task_name, "task_spec": task_name,
                                                        "config": cfg, "scenarios": {}, "revisions": [], **metrics}))
    detail = [{"seed": s, "success": True, "self_success": True, "pushed": False, "fired": ["t0"]} for s in seeds]
    (w / "run" / "evaluation_trials.json").write_text(json.dumps({"multiform": detail}))
    return w / "run"


def _demos(w: Path, edit: Callable[[h5py.File], None], name: str = "n.h5") -> str:
    """A copy of the demos with ``edit`` applied to the open file."""
    shutil.copy(w / "demos.h5", w / name)
    with h5py.File(w / name, "r+") as f:
        edit(f)
    return str(w / name)


def _replace(g: h5py.Group, key: str, data) -> None:
    del g[key]
    g.create_dataset(key, data=data)


def _attr_json(path: str, value) -> Callable[[h5py.File], None]:
    def edit(f: h5py.File) -> None:
        f[path.rsplit("/", 1)[0]].attrs[path.rsplit("/", 1)[1]] = value if isinstance(value, str) else json.dumps(value)
    return edit


def _env_kwargs(**kwargs) -> Callable[[h5py.File], None]:
    def edit(f: h5py.File) -> None:
        args = json.loads(f["data"].attrs["env_args"])
        args["env_kwargs"].update(kwargs)
        f["data"].attrs["env_args"] = json.dumps(args)
    return edit


def _all_labels_failed(f: h5py.File) -> None:
    for k in f["data"]:
        labels = f["data"][k]["labels"][()]
        labels["success"] = 0
        _replace(f["data"][k], "labels", labels)


def _only_transition(tag: str) -> Callable[[h5py.File], None]:
    """Every sample and label tagged with the one transition ``tag``."""
    def edit(f: h5py.File) -> None:
        code = json.loads(f["data"].attrs["transition_names"]).index(tag)
        for k in f["data"]:
            g = f["data"][k]
            _replace(g, "transition", np.full_like(g["transition"][()], code))
            labels = g["labels"][()]
            labels["transition"] = tag.encode()
            _replace(g, "labels", labels)
    return edit


def _action_past_the_scale(f: h5py.File) -> None:
    """A format-2 file (actions stored divided by a power-of-two scale) with one action finite as
    stored, infinite once multiplied by the file's action scale (2**1023 here; every other action 0)."""
    d = f["data"]
    d.attrs["format_version"] = 2
    for key in ("action_low", "action_high"):
        if key in d.attrs:
            del d.attrs[key]
    d.attrs["action_scale"] = np.full(len(json.loads(d.attrs["command_names"])), 2.0 ** 1023)
    for k in (k for k in d if k.startswith("demo_")):
        if "commands" in d[k]:
            del d[k]["commands"]
        actions = np.zeros_like(d[k]["actions"][()])
        actions[3, 0] = 2.5 if k == "demo_0" else 0.0
        _replace(d[k], "actions", actions)


def _command_out_of_range(f: h5py.File) -> None:
    """One of the exact commands training reads (format 3) finite but far beyond any physical value."""
    d = f["data"]["demo_0"]
    commands = d["commands"][()]
    commands[3, 0] = 1.7e308
    _replace(d, "commands", commands)


def _observation(value: float) -> Callable[[h5py.File], None]:
    def edit(f: h5py.File) -> None:
        g = f["data/demo_1/obs"]
        key = sorted(g)[0]
        col = g[key][()].astype(np.float64)
        col[4, 0] = value
        _replace(g, key, col)
    return edit


def _fifo(path: Path) -> str:
    path.unlink(missing_ok=True)
    os.mkfifo(path)
    return str(path)


def _chain(n: int) -> str:
    """A chain net of ``n`` places."""
    lines = ["skill: chain", "variables: [x]", "commands: [u]", "places:"]
    lines += [f"  P{i}: {{label: p{i}}}" for i in range(n - 1)] + [f"  P{n - 1}: {{final: success}}"]
    lines += ["initial_marking: {P0: 1}", "transitions:"] + [f"  t{i}: {{in: [P{i}], out: [P{i + 1}]}}"
                                                              for i in range(n - 1)]
    return "\n".join(lines) + "\n"


BOMB = ("a: &a [x, x, x, x, x, x, x, x, x, x]\n"
        + "".join(f"{c}: &{c} [{', '.join(['*' + p] * 10)}]\n" for p, c in zip("abcdefgh", "bcdefghi")))
PENDULUM_TEXT = resolve_skill("pendulum").read_text()
DEEP_JSON = "[" * 100_000 + "]" * 100_000


def _redraw(w: Path) -> list[str]:
    return ["report", str(w / "run"), "--redraw"]


def _skill(w: Path, old: str, new: str) -> str:
    assert old in PENDULUM_TEXT
    return skill_file(w, PENDULUM_TEXT.replace(old, new, 1))


CASES += [
    # 1. report --redraw runs only the task the user names; a run folder's config is bounded
    ("redraw_task_spec_names_a_module", lambda w: do(_run_folder(w, f"{EVIL}:T"), _redraw(w), "metrics.json")),
    ("redraw_task_spec_names_a_file", lambda w: do(
        (w / "evil.py").write_text(f"open({str(w / 'imported')!r}, 'w').write('x')\n"),
        _run_folder(w, str(w / "evil.py") + ":T"), _redraw(w), "metrics.json")),
    ("redraw_task_unknown_name", lambda w: do(_run_folder(w, "juggling"), _redraw(w), "juggling")),
    ("redraw_task_not_text", lambda w: do(_run_folder(w, ["pendulum"]), _redraw(w), "metrics.json")),
    ("redraw_user_task_missing", lambda w: do(_run_folder(w), [*_redraw(w), "--task", "no_such_pkg_xyz:T"],
                                              "no_such_pkg_xyz")),
    ("redraw_eval_trials_huge", lambda w: do(_run_folder(w, config={"eval_trials": 10**12}), _redraw(w),
                                             "config.eval_trials")),
    ("redraw_eval_trials_text", lambda w: do(_run_folder(w, config={"eval_trials": "200"}), _redraw(w),
                                             "config.eval_trials")),
    ("redraw_seed_negative", lambda w: do(_run_folder(w, config={"seed": -1}), _redraw(w), "config.seed")),
    ("redraw_push_fraction_nan", lambda w: do(_run_folder(w, config={"push_fraction": float("nan")}), _redraw(w),
                                              "config.push_fraction")),
    ("redraw_videos_not_bool", lambda w: do(_run_folder(w, config={"videos": "yes"}), _redraw(w), "config.videos")),
    ("redraw_config_a_list", lambda w: do(_run_folder(w), edit_json(w / "run" / "metrics.json",
                                                                    lambda d: d.update(config=[1])),
                                          _redraw(w), "config")),
    ("redraw_trials_disagree_with_config", lambda w: do(_run_folder(w, config={"eval_trials": 3}), _redraw(w),
                                                        "evaluation_trials.json")),
    ("redraw_scenario_name_a_path", lambda w: do(_run_folder(w, scenarios={"../../../tmp/x": {"title": "x"}}),
                                                 _redraw(w), "scenarios")),
    ("report_metrics_a_fifo", lambda w: do(_fifo(w / "run" / "metrics.json"), ["report", str(w / "run")],
                                           "metrics.json")),
    ("report_metrics_nested_deep", lambda w: do((w / "run" / "metrics.json").write_text(DEEP_JSON),
                                                ["report", str(w / "run")], "metrics.json")),
    # 7. analysis and YAML bounded
    ("check_alias_bomb_description", lambda w: do(["check", skill_file(w, BOMB + "skill: x\ndescription: *i\n")],
                                                  "bad.yaml")),
    ("check_alias_bomb_label", lambda w: do(["check", _skill(w, "P0:   {label: hanging at rest}",
                                                             "P0:   {label: *i}\n" + "".join(
                                                                 "  " + line + "\n" for line in BOMB.splitlines()))],
                                            "bad.yaml")),
    ("check_alias_holds_itself", lambda w: do(["check", skill_file(w, "skill: &s [1, *s]\n")], "bad.yaml")),
    ("check_dev_urandom", lambda w: do(["check", "/dev/urandom"], "/dev/urandom")),
    ("check_fifo", lambda w: do(["check", _fifo(w / "f.yaml")], "f.yaml")),
    ("check_file_too_large", lambda w: do((w / "big.yaml").write_text("# " + "x" * (17 << 20) + "\n"),
                                          ["check", str(w / "big.yaml")], "big.yaml")),
    ("check_max_seconds_zero", lambda w: do(["check", "pendulum", "--max-seconds", "0"], "--max-seconds")),
    ("check_max_seconds_nan", lambda w: do(["check", "pendulum", "--max-seconds", "nan"], "--max-seconds")),
    # 8. numbers range-checked where they enter
    ("check_max_duration_huge", lambda w: do(["check", _skill(w, "max_duration: 30.0", "max_duration: 1e12")],
                                             "max_duration")),
    ("check_control_rate_huge", lambda w: do(["check", _skill(w, "control_rate: 1000", "control_rate: 1e9")],
                                             "control_rate")),
    ("check_lambda_huge", lambda w: do(["check", _skill(w, "law: swing_up, lambda: 1.0", "law: swing_up, lambda: 1e300")],
                                       "lambda")),
    ("train_action_infinite_after_scale", lambda w: do(
        ["train", "pendulum", _demos(w, _action_past_the_scale), "-o", "m"], "actions")),
    ("train_command_out_of_range", lambda w: do(
        ["train", "pendulum", _demos(w, _command_out_of_range), "-o", "m"], "commands")),
    ("train_observation_1e308", lambda w: do(["train", "pendulum", _demos(w, _observation(1e308)), "-o", "m"], "obs/")),
    ("demos_info_observation_1e20", lambda w: do(["demos", "info", _demos(w, _observation(1e20))], "obs/")),
    ("train_reset_options_deep", lambda w: do(
        ["train", "pendulum", _demos(w, _attr_json("data/demo_0/reset_options", DEEP_JSON)), "-o", "m"],
        "reset_options")),
    ("train_reset_options_huge_number", lambda w: do(
        ["train", "pendulum", _demos(w, _attr_json("data/demo_0/reset_options", {"x0": 1e300})), "-o", "m"],
        "reset_options")),
    ("train_reset_options_a_list", lambda w: do(
        ["train", "pendulum", _demos(w, _attr_json("data/demo_0/reset_options", [1, 2])), "-o", "m"],
        "reset_options")),
    ("train_demo_seed_negative", lambda w: do(
        ["train", "pendulum", _demos(w, lambda f: f["data/demo_2"].attrs.__setitem__("seed", -5)), "-o", "m"],
        "seed")),
    ("train_env_kwargs_nan", lambda w: do(["train", "pendulum", _demos(w, _env_kwargs(gain=float("nan"))), "-o", "m"],
                                          "env_kwargs")),
    ("train_env_args_a_list", lambda w: do(["train", "pendulum", _demos(w, _attr_json("data/env_args", [1])), "-o", "m"],
                                           "env_args")),
    ("model_env_kwargs_huge", lambda w: do(
        edit_json(w / "model" / "model.json", lambda d: d["env_kwargs"].update(action_limit=1e300)),
        [*M, str(w / "model")], "env_kwargs")),
    ("model_env_kwargs_refused_by_the_env", lambda w: do(
        edit_json(w / "model" / "model.json", lambda d: d["env_kwargs"].update(gains=5)),
        [*M, str(w / "model")], "env_kwargs")),
    # 9. bad training data: exit 2 naming the file
    ("train_all_segments_failed", lambda w: do(["train", "pendulum", _demos(w, _all_labels_failed), "-o", "m"], "n.h5")),
    ("train_one_transition_demonstrated", lambda w: do(
        ["train", "pendulum", _demos(w, _only_transition("t1")), "-o", "m"], "n.h5")),
    ("train_env_kwargs_refused_by_the_env", lambda w: do(
        ["train", "pendulum", _demos(w, _env_kwargs(gains=5)), "-o", "m"], "n.h5")),
    # 11. FIFOs, deep nesting, forged lines, code named in data
    ("practice_demos_a_fifo", lambda w: do(
        _fifo(w / "d.fifo"), edit_json(w / "model" / "model.json", lambda d: d.update(demos=str(w / "d.fifo"))),
        [*M, str(w / "model")], "d.fifo")),
    ("demos_info_a_fifo", lambda w: do(["demos", "info", _fifo(w / "f.h5")], "f.h5")),
    ("replay_a_fifo", lambda w: do(["replay", _fifo(w / "f.h5")], "f.h5")),
    ("net_history_a_fifo", lambda w: do(["net", "history", "pendulum", "--history", _fifo(w / "h.jsonl")], "h.jsonl")),
    ("net_import_a_fifo", lambda w: do(["net", "import", _fifo(w / "n.pnml")], "n.pnml")),
    ("net_import_a_folder", lambda w: do(["net", "import", str(w / "run")], "run")),
    ("model_json_a_fifo", lambda w: do(_fifo(w / "model" / "model.json"), [*M, str(w / "model")], "model.json")),
    ("model_json_nested_deep", lambda w: do((w / "model" / "model.json").write_text(DEEP_JSON), [*M, str(w / "model")],
                                            "model.json")),
    ("model_history_nested_deep", lambda w: do(_history(w, DEEP_JSON), [*M, str(w / "model")], "skill.history.jsonl")),
    ("label_labels_nested_deep", lambda w: do(
        (w / "model" / "labels.jsonl").write_text(DEEP_JSON + "\n"),
        ["label", str(w / "demos.h5"), "-m", str(w / "model"), "--script", "s"], "labels.jsonl")),
    ("replay_demo_env_names_a_module", lambda w: do(
        ["replay", _demos(w, _attr_json("data/env_args", {"env_name": f"{EVIL}:Foo-v0", "type": 2, "env_kwargs": {}}))],
        EVIL)),
    ("check_newline_in_path", lambda w: do(["check", str(w / "a\nmultiform: error: forged.yaml")],
                                           "a\\nmultiform: error: forged.yaml")),
    ("record_newline_in_out", lambda w: do(["record", "pendulum", "--demos", "1", "-o", str(w / "no" / "x\ny.h5")],
                                           "x\\ny.h5")),
    ("check_escape_sequence_in_path", lambda w: do(["check", str(w / "\x1b[31mred.yaml")], "\\x1b[31mred.yaml")),
    ("unknown_command_with_newline", lambda w: do(["fl\ny"], "fl")),
]


# inputs that do not exist: their own exit status (66), every other case 2
MISSING = {"check_missing_file", "net_import_missing", "demos_info_missing", "train_missing_skill",
           "replay_missing_source", "demos_export_missing", "record_task_no_file", "report_no_metrics",
           "check_newline_in_path", "check_escape_sequence_in_path"}


def run(argv: list[str]) -> int:
    try:
        return main(argv)
    except SystemExit as exc:        # argparse
        return int(exc.code or 0)


@pytest.mark.parametrize("case", [c[0] for c in CASES])
def test_hostile_input_is_refused_in_one_line_and_changes_nothing(work, case, capsys, monkeypatch):
    setup = dict(CASES)[case]
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    argv, culprit = setup(work)
    before = snapshot(work)
    code = run(argv)
    err = capsys.readouterr().err
    assert code == (EXIT_MISSING if case in MISSING else 2), err
    first, *more = err.strip().splitlines()
    assert first.startswith("multiform") and "error" in first and culprit in first, err
    # a file with several problems lists the others, one per line, each naming the file again
    assert all(line.startswith("  ") and culprit in line for line in more), err
    assert "Traceback" not in err
    assert snapshot(work) == before
    assert not (work / "imported").exists() and EVIL not in sys.modules


def test_there_are_at_least_sixty_cases():
    assert len(CASES) >= 150


def test_default_outputs_stay_in_the_current_folder(work, capsys):
    """A net named like a path (from a file anyone may have written) lands as a base name here."""
    text = resolve_skill("pendulum").read_text()
    evil = skill_file(work, text.replace("skill: pendulum", "skill: ../../../evil/net", 1), "evil.yaml")
    assert run(["net", "export", evil]) == 0
    assert run(["draw", evil]) == 0
    assert sorted(p.name for p in Path.cwd().iterdir()) == ["net.pnml", "net.svg"]
    assert not (work.parent.parent / "evil").exists()
    assert run(["net", "import", "net.pnml"]) == 0
    assert (Path.cwd() / "net.yaml").exists()


def test_internal_errors_are_one_line_unless_debug(work, capsys, monkeypatch):
    import multiform.cli as cli

    def boom(args):
        raise RuntimeError("a bug")
    monkeypatch.setattr(cli, "cmd_check", boom)
    assert run(["check", "pendulum"]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "RuntimeError: a bug" in err and "--debug" in err
    with pytest.raises(RuntimeError):
        main(["--debug", "check", "pendulum"])


def test_the_model_lists_every_artifact_with_its_hash(lab):
    model = SkillModel(lab / "model")
    listed = model.manifest["artifacts"]
    on_disk = {p.relative_to(model.path).as_posix() for p in model.path.rglob("*.npz")} | {"skill.yaml"}
    assert set(listed) == on_disk
    for rel, info in listed.items():
        assert info["sha256"] == hashlib.sha256((model.path / rel).read_bytes()).hexdigest()
    assert model.problems() == []


def test_training_that_fails_leaves_no_model_behind(lab, tmp_path, monkeypatch, capsys):
    import multiform.trainer as trainer

    def fail(*a, **k):
        raise OSError(28, "No space left on device", str(tmp_path / "m" / "laws"))
    monkeypatch.setattr(trainer, "train_model", fail)
    assert run(["train", "pendulum", str(lab / "demos.h5"), "-o", str(tmp_path / "m")]) == 2
    assert "No space left on device" in capsys.readouterr().err
    assert sorted(os.listdir(tmp_path)) == []


# -- faults: a non-finite value in the tick ends the trial at once, never reaches MuJoCo, teaches nothing

class _Watch:
    """Wraps the env's step: every action and every ctrl MuJoCo held after the step must be finite."""

    def __init__(self, env):
        self.env, self.bad, self.steps = env, 0, 0
        inner = env.step

        def step(action):
            self.bad += int(not np.isfinite(np.asarray(action, float)).all())
            out = inner(action)
            self.bad += int(not np.isfinite(env.unwrapped.data.ctrl).all())
            self.steps += 1
            return out
        env.step = step


class _NaNAfter:
    """A learned piece that turns non-finite after ``tick`` calls (a corrupt artifact in memory)."""

    def __init__(self, inner, tick: int, method: str):
        self.inner, self.tick, self.calls, self.method = inner, tick, 0, method

    def __getattr__(self, name):
        return getattr(self.inner, name)

    def _wrap(self, *a):
        self.calls += 1
        out = np.array(getattr(self.inner, self.method)(*a), dtype=float)
        return out * np.nan if self.calls > self.tick else out

    def predict_one(self, x):
        return self._wrap(x)

    def torques(self, obs, cmd):
        return self._wrap(obs, cmd)


class _ZeroTorque:
    def torques(self, obs, cmd):
        return np.zeros(6)


def _sim_nan(tick: int):
    def perturb(k, runner, env):
        if k == tick:
            env.unwrapped.data.qvel[0] = np.nan
    return perturb


@pytest.mark.parametrize("where", ["law", "inverse_model", "simulator_state", "observation"])
def test_a_non_finite_value_ends_the_trial_as_a_fault_before_it_reaches_mujoco(lab, where):
    from multiform.runtime.executor import Executor
    model = SkillModel(lab / "model")
    kwargs = {"action_mode": "torque"} if where == "inverse_model" else {}
    env = model.make_env(**kwargs)
    watch = _Watch(env)
    laws = model.laws()
    inverse = None
    perturb = None
    if where == "law":
        laws = {name: _NaNAfter(law, 300, "predict_one") for name, law in laws.items()}
    elif where == "inverse_model":
        inverse = _NaNAfter(_ZeroTorque(), 20, "torques")
    elif where == "simulator_state":
        perturb = _sim_nan(300)
    else:
        from gymnasium.wrappers import TransformObservation
        base = env
        env = TransformObservation(base, lambda obs: obs * np.nan if base.unwrapped.data.time > 0.3 else obs,
                                   base.observation_space)
    ex = Executor(model.apn, env, laws, model.conditions(), inverse)
    trace = ex.run(seed=5, perturb=perturb)
    assert trace.outcome == "fault" and not trace.success
    expected = {"law": "law ", "inverse_model": "inverse model torque", "simulator_state": "simulator state",
                "observation": "observation"}[where]
    assert trace.fault.startswith(expected), trace.fault
    assert watch.bad == 0 and watch.steps <= (21 if where == "inverse_model" else 320)
    assert np.isfinite(trace.commands).all()
    assert task.physical_success(trace) is False and model.grade(trace, "x").score == 0.0
    env.close()


def test_practice_stops_at_a_fault_and_learns_nothing_from_it(work):
    from multiform.adapt.practice import Practice, PracticeConfig
    model = SkillModel(work / "model")
    practice = Practice(model, work / "p", PracticeConfig(max_trials=10, failures_in_a_row=1),
                        options=task.demo_options, perturb=lambda k: _sim_nan(200), name="a_strict")
    state = practice.run()
    assert state.stop_reason.startswith("fault in trial 0: simulator state") and not state.done
    assert state.trials == [] and state.failed_since_repair == [] and state.revisions == []
    assert model.version == 0 and (work / "p" / "faults" / "trial_0000.npz").exists()
    assert not (work / "p" / "traces").exists()


# -- two writers at once: one proceeds, one is refused, nothing is lost

def test_a_second_writer_of_a_model_or_a_demos_file_is_refused(work, capsys):
    import subprocess
    import textwrap
    holder = textwrap.dedent(f"""
        import sys, time
        from multiform.lock import exclusive
        with exclusive({str(work / 'model')!r}), exclusive({str(work / 'cwd' / 'd.h5')!r}):
            print("holding", flush=True)
            time.sleep(60)
    """)
    proc = subprocess.Popen([sys.executable, "-c", holder], stdout=subprocess.PIPE, text=True)
    try:
        assert proc.stdout.readline().strip() == "holding"
        before = snapshot(work)
        assert run(["practice", str(work / "model"), "--max-trials", "1"]) == 2
        err = capsys.readouterr().err
        assert f"in use by PID {proc.pid}" in err and "model" in err
        assert run(["record", "pendulum", "--demos", "1", "-o", "d.h5"]) == 2
        assert f"in use by PID {proc.pid}" in capsys.readouterr().err
        assert snapshot(work) == before
    finally:
        proc.kill()
        proc.wait()
    # the holder is gone (killed, not cleaned up): its locks went with it
    from multiform.lock import exclusive
    with exclusive(work / "model"):
        pass


def test_evaluate_runs_the_models_task_and_writes_every_trial(work, capsys):
    assert run(["evaluate", str(work / "model"), "--trials", "4", "--workers", "1", "--out", "ev"]) == 0
    out = capsys.readouterr().out
    assert "success" in out and "95 % CI" in out
    data = json.loads((Path("ev") / "evaluation.json").read_text())
    assert data["task"] == "pendulum" and data["trials"] == 4 and len(data["trials_detail"]) == 4
    assert [t["seed"] for t in data["trials_detail"]] == [s.seed for s in task.evaluation_specs(4, 0, 0.5)]
    assert {"outcome", "self_success", "duration", "pushed"} <= set(data["trials_detail"][0])


def test_overwrite_replaces_an_output_folder_of_its_own_kind_or_an_empty_one(work):
    pytest.importorskip("pyarrow")
    demos = str(work / "demos.h5")
    assert run(["demos", "export", demos, "-o", "lr", "--fps", "100"]) == 0
    first = (Path("lr") / "meta" / "info.json").read_text()
    assert run(["demos", "export", demos, "-o", "lr", "--overwrite"]) == 0           # its own: replaced
    assert (Path("lr") / "meta" / "info.json").read_text() != first
    Path("empty").mkdir()
    assert run(["demos", "export", demos, "-o", "empty", "--overwrite"]) == 0        # nothing to lose
    assert (Path("empty") / "meta" / "info.json").is_file()


@pytest.mark.parametrize("artifact", ["inverse_model.npz", "condition"])
def test_a_non_finite_inverse_model_or_condition_on_disk_is_refused_before_any_trial(work, artifact, capsys):
    from multiform.learn.inverse import InverseDynamicsModel
    from multiform.learn.servos import servo_factory
    from multiform.adapt.learners import ModelLearners
    model = SkillModel(work / "model")
    if artifact == "inverse_model.npz":
        rng = np.random.default_rng(0)
        n_obs = len(servo_factory("arm_pendulum")().observation_names)   # bundled: known before the envs are imported
        inv = InverseDynamicsModel(n_hyper=50).fit(rng.standard_normal((200, n_obs)), rng.standard_normal((200, 6)),
                                                   rng.standard_normal((200, 6)))
        model.save_inverse_model(inv)
        rel = artifact
    else:
        name, _ = ModelLearners(model).region_condition(model.apn, "P1", "P2")
        rel = f"conditions/{name}.npz"
    assert model.problems() == []
    with_nan(work / "model" / rel)
    rehash(work / "model", rel)
    before = snapshot(work)
    assert run(["practice", str(work / "model")]) == 2
    err = capsys.readouterr().err
    assert rel.split("/")[-1] in err and "finite" in err and "Traceback" not in err
    assert snapshot(work) == before


def test_a_baseline_made_from_a_trained_model_lists_what_it_adopted(lab, tmp_path):
    from multiform.tasks.baselines import same_laws_model
    other = same_laws_model(SkillModel(lab / "model"), tmp_path / "as_written", "pendulum_strict")
    assert other.problems() == []
    kinds = sorted(i["kind"] for i in other.manifest["artifacts"].values())
    assert kinds.count("law") == 2 and kinds.count("judge") == 2 and "regions" in kinds
