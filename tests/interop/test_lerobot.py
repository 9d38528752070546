"""LeRobot v3 datasets both ways: the export loads as LeRobot loads its frames (Hugging Face
`datasets` over the parquet files, features as info.json declares them) and equals the source; a
LeRobot dataset written by other tools imports, with the user's variable names, and trains."""

import json
from pathlib import Path

import datasets
import numpy as np
import pandas as pd
import pytest

from multiform.cli import main
from multiform.demos.dataset import read_dataset, write_dataset
from multiform.demos.lerobot import read_lerobot
from multiform.teach.record import record_many
from multiform.errors import InvalidInput
from multiform.learn.training import LawSettings, fit_law
from multiform.petri.skillfile import parse_skill
from multiform.task import load_task


@pytest.fixture(scope="module")
def demos(tmp_path_factory):
    task = load_task("pendulum")
    eps = record_many("pendulum", [0, 1, 2], task.DEMO_ENV_KWARGS)
    path = tmp_path_factory.mktemp("lr") / "demos.h5"
    write_dataset(path, eps, task.SKILL, task.ENV_ID, task.DEMO_ENV_KWARGS)
    return path


def _hf_features(info):
    """The Hugging Face features LeRobot derives from info.json (shape (1,) a value, else a list)."""
    out = {}
    for key, ft in info["features"].items():
        value = datasets.Value(ft["dtype"])
        out[key] = value if ft["shape"] == [1] else datasets.List(value, length=ft["shape"][0])
    return datasets.Features(out)


def test_export_loads_as_lerobot_loads_it_and_equals_the_source(demos, tmp_path, capsys):
    out = tmp_path / "lerobot"
    assert main(["demos", "export", str(demos), "--format", "lerobot", "--out", str(out)]) == 0
    assert "LeRobot v3 dataset, 3 episodes" in capsys.readouterr().out
    info = json.loads((out / "meta/info.json").read_text())
    src = read_dataset(demos)
    assert info["codebase_version"] == "v3.0" and info["fps"] == 1000
    assert info["total_frames"] == sum(ep.num_samples for ep in src) and info["splits"] == {"train": "0:3"}
    files = sorted(str(p) for p in out.glob(info["data_path"].split("{")[0] + "*/*.parquet"))
    frames = datasets.load_dataset("parquet", data_files=files, split="train", features=_hf_features(info),
                                   cache_dir=str(tmp_path / "cache"))
    assert frames.features == _hf_features(info)
    episodes = pd.read_parquet(out / "meta/episodes/chunk-000/file-000.parquet")
    subtasks = pd.read_parquet(out / "meta/subtasks.parquet")
    tasks = pd.read_parquet(out / "meta/tasks.parquet")
    assert list(tasks["task_index"]) == [0] and "pendulum_strict" in tasks.index[0]
    names = {int(i): str(n) for n, i in zip(subtasks.index, subtasks["subtask_index"])}
    assert info["features"]["observation.state"]["names"] == list(src.episodes[0].observation_names)
    for e, ep in enumerate(src.episodes):
        row = episodes[episodes["episode_index"] == e].iloc[0]
        lo, hi = int(row["dataset_from_index"]), int(row["dataset_to_index"])
        assert hi - lo == ep.num_samples == int(row["length"])
        part = {k: np.asarray(v) for k, v in frames[lo:hi].items()}
        assert np.array_equal(part["observation.state"], ep.obs)            # float64, bit for bit
        assert np.array_equal(part["action"], ep.actions[:, 0])
        # LeRobotDataset hands frames out through torch.tensor, i.e. as float32
        item = frames[lo + 7]
        assert np.array_equal(np.float32(item["observation.state"]), ep.obs[7].astype(np.float32))
        assert [names[int(k)] for k in part["subtask_index"]] == list(ep.transitions)
        assert np.array_equal(part["frame_index"], np.arange(ep.num_samples)) and set(part["episode_index"]) == {e}
        assert part["next.success"][-1] == (ep.outcome == "success") and not part["next.success"][:-1].any()
        assert part["next.done"].sum() == 1 and part["next.done"][-1]
        for lab in ep.labels:
            assert set(part["segment.success"][lab.start:lab.end]) == {int(lab.success)}
        assert row["multiform/outcome"] == ep.outcome


def test_export_imports_back_exactly(demos, tmp_path):
    out = tmp_path / "lerobot"
    assert main(["demos", "export", str(demos), "--out", str(out)]) == 0
    assert main(["demos", "import", str(out), "--out", str(tmp_path / "back.h5")]) == 0
    a, b = read_dataset(demos), read_dataset(tmp_path / "back.h5")
    assert (a.skill, a.env_name, a.env_kwargs) == (b.skill, b.env_name, b.env_kwargs)
    for x, y in zip(a.episodes, b.episodes, strict=True):
        assert np.array_equal(x.obs, y.obs) and np.array_equal(x.actions, y.actions)
        assert list(x.transitions) == list(y.transitions) and x.labels == y.labels
        assert (x.outcome, x.seed, x.reset_options) == (y.outcome, y.seed, y.reset_options)
    assert main(["demos", "export", str(demos), "--out", str(out)]) == 2            # never over a dataset


