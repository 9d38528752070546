"""Run a mentor on an env and keep what happened as an :class:`~multiform.demos.episode.Episode`."""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np

from .episode import Episode, Mentor


def record_episode(env: gym.Env, mentor: Mentor, seed: int, options: dict[str, Any] | None = None,
                   max_steps: int | None = None) -> Episode:
    """Record one demonstration of ``mentor`` on ``env`` (an env in end-effector command mode).

    The env is reset with ``seed`` and ``options``; the mentor gets its own generator seeded from
    ``seed`` so a demo is reproducible from its seed alone. The demo ends when the mentor says so,
    the env terminates or truncates, or after ``max_steps``.
    """
    base = env.unwrapped
    obs, info = env.reset(seed=seed, options=options)
    mentor.reset(obs, np.random.default_rng([seed, 1]))
    dt = float(base.dt)
    obs_rows, act_rows, tags = [], [], []
    t = 0.0
    limit = max_steps if max_steps is not None else 10**9
    for _ in range(limit):
        cmd, tag = mentor.act(obs, info, t)
        cmd = np.asarray(cmd, dtype=np.float64)
        obs_rows.append(np.asarray(obs, dtype=np.float64))
        act_rows.append(cmd)
        tags.append(tag)
        obs, _, terminated, truncated, info = env.step(cmd)
        t += dt
        if terminated or truncated or mentor.finished():
            break
    episode = Episode(
        obs=np.asarray(obs_rows), actions=np.asarray(act_rows), transitions=np.asarray(tags, dtype=str),
        observation_names=tuple(base.observation_names), command_names=tuple(base.command_names),
        dt=dt, seed=seed, reset_options=dict(options or {}))
    episode.labels = list(mentor.label(episode))
    episode.outcome = "success" if episode.labels and all(l.success for l in episode.labels) else "failure"
    return episode


_WORKER: dict[str, Any] = {}


def _init(task: str, env_kwargs: dict[str, Any], mentor_kwargs: dict[str, Any]) -> None:
    from threadpoolctl import threadpool_limits

    from ..tasks import get_task
    threadpool_limits(1)
    t = get_task(task)
    _WORKER.update(task=t, env=gym.make(t.ENV_ID, **env_kwargs), mentor=t.make_mentor(**mentor_kwargs))


def _record(seed: int) -> Episode:
    w = _WORKER
    return record_episode(w["env"], w["mentor"], seed, w["task"].demo_options(seed))


def record_many(task: str, seeds: list[int], env_kwargs: dict[str, Any] | None = None,
                mentor_kwargs: dict[str, Any] | None = None, workers: int = 1,
                progress: Any = None) -> list[Episode]:
    """Record one demonstration per seed with the task's scripted mentor, on ``workers`` processes.

    ``progress`` is called with (done, total) after each demo. The result is in seed order and does
    not depend on the number of workers.
    """
    import multiprocessing as mp
    from concurrent.futures import ProcessPoolExecutor

    import multiform.envs  # noqa: F401  (registers the envs)
    env_kwargs, mentor_kwargs = dict(env_kwargs or {}), dict(mentor_kwargs or {})
    out: list[Episode] = []
    if workers <= 1:
        _init(task, env_kwargs, mentor_kwargs)
        for i, s in enumerate(seeds):
            out.append(_record(s))
            if progress:
                progress(i + 1, len(seeds))
        _WORKER["env"].close()
        return out
    with ProcessPoolExecutor(max_workers=workers, mp_context=mp.get_context("fork"), initializer=_init,
                             initargs=(task, env_kwargs, mentor_kwargs)) as pool:
        for i, ep in enumerate(pool.map(_record, seeds)):
            out.append(ep)
            if progress:
                progress(i + 1, len(seeds))
    return out
