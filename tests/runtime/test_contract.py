"""The env contract: names and dt through the wrapper chain, NamedEnv on a Gymnasium env multiform
does not ship, and a skill whose control rate is not the env's step refused by name."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
import yaml

from multiform.errors import InvalidInput
from multiform.petri.skillfile import parse_skill
from multiform.runtime.contract import NamedEnv, env_contract
from multiform.runtime.executor import Executor


class Push:
    """A law pushing right at full force."""

    def predict_one(self, x):
        return np.array([1.0])


def skill(rate: float) -> str:
    return yaml.safe_dump({
        "skill": "push_right", "control_rate": rate, "max_duration": 100.0,
        "variables": {"position": "car position [m]", "velocity": "car velocity [m/step]"}, "commands": ["force"],
        "laws": {"right": {"inputs": ["position", "velocity"]}},
        "places": {"A": {}, "B": {}, "top": {"final": "success"}}, "initial_marking": {"A": 1},
        "transitions": {"go": {"in": ["A"], "out": ["B"], "law": "right", "condition": "true"},
                        "up": {"in": ["B"], "out": ["top"], "condition": "dwell > 20"}}})


def mountain_car(dt: float = 1.0) -> gym.Env:
    return NamedEnv(gym.make("MountainCarContinuous-v0"), ("position", "velocity"), ("force",), dt=dt)


def test_names_and_dt_are_read_through_the_wrapper_chain():
    env = gym.wrappers.TimeAwareObservation(gym.make("MountainCarContinuous-v0"))
    with pytest.raises(InvalidInput, match="NamedEnv"):
        env_contract(env)
    wrapped = gym.wrappers.ClipAction(mountain_car(0.02))        # the names sit below another wrapper
    assert env_contract(wrapped) == (("position", "velocity"), ("force",), 0.02)


def test_named_env_refuses_names_that_do_not_fit():
    with pytest.raises(InvalidInput, match="3 name"):
        NamedEnv(gym.make("MountainCarContinuous-v0"), ("a", "b", "c"), ("force",), dt=1.0)
    with pytest.raises(InvalidInput, match="no dt"):
        NamedEnv(gym.make("MountainCarContinuous-v0"), ("a", "b"), ("force",))
    with pytest.raises(InvalidInput, match="flat Box"):
        NamedEnv(gym.make("CartPole-v1"), ("a", "b", "c", "d"), ("push",), dt=0.02)


def test_a_net_runs_a_foreign_env_in_direct_command_mode():
    env = mountain_car(dt=1.0)
    trace = Executor(parse_skill(skill(1.0)), env, {"right": Push()}).run(seed=0)
    assert trace.fired()[:2] == ["go", "up"] and trace.outcome == "success"
    assert np.all(np.diff(trace.value("position")[:20]) > 0)       # the command reached the car


def test_a_control_rate_that_is_not_the_env_step_is_refused():
    with pytest.raises(InvalidInput, match=r"control_rate: .*ticks at 1000 Hz.*every 1 s.*control_rate: 1"):
        Executor(parse_skill(skill(1000.0)), mountain_car(dt=1.0), {"right": Push()})


def test_terminal_false_leaves_the_end_of_a_trial_to_the_net():
    """MountainCar terminates at its goal; with terminal=False the env's own end is not passed on."""
    for terminal in (True, False):
        env = NamedEnv(gym.make("MountainCarContinuous-v0"), ("position", "velocity"), ("force",), dt=1.0,
                       terminal=terminal)
        env.reset(seed=0)
        env.unwrapped.state = np.array([0.449, 0.05])
        _, _, terminated, _, _ = env.step(np.array([1.0], np.float32))
        assert terminated is terminal
