"""The paper's two tasks as users of the library: what is specific to the pendulum and to the
nunchaku (env, mentor, randomisation, the experimenter's pushes, the physical success check, the
end-to-end job) lives here, never inside petri/learn/adapt/runtime."""

from __future__ import annotations

from importlib import import_module
from types import ModuleType

TASKS = {"pendulum": "multiform.tasks.pendulum", "nunchaku": "multiform.tasks.nunchaku"}


def get_task(name: str) -> ModuleType:
    """The task module by name (``pendulum``, ``nunchaku``)."""
    if name not in TASKS:
        raise KeyError(f"unknown task {name!r}; tasks: {', '.join(TASKS)}")
    return import_module(TASKS[name])
