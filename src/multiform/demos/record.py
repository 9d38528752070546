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