SKILL = """
skill: balance_from_lerobot
variables: [theta, omega, x, xdot]
commands: [v_cmd]
laws:
  move: {inputs: [theta, omega, x, xdot]}
places:
  P0: {label: moving}
  done: {final: success}
initial_marking: {P0: 1}
transitions:
  t0: {in: [P0], out: [done], law: move, condition: "time > 30"}
"""


def _foreign_dataset(root: Path, eps) -> None:
    """A LeRobot v3 dataset as another tool writes it: 4-D state without names, float32, a success
    flag, no subtasks and nothing of multiform's."""
    cols = {"observation.state": [], "action": [], "next.success": [], "timestamp": [], "frame_index": [],
            "episode_index": [], "index": [], "task_index": []}
    rows, index = [], 0
    for e, ep in enumerate(eps):
        n = ep.num_samples
        cols["observation.state"].extend(ep.obs[:, :4].astype(np.float32).tolist())
        cols["action"].extend(ep.actions[:, 0].astype(np.float32).tolist())
        cols["next.success"].extend([False] * (n - 1) + [ep.outcome == "success"])
        cols["timestamp"].extend((np.arange(n) / 1000).tolist())
        cols["frame_index"].extend(range(n))
        cols["episode_index"].extend([e] * n)
        cols["index"].extend(range(index, index + n))
        cols["task_index"].extend([0] * n)
        rows.append({"episode_index": e, "tasks": ["balance"], "length": n, "data/chunk_index": 0,
                     "data/file_index": 0, "dataset_from_index": index, "dataset_to_index": index + n})
        index += n
    features = {"observation.state": {"dtype": "float32", "shape": [4], "names": None},
                "action": {"dtype": "float32", "shape": [1], "names": None},
                "next.success": {"dtype": "bool", "shape": [1], "names": None},
                "timestamp": {"dtype": "float32", "shape": [1], "names": None},
                **{k: {"dtype": "int64", "shape": [1], "names": None}
                   for k in ("frame_index", "episode_index", "index", "task_index")}}
    (root / "data/chunk-000").mkdir(parents=True)
    datasets.Dataset.from_dict(cols, features=_hf_features({"features": features})).to_parquet(
        str(root / "data/chunk-000/file-000.parquet"))
    (root / "meta/episodes/chunk-000").mkdir(parents=True)
    pd.DataFrame(rows).to_parquet(root / "meta/episodes/chunk-000/file-000.parquet")
    pd.DataFrame({"task_index": [0]}, index=["balance"]).to_parquet(root / "meta/tasks.parquet")
    (root / "meta/info.json").write_text(json.dumps({
        "codebase_version": "v3.0", "robot_type": "arm", "total_episodes": len(eps), "total_frames": index,
        "total_tasks": 1, "chunks_size": 1000, "fps": 1000, "splits": {"train": f"0:{len(eps)}"},
        "data_path": "data/chunk-{chunk_index:03d}/file-{file_index:03d}.parquet", "video_path": None,
        "features": features}))


def test_a_foreign_lerobot_dataset_imports_and_trains(demos, tmp_path, capsys):
    src = read_dataset(demos).episodes
    root = tmp_path / "foreign"
    _foreign_dataset(root, src)
    out = tmp_path / "imported.h5"
    assert main(["demos", "import", str(root), "--out", str(out)]) == 2          # no names: refused
    assert "name them (--variables a,b,...)" in capsys.readouterr().err
    assert main(["demos", "import", str(root), "--out", str(out), "--variables", "theta,omega,x,xdot",
                 "--commands", "v_cmd", "--skill", "balance_from_lerobot"]) == 0
    eps = read_dataset(out).episodes
    assert [ep.outcome for ep in eps] == [ep.outcome for ep in src]
    assert all(set(ep.transitions) == {"t0"} for ep in eps)
    np.testing.assert_array_equal(eps[0].column("omega"), src[0].column("omega").astype(np.float32))
    small = LawSettings(n_hyper=300, n_restarts=0, n_inducing=100, max_train=4000)
    law, summary = fit_law(parse_skill(SKILL), eps, "move", seed=0, settings=small)
    assert 0 < summary["heldout_nrmse"] < 1.0          # better than predicting the mean command
    x = eps[0].obs[::500]
    assert law.predict(x).shape == (len(x), 1)


def test_bad_lerobot_input_is_named(tmp_path):
    with pytest.raises(InvalidInput, match="not a LeRobot dataset"):
        read_lerobot(tmp_path)
    (tmp_path / "meta").mkdir()
    (tmp_path / "meta/info.json").write_text('{"codebase_version": "v2.1", "features": {}}')
    with pytest.raises(InvalidInput, match="codebase_version 'v2.1'"):
        read_lerobot(tmp_path)


def _downsampled(ep, step):
    """What a frame of an export at 1/step of the control rate holds: the state, subtask and
    segment label at its first tick, the mean command over its ticks."""
    starts = np.arange(0, ep.num_samples, step)
    ends = np.append(starts[1:], ep.num_samples)
    return (ep.obs[starts], np.stack([ep.actions[s:t].mean(axis=0) for s, t in zip(starts, ends)]),
            [ep.transitions[s] for s in starts])


