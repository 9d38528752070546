"""The library's verbs, as the command line runs them: record, train, run a trial, practise,
evaluate, the mentor's own rate, and demonstrations to and from LeRobot. Each takes a
:class:`~multiform.task.Task` (or its name, see :func:`~multiform.task.load_task`) where the
experiment matters.

``multiform`` (the command) is a thin shell over these functions: its options are their
parameters, with the same defaults. Outputs follow one policy: a verb never replaces an existing
output unless ``overwrite=True`` (``--overwrite``), and then only once the new one is complete.
A missing input raises :class:`~multiform.errors.MissingInput`, any other bad input
:class:`~multiform.errors.InvalidInput`; both name the file and what is wrong, and nothing is
written.

Seeds: demonstration ``i`` of ``record(..., seed=s)`` starts from seed ``100000 * s + i``;
evaluation trial ``i`` of ``evaluate(..., seed=s)`` from seed ``50000000 + 100000 * s + i``
(:meth:`multiform.Task.evaluation_specs`), so the two never share a start.
"""

from __future__ import annotations

import os
import shutil
from dataclasses import replace
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

from .errors import InvalidInput
from .parallel import fitting
from .task import Scenario, Task, load_task

TaskLike = Task | str
Progress = Callable[[int, int], None]         # (done, total) after each demonstration or trial
DEMO_SEED_STRIDE = 100_000                    # demo i of record(seed=s) starts from seed 100000 * s + i


def record(task: TaskLike, out: str | os.PathLike, demos: int | None = None, seed: int = 0, workers: int = 2,
           overwrite: bool = False, progress: Progress | None = None, ray: str | None = None,
           mentor: str | None = None, kinesthetic: bool | None = None) -> Path:
    """Record ``demos`` demonstrations (default: the task's ``DEMOS``) of the task's scripted mentor
    (``mentor``: one of the task's ``MENTORS`` by name; default: its default mentor) into the demos
    file ``out`` (HDF5, see docs/demonstrations.md) on ``workers`` processes (or as Ray tasks at the
    cluster ``ray``); demo ``i`` starts from seed ``100000 * seed + i``. Every demo and label names
    its mentor. ``kinesthetic``: the mentor guides the compliant arm by hand and the commands are
    recovered from the arm's motion, the person's forces never kept (None: the task's
    ``KINESTHETIC``). The file's folder is made if missing. Returns the path."""
    from .demos.dataset import write_dataset
    from .teach.kinesthetic import KINESTHETIC, check_kinesthetic
    from .teach.record import record_many
    from .lock import check_writable, exclusive
    task = load_task(task)
    mentor_kwargs = task.mentor_kwargs(mentor)            # an unknown mentor is refused before anything
    guided = bool(task.KINESTHETIC if kinesthetic is None else kinesthetic)
    if guided:
        check_kinesthetic(task.ENV_ID, task.DEMO_ENV_KWARGS, task.TASK)
    out = _new_output(out, overwrite, "file")
    if not out.parent.exists():
        out.parent.mkdir(parents=True)
    check_writable(out)                       # before recording, not after
    n = task.DEMOS if demos is None else int(demos)
    with exclusive(out):
        eps = record_many(task.spec or task, [seed * DEMO_SEED_STRIDE + i for i in range(n)], task.DEMO_ENV_KWARGS,
                          mentor_kwargs=mentor_kwargs, workers=workers, progress=progress, ray=ray, kinesthetic=guided)
        return write_dataset(out, eps, task.SKILL, task.ENV_ID, task.DEMO_ENV_KWARGS,
                             teaching=KINESTHETIC if guided else "")


def merge_demos(demos: list[str | os.PathLike], out: str | os.PathLike, mentors: Mapping[str, str] | None = None,
                overwrite: bool = False) -> Any:
    """Merge the demos files of several people into one demos file ``out`` (each demo keeps its
    mentor; one robomimic filter key per mentor, ``mask/mentor_<name>``). Files of different skills,
    envs, variables, commands or control periods are refused, naming the file; ``mentors`` names the
    mentor of a file whose demos record none (the file as given → the name). Returns the
    :class:`~multiform.demos.dataset.Dataset` written."""
    from .demos.dataset import read_dataset
    from .demos.merge import merge_datasets
    from .lock import exclusive
    target = _new_output(out, overwrite, "file")
    if any(Path(d).resolve() == target.resolve() for d in demos):
        raise InvalidInput("is also one of the files to merge; write the merged file elsewhere", file=str(target))
    with exclusive(target):
        merge_datasets(demos, target, mentors)
    return read_dataset(target)


