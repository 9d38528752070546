"""The library's few verbs, as the command line runs them: record, train, run a trial, practise,
evaluate. Each takes a :class:`~multiform.task.Task` (or its name, see
:func:`~multiform.task.load_task`) where the experiment matters."""

from __future__ import annotations

import os
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

from .errors import InvalidInput
from .task import Task, load_task

TaskLike = Task | str


def record(task: TaskLike, out: str | os.PathLike, demos: int = 40, seed: int = 0, workers: int = 1) -> Path:
    """Record ``demos`` demonstrations of the task's scripted mentor into the demos file ``out``
    (HDF5); demo ``i`` starts from seed ``100000 * seed + i``."""
    from .demos.dataset import write_dataset
    from .demos.record import record_many
    task = load_task(task)
    eps = record_many(task, [seed * 100_000 + i for i in range(demos)], task.DEMO_ENV_KWARGS, workers=workers)
    return write_dataset(out, eps, task.SKILL, task.ENV_ID, task.DEMO_ENV_KWARGS)


def train(skill: str | os.PathLike, demos: str | os.PathLike, out: str | os.PathLike, task: TaskLike | None = None,
          seed: int = 0, inverse_model: bool = False, log: Callable[[str], None] = print) -> Any:
    """Fit a skill model in the new directory ``out`` from the skill file and the demos: a GP law
    per maneuver, an SVM judge per judged place, the place regions, and (``inverse_model``, with a
    task that has a trainer) the auxiliary inverse model. Returns the :class:`~multiform.model.SkillModel`."""
    from .demos.dataset import read_dataset
    from .job import train_model
    from .model import SkillModel, staged_model_dir
    ds = read_dataset(demos)
    env_kwargs, trainer = ds.env_kwargs, None
    if inverse_model:
        if task is None or load_task(task).train_inverse_model is None:
            raise InvalidInput("an inverse model needs a task with train_inverse_model", element="inverse_model")
        task = load_task(task)
        env_kwargs, trainer = task.robot_env_kwargs(True), task.train_inverse_model
    with staged_model_dir(out) as partial:
        model = SkillModel.create(partial, skill, demos, ds.env_name, env_kwargs)
        train_model(model, seed=seed, log=log, inverse_trainer=trainer)
    return SkillModel(out)


def open_model(path: str | os.PathLike) -> Any:
    """The model directory ``path`` (:class:`~multiform.model.SkillModel`), checked before it runs."""
    from .model import SkillModel
    return SkillModel(path)


def run_trial(model: Any, seed: int, options: Mapping[str, Any] | None = None, task: TaskLike | None = None,
              version: int | None = None) -> Any:
    """One trial of the model's net (latest, or ``version``) on its env; returns the
    :class:`~multiform.runtime.trace.Trace`. Reset options: ``options``, else the task's
    ``trial_options(seed)``."""
    model = open_model(model) if isinstance(model, (str, os.PathLike)) else model
    if options is None and task is not None:
        options = load_task(task).trial_options(seed)
    env = model.make_env()
    try:
        apn = model.history.version(version) if version is not None else None
        return model.executor(env, apn).run(seed=seed, options=options)
    finally:
        env.close()


def practise(model: Any, task: TaskLike, scenario: str | None = None, out: str | os.PathLike | None = None,
             max_trials: int = 30, seed: int = 0,
             progress: Callable[[Any, dict[str, Any]], None] | None = None) -> Any:
    """Practise the model through one of the task's scenarios (default: its first); constant
    failure triggers diagnosis and a repair of the net, recorded as a revision. Returns the
    :class:`~multiform.adapt.practice.PracticeState` (trials, revisions, why it stopped)."""
    model = open_model(model) if isinstance(model, (str, os.PathLike)) else model
    task = load_task(task)
    scenarios = task.scenarios()
    names = [s.name for s in scenarios]
    if scenario is not None and scenario not in names:
        raise InvalidInput(f"task {task.TASK} has no scenario {scenario!r}; its scenarios: {', '.join(names)}",
                           element="scenario")
    index = names.index(scenario) if scenario is not None else 0
    sc = scenarios[index]
    folder = Path(out) if out is not None else Path(model.path) / "practice" / sc.name
    return sc.practice(model, folder, max_trials, seed + index).run(progress=progress)


def evaluate(model: Any, task: TaskLike, trials: int = 200, seed: int = 0, push_fraction: float = 0.5,
             workers: int = 1, version: int | None = None) -> dict[str, Any]:
    """The model on the task's evaluation trials, judged by the task's physical check: the success
    rate with its 95 % Wilson interval, the robot's own verdict beside it, one record per trial
    (``trials_detail``) — what ``multiform evaluate`` writes to ``evaluation.json``."""
    from .evaluation import Variant
    from .evaluation import evaluate as run
    model = open_model(model) if isinstance(model, (str, os.PathLike)) else model
    task = load_task(task)
    model.verify()
    variant = Variant(model.apn.name, str(Path(model.path).resolve()), net_version=version,
                      env_modules=model.env_modules)
    return run(task, variant, task.evaluation_specs(trials, seed, push_fraction), workers=workers)
