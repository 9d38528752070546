"""The experimenter's pushes during practice and evaluation (the executor's ``perturb`` hook)."""

from __future__ import annotations

from dataclasses import dataclass

import gymnasium as gym

from ..petri.firing import NetRunner


@dataclass
class PushInPlace:
    """Push once, ``after`` seconds into the first stay of the token in ``place``, as a person
    pushes a pendulum that has been balancing for a moment. Calls ``env.unwrapped.push(size,
    duration)``; plain data, so it crosses process boundaries."""

    place: str
    after: float
    size: float
    duration: float
    done: bool = False
    tick: int | None = None         # when it pushed (for the plots, the view and the video overlay)

    def __call__(self, tick: int, runner: NetRunner, env: gym.Env) -> None:
        if self.done:
            return
        slot = runner.slots.get(f"dwell_{self.place}")
        if slot is None:
            self.done = True
            return
        if runner.values[slot] >= self.after and runner.marking[runner.apn.place_index(self.place)] > 0:
            env.unwrapped.push(self.size, self.duration)
            self.done = True
            self.tick = tick
