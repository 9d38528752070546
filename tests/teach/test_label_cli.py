"""`multiform label`: a person labels segments of demos or trials by script; labels append, judges revise."""

from __future__ import annotations

import json
import shutil

import gymnasium as gym
import numpy as np
import pytest

import multiform.envs  # noqa: F401  (registers the envs)
from multiform.cli import EXIT_MISSING, main
from multiform.demos.dataset import write_dataset
from multiform.teach.labelling import read_sources, segments_to_label
from multiform.teach.record import record_many
from multiform.learn.labels import LabelStore
from multiform.learn.training import fit_judge, mentor_records
from multiform.learn.views import MIRROR_SUFFIX
from multiform.model import SkillModel
from multiform.petri.skillfile import bundled_skills
from multiform.runtime.executor import Executor
from multiform.task import load_task
task = load_task("pendulum")

SEEDS = [0, 1, 2, 9]               # demos without a push (each has one P1 and one P2 segment)


def _base(root, skill):
    eps = record_many("pendulum", SEEDS, task.DEMO_ENV_KWARGS)
    demos = write_dataset(root / "demos.h5", eps, task.SKILL, task.ENV_ID, task.DEMO_ENV_KWARGS)
    model = SkillModel.create(root / "model", skill, demos, task.ENV_ID, task.DEMO_ENV_KWARGS)
    store = model.labels
    store.add_many(mentor_records(model.apn, eps))
    for place in ("P1", "P2"):
        judge, _ = fit_judge(model.apn, eps, store, place, heldout=0)
        model.save_judge(place, judge)
    return root


@pytest.fixture(scope="module")
def base(tmp_path_factory):
    """Four scripted-mentor demos and a model whose judges were fitted on the mentor's labels."""
    return _base(tmp_path_factory.mktemp("label"), task.SKILL)


@pytest.fixture(scope="module")
def base_unmirrored(tmp_path_factory):
    """The same without the skill's mirror declaration: four segments with arbitrary new labels can
    contradict their own mirror images, and this file tests the labelling, not the mirror."""
    root = tmp_path_factory.mktemp("label_plain")
    text = "\n".join(line for line in bundled_skills()[task.SKILL].read_text().splitlines()
                     if not line.startswith("mirror:") and "learners may learn from both images" not in line)
    (root / "skill.yaml").write_text(text)
    return _base(root, root / "skill.yaml")


def _work(base, tmp_path):
    shutil.copy(base / "demos.h5", tmp_path / "demos.h5")
    shutil.copytree(base / "model", tmp_path / "model")
    m = tmp_path / "model"
    m.joinpath("model.json").write_text(m.joinpath("model.json").read_text().replace(
        str((base / "demos.h5").resolve()), str((tmp_path / "demos.h5").resolve())))
    return tmp_path


@pytest.fixture()
def work(base, tmp_path):
    return _work(base, tmp_path)


@pytest.fixture()
def work_unmirrored(base_unmirrored, tmp_path):
    return _work(base_unmirrored, tmp_path)


def lines(path):
    return path.read_text().splitlines()


def snapshot(model_dir):
    return {p.relative_to(model_dir): p.read_bytes() for p in sorted(model_dir.rglob("*")) if p.is_file()}


