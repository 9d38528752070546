"""The tutorial's task: Gymnasium's MountainCarContinuous-v0 as a multiform task."""
from pathlib import Path

import gymnasium as gym
import numpy as np

import multiform

ENV_ID = "tutorial/MountainCar-v0"
if ENV_ID not in gym.registry:      # the env with named entries; the net, not the env, ends a trial
    gym.register(ENV_ID, entry_point=lambda **kw: multiform.NamedEnv(
        gym.make("MountainCarContinuous-v0", **kw), ["position", "velocity"], ["force"], dt=1.0, terminal=False))


class Mentor:
    """A scripted person at the controls: backs up until the car stops, then charges right."""

    def reset(self, obs, rng):
        self.charging, self.at_flag = False, False

    def act(self, obs, info, t):
        self.charging = self.charging or (t > 0 and obs[1] >= 0)
        self.at_flag = obs[0] >= 0.45
        return np.array([1.0 if self.charging else -1.0]), "t1" if self.charging else "t0"

    def finished(self):
        return self.at_flag

    def label(self, episode):
        return [multiform.SegmentLabel(s, e, tag, True) for s, e, tag in episode.segments()]


class MountainCar(multiform.Task):
    TASK, ENV_ID, DEMOS = "mountain_car", ENV_ID, 10
    SKILL = str(Path(__file__).with_name("skill.yaml"))

    def make_mentor(self, **kwargs):
        return Mentor()

    def physical_success(self, trace):
        return bool(trace.obs[:, 0].max() >= 0.45)      # the car reached the flag
