"""The Task API: what is specific to one experiment, behind one protocol.

The method (:mod:`multiform.petri`, :mod:`~multiform.learn`, :mod:`~multiform.adapt`,
:mod:`~multiform.runtime`) works on any Gymnasium env that names its observation and command
entries. Everything else — which env, how trials start, the experimenter's disturbances, the
physical success check that compares variants alike, the practice scenarios, a scripted mentor and
the inverse model's trainer — is a *task*: a subclass of :class:`Task` (or any object or module
with the same attributes). The bundled ``pendulum`` and ``nunchaku`` are two tasks.

Only ``TASK``, ``SKILL``, ``ENV_ID`` and :meth:`Task.physical_success` are required; every other
part has a default here. A task is found by :func:`load_task` from

* a bundled name (``pendulum``, ``nunchaku``),
* an installed entry point of the group ``multiform.tasks`` (``name = "package.module:NAME"``),
* ``package.module:NAME`` or ``path/to/file.py:NAME`` (NAME a :class:`Task` subclass, instance or
  module),

so worker processes can load the same task from its name.
"""

from __future__ import annotations

import importlib
import sys
from collections.abc import Iterable, Mapping
from pathlib import Path
from types import ModuleType
from typing import Any

from .errors import InvalidInput

BUNDLED = {"pendulum": "multiform.tasks.pendulum", "nunchaku": "multiform.tasks.nunchaku"}
ENTRY_POINT_GROUP = "multiform.tasks"


