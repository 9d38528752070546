"""multiform: teach a robot a dynamic skill by definition, demonstration and evaluation.

The three forms of teaching live in three sub-packages:

* :mod:`multiform.petri` — the adaptive Petri net (definition),
* :mod:`multiform.learn` — GP control laws, SVM judges, learned conditions (demonstration, evaluation),
* :mod:`multiform.adapt` — diagnosis and repair of the net from practice (the adaptive part).

The names below are the public API (``import multiform`` stays cheap: each is imported on first
use, and importing the package registers nothing and imports neither Gymnasium nor MuJoCo; it only
picks MuJoCo's offscreen OpenGL backend, see :mod:`multiform._gl`). A user's experiment is a
:class:`Task`; docs/api.md lists every name with its docstring.

The envs register with Gymnasium when :mod:`multiform.envs` is imported, which
``gymnasium.make("multiform.envs:multiform/ArmPendulum-v0")`` does by itself.
"""

from __future__ import annotations

from importlib import import_module
from typing import Any

__version__ = "0.1.0"

from . import _gl  # noqa: E402,F401  (MuJoCo's offscreen GL, chosen before mujoco loads)

_EXPORTS = {
    # the experiment
    "Task": "multiform.task", "load_task": "multiform.task",
    "NamedEnv": "multiform.runtime.contract", "env_contract": "multiform.runtime.contract",
    # the skill (definition)
    "load_skill": "multiform.petri.skillfile", "parse_skill": "multiform.petri.skillfile", "APN": "multiform.petri.net",
    # demonstrations
    "Episode": "multiform.demos.episode", "SegmentLabel": "multiform.demos.episode",
    "write_dataset": "multiform.demos.dataset", "read_dataset": "multiform.demos.dataset",
    "Dataset": "multiform.demos.dataset",
    "record_episode": "multiform.teach.record", "Mentor": "multiform.demos.episode",
    # the verbs
    "record": "multiform.api", "train": "multiform.api", "open_model": "multiform.api", "run_trial": "multiform.api",
    "practise": "multiform.api", "evaluate": "multiform.api", "mentor_rate": "multiform.api",
    "scenario_names": "multiform.api", "export_demos": "multiform.api", "import_demos": "multiform.api",
    "merge_demos": "multiform.api",
    # what they return or run
    "SkillModel": "multiform.model", "Executor": "multiform.runtime.executor", "Trace": "multiform.runtime.trace",
    "Job": "multiform.job", "JobConfig": "multiform.job", "InvalidInput": "multiform.errors",
    "MissingInput": "multiform.errors",
}
__all__ = sorted(_EXPORTS)


def __getattr__(name: str) -> Any:
    if name in _EXPORTS:
        value = getattr(import_module(_EXPORTS[name]), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'multiform' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
