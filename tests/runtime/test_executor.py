import gymnasium as gym
import numpy as np
import pytest
import yaml

import multiform.envs  # noqa: F401
from multiform.errors import InvalidInput
from multiform.petri.skillfile import parse_skill
from multiform.runtime.executor import Executor
from multiform.runtime.trace import Trace

NET = {
    "skill": "push_and_hold", "variables": {"theta": "", "omega": "", "x": "", "xdot": ""},
    "commands": ["v_cmd"], "laws": {"go": {"inputs": ["x"]}, "back": {"inputs": ["x"]}},
    "safety": {"commands": {"v_cmd": {"min": -0.5, "max": 0.5, "rate": 20.0}}, "divergence": 1000.0},
    "max_duration": 2.0,
    "places": {"P0": {}, "P1": {}, "P2": {}, "done": {"final": "success"}},
    "initial_marking": {"P0": 1},
    "transitions": {"t0": {"in": ["P0"], "out": ["P1"], "law": "go", "condition": "true"},
                    "t1": {"in": ["P1"], "out": ["P2"], "law": "back", "condition": "x > 0.1"},
                    "t2": {"in": ["P2"], "out": ["done"], "condition": "abs(x) < 0.02 and dwell > 0.2"}},
}


class Const:
    def __init__(self, v):
        self.v = np.array([v])

    def predict_one(self, x):
        return self.v


class Spring:
    def predict_one(self, x):
        return np.array([-3.0 * x[0]])


@pytest.fixture
def env():
    e = gym.make("multiform/ArmPendulum-v0", action_mode="ee")
    yield e
    e.close()


def test_trial_runs_laws_fires_and_records(env, tmp_path):
    apn = parse_skill(yaml.safe_dump(NET))
    ex = Executor(apn, env, {"go": Const(0.8), "back": Spring()})
    tr = ex.run(seed=3)
    assert tr.fired()[:2] == ["t0", "t1"]
    assert tr.outcome == "success" and tr.fired()[-1] == "t2"
    k1 = next(f.tick for f in tr.firings if f.transition == "t1")
    x = tr.value("x")
    assert x[k1] > 0.1 and (x[:k1] <= 0.1).all()                          # fired exactly when the condition held
    assert tr.raw_commands[5, 0] == pytest.approx(0.8)
    assert np.abs(tr.commands[:, 0]).max() <= 0.5 + 1e-6                  # bound applied...
    assert tr.clips["command v_cmd bounds"]["count"] > 0                   # ...and recorded
    assert np.abs(np.diff(tr.commands[:k1, 0])).max() <= 20.0 * 1e-3 + 1e-6   # rate limit
    assert tr.marking.shape == (tr.num_ticks, 4) and tr.dwell.shape == (tr.num_ticks, 4)
    tr.save(tmp_path / "t.npz")
    back = Trace.load(tmp_path / "t.npz")
    assert back.fired() == tr.fired() and np.array_equal(back.obs, tr.obs) and back.clips == tr.clips


def test_timeout_is_a_failure(env):
    net = {**NET, "transitions": {**NET["transitions"], "t1": {**NET["transitions"]["t1"], "condition": "x > 5"}}}
    tr = Executor(parse_skill(yaml.safe_dump(net)), env, {"go": Const(0.0), "back": Spring()}).run(seed=1)
    assert tr.outcome == "timeout" and not tr.success
    assert tr.num_ticks == 2001


def test_nan_law_ends_as_a_fault_naming_the_law_not_a_crash(env):
    tr = Executor(parse_skill(yaml.safe_dump(NET)), env, {"go": Const(float("nan")), "back": Spring()}).run(seed=1)
    assert tr.outcome == "fault" and not tr.success
    assert tr.fault.startswith("law go output")
    assert np.isfinite(tr.commands).all() and np.isfinite(tr.raw_commands).all()


def test_collector_paused_during_a_trial_and_restored_even_on_error(env):
    import gc
    ex = Executor(parse_skill(yaml.safe_dump(NET)), env, {"go": Const(0.8), "back": Spring()})
    seen = set()
    ex.run(seed=3, perturb=lambda k, runner, e: seen.add(gc.isenabled()))
    assert seen == {False} and gc.isenabled()

    def boom(k, runner, e):
        raise RuntimeError("experimenter slipped")
    with pytest.raises(RuntimeError):
        ex.run(seed=3, perturb=boom)
    assert gc.isenabled()
    gc.disable()
    try:                                       # a caller that had it off keeps it off
        ex.run(seed=3)
        assert not gc.isenabled()
    finally:
        gc.enable()


def test_missing_law_or_command_refused(env):
    apn = parse_skill(yaml.safe_dump(NET))
    with pytest.raises(InvalidInput, match="no fitted law for back"):
        Executor(apn, env, {"go": Const(0.1)})
    bad = {**NET, "commands": ["torque"], "safety": {}}
    with pytest.raises(InvalidInput, match="no command"):
        Executor(parse_skill(yaml.safe_dump(bad)), env, {"go": Const(0.1), "back": Spring()})