def train(skill: str | os.PathLike, demos: str | os.PathLike, out: str | os.PathLike, task: TaskLike | None = None,
          seed: int = 0, inverse_model: bool = False, overwrite: bool = False,
          log: Callable[[str], None] = print, fusion: bool = True, workers: int = 2) -> Any:
    """Fit a skill model in the directory ``out`` from the skill file and the demos: a GP law per
    maneuver, an SVM judge per judged place, the place regions, and (``inverse_model``) the
    auxiliary inverse model of ``task`` (default: the bundled or installed task whose env recorded
    the demos). The skill file's ``env:`` must be the demos' env. Demos of several mentors are
    weighed by how far each is trusted (``MODEL/mentors.json``; docs/how-it-learns.md), or pooled
    as one mentor's with ``fusion=False``. ``workers`` processes fit each law's hyperparameter subsets
    side by side (the model does not depend on it). Returns the :class:`~multiform.model.SkillModel`."""
    from .demos.dataset import read_dataset
    from .trainer import train_model
    from .model import SkillModel, staged_model_dir
    from .petri.skillfile import load_skill
    from .task import task_for_env
    task = load_task(task) if task is not None else None     # first: a user's task registers its env
    load_skill(skill)
    ds = read_dataset(demos)
    final = _new_output(out, overwrite, "folder", marker="model.json")
    trainer, env_kwargs = None, ds.env_kwargs
    if inverse_model:                          # decided before anything is written
        task = task or _task_or_none(task_for_env, ds.env_name)
        if task is None or getattr(task, "train_inverse_model", None) is None:
            raise InvalidInput(f"no inverse-model trainer for {ds.env_name}; train without it",
                               element="inverse_model (--inverse-model)")
        trainer, env_kwargs = task.train_inverse_model, task.robot_env_kwargs(True)
    target = final.with_name(f".{final.name}.replacing") if final.exists() else final
    with staged_model_dir(target) as partial:
        model = SkillModel.create(partial, skill, demos, ds.env_name, env_kwargs)
        log(f"training {model.apn.name} from {len(ds)} demos into {final}")
        with fitting(workers):
            train_model(model, seed=seed, log=log, inverse_trainer=trainer, beside=True, fusion=fusion)
    if target != final:
        _swap_in(target, final)
    return SkillModel(final)


def open_model(path: str | os.PathLike, env_modules: tuple[str, ...] = ()) -> Any:
    """The model directory ``path`` (:class:`~multiform.model.SkillModel`), checked before it runs;
    ``env_modules`` are the modules its ``module:Env-v0`` env id may import."""
    from .model import SkillModel
    return SkillModel(path, env_modules=env_modules)


def run_trial(model: Any, seed: int, options: Mapping[str, Any] | None = None, task: TaskLike | None = None,
              version: int | None = None) -> Any:
    """One trial of the model's net (latest, or ``version``) on its env; returns the
    :class:`~multiform.runtime.trace.Trace`. Reset options: ``options``, else the task's
    ``trial_options(seed)``. The trace ends when the net stops (a final place, or the skill's
    ``max_duration``): a physical check on its last samples judges the moment the net stopped."""
    from .runtime.perturb import TrialSpec, run_spec
    model = _model(model)
    if options is None and task is not None:
        options = load_task(task).trial_options(seed)
    env = model.make_env()
    try:
        apn = model.history.version(version) if version is not None else None
        return run_spec(model.executor(env, apn), TrialSpec(seed, dict(options or {})))[0]
    finally:
        env.close()


def practise(model: Any, task: TaskLike | None = None, scenario: str | None = None,
             out: str | os.PathLike | None = None, max_trials: int = 30, seed: int = 0,
             stop_after: int | None = None, progress: Callable[[Any, dict[str, Any]], None] | None = None,
             observe: Callable[..., Any] | None = None, options: Mapping[str, Any] | None = None,
             workers: int = 2) -> Any:
    """Practise the model through one of the task's scenarios (default: the task's first; task
    default: the bundled or installed one whose env the model runs); constant failure triggers
    diagnosis and a repair of the net, recorded as a revision. The practice folder ``out``
    (default ``MODEL/practice/SCENARIO``) is resumed where it stopped; ``stop_after`` ends this
    call after that many more trials. ``progress(state, trial)`` is called after each trial.
    ``options`` (env reset options, e.g. ``{"length": 0.24}``) override the task's in every trial:
    practice on a changed object, which adapts the skill to it like any other practice. ``workers``
    processes fit each refitted law's hyperparameter subsets side by side (the trials do not depend on it).
    Returns the :class:`~multiform.adapt.practice.PracticeState` (trials, revisions, why it stopped)."""
    model = _model(model)
    task = _task_of(model, task)
    index, sc = _scenario(task, scenario)
    if options:
        sc = sc.with_options(_reset_options(options, model, task))
    folder = Path(out) if out is not None else Path(model.path) / "practice" / sc.name
    practice = sc.practice(model, folder, max_trials, seed + index, observe=observe(folder) if observe else None)
    with fitting(workers):
        return practice.run(progress=progress, stop_after=stop_after)


