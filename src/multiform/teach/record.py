"""Run a mentor on an env and keep what happened as an :class:`~multiform.demos.episode.Episode`."""

from __future__ import annotations

import functools
import inspect
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import gymnasium as gym
import numpy as np

from ..errors import InvalidInput
from ..parallel import WorkerState, mp_context, ray_backend, task_key
from ..runtime.contract import env_contract
from ..demos.episode import Episode, Mentor
from .kinesthetic import guided, is_kinesthetic, kinesthetic_env_kwargs


@dataclass
class PushDuring:
    """The experimenter's push during a demonstration: once, ``after`` s into the mentor's first
    run of samples tagged with one of ``tags`` (the transitions into the place the push is aimed at:
    a person pushes a pendulum the mentor has balanced for a moment), a torque pulse ``size`` [N m]
    for ``duration`` s through ``env.unwrapped.push``. ``pulses`` keeps what was applied (absolute
    times), so the episode's reset options can replay it."""

    tags: tuple[str, ...]
    after: float
    size: float
    duration: float

    def __post_init__(self) -> None:
        self.pulses: list[dict[str, float]] = []
        self._since: int | None = None

    def __call__(self, tick: int, tag: str, env: gym.Env) -> None:
        if self.pulses:
            return
        if tag not in self.tags:
            self._since = None if self._since is None else -1      # the first such segment only
            return
        if self._since is None:
            self._since = tick
        if self._since >= 0 and (tick - self._since) * env.unwrapped.dt >= self.after:
            t = float(env.unwrapped.data.time)
            env.unwrapped.push(self.size, self.duration)
            self.pulses.append({"time": t, "duration": self.duration, "torque": self.size})


def record_episode(env: gym.Env, mentor: Mentor, seed: int, options: dict[str, Any] | None = None,
                   max_steps: int | None = None, push: PushDuring | None = None) -> Episode:
    """Record one demonstration of ``mentor`` on ``env``.

    In end-effector command mode the episode's commands are the mentor's. With the env's arm in
    hand-guiding mode (``action_mode="kinesthetic"``, :mod:`multiform.teach.kinesthetic`) the
    mentor's actions are its hand's forces on the arm: they drive the env and are never kept, and the
    episode's commands are those the env recovers from the arm's recorded motion
    (``env.command_from_motion``). The env is reset with ``seed`` and ``options``; the mentor gets its own generator seeded from
    ``seed`` so a demo is reproducible from its seed alone. The demo ends when the mentor says so,
    the env terminates or truncates, or after ``max_steps``. With ``push`` the experimenter pushes
    during the demo; the episode's reset options then hold the pulses applied (``disturbances``,
    empty if the push never came), so replaying them from the seed reproduces the demo.
    """
    obs_names, cmd_names, dt = env_contract(env)
    obs, info = env.reset(seed=seed, options=options)
    _reset(mentor, obs, np.random.default_rng([seed, 1]), seed)
    hand_guided = is_kinesthetic(env)              # the actions are a person's forces: never kept
    obs_rows, act_rows, tags = [], [], []
    t = 0.0
    limit = max_steps if max_steps is not None else 10**9
    for _ in range(limit):
        cmd, tag = mentor.act(obs, info, t)
        cmd = np.asarray(cmd, dtype=np.float64)
        obs_rows.append(np.asarray(obs, dtype=np.float64))
        if not hand_guided:
            act_rows.append(cmd)
        tags.append(tag)
        if push is not None:
            push(len(tags) - 1, tag, env)
        obs, _, terminated, truncated, info = env.step(cmd)
        t += dt
        if terminated or truncated or mentor.finished():
            break
    options = dict(options or {})
    if push is not None:
        options["disturbances"] = list(options.get("disturbances") or []) + push.pulses
    obs_rows = np.asarray(obs_rows)
    if hand_guided:
        commands = np.asarray(env.unwrapped.command_from_motion(obs_rows), dtype=np.float64).reshape(len(obs_rows), -1)
    else:
        commands = np.asarray(act_rows)
    episode = Episode(
        obs=obs_rows, actions=commands, transitions=np.asarray(tags, dtype=str),
        observation_names=obs_names, command_names=cmd_names,
        dt=dt, seed=seed, reset_options=options, mentor=str(getattr(mentor, "name", "") or ""))
    episode.labels = list(mentor.label(episode))
    # the mentor's verdict on the whole attempt where it gives one (a pushed demo that the mentor
    # recovered and balanced is a success with one failed segment); else: every segment succeeded
    verdict = getattr(mentor, "outcome", "")
    if verdict not in ("success", "failure"):
        verdict = "success" if episode.labels and all(l.success for l in episode.labels) else "failure"
    episode.outcome = verdict
    return episode


def _reset(mentor: Mentor, obs: np.ndarray, rng: np.random.Generator, seed: int) -> None:
    """``mentor.reset``, told the demonstration's seed when it takes a ``seed`` argument."""
    params = inspect.signature(mentor.reset).parameters.values()
    if any(p.name == "seed" or p.kind is p.VAR_KEYWORD for p in params):
        mentor.reset(obs, rng, seed=seed)
    else:
        mentor.reset(obs, rng)

def _setup(task: Any, env_kwargs: dict[str, Any], mentor_kwargs: dict[str, Any]) -> dict[str, Any]:
    import multiform.envs  # noqa: F401  (registers the envs; a spawned worker has not imported them)

    from ..task import load_task
    t = load_task(task) if isinstance(task, str) else task
    env = gym.make(t.ENV_ID, **env_kwargs)
    return {"task": t, "env": env, "mentor": guided(t.make_mentor(**mentor_kwargs), env)}


