"""The Task API: what is specific to one experiment, behind one protocol.

The method (:mod:`multiform.petri`, :mod:`~multiform.learn`, :mod:`~multiform.adapt`,
:mod:`~multiform.runtime`) works on any Gymnasium env that names its observation and command
entries. Everything else — which env, how trials start, the experimenter's disturbances, the
physical success check that compares variants alike, the practice scenarios, a scripted mentor and
the inverse model's trainer — is a *task*: a subclass of :class:`Task` (or any object or module
with the same attributes). The bundled ``pendulum``, ``nunchaku`` and ``ball_in_cup`` are three tasks.

Only ``TASK``, ``SKILL``, ``ENV_ID`` and :meth:`Task.physical_success` are required; every other
part has a default here, and practice defaults to the method's own settings
(:class:`~multiform.adapt.practice.PracticeConfig`): a task holds only what is specific to it. A
task is found by :func:`load_task` from

* a bundled name (``pendulum``, ``nunchaku``, ``ball_in_cup``),
* an installed entry point of the group ``multiform.tasks`` (``name = "package.module:NAME"``),
* ``package.module:NAME`` or ``path/to/file.py:NAME`` (NAME a :class:`Task` subclass or instance),

so worker processes can load the same task from its name.
"""

from __future__ import annotations

import importlib
import math
import sys
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from types import ModuleType
from typing import Any

from .errors import InvalidInput, MissingInput
from .runtime.perturb import PushInPlace, TrialSpec

BUNDLED = {"pendulum": "multiform.tasks.pendulum:Pendulum", "nunchaku": "multiform.tasks.nunchaku:Nunchaku",
           "ball_in_cup": "multiform.tasks.ball_in_cup:BallInCup"}
ENTRY_POINT_GROUP = "multiform.tasks"


@dataclass(frozen=True)
class Scenario:
    """One practice run of a task: which trials (``options``: reset options per trial seed, ``perturb``:
    the experimenter's push per draw, or None), whether it learns from practice (``learn``; else it
    only repairs the net) and with the mentor's help (``mentor``: a factory of its grader of a
    trial; ``takeover``: a factory of its takeover of a failed trial, see
    :mod:`multiform.adapt.takeover`), and the :class:`~multiform.adapt.practice.PracticeConfig`
    fields in which it departs from the method's defaults (``config``; each with its reason in the
    task). Its trials are drawn from the job seed plus the scenario's place in the task's list."""

    name: str
    title: str
    options: Callable[[int], dict[str, Any]]
    perturb: Callable[[int], Any] | None = None
    learn: bool = False
    mentor: Callable[[], Any] | None = None
    takeover: Callable[[], Any] | None = None
    config: Mapping[str, Any] = field(default_factory=dict)
    push: Callable[[int], Any] | None = None    # draw -> the push, scheduled or not (deliberate practice)

    def with_options(self, options: Mapping[str, Any]) -> Scenario:
        """This scenario with ``options`` overriding its reset options in every trial (a changed object)."""
        base = self.options
        return replace(self, options=lambda k: {**base(k), **options})

    def with_config(self, overrides: Mapping[str, Any]) -> Scenario:
        """This scenario with ``overrides`` (:class:`~multiform.adapt.practice.PracticeConfig` fields)
        over its own practice settings."""
        return replace(self, config={**self.config, **overrides})

    def practice_config(self, max_trials: int, seed: int) -> Any:
        """The scenario's :class:`~multiform.adapt.practice.PracticeConfig`."""
        from .adapt.practice import REPAIR_ONLY, PracticeConfig
        return PracticeConfig(**{**({} if self.learn else REPAIR_ONLY), **self.config}, max_trials=max_trials,
                              seed=seed)

    def practice(self, model: Any, folder: str | Path, max_trials: int, seed: int = 0,
                 observe: Callable[[int, Any], Any] | None = None, mentors: Sequence[str] = ()) -> Any:
        """A :class:`~multiform.adapt.practice.Practice` of ``model`` in ``folder`` through this
        scenario (``seed``: the job seed plus the scenario's place in its task's list); ``mentors``
        (the task's named mentors) take turns at grading trials, else its default mentor does."""
        from .adapt.practice import Practice
        cfg = self.practice_config(max_trials, seed)
        mentor = None
        if self.learn and self.mentor is not None:
            mentor = self.mentor(mentors) if mentors else self.mentor()
        takeover = self.takeover() if self.learn and self.takeover is not None and cfg.budgets(True)[1] else None
        return Practice(model, folder, cfg, options=self.options, perturb=self.perturb, name=self.name,
                        mentor=mentor, observe=observe, takeover=takeover, push=self.push)