class Task:
    """One experiment: env, randomisation, disturbances, success check, scenarios, mentor.

    Subclass it and set the upper-case attributes; override the methods you need. ``ENV_ID`` is a
    Gymnasium id (register your env, or name a wrapped one with
    :class:`multiform.NamedEnv` in the registered factory); the env must name its observation and
    command entries (``observation_names``, ``command_names``) and step ``dt`` seconds.

    Action modes (the skill's laws output end-effector commands, the ``commands`` of its skill file):
    *direct* — the env's action is that command (``robot_env_kwargs(False)``, the default), or
    *inverse model* — the env takes joint torques and a learned inverse model turns the command
    into them (``robot_env_kwargs(True)`` and a :meth:`train_inverse_model`).
    """

    TASK: str = ""                              # the task's name (reports, evaluation.json)
    SKILL: str = ""                             # skill file, or a bundled skill's name
    ENV_ID: str = ""                            # the Gymnasium env id
    DEMO_ENV_KWARGS: dict[str, Any] = {}        # gymnasium.make arguments while the mentor demonstrates
    DEMOS: int = 40                             # the main job's demonstrations
    LEARN: bool = False                         # the main job learns from practice (a scenario with "learn")
    DESCRIPTION: str = ""
    TARGET_SUCCESS_RATE: float = 0.9
    PLOT_VARIABLES: list[tuple[str, str]] = []  # (variable, axis label) of the report's motion plot
    REPORT: dict[str, str] = {}                 # the report's words for its pictures
    ABLATIONS_AFTER_PRACTICE: bool = True       # baselines need the practised model (False: run beside practice)
    train_inverse_model: Any = None             # (model, seed=, log=, laws_ready=) -> info; None: direct commands
    demo_push: Any = None                       # (seed) -> PushDuring arguments of a demo's push, or None

    spec: str = ""                              # how load_task found it (set by load_task)

    def physical_success(self, trace: Any) -> bool:
        """The task done, judged on the simulated world itself (the experimenter's check)."""
        raise NotImplementedError(f"task {self.TASK or type(self).__name__} has no physical_success")

    def make_mentor(self, **kwargs: Any) -> Any:
        """A scripted mentor (:class:`multiform.demos.episode.Mentor`): ``reset``, ``act``, ``label``."""
        raise InvalidInput(f"task {self.TASK} has no scripted mentor; record demonstrations yourself", element="task")

    def demo_options(self, seed: int) -> dict[str, Any]:
        """Reset options of demonstration ``seed``."""
        return {}

    def trial_options(self, seed: int) -> dict[str, Any]:
        """Reset options of practice and evaluation trial ``seed``."""
        return {}

    def push(self, seed: int) -> dict[str, Any] | None:
        """The experimenter's push in evaluation trial ``seed`` (:class:`multiform.adapt.perturb.PushInPlace`
        arguments; the env needs ``push(size, duration)``), or None: no disturbance."""
        return None

    def evaluation_specs(self, n: int, seed: int, push_fraction: float) -> list:
        """``n`` evaluation trials (:class:`multiform.adapt.evaluation.TrialSpec`); every trial whose
        index falls in ``push_fraction`` gets :meth:`push`."""
        from .adapt.evaluation import TrialSpec
        every = 0 if push_fraction <= 0 else max(1, int(round(1.0 / push_fraction)))
        out = []
        for i in range(n):
            s = 50_000_000 + seed * 100_000 + i
            out.append(TrialSpec(seed=s, options=self.trial_options(s),
                                 push=self.push(s) if every and i % every == 0 else None))
        return out

    def scenarios(self) -> list[dict[str, Any]]:
        """Practice scenarios, in order: ``name``, ``title``, ``options`` (seed -> reset options) and
        optionally ``perturb`` (trial -> perturbation), ``config`` (PracticeConfig fields), ``seed``,
        ``mentor`` (factory of a grader), ``takeover`` (factory of the mentor's takeover of a failed trial:
        trace, tick -> a demonstration from there; see :mod:`multiform.adapt.takeover`), ``learn``.
        Default: one scenario, ``practice``, repairing on three failures in a row."""
        return [{"name": "practice", "title": "practice from the task's trial starts", "options": self.trial_options,
                 "config": {"failures_in_a_row": 3, "success_streak": 5}}]

    def robot_env_kwargs(self, inverse_model: bool) -> dict[str, Any]:
        """gymnasium.make arguments of the robot's own trials (torques with the inverse model)."""
        if inverse_model:
            raise InvalidInput(f"task {self.TASK} has no inverse model; its env takes the commands directly",
                               element="--inverse-model")
        return dict(self.DEMO_ENV_KWARGS)

    def ablations(self, model: Any, out: Path, cfg: Any) -> Iterable:
        """Baselines to evaluate beside the skill (:class:`multiform.adapt.evaluation.Variant`)."""
        return []

    def __repr__(self) -> str:
        return f"<task {self.TASK or type(self).__name__} ({self.spec or 'in memory'})>"


class ModuleTask(Task):
    """A module (as the bundled tasks are) or any object with the task attributes, read through at
    each use, with :class:`Task`'s defaults for what it lacks."""

    def __init__(self, module: Any):
        self.module = module

    def __getattribute__(self, name: str) -> Any:
        if not name.startswith("_") and name not in ("module", "spec"):
            module = object.__getattribute__(self, "module")
            if hasattr(module, name):
                return getattr(module, name)
        return object.__getattribute__(self, name)


def as_task(obj: Any, spec: str = "") -> Task:
    """``obj`` as a :class:`Task`: a Task instance as it is, a Task subclass instantiated, a module
    or other object wrapped with the defaults for what it lacks."""
    if isinstance(obj, type) and issubclass(obj, Task):
        obj = obj()
    task = obj if isinstance(obj, Task) else ModuleTask(obj)
    missing = [a for a in ("TASK", "SKILL", "ENV_ID") if not getattr(task, a, "")]
    if missing:
        raise InvalidInput(f"is not a task: it lacks {', '.join(missing)}", element=spec or repr(obj))
    if spec and not task.spec:
        task.spec = spec
    return task


_LOADED: dict[str, Task] = {}


