"""robomimic reads a recorded demos.h5 and its data mean what they say: its SequenceDataset with the
train/valid filter keys, its get_dataset_info.py script (which stops on actions outside [-1, 1]),
and an env made from the file's env_args, stepped with a stored action, gives the recorded next
state. robomimic's file_utils needs torchvision, which this environment cannot have beside its CPU
torch: that part runs in the interop environment (`make test-interop`)."""

import json
import os
import subprocess
import sys
from pathlib import Path

import gymnasium
import h5py
import numpy as np
import pytest
import robomimic

import multiform.envs  # noqa: F401  (registers the envs)
from multiform import api
from multiform.demos.dataset import read_dataset, train_valid_split, write_dataset
from multiform.teach.record import record_many
from multiform.task import load_task

KEYS = ["theta", "omega", "x", "xdot"]


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    task = load_task("pendulum")
    eps = record_many("pendulum", [0, 1], task.DEMO_ENV_KWARGS)
    path = tmp_path_factory.mktemp("rm") / "demos.h5"
    write_dataset(path, eps, task.SKILL, task.ENV_ID, task.DEMO_ENV_KWARGS)
    return path


def _stored(path, demo):
    with h5py.File(path) as f:
        g = f[f"data/{demo}"]
        return (json.loads(f["data"].attrs["env_args"]), int(g.attrs["seed"]), json.loads(g.attrs["reset_options"]),
                g["actions"][()], np.stack([g["next_obs"][k][()][:, 0] for k in KEYS], 1))


def _replays(env_args, seed, options, actions, next_obs, steps):
    """The env made from env_args, reset as the demo was and stepped with its stored actions, gives
    the recorded next states (stored as float32) exactly."""
    env = gymnasium.make(env_args["env_name"], **env_args["env_kwargs"])
    base = env.unwrapped
    env.reset(seed=seed, options=options)
    idx = [base.observation_names.index(k) for k in KEYS]
    for k in range(steps):
        obs, *_ = env.step(actions[k])
        assert np.array_equal(obs[idx].astype(np.float32), next_obs[k]), k
    env.close()


def test_actions_are_what_the_env_in_env_args_takes(recorded):
    env_args, seed, options, actions, next_obs = _stored(recorded, "demo_1")
    assert env_args["env_kwargs"] == {"action_mode": "ee", "normalize_actions": True}
    assert np.abs(actions).max() <= 1.0
    _replays(env_args, seed, options, actions, next_obs, 2000)
    ds = read_dataset(recorded)
    assert ds.env_kwargs == {"action_mode": "ee"}                      # the env that takes the commands
    assert np.allclose(ds.episodes[1].actions, 1.5 * actions, rtol=0, atol=1e-15)


def test_sequence_dataset_with_default_arguments(recorded):
    import robomimic.utils.obs_utils as obs_utils
    import torch
    from robomimic.utils.dataset import SequenceDataset
    obs_utils.initialize_obs_utils_with_obs_specs({"obs": {"low_dim": KEYS}})
    ds = SequenceDataset(hdf5_path=str(recorded), obs_keys=KEYS, dataset_keys=["actions", "rewards", "dones"])
    ours = read_dataset(recorded)
    assert len(ds) == sum(ep.num_samples for ep in ours)
    with h5py.File(recorded) as f:
        stored = f["data/demo_1/actions"][()]
    ep = ours.episodes[1]
    first = ours.episodes[0].num_samples
    for k in (0, 17, ep.num_samples - 1):
        s = ds[first + k]
        assert s["obs"]["theta"][0, 0] == np.float32(ep.column("theta")[k])
        assert s["next_obs"]["omega"][0, 0] == np.float32(ep.column("omega")[min(k + 1, ep.num_samples - 1)])
        assert s["actions"][0, 0] == stored[k, 0]
        assert s["dones"][0] == (k == ep.num_samples - 1)
        assert s["rewards"][0] == (k == ep.num_samples - 1 and ep.outcome == "success")
    batch = next(iter(torch.utils.data.DataLoader(ds, batch_size=32, shuffle=True)))
    assert batch["obs"]["x"].shape == (32, 1, 1) and batch["actions"].shape == (32, 1, 1)


