"""robomimic's own loaders read a recorded demos.h5: its SequenceDataset with default arguments and
its get_dataset_info.py script (which stops on actions outside [-1, 1])."""

import subprocess
import sys
from pathlib import Path

import h5py
import numpy as np
import pytest
import robomimic

from multiform.demos.dataset import read_dataset, write_dataset
from multiform.demos.record import record_many
from multiform.task import load_task


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    task = load_task("pendulum")
    eps = record_many("pendulum", [0, 1], task.DEMO_ENV_KWARGS)
    path = tmp_path_factory.mktemp("rm") / "demos.h5"
    write_dataset(path, eps, task.SKILL, task.ENV_ID, task.DEMO_ENV_KWARGS)
    return path


def test_sequence_dataset_with_default_arguments(recorded):
    import robomimic.utils.obs_utils as obs_utils
    import torch
    from robomimic.utils.dataset import SequenceDataset
    keys = ["theta", "omega", "x", "xdot"]
    obs_utils.initialize_obs_utils_with_obs_specs({"obs": {"low_dim": keys}})
    ds = SequenceDataset(hdf5_path=str(recorded), obs_keys=keys, dataset_keys=["actions", "rewards", "dones"])
    ours = read_dataset(recorded)
    assert len(ds) == sum(ep.num_samples for ep in ours)
    with h5py.File(recorded) as f:
        scale = f["data"].attrs["action_scale"]
    ep = ours.episodes[1]
    first = ours.episodes[0].num_samples
    for k in (0, 17, ep.num_samples - 1):
        s = ds[first + k]
        assert s["obs"]["theta"][0, 0] == ep.column("theta")[k]
        assert s["next_obs"]["omega"][0, 0] == ep.column("omega")[min(k + 1, ep.num_samples - 1)]
        assert s["actions"][0, 0] * scale[0] == ep.actions[k, 0]
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
    assert '"type": 2' in out and "filter key success with" in out
    lo, hi = (float(line.split(":")[1]) for line in out.splitlines() if line.startswith("action m"))
    assert -1.0 <= lo < hi <= 1.0 and np.isfinite([lo, hi]).all()