def test_script_appends_exactly_the_labels_given(work, capsys):
    model = work / "model"
    before = lines(model / "labels.jsonl")
    judges_before = snapshot(model / "judges")
    # segments in order: demo_0 P1, demo_0 P2, demo_1 P1, demo_1 P2, ...; the script ends after four keys
    code = main(["label", str(work / "demos.h5"), "--model", str(model), "--labeller", "alice",
                 "--script", "sf k s", "--no-show", "--plots", str(work / "plots")])
    assert code == 0
    out = capsys.readouterr().out
    assert "labelled 3 of 8 segment(s) (2 success, 1 failure), skipped 1, 4 left" in out
    after = lines(model / "labels.jsonl")
    assert after[: len(before)] == before                                  # earlier records untouched
    new = [json.loads(s) for s in after[len(before):]]
    mentor = {(r.source, r.place): r for r in LabelStore(model / "labels.jsonl").records if r.labeller != "alice"}
    assert [(r["source"], r["place"], r["success"], r["labeller"]) for r in new] == [
        ("demo_0", "P1", True, "alice"), ("demo_0", "P2", False, "alice"), ("demo_1", "P2", True, "alice")]
    for r in new:                                        # the same segments the mentor's labels name
        m = mentor[(r["source"], r["place"])]
        assert (r["start"], r["end"]) == (m.start, m.end)
    store = LabelStore(model / "labels.jsonl")
    assert len(store) == len(before) - 1 + 3
    eff = {(r.source, r.place): r for r in store.effective()}
    assert not eff[("demo_0", "P2")].success and eff[("demo_0", "P2")].labeller == "alice"
    assert eff[("demo_2", "P2")].labeller != "alice"
    pngs = sorted((work / "plots").glob("*.png"))
    assert len(pngs) == 5 and pngs[0].name == "001_demo_0_P1_0-7130.png"   # the shown segments, incl. the last
    assert all(p.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" for p in pngs)
    assert snapshot(model / "judges") == judges_before                   # no --refit: judges unchanged


def test_refit_follows_the_new_labels(work_unmirrored):
    work = work_unmirrored
    model = work / "model"
    m = SkillModel(model)
    sources = read_sources(work / "demos.h5", m.manifest["demos"])
    segs = [s for s in segments_to_label(m.apn, sources) if s.place == "P2"]
    judge = m.judges()["P2"]
    assert judge.predict([s.segment for s in segs]).all()          # the mentor called every balance a success
    p1_before = (model / "judges" / "P1.npz").read_bytes()
    # a stricter mentor: the balancing of demos 0 and 1 was not good enough
    assert main(["label", str(work / "demos.h5"), "--model", str(model), "--labeller", "bob",
                 "--script", "kfkfksks", "--no-show", "--refit"]) == 0
    judge = SkillModel(model).judges()["P2"]
    assert list(judge.predict([s.segment for s in segs])) == [False, False, True, True]
    assert sorted(judge.keys_) == sorted((s.source, s.start, s.end) for s in segs)
    assert (model / "judges" / "P1.npz").read_bytes() == p1_before      # no new P1 labels, P1 untouched
    info = SkillModel(model).manifest["training"]["judges"]["P2"]
    assert info["revised_by"] == "bob" and info["segments"] == 4 and info["success_labels"] == 2
    assert info["mirror_images"] == 0
    # the note on how much the labels can teach follows them: 4 successes, now 2 and 2
    assert not info["informative"] and info["uninformative"].startswith("only 2 failure label(s) among 4 segments")


class Pump:
    """An energy-pumping swing law (inputs s, c, omega, x), enough to make a real trial."""

    def predict_one(self, x):
        return np.array([np.clip(-1.2 * np.sign(x[2] * x[1]) - 3.0 * x[3], -1.5, 1.5)])


class Hold:
    def predict_one(self, x):
        return np.array([-2.0 * x[2]])


def test_labels_a_practice_trace_and_revises_with_it(work, capsys):
    model = work / "model"
    m = SkillModel(model)
    env = gym.make(task.ENV_ID, **task.DEMO_ENV_KWARGS)
    trace = Executor(m.apn, env, {"swing_up": Pump(), "balance": Hold()}).run(seed=5, max_duration=1.5)
    env.close()
    path = work / "practice" / "a_strict" / "traces" / "trial_0007.npz"
    path.parent.mkdir(parents=True)
    trace.save(path)
    before = lines(model / "labels.jsonl")
    assert main(["label", str(work / "practice" / "a_strict"), "--model", str(model), "--labeller", "carol",
                 "--script", "f", "--no-show", "--refit"]) == 0
    new = [json.loads(s) for s in lines(model / "labels.jsonl")[len(before):]]
    assert len(new) == 1
    r = new[0]
    assert (r["source"], r["place"], r["success"], r["labeller"]) == ("a_strict_7", "P1", False, "carol")
    assert r["end"] - r["start"] > 1000                                    # the whole stay in "swung up"
    judge = SkillModel(model).judges()["P1"]
    assert ("a_strict_7", r["start"], r["end"]) in judge.keys_
    assert ("a_strict_7" + MIRROR_SUFFIX, r["start"], r["end"]) in judge.keys_
    assert len(judge.keys_) == 10                    # 4 demos kept + the trial, each with its mirror image
    assert not judge.y_[judge.keys_.index(("a_strict_7", r["start"], r["end"]))]


@pytest.mark.parametrize("case", ["missing_file", "text_file", "judge_npz", "unknown_model", "bad_script",
                                  "robot_labeller", "unknown_place", "corrupt_labels"])
def test_bad_input_is_refused_and_nothing_changes(work, case, capsys):
    model = work / "model"
    args = {"source": str(work / "demos.h5"), "model": str(model), "script": "ss", "extra": []}
    named = ""
    if case == "missing_file":
        args["source"] = named = str(work / "nope.h5")
    elif case == "text_file":
        args["source"] = named = str(work / "notes.txt")
        (work / "notes.txt").write_text("hello")
    elif case == "judge_npz":
        args["source"] = named = str(model / "judges" / "P1.npz")
    elif case == "unknown_model":
        (work / "empty").mkdir()
        args["model"] = named = str(work / "empty")
    elif case == "bad_script":
        args["script"], named = "sfx", "--script"
    elif case == "robot_labeller":
        args["extra"], named = ["--labeller", "robot"], "--labeller"
    elif case == "unknown_place":
        args["extra"], named = ["--place", "P0"], "--place"
    elif case == "corrupt_labels":
        with open(model / "labels.jsonl", "a") as f:
            f.write('{"source": "demo_0"\n')
        named = "labels.jsonl"
    before = snapshot(model)
    argv = ["label", args["source"], "--model", args["model"], "--script", args["script"], "--no-show",
            "--refit", "--plots", str(work / "plots"), *args["extra"]]
    assert main(argv) == (EXIT_MISSING if case == "missing_file" else 2)
    err = capsys.readouterr().err
    assert named in err, err
    assert snapshot(model) == before
    assert not (work / "plots").exists()
