"""Run by the interop environment's Python (robomimic with a working torchvision): read a demos file
with robomimic's own ``file_utils`` and ``SequenceDataset`` (filter keys ``train`` and ``valid``) and
write what they give to an ``.npz`` (no pickle) and a JSON file for the test."""

import json
import sys

import numpy as np
import robomimic.utils.file_utils as file_utils
import robomimic.utils.obs_utils as obs_utils
from robomimic.utils.dataset import SequenceDataset

path, out, samples = sys.argv[1], sys.argv[2], int(sys.argv[3])
keys = ["theta", "omega", "x", "xdot"]
obs_utils.initialize_obs_utils_with_obs_specs({"obs": {"low_dim": keys}})
env_meta = file_utils.get_env_metadata_from_dataset(path)
shape = file_utils.get_shape_metadata_from_dataset(path, all_obs_keys=keys)
train = SequenceDataset(hdf5_path=path, obs_keys=keys, dataset_keys=["actions", "rewards", "dones"],
                        filter_by_attribute="train")
valid = SequenceDataset(hdf5_path=path, obs_keys=keys, dataset_keys=["actions", "rewards", "dones"],
                        filter_by_attribute="valid")
first = train.demos[0]
start = train._demo_id_to_start_indices[first]
items = [train[start + k] for k in range(samples)]
np.savez(out + ".npz", obs=np.stack([np.concatenate([it["obs"][k][0] for k in keys]) for it in items]),
         next_obs=np.stack([np.concatenate([it["next_obs"][k][0] for k in keys]) for it in items]),
         actions=np.stack([it["actions"][0] for it in items]))
with open(out + ".json", "w") as fh:
    json.dump({"env_meta": env_meta, "action_dim": shape["ac_dim"], "train": list(train.demos),
               "valid": list(valid.demos), "train_len": len(train), "valid_len": len(valid), "first": first}, fh)
