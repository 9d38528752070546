"""The paper's two tasks as users of the library: what is specific to the pendulum and to the
nunchaku (env, mentor, randomisation, the experimenter's pushes, the physical success check, the
end-to-end job) lives here, never inside petri/learn/adapt/runtime."""

from __future__ import annotations

from importlib import import_module
from types import ModuleType

from ..errors import InvalidInput

TASKS = {"pendulum": "multiform.tasks.pendulum", "nunchaku": "multiform.tasks.nunchaku"}


def get_task(name: str) -> ModuleType:
    """The task module by name (``pendulum``, ``nunchaku``)."""
    if name not in TASKS:
        raise KeyError(f"unknown task {name!r}; tasks: {', '.join(TASKS)}")
    return import_module(TASKS[name])


def task_for_env(env_id: str) -> str:
    """The name of the task whose env is ``env_id`` (how a model directory's task is found)."""
    for name in TASKS:
        if get_task(name).ENV_ID == env_id:
            return name
    raise InvalidInput(f"no task runs the env {env_id!r}; tasks: "
                       + ", ".join(f"{n} ({get_task(n).ENV_ID})" for n in TASKS), element="env")
