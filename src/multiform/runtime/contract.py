"""The env contract: what the method needs of any Gymnasium env, and an adapter that meets it.

A skill names its state variables and commands; the env must name the entries of its observation
(``observation_names``) and of the command the skill's laws output (``command_names``), and say how
long one step is (``dt``, seconds). They are read through the wrapper chain
(``env.get_wrapper_attr``), so a wrapper may supply them; :class:`NamedEnv` names any env's entries.

Two action modes, chosen by the env's action space:

* **direct command** — the env's action *is* the skill's command vector (``len(command_names)``
  entries): the law's output is stepped as it is, after the skill's safety limits;
* **inverse model** — the env takes joint torques; a learned inverse model
  (:class:`multiform.learn.inverse.InverseDynamicsModel`) turns the end-effector command into them.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import gymnasium as gym

from ..errors import InvalidInput


def _attr(env: gym.Env, name: str) -> Any:
    try:
        return env.get_wrapper_attr(name)
    except AttributeError:
        return None


def env_contract(env: gym.Env) -> tuple[tuple[str, ...], tuple[str, ...], float]:
    """``(observation_names, command_names, dt)`` of ``env``, read through its wrappers; a clear
    error when it lacks one (wrap it in :class:`NamedEnv`)."""
    obs, cmd, dt = (_attr(env, n) for n in ("observation_names", "command_names", "dt"))
    what = getattr(env.spec, "id", None) or type(env.unwrapped).__name__
    for value, name in ((obs, "observation_names"), (cmd, "command_names"), (dt, "dt")):
        if value is None:
            raise InvalidInput(f"the env {what} has no {name}; wrap it in multiform.NamedEnv to name its "
                               "observation and command entries and its time step", element="env")
    if not (isinstance(dt, (int, float)) and math.isfinite(dt) and dt > 0):
        raise InvalidInput(f"the env {what} has dt = {dt!r}; it must be a time step in seconds above 0", element="env")
    return tuple(obs), tuple(cmd), float(dt)


def check_control_rate(control_rate: float, dt: float, what: str = "the env") -> None:
    """The skill's ``control_rate`` must be the env's step rate: one net tick per env step (a
    mismatch would run every law and every dwell time at the wrong speed)."""
    if abs(control_rate * dt - 1.0) > 1e-6:
        raise InvalidInput(f"the skill ticks at {control_rate:g} Hz but {what} steps every {dt:g} s "
                           f"({1.0 / dt:g} Hz); set control_rate: {1.0 / dt:g} in the skill file",
                           element="control_rate")


class NamedEnv(gym.Wrapper):
    """Any Gymnasium env with names for its observation and action entries and its time step.

    ``observation_names`` name the entries of the (flat, Box) observation; ``command_names`` those
    of the action (direct-command mode: the skill's laws output the action itself); ``dt`` the
    seconds one step simulates (default: the env's own ``dt``, as Gymnasium's MuJoCo envs have).
    The executor ends a trial the env terminates as a failure (bundled envs terminate when the
    state diverges); ``terminal=False`` keeps an env's own termination from ending it — for an env
    that terminates at its goal, so the skill's net decides when it is done.
    """

    def __init__(self, env: gym.Env, observation_names: Sequence[str], command_names: Sequence[str],
                 dt: float | None = None, terminal: bool = True):
        super().__init__(env)
        self.terminal = terminal
        what = getattr(env.spec, "id", None) or type(env.unwrapped).__name__
        for space, names, kind in ((env.observation_space, observation_names, "observation"),
                                   (env.action_space, command_names, "action")):
            if not isinstance(space, gym.spaces.Box) or len(space.shape) != 1:
                raise InvalidInput(f"the env {what} has a {kind} space {space}; NamedEnv needs a flat Box",
                                   element=f"{kind}_names")
            if len(names) != space.shape[0] or len(set(names)) != len(names):
                raise InvalidInput(f"{len(names)} name(s) {list(names)} for the {space.shape[0]} entries of "
                                   f"{what}'s {kind} (one distinct name each)", element=f"{kind}_names")
        self.observation_names = tuple(observation_names)
        self.command_names = tuple(command_names)
        base_dt = getattr(env.unwrapped, "dt", None) if dt is None else dt
        if base_dt is None:
            raise InvalidInput(f"the env {what} has no dt; give NamedEnv the seconds one step simulates",
                               element="dt")
        self.dt = float(base_dt)

    def step(self, action: Any) -> tuple[Any, Any, bool, bool, dict[str, Any]]:
        obs, reward, terminated, truncated, info = self.env.step(action)
        return obs, reward, bool(terminated and self.terminal), truncated, info