_WORKER = WorkerState(_setup, lambda state: state["env"].close())


def _key(task: Any, env_kwargs: dict[str, Any], mentor_kwargs: dict[str, Any]) -> tuple[str, str, str]:
    return task_key(task), repr(env_kwargs), repr(mentor_kwargs)


def _pool_init(task: Any, env_kwargs: dict[str, Any], mentor_kwargs: dict[str, Any]) -> None:
    _WORKER.start(_key(task, env_kwargs, mentor_kwargs), task, env_kwargs, mentor_kwargs)


def demonstration_in_worker(task: str, env_kwargs: dict[str, Any], mentor_kwargs: dict[str, Any],
                            seed: int, starts: str = "demo") -> Episode:
    """One scripted-mentor demonstration in a worker that may record many (a Ray worker)."""
    _WORKER.ensure(_key(task, env_kwargs, mentor_kwargs), task, env_kwargs, mentor_kwargs)
    return _record(seed, starts)


def demo_push(task: Any, seed: int) -> PushDuring | None:
    """The experimenter's push in demonstration ``seed`` of ``task`` (its ``demo_push``), if any."""
    plan = getattr(task, "demo_push", None)
    spec = plan(seed) if plan is not None else None
    return PushDuring(**spec) if spec else None


def _record(seed: int, starts: str = "demo") -> Episode:
    w = _WORKER.state
    if starts == "trial":          # the evaluation trials' starts, no experimenter's push
        return record_episode(w["env"], w["mentor"], seed, w["task"].trial_options(seed))
    return record_episode(w["env"], w["mentor"], seed, w["task"].demo_options(seed), push=demo_push(w["task"], seed))


def record_many(task: Any, seeds: list[int], env_kwargs: dict[str, Any] | None = None,
                mentor_kwargs: dict[str, Any] | None = None, workers: int = 1,
                progress: Any = None, start_method: str | None = None, ray: str | None = None,
                starts: str = "demo", kinesthetic: bool = False) -> list[Episode]:
    """Record one demonstration per seed with the task's scripted mentor, on ``workers`` processes
    (``start_method``: see :func:`multiform.parallel.mp_context`), or as Ray tasks with ``ray``
    (``auto``, ``local`` or a cluster address). ``task`` is a :class:`~multiform.task.Task` or what
    :func:`~multiform.task.load_task` reads (spawned and Ray workers need the latter).

    ``progress`` is called with (done, total) after each demo. The result is in seed order and does
    not depend on the number of workers nor on where they run. ``starts="trial"`` starts each from
    the task's ``trial_options(seed)`` instead of its ``demo_options(seed)``, without the
    experimenter's push (the mentor on the robot's evaluation starts). ``kinesthetic``: the mentor
    guides the arm in hand-guiding mode (:mod:`.kinesthetic`); the episodes' commands are recovered
    from the arm's motion, for the env ``env_kwargs`` make.
    """
    if starts not in ("demo", "trial"):
        raise InvalidInput(f"starts must be 'demo' or 'trial', got {starts!r}", element="starts")
    from concurrent.futures import ProcessPoolExecutor

    import multiform.envs  # noqa: F401  (registers the envs)

    env_kwargs, mentor_kwargs = dict(env_kwargs or {}), dict(mentor_kwargs or {})
    if kinesthetic:
        env_kwargs = kinesthetic_env_kwargs(env_kwargs)
    if ray:
        return ray_backend().record_demos(functools.partial(demonstration_in_worker, starts=starts), task, seeds,
                                          env_kwargs, mentor_kwargs, ray, num_cpus=max(1, workers), progress=progress)
    out: list[Episode] = []
    if workers <= 1:
        for i, s in enumerate(seeds):
            out.append(demonstration_in_worker(task, env_kwargs, mentor_kwargs, s, starts))
            if progress:
                progress(i + 1, len(seeds))
        _WORKER.clear()
        return out
    with ProcessPoolExecutor(max_workers=workers, mp_context=mp_context(start_method), initializer=_pool_init,
                             initargs=(task, env_kwargs, mentor_kwargs)) as pool:
        for i, ep in enumerate(pool.map(functools.partial(_record, starts=starts), seeds)):
            out.append(ep)
            if progress:
                progress(i + 1, len(seeds))
    return out



def record_by_mentors(task: Any, seeds: list[int], plan: Sequence[tuple[str | None, int]],
                      env_kwargs: dict[str, Any] | None = None, workers: int = 1, progress: Any = None,
                      start_method: str | None = None, ray: str | None = None,
                      kinesthetic: bool = False) -> list[Episode]:
    """Demonstrations by several of the task's scripted mentors: ``plan`` lists (mentor name, count)
    in order (None: the task's default mentor), the counts adding up to ``len(seeds)``; the first
    ``count`` seeds go to the first mentor, and so on (:func:`record_many` records each block)."""
    from ..task import load_task
    if sum(n for _, n in plan) != len(seeds) or any(n < 0 for _, n in plan):
        raise InvalidInput(f"the mentors' counts {[n for _, n in plan]} do not add up to {len(seeds)} demonstrations",
                           element="mentors")
    t = load_task(task)
    out: list[Episode] = []
    for name, n in plan:
        block = seeds[len(out):len(out) + n]
        if not block:
            continue
        done = len(out)
        out += record_many(task, block, env_kwargs, mentor_kwargs=t.mentor_kwargs(name), workers=workers,
                           progress=(lambda i, k, done=done: progress(done + i, len(seeds))) if progress else None,
                           start_method=start_method, ray=ray, kinesthetic=kinesthetic)
    return out