def test_get_dataset_info_script(recorded):
    script = Path(robomimic.__file__).parent / "scripts" / "get_dataset_info.py"
    proc = subprocess.run([sys.executable, str(script), "--dataset", str(recorded)], capture_output=True,
                          text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    out = proc.stdout
    total = sum(ep.num_samples for ep in read_dataset(recorded))
    assert f"total transitions: {total}" in out and "total trajectories: 2" in out
    assert '"type": 2' in out and "filter key success with" in out and "filter key train with 2 demos" in out
    lo, hi = (float(line.split(":")[1]) for line in out.splitlines() if line.startswith("action m"))
    assert -1.0 <= lo < hi <= 1.0 and np.isfinite([lo, hi]).all()


def test_the_train_valid_split_is_robomimics_seeded():
    names = [f"demo_{i}" for i in range(25)]
    a, b = train_valid_split(names, seed=0), train_valid_split(list(reversed(names)), seed=0)
    assert a == b and len(a["valid"]) == 2 and sorted(a["train"] + a["valid"]) == sorted(names)
    assert train_valid_split(names, seed=1) != a
    assert train_valid_split(names[:9], seed=0)["valid"] == []           # int(0.1 * 9) = 0, as robomimic


@pytest.mark.interop
def test_robomimics_own_loaders_read_the_main_jobs_demos_and_the_env_reproduces_them(tmp_path):
    """The main job's demos.h5 (the pendulum task's 10 demos, seed 0) through robomimic's file_utils
    and SequenceDataset(filter_by_attribute="train") in the interop environment; its env metadata
    makes the env here, whose steps with the stored actions reproduce robomimic's next_obs."""
    python = os.environ.get("MULTIFORM_INTEROP_PYTHON")
    if not python:
        pytest.skip("the interop environment is not set up (make test-interop)")
    demos = api.record("pendulum", tmp_path / "demos.h5", workers=2)
    out = tmp_path / "robomimic"
    subprocess.run([python, str(Path(__file__).with_name("robomimic_read.py")), str(demos), str(out), "3000"],
                   check=True, timeout=900, env={**os.environ, "PYTHONPATH": ""}, stdout=sys.stderr)
    got = json.loads(out.with_suffix(".json").read_text())
    arrays = np.load(out.with_suffix(".npz"), allow_pickle=False)
    with h5py.File(demos) as f:
        masks = {k: sorted(v.decode() for v in f[f"mask/{k}"][()]) for k in ("train", "valid")}
        lengths = {k: int(f[f"data/{k}"].attrs["num_samples"]) for k in f["data"]}
    assert sorted(got["train"]) == masks["train"] and sorted(got["valid"]) == masks["valid"]
    assert len(masks["valid"]) == 1 and got["train_len"] == sum(lengths[d] for d in masks["train"])
    assert got["env_meta"]["env_kwargs"] == {"action_mode": "ee", "normalize_actions": True}
    assert got["action_dim"] == 1
    env_args, seed, options, actions, next_obs = _stored(demos, got["first"])
    assert np.array_equal(arrays["actions"], actions[:3000])
    _replays(got["env_meta"], seed, options, arrays["actions"], arrays["next_obs"], 3000)


def test_sequence_dataset_reads_one_mentors_demos_of_a_merged_file(recorded, tmp_path):
    """robomimic's multi-human convention: a filter key per mentor; SequenceDataset with
    ``filter_by_attribute`` reads only that mentor's demos of a merged file."""
    import robomimic.utils.obs_utils as obs_utils
    from robomimic.utils.dataset import SequenceDataset
    other = tmp_path / "other.h5"
    task = load_task("pendulum")
    eps = record_many("pendulum", [7], task.DEMO_ENV_KWARGS)
    eps[0].mentor = "ana"
    write_dataset(other, eps, task.SKILL, task.ENV_ID, task.DEMO_ENV_KWARGS)
    merged = api.merge_demos([recorded, other], tmp_path / "merged.h5")
    assert [ep.mentor for ep in merged] == ["scripted-pendulum", "scripted-pendulum", "ana"]
    obs_utils.initialize_obs_utils_with_obs_specs({"obs": {"low_dim": KEYS}})
    for key, demos in (("mentor_ana", [2]), ("mentor_scripted-pendulum", [0, 1])):
        ds = SequenceDataset(hdf5_path=str(merged.path), obs_keys=KEYS, dataset_keys=["actions"],
                             filter_by_attribute=key)
        assert ds.demos == [f"demo_{i}" for i in demos]
        assert len(ds) == sum(merged.episodes[i].num_samples for i in demos)
