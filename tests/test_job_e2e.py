"""End to end: a small main job on the pendulum, the report in headless Chromium, and a practice loop
killed midway that resumes with nothing lost. Slow (minutes): `make test-slow`, run in CI."""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import time
from dataclasses import replace
from pathlib import Path

import pytest

from multiform.evaluation import Evaluator, Variant, evaluate
from multiform.job import Job, JobConfig
from multiform.trainer import train_model
from multiform.model import SkillModel
from multiform.report.browser import chromium, render

pytestmark = pytest.mark.slow

SMALL = JobConfig(demos=14, eval_trials=12, ablation_trials=6, practice_max_trials=10, workers=2, seed=3,
                  videos=True, inverse_model=False, learn=False)     # learning: test_learning_from_practice_* below


@pytest.fixture(scope="module")
def run(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("run")
    Job("pendulum", out, SMALL, log=lambda s: None, progress=False, view="").run()   # view: the .rrd files only
    return out


def test_small_job_leaves_a_complete_run_folder(run):
    m = json.loads((run / "metrics.json").read_text())
    assert m["demos"]["count"] == SMALL.demos
    assert m["practice_trials"] == sum(s["trials"] for s in m["scenarios"].values()) > 0
    sr = m["success_rate"]
    assert sr["trials"] == SMALL.eval_trials and 0.0 <= sr["low"] <= sr["rate"] <= sr["high"] <= 1.0
    for r in m["revisions"]:
        assert {"operator", "target", "reason", "scenario"} <= set(r) and r["reason"]
    # Scenario (a): the over-strict t1 never holds, so the loop must relearn it.
    a = m["scenarios"]["a_strict"]
    assert any(r["operator"] == "set_condition" and r["target"] == "t1" for r in a["revisions"])
    assert a["outcomes"][:3] != ["success"] * 3
    names = [row["name"] for row in m["ablation"]]
    assert len(names) == 4 and names[0].startswith("multiform")
    assert {"record_s", "train_s", "practice_s", "evaluate_s", "total_s"} <= set(m["timings"])
    assert 1.0 < m["timings"]["closed_loop_us_per_sim_ms"] < 1000.0       # faster than real time, not free
    for rel in ("nets/net_v0.svg", "report.html"):
        assert (run / rel).stat().st_size > 500, rel
    assert len(list((run / "nets").glob("net_v*.svg"))) == 1 + len(m["revisions"])
    videos = list(run.rglob("*.mp4"))
    assert videos and all(v.stat().st_size > 10_000 for v in videos)
    assert list((run / "plots").glob("*.png"))


def test_one_pool_runs_several_variants_as_separate_evaluations_do(run):
    """The job queues the baselines' trials while it practises, on the pool that later runs the final
    skill's: interleaved in one pool of two processes, each trial comes out as in a one-process
    evaluation of its variant alone."""
    from multiform.task import load_task
    task = load_task("pendulum")
    specs = task.evaluation_specs(4, SMALL.seed, 0.5)
    final = Variant("final", str(run / "model"), use_inverse_model=False)
    as_written = Variant("as written", str(run / "baselines" / "as_written"), use_inverse_model=False)
    assert not (run / "baselines" / "as_written" / "skill.history.jsonl").exists()   # a snapshot, never revised
    with Evaluator("pendulum", workers=2) as ev:
        queued = [(v, ev.submit(v, specs)) for v in (as_written, final)]
        pooled = [ev.collect(v, f) for v, f in queued]
    for v, got in zip((as_written, final), pooled):
        alone = evaluate("pendulum", v, specs, workers=1)
        strip = lambda rows: [{k: r[k] for k in r if k != "wall"} for r in rows]  # noqa: E731
        assert strip(got["trials_detail"]) == strip(alone["trials_detail"])
        assert (got["successes"], got["trials"]) == (alone["successes"], alone["trials"]) and got["name"] == v.name


@pytest.mark.skipif(chromium() is None, reason="chromium not installed (make setup installs it)")
def test_report_renders_in_headless_chromium(run):
    page = render(run / "report.html")
    assert page["returncode"] == 0
    assert page["images"] >= 3 and page["images_ok"] == page["images"], page
    assert page["tables"] >= 2, {k: v for k, v in page.items() if k not in ("dom", "text")}
    assert page["console_errors"] == []
    m = json.loads((run / "metrics.json").read_text())
    text = page["text"]
    for item in ("pushed trials", "trials not pushed", "the robot's own verdict", "Configuration", "Demonstrations",
                 "cf. the paper's Fig. 7", f"seed {SMALL.seed}", "multiform version"):
        assert item in text, item
    for key, plot in m["artifacts"]["plots"].items():
        if isinstance(plot, dict) and plot.get("fired"):
            assert "Fired in order: " + " ".join(plot["fired"]) in text, key


def test_the_picked_trials_are_saved_for_the_view_and_equal_their_plots(run):
    pytest.importorskip("rerun")
    from multiform.view.stream import read_recording
    m = json.loads((run / "metrics.json").read_text())
    views = m["artifacts"].get("views", {})
    assert "success_trial" in views
    for key, v in views.items():
        rec = read_recording(run / v["file"])
        assert [t[0] for t in rec["/net/fired"]["TextLog:text"]] == m["artifacts"]["plots"][key]["fired"]
        assert any(t[0].startswith("the judges: score") for t in rec["/events"]["TextLog:text"])


def _practice_cmd(model: Path, folder: Path) -> list[str]:
    return [sys.executable, "-m", "multiform.cli", "practice", str(model), "--scenario", "a_strict",
            "--out", str(folder), "--max-trials", "8", "--seed", "5"]


def test_killed_practice_resumes_from_the_last_saved_revision(run, tmp_path):
    """Kill the loop after its first repair, rerun the same command: it goes on from the saved state,
    with every earlier trial and the revision kept, and nothing repeated."""
    model_dir = tmp_path / "model"
    src = SkillModel(run / "model")
    fresh = SkillModel.create(model_dir, "pendulum_strict", run / "demos.h5", src.manifest["env"],
                              src.manifest.get("env_kwargs", {}))
    fresh.adopt(src, ("law", "judge", "regions"))         # copied with their hashes, as a baseline is
    shutil.copy2(run / "model" / "labels.jsonl", model_dir / "labels.jsonl")
    fresh.update_manifest(training={k: v for k, v in src.manifest["training"].items()
                                    if k in ("laws", "judges", "regions")})
    train_model(SkillModel(model_dir), log=lambda s: None)      # nothing left to fit: must not refit
    folder = tmp_path / "practice"
    state_file = folder / "state.json"
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    proc = subprocess.Popen(_practice_cmd(model_dir, folder), env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, text=True)
    killed_at = None
    deadline = time.monotonic() + 600
    while time.monotonic() < deadline and proc.poll() is None:
        if state_file.exists():
            s = json.loads(state_file.read_text())
            if s["revisions"] and s["trial"] >= s["revisions"][0]["after_trial"] + 2:
                proc.send_signal(signal.SIGKILL)
                killed_at = s
                break
        time.sleep(0.05)
    proc.wait(30)
    assert killed_at is not None, "the loop finished or stalled before its first repair"
    before = json.loads(state_file.read_text())
    history_before = (model_dir / "skill.history.jsonl").read_text().splitlines()
    assert len(history_before) == 1 and json.loads(history_before[0])["target"] == "t1"

    rerun = subprocess.run(_practice_cmd(model_dir, folder), env=env, capture_output=True, text=True, timeout=900)
    assert rerun.returncode == 0, rerun.stdout + rerun.stderr
    after = json.loads(state_file.read_text())
    assert after["trials"][: len(before["trials"])] == before["trials"]
    assert [t["trial"] for t in after["trials"]] == list(range(len(after["trials"])))
    assert after["revisions"][: len(before["revisions"])] == before["revisions"]
    assert (model_dir / "skill.history.jsonl").read_text().splitlines()[:1] == history_before
    assert all(t["net_version"] >= 1 for t in after["trials"][before["trial"]:])
    assert after["done"]


def test_inverse_model_trained_beside_the_laws_is_the_one_trained_after_them(run, tmp_path):
    """The job trains the inverse model in a second process while it fits the laws (its babbling
    needs none; its exercises wait for them): every array of every fitted piece is the same as
    when it is trained afterwards in this process."""
    import numpy as np

    from multiform.task import load_task

    task = load_task("pendulum")
    dirs = {}
    for beside in (False, True):
        m = SkillModel.create(tmp_path / f"beside_{beside}", task.SKILL, run / "demos.h5", task.ENV_ID,
                              task.robot_env_kwargs(True))
        train_model(m, log=lambda s: None, inverse_trainer=task.train_inverse_model, beside=beside)
        dirs[beside] = m.path
    files = sorted(p.relative_to(dirs[False]) for p in dirs[False].rglob("*.npz"))
    assert Path("inverse_model.npz") in files and files == sorted(p.relative_to(dirs[True]) for p in dirs[True].rglob("*.npz"))
    for rel in files:           # the arrays; the metadata beside them holds fit times
        with np.load(dirs[False] / rel) as a, np.load(dirs[True] / rel) as b:
            names = [k for k in a.files if k != "__format__"]
            assert names and names == [k for k in b.files if k != "__format__"], rel
            assert all(np.array_equal(a[k], b[k]) for k in names), rel


def _learning_practice(model_dir: Path, folder: Path):
    from multiform.adapt.practice import Practice
    from multiform.task import load_task
    task = load_task("pendulum")
    sc = {s.name: s for s in task.scenarios()}["c_keep"]
    cfg = replace(sc.practice_config(max_trials=12, seed=4), refit_every=4, refit_min_segments=1, revert_window=2,
                  mentor_every=3, mentor_trials=4, target_rate=0.0)     # refit even when the skill already succeeds
    return Practice(SkillModel(model_dir), folder, cfg, options=sc.options, perturb=sc.perturb, name="c_keep",
                    mentor=sc.mentor(), takeover=sc.takeover())


def test_learning_from_practice_resumes_as_if_never_stopped(run, tmp_path):
    """Practice that learns from its own graded trials, stopped after 5 trials and run again, ends where
    an uninterrupted run ends: the same trials, the same own segments with their provenance, the same
    refits, mentor grades and takeovers; the own-experience data of the first part is kept, nothing is
    added twice."""
    states, segments, histories, takeovers = [], [], [], []
    for stop in (None, 5):
        model_dir = tmp_path / f"model_{stop}"
        shutil.copytree(run / "model", model_dir, ignore=shutil.ignore_patterns("practice", "experience"))
        folder = tmp_path / f"practice_{stop}"
        if stop is not None:
            _learning_practice(model_dir, folder).run(stop_after=stop)
            first = (model_dir / "experience" / "segments.jsonl").read_text() \
                if (model_dir / "experience" / "segments.jsonl").exists() else ""
        state = _learning_practice(model_dir, folder).run()
        if stop is not None:
            assert (model_dir / "experience" / "segments.jsonl").read_text().startswith(first)
        states.append([replace(t, wall=0.0, time="") for t in state.trials])
        segs = [json.loads(line) for line in (model_dir / "experience" / "segments.jsonl").read_text().splitlines()]
        assert len({(s["source"], s["start"], s["end"]) for s in segs}) == len(segs)
        assert all({"trial", "net_version", "laws", "judge_score", "scenario", "seed"} <= set(s) for s in segs)
        segments.append(segs)
        histories.append([(json.loads(line)["operator"], json.loads(line)["target"])
                          for line in (model_dir / "skill.history.jsonl").read_text().splitlines()])
        kept = sorted(p.name for p in (model_dir / "experience" / "takeovers").glob("*.h5"))
        assert kept == [f"c_keep_{t.trial}.h5" for t in state.takeovers]
        takeovers.append(list(state.takeovers))
    assert states[0] == states[1] and segments[0] == segments[1] and histories[0] == histories[1]
    assert takeovers[0] == takeovers[1]
    assert len(states[0]) == 12 and segments[0], "no own segment in 12 trials: nothing was learned from"
    assert any(op == "refit_law" for op, _ in histories[0])
    assert sum(t.mentor is not None for t in states[0]) == 2


def test_practice_with_the_view_saves_every_trial_as_it_ran(run, tmp_path):
    pytest.importorskip("rerun")
    from multiform.view.stream import read_recording
    model_dir = tmp_path / "model"
    shutil.copytree(run / "model", model_dir, ignore=shutil.ignore_patterns("practice", "experience"))
    folder = tmp_path / "practice"
    cmd = [sys.executable, "-m", "multiform.cli", "practice", str(model_dir), "--scenario", "a_strict", "--out",
           str(folder), "--max-trials", "2", "--seed", "5", "--view"]
    done = subprocess.run(cmd, capture_output=True, text=True, timeout=600, env={**os.environ, "DISPLAY": ""})
    assert done.returncode == 0, done.stdout + done.stderr
    state = json.loads((folder / "state.json").read_text())
    for t in state["trials"]:
        rec = read_recording(folder / "view" / f"trial_{t['trial']:04d}.rrd")
        assert [x[0] for x in rec["/net/fired"]["TextLog:text"]] == t["fired"]
        assert any(x[0].startswith("the judges: score") for x in rec["/events"]["TextLog:text"])
