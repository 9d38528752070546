"""The paper's two tasks as users of the library: what is specific to the pendulum and to the
nunchaku (env, mentor, randomisation, the experimenter's pushes, the physical success check, the
end-to-end job) lives here, never inside petri/learn/adapt/runtime. Each module satisfies the Task
protocol (:class:`multiform.task.Task`); load them with :func:`multiform.task.load_task`."""

from __future__ import annotations

from importlib import import_module
from types import ModuleType

from ..task import BUNDLED as TASKS


def get_task(name: str) -> ModuleType:
    """The bundled task module by name (``pendulum``, ``nunchaku``)."""
    if name not in TASKS:
        raise KeyError(f"unknown task {name!r}; tasks: {', '.join(TASKS)}")
    return import_module(TASKS[name])