def test_every_feature_has_statistics_per_episode_and_over_the_dataset(demos, tmp_path):
    out = tmp_path / "lerobot"
    assert main(["demos", "export", str(demos), "--out", str(out)]) == 0
    info = json.loads((out / "meta/info.json").read_text())
    stats = json.loads((out / "meta/stats.json").read_text())
    episodes = pd.read_parquet(out / "meta/episodes/chunk-000/file-000.parquet")
    src = read_dataset(demos)
    names = ("min", "max", "mean", "std", "count", "q01", "q10", "q50", "q90", "q99")
    for key, ft in info["features"].items():
        assert set(stats[key]) == set(names), key
        for name in names:
            assert f"stats/{key}/{name}" in episodes.columns, (key, name)
        assert len(stats[key]["mean"]) == ft["shape"][0]
    for e, ep in enumerate(src.episodes):
        row = episodes[episodes["episode_index"] == e].iloc[0]
        assert list(row["stats/observation.state/max"]) == list(ep.obs.max(axis=0))
        assert list(row["stats/action/min"]) == list(ep.actions.min(axis=0))
        assert list(row["stats/timestamp/max"]) == [float(np.float32((ep.num_samples - 1) * ep.dt))]
        assert list(row["stats/next.done/count"]) == [ep.num_samples]
    assert stats["index"]["max"] == [sum(ep.num_samples for ep in src) - 1]
    assert stats["observation.state"]["count"] == [sum(ep.num_samples for ep in src)]


def test_an_export_at_50_fps_holds_the_state_at_each_frame_and_the_mean_command_over_it(demos, tmp_path, capsys):
    out = tmp_path / "lerobot50"
    assert main(["demos", "export", str(demos), "--out", str(out), "--fps", "50"]) == 0
    assert "at 50 fps" in capsys.readouterr().out
    info = json.loads((out / "meta/info.json").read_text())
    assert info["fps"] == 50
    back, _ = read_lerobot(out)
    for ep, got in zip(read_dataset(demos).episodes, back, strict=True):
        obs, act, tags = _downsampled(ep, 20)
        assert np.array_equal(got.obs, obs) and np.allclose(got.actions, act, rtol=1e-12, atol=1e-15)
        assert list(got.transitions) == tags and got.dt == 0.02 and got.outcome == ep.outcome
        assert [(lab.start, lab.transition) for lab in got.labels] == [(lab.start // 20, lab.transition)
                                                                        for lab in ep.labels]
    for bad in ("30", "0.5", "2000"):
        assert main(["demos", "export", str(demos), "--out", str(tmp_path / f"x{bad}"), "--fps", bad]) == 2
    assert "must be a whole number that divides the control rate 1000 Hz" in capsys.readouterr().err


@pytest.mark.interop
def test_lerobots_own_dataset_class_loads_a_50_fps_export_with_its_statistics(demos, tmp_path):
    """LeRobot pins torch and rerun releases of its own, so it lives in a separate environment
    (`make test-interop` builds it and names its Python in MULTIFORM_INTEROP_PYTHON)."""
    import os
    import subprocess
    import sys
    python = os.environ.get("MULTIFORM_INTEROP_PYTHON")
    if not python:
        pytest.skip("the interop environment is not set up (make test-interop)")
    out = tmp_path / "lerobot"
    assert main(["demos", "export", str(demos), "--out", str(out), "--fps", "50"]) == 0
    script = Path(__file__).with_name("lerobot_frames.py")
    subprocess.run([python, str(script), str(out), str(tmp_path / "frames.npz")], check=True, timeout=900,
                   env={**os.environ, "HF_HUB_OFFLINE": "1", "PYTHONPATH": ""}, stdout=sys.stderr)
    got = np.load(tmp_path / "frames.npz", allow_pickle=False)
    src = read_dataset(demos)
    info = json.loads((out / "meta/info.json").read_text())
    assert int(got["num_episodes"]) == len(src) and int(got["fps"]) == 50
    assert set(got["stats_keys"]) == set(info["features"])              # every feature has its statistics
    at = 0
    for e, ep in enumerate(src.episodes):
        obs, act, tags = _downsampled(ep, 20)
        n = len(obs)
        sl = slice(at, at + n)
        assert set(got["episode_index"][sl]) == {e} and np.array_equal(got["frame_index"][sl], np.arange(n))
        # LeRobot hands frames out as float32 tensors: equal to the source rounded to float32
        assert np.array_equal(got["observation_state"][sl], obs.astype(np.float32))
        assert np.allclose(got["action"][sl].reshape(n, -1), act.astype(np.float32), rtol=1e-6, atol=1e-7)
        assert np.allclose(got["timestamp"][sl].reshape(n), np.arange(n) / 50, atol=1e-6)
        assert list(got["subtask"][sl]) == tags
        assert bool(got["next_success"][sl][-1]) == (ep.outcome == "success") and not got["next_success"][sl][:-1].any()
        at += n
    assert at == len(got["frame_index"])