class Task:
    """One experiment: env, randomisation, disturbances, success check, scenarios, mentor.

    Subclass it and set the upper-case attributes; override the methods you need. ``ENV_ID`` is a
    Gymnasium id (register your env, or name a wrapped one with
    :class:`multiform.NamedEnv` in the registered factory); the env must name its observation and
    command entries (``observation_names``, ``command_names``) and step ``dt`` seconds.

    ``DEMO_ENV_KWARGS`` make the env the demonstrations' commands are meant for; with
    ``KINESTHETIC`` the mentor guides the arm instead (the same env in its hand-guiding mode,
    ``action_mode="kinesthetic"``) and the commands are recovered from the arm's motion
    (:mod:`multiform.teach.kinesthetic`).

    Action modes (the skill's laws output end-effector commands, the ``commands`` of its skill file):
    *direct* — the env's action is that command (``robot_env_kwargs(False)``, the default), or
    *inverse model* — the env takes joint torques and a learned inverse model turns the command
    into them (``robot_env_kwargs(True)`` and a :meth:`train_inverse_model`).
    """

    TASK: str = ""                              # the task's name (reports, evaluation.json)
    SKILL: str = ""                             # skill file, or a bundled skill's name
    ENV_ID: str = ""                            # the Gymnasium env id
    DEMO_ENV_KWARGS: dict[str, Any] = {}        # gymnasium.make arguments while the mentor demonstrates
    DEMOS: int = 10                             # the main job's demonstrations
    KINESTHETIC: bool = False                   # the mentor teaches by guiding the arm by hand (False: it sends
                                                # commands, at a joystick); --kinesthetic overrides it
    DESCRIPTION: str = ""
    TARGET_SUCCESS_RATE: float = 0.9
    EVALUATION_SEEDS: int = 50_000_000          # evaluation trial i of job seed s: seed EVALUATION_SEEDS + 100000 s + i
    PLOT_VARIABLES: list[tuple[str, str]] = []  # (variable, axis label) of the report's motion plot
    REPORT: dict[str, str] = {}                 # the report's words for its pictures
    ABLATIONS_AFTER_PRACTICE: bool = True       # baselines need the practised model (False: run beside practice)
    train_inverse_model: Any = None             # (model, seed=, log=, laws_ready=) -> info; None: direct commands
    MENTORS: dict[str, dict[str, Any]] = {}     # named scripted mentors: name -> make_mentor arguments

    spec: str = ""                              # how load_task found it (set by load_task)

    def physical_success(self, trace: Any) -> bool:
        """The task done, judged on the simulated world itself (the experimenter's check).

        A trial's trace ends when the net stops: at a final place (success or failure) or at the
        skill's ``max_duration``, not at a fixed time. Judge what happened over the whole trace
        (e.g. "upright for 5 s at some point"), not only its last samples: a skill that gives up
        early ends its trace early too, and its last samples may look fine."""
        raise NotImplementedError(f"task {self.TASK or type(self).__name__} has no physical_success")

    def make_mentor(self, **kwargs: Any) -> Any:
        """A scripted mentor (:class:`multiform.demos.episode.Mentor`), made once per recording process:
        its ``name`` (stored with its episodes and labels), ``reset(obs, rng)`` at each
        demonstration (``rng`` seeded from the demonstration's seed; a ``reset`` that takes a
        ``seed`` keyword is told the seed too), ``act(obs, info, t)`` -> (command, transition),
        ``finished()``, ``label(episode)`` -> segment labels, and optionally ``outcome``
        (``"success"``/``"failure"``), its verdict on the whole attempt. ``kwargs`` come from
        :func:`multiform.teach.record.record_many`'s ``mentor_kwargs``. Optionally ``grade_trial``:
        its verdict on each stay of a practice trial (:meth:`mentor_grader`)."""
        raise InvalidInput(f"task {self.TASK} has no scripted mentor; record demonstrations yourself", element="task")

    def mentor_kwargs(self, name: str | None = None) -> dict[str, Any]:
        """:meth:`make_mentor`'s arguments for the task's scripted mentor ``name`` (one of
        ``MENTORS``; None: the task's default mentor, no arguments)."""
        if name is None:
            return {}
        if name not in self.MENTORS:
            known = ", ".join(self.MENTORS) or "none besides its default"
            raise InvalidInput(f"task {self.TASK} has no scripted mentor {name!r}; its mentors: {known}",
                               element="mentor")
        return dict(self.MENTORS[name])

    def demo_push(self, seed: int) -> dict[str, Any] | None:
        """The experimenter's push in demonstration ``seed`` (:class:`multiform.teach.record.PushDuring`
        arguments), or None: no push."""
        return None

    def mentor_grader(self, mentors: Sequence[str] = ()) -> Callable[[Any, Any], list] | None:
        """The scripted mentor watching a practice trial: one verdict per stay, from the trace alone
        (its ``grade_trial``); None if the task has no scripted mentor that grades trials. With
        ``mentors`` (names of ``MENTORS``), they take turns: the first grades the first trial it is
        asked to, the second the next, and so on."""
        try:
            graders = [self.make_mentor(**self.mentor_kwargs(m)) for m in mentors] or [self.make_mentor()]
        except InvalidInput:
            if mentors:
                raise
            return None
        if not all(callable(getattr(g, "grade_trial", None)) for g in graders):
            return None
        turn = [0]

        def grade(episode: Any, apn: Any) -> list:
            g = graders[turn[0] % len(graders)]
            turn[0] += 1
            return g.grade_trial(episode)
        return grade

    def mentor_takeover(self) -> Callable[[Any, int], Any] | None:
        """The mentor taking over a failed practice trial (trace, tick -> a demonstration from there;
        :mod:`multiform.adapt.takeover`), or None: it does not."""
        return None

    def demo_options(self, seed: int) -> dict[str, Any]:
        """Reset options of demonstration ``seed``."""
        return {}

    def trial_options(self, seed: int) -> dict[str, Any]:
        """Reset options of practice and evaluation trial ``seed``."""
        return {}

    def push(self, seed: int) -> dict[str, Any] | None:
        """The experimenter's push in trial ``seed`` (:class:`multiform.runtime.perturb.PushInPlace`
        arguments; the env needs ``push(size, duration)``), or None: no disturbance."""
        return None

    def evaluation_specs(self, n: int, seed: int, push_fraction: float) -> list[TrialSpec]:
        """``n`` evaluation trials of job seed ``seed``: trial ``i`` has seed ``EVALUATION_SEEDS +
        100000 * seed + i`` and its :meth:`trial_options`; every trial whose index falls in
        ``push_fraction`` (every ``round(1 / push_fraction)``-th, from the first) gets :meth:`push`; never a
        demonstration's seed (``100000 * seed + i``)."""
        every = 0 if push_fraction <= 0 else max(1, int(round(1.0 / push_fraction)))
        out = []
        for i in range(n):
            s = self.EVALUATION_SEEDS + seed * 100_000 + i
            out.append(TrialSpec(seed=s, options=self.trial_options(s),
                                 push=self.push(s) if every and i % every == 0 else None))
        return out

    def pushed(self, base: int, fraction: float) -> Callable[[int], Any] | None:
        """The experimenter's pushes in a practice scenario: trial ``k`` gets :meth:`push` of seed
        ``base + k`` in ``fraction`` of the trials, by pairs (a plain and an exploring trial alike);
        None if the task never pushes or ``fraction`` is 0."""
        if fraction <= 0 or self.push(base) is None:
            return None

        def perturb(k: int) -> Any:
            j = k // 2
            hit = math.ceil((j + 1) * fraction - 1e-9) > math.ceil(j * fraction - 1e-9)
            return PushInPlace(**self.push(base + k)) if hit else None
        return perturb

    def scenarios(self) -> list[Scenario]:
        """Practice scenarios, in order. Default: ``practice``, which repairs the net from the task's
        trial starts, then ``keep``, practice as the skill will be evaluated (pushed in half the
        trials where the task pushes) that also learns from its own graded experience, with the
        scripted mentor's grades and takeovers where the task has them."""
        return [Scenario("practice", "practice from the task's trial starts: repair the net", self.trial_options),
                Scenario("keep", "practice as evaluated, learning from its own graded experience",
                         self.trial_options, perturb=self.pushed(1_000, 0.5), learn=True,
                         mentor=self.mentor_grader, takeover=self.mentor_takeover, push=self.pushed(1_000, 1.0))]

    def robot_env_kwargs(self, inverse_model: bool) -> dict[str, Any]:
        """gymnasium.make arguments of the robot's own trials (torques with the inverse model)."""
        if inverse_model:
            raise InvalidInput(f"task {self.TASK} has no inverse model; its env takes the commands directly",
                               element="--inverse-model")
        return dict(self.DEMO_ENV_KWARGS)

    def ablations(self, model: Any, out: Path, cfg: Any) -> Iterable:
        """Baselines to evaluate beside the skill (:class:`multiform.evaluation.Variant`)."""
        return []

    def __repr__(self) -> str:
        return f"<task {self.TASK or type(self).__name__} ({self.spec or 'in memory'})>"


def as_task(obj: Any, spec: str = "") -> Task:
    """``obj`` as a :class:`Task`: a Task instance as it is, a Task subclass instantiated."""
    if isinstance(obj, type) and issubclass(obj, Task):
        obj = obj()
    if not isinstance(obj, Task):
        raise InvalidInput(f"is not a multiform.Task subclass or instance (got {type(obj).__name__})",
                           element=spec or repr(obj))
    task = obj
    missing = [a for a in ("TASK", "SKILL", "ENV_ID") if not getattr(task, a, "")]
    if missing:
        raise InvalidInput(f"is not a task: it lacks {', '.join(missing)}", element=spec or repr(obj))
    if spec and not task.spec:
        task.spec = spec
    return task


_LOADED: dict[str, Task] = {}


def load_task(spec: str | Task) -> Task:
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
        module, _, name = BUNDLED[spec].partition(":")
        return getattr(importlib.import_module(module), name)
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
        raise MissingInput("no such file", file=path, element=spec)
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
