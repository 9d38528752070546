"""Kinesthetic teaching: a person guides the compliant arm by hand, and the robot keeps only what it sensed.

A scripted mentor decides, as a person would, how the hand should move (its commands are the
hand's intended velocity). :class:`GuidingHand` is that person's arm: it pushes on the flange of
the arm in hand-guiding mode (an env's ``action_mode="kinesthetic"``, see
:mod:`multiform.envs.compliant`) with the force that makes the hand follow the intention — a
muscle's finite bandwidth and strength, the arm's inertia felt and only roughly compensated, and
the tremor of a human hand — so the motion is the person's, not a servo's.

The recorder (:func:`multiform.teach.record.record_episode`) stores the robot's own observations
and, as the demonstration's commands, what the env recovers from the arm's motion
(``env.command_from_motion``: the velocity commands its end-effector servo would need to reproduce
it). The forces are the action of the env's steps and are never stored.
"""

from __future__ import annotations

import inspect
import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from ..demos.episode import Episode, Mentor, SegmentLabel
from ..errors import InvalidInput

KINESTHETIC = "kinesthetic"


def kinesthetic_env_kwargs(env_kwargs: Mapping[str, Any]) -> dict[str, Any]:
    """The env arguments of a kinesthetic recording: ``env_kwargs`` with the arm in hand-guiding mode."""
    return {**dict(env_kwargs), "action_mode": KINESTHETIC}


def is_kinesthetic(env: Any) -> bool:
    """Whether ``env`` (or the env it wraps) runs in hand-guiding mode."""
    return getattr(getattr(env, "unwrapped", env), "action_mode", None) == KINESTHETIC


def guides(mentor: Any) -> bool:
    """Whether ``mentor`` already acts with forces on a guided arm (a :class:`GuidingHand`)."""
    return bool(getattr(mentor, "guides_arm", False))


class GuidingHand:
    """A person's hand guiding the arm: a mentor's intended hand velocity turned into a force.

    ``mentor`` is any :class:`~multiform.demos.episode.Mentor` whose commands are hand velocities
    (m/s, one per guided axis); ``velocity_index`` the observation entries of the hand's measured
    velocity along those axes (what the person feels the hand do). Per axis the force is
    ``mass (bandwidth (v_intended - v) + dv_intended/dt)`` plus tremor, limited to ``force_max``:
    ``mass`` [kg] the arm's inertia as the person feels it (the arm's own is 3-7 kg at the flange,
    direction-dependent), ``bandwidth`` [1/s] how quickly the person's arm corrects an error,
    ``tremor`` [N] the standard deviation of a hand's physiological tremor (8-12 Hz).
    ``muscle`` [s] is the time constant with which the intention becomes a force.
    """

    guides_arm = True

    def __init__(self, mentor: Any, velocity_index: Sequence[int], mass: float = 4.5, bandwidth: float = 20.0,
                 force_max: float = 150.0, tremor: float = 1.5, muscle: float = 0.02, dt: float = 0.001):
        self.mentor = mentor
        self.velocity_index = [int(i) for i in velocity_index]
        self.mass, self.bandwidth, self.force_max = float(mass), float(bandwidth), float(force_max)
        self.tremor, self.muscle, self.dt = float(tremor), float(muscle), float(dt)
        self.name = getattr(mentor, "name", "mentor")
        self._reset_state(np.random.default_rng(0))

    def _reset_state(self, rng: np.random.Generator) -> None:
        n = len(self.velocity_index)
        self.rng = rng
        self._intent = np.zeros(n)
        self._force = np.zeros(n)
        self._phase = rng.uniform(0.0, 2.0 * math.pi, n)
        self._freq = rng.uniform(8.0, 12.0, n)
        self._t = 0.0

    @property
    def outcome(self) -> str:
        return getattr(self.mentor, "outcome", "")

    def reset(self, obs: np.ndarray, rng: np.random.Generator, seed: int | None = None) -> None:
        params = inspect.signature(self.mentor.reset).parameters.values()
        if seed is not None and any(p.name == "seed" or p.kind is p.VAR_KEYWORD for p in params):
            self.mentor.reset(obs, rng, seed=seed)
        else:
            self.mentor.reset(obs, rng)
        self._reset_state(rng.spawn(1)[0])
        self._intent = np.asarray(obs, dtype=np.float64)[self.velocity_index].copy()

    def act(self, obs: np.ndarray, info: dict[str, Any], t: float) -> tuple[np.ndarray, str]:
        want, tag = self.mentor.act(obs, info, t)
        want = np.asarray(want, dtype=np.float64)
        v = np.asarray(obs, dtype=np.float64)[self.velocity_index]
        accel = (want - self._intent) / self.dt
        self._intent = want
        target = self.mass * (self.bandwidth * (want - v) + accel)
        a = self.dt / (self.muscle + self.dt)
        self._force += a * (target - self._force)
        self._t += self.dt
        shake = self.tremor * (math.sqrt(2.0) * np.sin(2.0 * math.pi * self._freq * self._t + self._phase))
        force = np.clip(self._force + shake, -self.force_max, self.force_max)
        return force, tag

    def finished(self) -> bool:
        return self.mentor.finished()

    def label(self, episode: Episode) -> list[SegmentLabel]:
        return self.mentor.label(episode)

    def __getattr__(self, name: str) -> Any:
        # the person's own judgement (e.g. ``grade_trial``) is the wrapped mentor's
        if name.startswith("_") or name == "mentor":
            raise AttributeError(name)
        return getattr(self.mentor, name)


def guided(mentor: Mentor, env: Any) -> Mentor:
    """``mentor`` as it acts on ``env``: on an arm in hand-guiding mode a mentor that commands hand
    velocities gets a person's hand (:class:`GuidingHand`) that pushes the arm along them;
    otherwise it is used as it is. An env that names no ``guided_velocity_names`` cannot be taught
    this way (:class:`~multiform.errors.InvalidInput`)."""
    if not is_kinesthetic(env) or guides(mentor):
        return mentor
    base = getattr(env, "unwrapped", env)
    names = getattr(base, "guided_velocity_names", None)
    if not names:
        raise InvalidInput(f"{type(base).__name__} names no guided hand velocities (guided_velocity_names); "
                           "it cannot be taught kinesthetically", element="kinesthetic")
    return GuidingHand(mentor, [list(base.observation_names).index(n) for n in names], dt=base.dt)



def check_kinesthetic(env_id: str, env_kwargs: Mapping[str, Any], task: str = "") -> None:
    """Refuse, before anything is recorded, an env that has no hand-guiding mode
    (:class:`~multiform.errors.InvalidInput` naming the task)."""
    import gymnasium as gym

    import multiform.envs  # noqa: F401  (registers the bundled envs)
    try:
        env = gym.make(env_id, **kinesthetic_env_kwargs(env_kwargs))
    except (TypeError, ValueError) as exc:
        raise InvalidInput(f"the env {env_id} has no hand-guiding mode (action_mode={KINESTHETIC!r}: {exc}); "
                           "teach it with commands instead", element=task or "kinesthetic") from None
    try:
        if not getattr(env.unwrapped, "guided_velocity_names", None):
            raise InvalidInput(f"the env {env_id} names no guided hand velocities (guided_velocity_names)",
                               element=task or "kinesthetic")
    finally:
        env.close()