def load_task(spec: str | Task | ModuleType) -> Task:
    """The task ``spec`` names (see the module docstring); a Task passes through. Bad specs raise
    :class:`~multiform.errors.InvalidInput` naming the spec."""
    if not isinstance(spec, str):
        return as_task(spec)
    if spec in _LOADED:
        return _LOADED[spec]
    task = as_task(_resolve(spec), spec)
    _LOADED[spec] = task
    return task


def installed_task(name: Any, file: str = "", element: str = "task") -> Task:
    """The bundled or installed task of the plain name ``name`` (read from a file): never a
    ``module:NAME`` or ``file.py:NAME`` spec, whose loading would run code the file names."""
    known = sorted(set(BUNDLED) | set(_entry_points()))
    if not isinstance(name, str) or name not in known:
        shown = repr(name) if len(repr(name)) <= 60 else repr(name)[:50] + "..."
        raise InvalidInput(f"names the task {shown}, not a bundled or installed task ({', '.join(known)}); name "
                           f"the task yourself (--task): a file never makes multiform import code",
                           file=file, element=element)
    return load_task(name)


def _resolve(spec: str) -> Any:
    if spec in BUNDLED:
        return importlib.import_module(BUNDLED[spec])
    if ":" not in spec:
        ep = _entry_points().get(spec)
        if ep is None:
            known = sorted(set(BUNDLED) | set(_entry_points()))
            raise InvalidInput(f"unknown task; tasks: {', '.join(known)}, or package.module:NAME, "
                               "or path/to/file.py:NAME", element=spec)
        try:
            return ep.load()
        except Exception as exc:
            raise InvalidInput(f"the entry point {ep.value} cannot be loaded ({type(exc).__name__}: {exc})",
                               element=spec) from None
    where, _, name = spec.rpartition(":")
    if not where or not name.isidentifier():
        raise InvalidInput("a task is package.module:NAME or path/to/file.py:NAME", element=spec)
    module = _import_file(where, spec) if where.endswith(".py") else _import_module(where, spec)
    if not hasattr(module, name):
        raise InvalidInput(f"{where} has no {name}", element=spec)
    return getattr(module, name)


def _import_module(name: str, spec: str) -> ModuleType:
    try:
        return importlib.import_module(name)
    except ModuleNotFoundError as exc:
        raise InvalidInput(f"no module {exc.name!r}", element=spec) from None
    except Exception as exc:
        raise InvalidInput(f"importing {name} failed ({type(exc).__name__}: {exc})", element=spec) from None


def _import_file(path: str, spec: str) -> ModuleType:
    file = Path(path).resolve()
    if not file.is_file():
        raise InvalidInput("no such file", file=path, element=spec)
    key = "multiform_task_" + "".join(c if c.isalnum() else "_" for c in str(file))
    if key in sys.modules:
        return sys.modules[key]
    module = ModuleType(key)
    module.__file__ = str(file)
    sys.modules[key] = module
    try:        # compiled here, not imported: reading a task file writes no bytecode beside it
        exec(compile(file.read_bytes(), str(file), "exec"), module.__dict__)
    except Exception as exc:
        del sys.modules[key]
        raise InvalidInput(f"importing it failed ({type(exc).__name__}: {exc})", file=path, element=spec) from None
    return module


def _entry_points() -> Mapping[str, Any]:
    from importlib.metadata import entry_points
    return {ep.name: ep for ep in entry_points(group=ENTRY_POINT_GROUP)}


def task_for_env(env_id: str) -> Task:
    """The bundled or installed task whose env is ``env_id`` (how a model directory's task is found)."""
    names = list(BUNDLED) + [n for n in _entry_points() if n not in BUNDLED]
    for name in names:
        task = load_task(name)
        if task.ENV_ID == env_id:
            return task
    raise InvalidInput(f"no known task runs the env {env_id!r}; name it with --task (tasks: "
                       + ", ".join(f"{n} ({load_task(n).ENV_ID})" for n in names) + ")", element="env")