def scenario_names(task: TaskLike) -> list[str]:
    """The task's practice scenarios, in order (the first is :func:`practise`'s default)."""
    return [s.name for s in load_task(task).scenarios()]


def evaluate(model: Any, task: TaskLike | None = None, trials: int = 200, seed: int = 0, push_fraction: float = 0.5,
             workers: int = 2, version: int | None = None, out: str | os.PathLike | None = None,
             overwrite: bool = False, progress: Progress | None = None, ray: str | None = None,
             options: Mapping[str, Any] | None = None) -> dict[str, Any]:
    """The model (its latest net, or ``version``) on the task's evaluation trials (seeds: see the
    module docstring), judged by the task's physical check: the success rate with its 95 % Wilson
    interval, the robot's own verdict beside it, one record per trial (``trials_detail``). With
    ``out`` (a folder) the result is also written to ``out/evaluation.json``. ``options`` (env reset
    options) override the task's in every trial (a changed object)."""
    from .evaluation import Variant
    from .evaluation import evaluate as run
    from .io import write_json
    from .lock import check_writable
    model = _model(model)
    task = _task_of(model, task)
    if version is not None:
        model.history.version(version)          # refuses a version the model does not have
    model.verify()
    target = None
    if out is not None:
        if Path(out).exists() and not Path(out).is_dir():
            raise InvalidInput("is a file; give a folder", file=str(out))
        target = _new_output(Path(out) / "evaluation.json", overwrite, "file")
        check_writable(target if Path(out).is_dir() else Path(out))      # the folder is made at the end
    specs = task.evaluation_specs(trials, seed, push_fraction)
    if options:
        extra = _reset_options(options, model, task)
        specs = [replace(s, options={**s.options, **extra}) for s in specs]
    variant = Variant(f"{model.apn.name} v{model.version if version is None else version}",
                      str(Path(model.path).resolve()), net_version=version, env_modules=model.env_modules)
    res = run(task.spec or task, variant, specs, workers=workers, progress=progress, ray=ray)
    if target is not None:
        write_json(target, {"model": str(model.path), "task": task.TASK, "seed": seed,
                            "push_fraction": push_fraction, "net_version": version,
                            **({"options": dict(options)} if options else {}), **res})
    return res


def mentor_rate(task: TaskLike, trials: int = 200, seed: int = 0, workers: int = 2,
                progress: Progress | None = None) -> dict[str, Any]:
    """The scripted mentor's own success rate from the starts of the evaluation trials
    :func:`evaluate` runs with the same ``trials`` and ``seed`` (their seeds and reset options; no
    experimenter's push), by the mentor's own verdict on each attempt, with its 95 % Wilson
    interval: the bar the robot's rate is read against."""
    from .teach.record import record_many
    from .stats import rate
    task = load_task(task)
    specs = task.evaluation_specs(trials, seed, 0.0)
    eps = record_many(task.spec or task, [s.seed for s in specs], task.DEMO_ENV_KWARGS, workers=workers,
                      progress=progress, starts="trial")
    ok = sum(ep.outcome == "success" for ep in eps)
    return {**rate(ok, len(eps)), "outcomes": [ep.outcome for ep in eps], "seeds": [s.seed for s in specs]}


def export_demos(demos: str | os.PathLike, out: str | os.PathLike, fps: float | None = None, task_text: str = "",
                 overwrite: bool = False) -> Path:
    """Write a demos file as a LeRobot v3 dataset folder ``out`` (see :mod:`multiform.demos.lerobot`),
    at the control rate or at ``fps`` frames per second (a whole divisor of it); ``task_text`` is
    LeRobot's task description (default: the skill's name). Returns the folder."""
    from .demos.dataset import read_dataset
    from .demos.lerobot import write_lerobot
    ds = read_dataset(demos)
    final = _new_output(out, overwrite, "folder", marker="meta/info.json")
    target = final.with_name(f".{final.name}.replacing") if final.exists() else final
    write_lerobot(target, ds.episodes, ds.skill, ds.env_name, ds.env_kwargs, task=task_text, fps=fps)
    if target != final:
        _swap_in(target, final)
    return final


