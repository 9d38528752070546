"""Run by LeRobot's own Python: load a dataset folder with LeRobot's ``LeRobotDataset`` and write
every frame's state, action, subtask, success flags and timestamp, the fps and the features with
statistics to an ``.npz`` (no pickle) for the test."""

import sys

import numpy as np
from lerobot.datasets.lerobot_dataset import LeRobotDataset

root, out = sys.argv[1], sys.argv[2]
ds = LeRobotDataset("local/multiform-export", root=root)
frames = [ds[i] for i in range(len(ds))]
keys = ("observation.state", "action", "subtask_index", "episode_index", "frame_index", "next.success", "next.done")
np.savez(out, **{k.replace(".", "_"): np.stack([np.asarray(f[k]) for f in frames]) for k in keys},
         num_episodes=np.array(ds.num_episodes), subtask=np.array([f["subtask"] for f in frames]),
         fps=np.array(ds.fps), stats_keys=np.array(sorted(ds.meta.stats)),
         timestamp=np.stack([np.asarray(f["timestamp"]) for f in frames]))
