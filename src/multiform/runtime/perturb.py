"""The experimenter's push during a trial (the executor's ``perturb`` hook), and one trial run as
described by plain data (:class:`TrialSpec`: seed, reset options, push), the same way wherever it runs."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

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


@dataclass(frozen=True)
class TrialSpec:
    """One trial: seed, env reset options, and the experimenter's push (if any)."""

    seed: int
    options: dict[str, Any] = field(default_factory=dict)
    push: dict[str, Any] | None = None          # PushInPlace arguments


def run_spec(executor: Any, spec: TrialSpec, **run: Any) -> tuple[Any, PushInPlace | None]:
    """Run the trial ``spec`` describes on ``executor`` (:class:`~.executor.Executor`; ``run``: its
    ``run`` arguments such as ``observer`` or ``qpos_every``); returns the trace and the push (its
    ``tick`` says when it pushed), or None without one."""
    push = PushInPlace(**spec.push) if spec.push else None
    return executor.run(seed=spec.seed, options=spec.options, perturb=push, **run), push