def import_demos(dataset: str | os.PathLike, out: str | os.PathLike, variables: list[str] | None = None,
                 commands: list[str] | None = None, state_key: str = "observation.state", action_key: str = "action",
                 transition: str = "t0", skill: str | None = None, env: str | None = None,
                 overwrite: bool = False, mentor: str = "") -> Any:
    """Read a LeRobot v3 dataset folder and write it as a demos file ``out``; returns the
    :class:`~multiform.demos.dataset.Dataset` written. ``variables``/``commands`` name the entries of
    the state and action vectors (default: the features' own names). An episode's mentor is the
    one multiform's export recorded, else ``mentor`` (default: none)."""
    from .demos.episode import check_mentor_name
    if mentor:
        check_mentor_name(mentor, element="mentor (--mentor)")
    from .demos.dataset import read_dataset, write_dataset
    from .demos.lerobot import read_lerobot
    eps, meta = read_lerobot(dataset, variables, commands, state_key, action_key, transition)
    target = _new_output(out, overwrite, "file")
    env_args = meta.get("env_args", {}) if isinstance(meta.get("env_args"), dict) else {}
    write_dataset(target, eps, skill or str(meta.get("skill") or Path(dataset).name),
                  env or str(env_args.get("env_name") or ""), env_args.get("env_kwargs") or {}, mentor=mentor)
    return read_dataset(target)


# -- helpers ---------------------------------------------------------------------------------------

def _new_output(path: str | os.PathLike, overwrite: bool, kind: str, marker: str = "") -> Path:
    """``path`` as a new output: refused when it exists and ``overwrite`` is not set, or when it is
    a folder where a file is wanted (or the reverse). A folder is replaced only if it is empty or
    holds ``marker`` (what the command writes there: a folder of anything else is not its to delete)."""
    path = Path(path)
    if path.exists() or path.is_symlink():
        if not overwrite:
            raise InvalidInput("exists; pass --overwrite (overwrite=True) to replace it, or choose another name",
                               file=str(path))
        if (kind == "file") == path.is_dir():
            raise InvalidInput(f"exists and is a {'folder' if path.is_dir() else 'file'}; give a {kind} name",
                               file=str(path))
        if marker and path.is_dir() and any(path.iterdir()) and not (path / marker).is_file():
            raise InvalidInput(f"exists and has no {marker}: --overwrite replaces only a folder of what this "
                               "command writes; remove it yourself or choose another name", file=str(path))
    return path


def _swap_in(new: Path, final: Path) -> None:
    """Replace the folder ``final`` by the complete folder ``new`` (the old one removed after)."""
    old = final.with_name(f".{final.name}.old")
    shutil.rmtree(old, ignore_errors=True)
    os.rename(final, old)
    os.rename(new, final)
    shutil.rmtree(old, ignore_errors=True)


def _model(model: Any) -> Any:
    return open_model(model) if isinstance(model, (str, os.PathLike)) else model


def _task_of(model: Any, task: TaskLike | None) -> Task:
    """``task``, else the bundled or installed task whose env the model runs."""
    from .task import task_for_env
    return load_task(task) if task is not None else task_for_env(model.manifest["env"])


def _task_or_none(find: Callable[[str], Task], env_id: str) -> Task | None:
    try:
        return find(env_id)
    except InvalidInput:
        return None


def _reset_options(options: Mapping[str, Any], model: Any, task: Task) -> dict[str, Any]:
    """Reset options given by a caller, checked as plain bounded data and then by the model's env
    itself (one reset over the task's options of a trial), so that an option the env refuses is
    reported before a trial runs or anything is written."""
    from .io import plain_data_problems
    problems = plain_data_problems(dict(options), "options")
    if problems:
        where, msg = problems[0]
        raise InvalidInput(msg, element=where)
    env = model.make_env()
    try:
        env.reset(seed=0, options={**task.trial_options(0), **options})
    except (ValueError, TypeError, KeyError) as exc:
        raise InvalidInput(f"the env refuses them: {exc}", element="options") from None
    finally:
        env.close()
    return dict(options)


def _scenario(task: Task, name: str | None) -> tuple[int, Scenario]:
    """The task's scenario ``name`` (default: its first) and its place in the task's list (its seed offset)."""
    scenarios = task.scenarios()
    names = [s.name for s in scenarios]
    if name is None:
        return 0, scenarios[0]
    if name not in names:
        raise InvalidInput(f"unknown scenario {name!r}; {task.TASK} has: {', '.join(names)}", element="scenario")
    return names.index(name), scenarios[names.index(name)]
