"""A mentor's identity survives every file format: demos.h5 (an attribute per demo and robomimic's
filter key per mentor), a merge of several people's files, the LeRobot export and labels.jsonl."""

import h5py
import numpy as np
import pytest

from multiform import api
from multiform.cli import main
from multiform.demos.dataset import read_dataset, write_dataset
from multiform.demos.merge import merge_datasets
from multiform.demos.episode import Episode, SegmentLabel, check_mentor_name
from multiform.errors import InvalidInput
from multiform.learn.labels import LabelStore
from multiform.learn.training import mentor_records
from multiform.petri.skillfile import load_skill

NAMES = ("theta", "omega", "x", "xdot")
ENV = "multiform/ArmPendulum-v0"


def _episode(seed: int, mentor: str, n: int = 400) -> Episode:
    rng = np.random.default_rng(seed)
    tags = np.array(["t0"] * (n // 4) + ["t2"] * (n // 4) + ["t1"] * (n // 4) + ["t3"] * (n - 3 * (n // 4)))
    labels = [SegmentLabel(s, e, t, bool(rng.random() < 0.7), mentor or "mentor")
              for s, e, t in ((0, n // 4, "t0"), (n // 4, n // 2, "t2"), (n // 2, 3 * n // 4, "t1"),
                              (3 * n // 4, n, "t3"))]
    return Episode(obs=rng.normal(size=(n, 4)), actions=rng.normal(size=(n, 1)), transitions=tags,
                   observation_names=NAMES, command_names=("v_cmd",), dt=1e-3, seed=seed, labels=labels,
                   outcome="success" if seed % 2 == 0 else "failure", mentor=mentor)


def _file(path, mentors, skill="pendulum_strict", env=ENV, seed0=0):
    eps = [_episode(seed0 + i, m) for i, m in enumerate(mentors)]
    return write_dataset(path, eps, skill, env, {"action_mode": "ee"}), eps


def test_every_demo_keeps_its_mentor_and_each_mentor_has_a_filter_key(tmp_path):
    path, eps = _file(tmp_path / "d.h5", ["ana", "bo", "ana", "cy d"])
    ds = read_dataset(path)
    assert [ep.mentor for ep in ds] == ["ana", "bo", "ana", "cy d"]
    assert [[lab.labeller for lab in ep.labels] for ep in ds] == [[lab.labeller for lab in ep.labels] for ep in eps]
    with h5py.File(path) as f:
        assert f["data/demo_1"].attrs["mentor"] == "bo"
        masks = {k: sorted(v.decode() for v in f[f"mask/{k}"][()]) for k in f["mask"]}
    assert masks["mentor_ana"] == ["demo_0", "demo_2"] and masks["mentor_bo"] == ["demo_1"]
    assert masks["mentor_cy_d"] == ["demo_3"]
    assert ds.summary()["mentors"] == {"ana": {"demos": 2, "success": 2}, "bo": {"demos": 1, "success": 0},
                                       "cy d": {"demos": 1, "success": 0}}


def test_a_file_wide_mentor_names_the_demos_that_name_none(tmp_path):
    eps = [_episode(0, ""), _episode(1, "bo")]
    ds = read_dataset(write_dataset(tmp_path / "d.h5", eps, "s", ENV, {"action_mode": "ee"}, mentor="ana"))
    assert [ep.mentor for ep in ds] == ["ana", "bo"]


def test_names_that_would_share_a_filter_key_are_refused(tmp_path):
    with pytest.raises(InvalidInput, match="share the filter key mask/mentor_a_b"):
        _file(tmp_path / "d.h5", ["a b", "a/b"])
    assert not (tmp_path / "d.h5").exists()


def test_merge_keeps_every_mentor_and_refuses_other_skills_envs_and_unnamed_demos(tmp_path):
    a, ea = _file(tmp_path / "a.h5", ["ana", "ana"])
    b, eb = _file(tmp_path / "b.h5", ["bo"], seed0=10)
    c, _ = _file(tmp_path / "c.h5", [""], seed0=20)
    out = tmp_path / "m.h5"
    ds = api.merge_demos([a, b, str(c)], out, mentors={str(c): "cy"})
    assert [ep.mentor for ep in ds] == ["ana", "ana", "bo", "cy"]
    assert [ep.seed for ep in ds] == [0, 1, 10, 20]
    assert all(x.labels == y.labels for x, y in zip(ds, ea + eb))
    with h5py.File(out) as f:
        assert sorted(k for k in f["mask"] if k.startswith("mentor_")) == ["mentor_ana", "mentor_bo", "mentor_cy"]
    other, _ = _file(tmp_path / "o.h5", ["dee"], skill="nunchaku")
    with pytest.raises(InvalidInput) as exc:
        api.merge_demos([a, other], tmp_path / "x.h5")
    assert "o.h5" in str(exc.value) and "skill" in str(exc.value)
    with pytest.raises(InvalidInput, match="records no mentor"):
        api.merge_demos([a, c], tmp_path / "x.h5")
    with pytest.raises(InvalidInput, match="not renamed"):
        merge_datasets([a], tmp_path / "x.h5", {str(a): "zed"})
    assert not (tmp_path / "x.h5").exists()


def test_merge_from_the_command_line(tmp_path, capsys):
    a, _ = _file(tmp_path / "a.h5", ["ana"])
    c, _ = _file(tmp_path / "c.h5", [""], seed0=5)
    out = tmp_path / "m.h5"
    assert main(["demos", "merge", str(a), str(c), "--mentor", f"{c}=cy", "--out", str(out)]) == 0
    assert "by ana (1), cy (1)" in capsys.readouterr().out
    assert main(["demos", "merge", str(a), str(c), "--out", str(tmp_path / "n.h5")]) == 2
    assert "records no mentor" in capsys.readouterr().err
    assert main(["demos", "info", str(out)]) == 0
    assert "mentors: ana (1 demos, 1 successful), cy (1 demos, 0 successful)" in capsys.readouterr().out


def test_the_lerobot_export_round_trips_the_mentor_column(tmp_path):
    pytest.importorskip("pyarrow")
    import pandas as pd
    path, _ = _file(tmp_path / "d.h5", ["ana", "bo"])
    out = api.export_demos(path, tmp_path / "lr")
    rows = pd.read_parquet(out / "meta/episodes/chunk-000/file-000.parquet")
    assert list(rows["multiform/mentor"]) == ["ana", "bo"]
    back = api.import_demos(out, tmp_path / "back.h5")
    assert [ep.mentor for ep in back] == ["ana", "bo"]


def test_labels_jsonl_names_each_labeller(tmp_path):
    _, eps = _file(tmp_path / "d.h5", ["ana", "bo"])
    apn = load_skill("pendulum_strict")
    store = LabelStore(tmp_path / "labels.jsonl")
    store.add_many(mentor_records(apn, eps))
    assert {(r.source, r.labeller) for r in LabelStore(tmp_path / "labels.jsonl")} == {("demo_0", "ana"),
                                                                                       ("demo_1", "bo")}


@pytest.mark.parametrize("bad", ["", " ana", "robot-7", "a" * 65, "x/y", "-a"])
def test_bad_mentor_names_are_refused(bad):
    with pytest.raises(InvalidInput):
        check_mentor_name(bad)


def test_record_names_the_task_mentor_and_refuses_an_unknown_one(tmp_path, capsys):
    out = tmp_path / "poor.h5"
    assert main(["record", "pendulum", "--demos", "1", "--workers", "1", "--mentor", "poor", "--out", str(out)]) == 0
    assert "1 demos by poor" in capsys.readouterr().out
    ds = read_dataset(out)
    assert ds.episodes[0].mentor == "poor" and {lab.labeller for lab in ds.episodes[0].labels} == {"poor"}
    assert main(["record", "pendulum", "--demos", "1", "--mentor", "nobody", "--out", str(tmp_path / "n.h5")]) == 2
    assert "no scripted mentor 'nobody'; its mentors: expert, average, poor" in capsys.readouterr().err
    assert not (tmp_path / "n.h5").exists()


@pytest.mark.parametrize("text, plan", [("expert:5,poor:10", (("expert", 5), ("poor", 10))),
                                        ("expert,average,poor", (("expert", 0), ("average", 0), ("poor", 0)))])
def test_the_main_jobs_mentors_option(text, plan):
    from multiform.cli import build_parser
    args = build_parser().parse_args(["demo", "pendulum", "--out", "x", "--mentors", text, "--no-fusion"])
    assert args.mentors == plan and args.fusion is False


def test_a_job_refuses_mentors_that_do_not_add_up_or_do_not_exist(tmp_path):
    from multiform.job import Job, JobConfig
    with pytest.raises(InvalidInput, match="do not add up"):
        Job("pendulum", tmp_path / "a", JobConfig(demos=10, mentors=(("expert", 5), ("poor", 4))))
    with pytest.raises(InvalidInput, match="no scripted mentor"):
        Job("pendulum", tmp_path / "b", JobConfig(mentors=(("expert", 5), ("novice", 5))))
    assert not (tmp_path / "a").exists() and not (tmp_path / "b").exists()
