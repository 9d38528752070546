import math

import numpy as np

from multiform.runtime.safety import Saturator

SAFETY = {"commands": {"v": {"min": -1.0, "max": 1.0, "rate": 10.0}},
          "workspace": {"x": {"min": -0.3, "max": 0.3, "command": "v"}}, "divergence": 100.0}


def make():
    return Saturator(SAFETY, ["v"], {"x": 0}, dt=0.001, torque_low=-np.ones(2), torque_high=np.ones(2))


def test_bounds_rate_and_workspace_clip_and_log():
    s = make()
    assert s.command([5.0], [0.0], 0) == [1.0]                    # bound
    assert s.log.counts["command v bounds"] == 1
    out = s.command([-1.0], [0.0], 1)                              # rate: at most 10 m/s^2 * 1 ms
    assert math.isclose(out[0], 1.0 - 0.01)
    assert s.log.counts["command v rate"] == 1
    assert s.log.worst["command v rate"] > 1000                    # asked for ~2000 m/s^2
    s2 = make()
    assert s2.command([0.5], [0.31], 0) == [0.0]                   # pushing further out of the workspace
    assert s2.command([-0.005], [0.31], 1) == [-0.005]             # back inside is allowed
    assert s2.log.counts["workspace x"] == 1


def test_workspace_stop_respects_rate_limit():
    s = make()
    s.command([0.8], [0.0], 0)
    out = s.command([0.8], [0.35], 1)                              # zeroed by the wall, then rate-limited
    assert math.isclose(out[0], 0.8 - 0.01)


def test_torque_clip_and_divergence():
    s = make()
    tau = np.array([2.0, -0.5])
    s.torque(tau, 3)
    assert (tau == [1.0, -0.5]).all() and s.log.counts["joint torque"] == 1
    assert s.diverged([float("nan")], 1) and s.diverged([1e3], 1) and not s.diverged([50.0], 1)
    assert s.log.to_json()["joint torque"]["first_tick"] == 3
