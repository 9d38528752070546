"""Safety limits: saturate commands and torques before they reach the robot, and record every clip.

Limits come from the skill file's ``safety`` section (command bounds and rates — for a velocity
command the rate limit is an acceleration limit —, workspace limits on state variables, a
divergence threshold) and from the env (joint torque limits = the torque action space's bounds).
Clipping is per tick in plain Python floats: a handful of comparisons is cheaper than numpy calls
on one- to six-element arrays.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np


@dataclass
class ClipLog:
    """Counts and extremes of the clips of one trial, per limit."""

    counts: dict[str, int] = field(default_factory=dict)
    first_tick: dict[str, int] = field(default_factory=dict)
    worst: dict[str, float] = field(default_factory=dict)

    def add(self, limit: str, tick: int, excess: float) -> None:
        if limit not in self.counts:
            self.counts[limit] = 0
            self.first_tick[limit] = tick
            self.worst[limit] = 0.0
        self.counts[limit] += 1
        if excess > self.worst[limit]:
            self.worst[limit] = excess

    def to_json(self) -> dict[str, Any]:
        return {k: {"count": self.counts[k], "first_tick": self.first_tick[k], "worst_excess": self.worst[k]}
                for k in self.counts}


class Saturator:
    """Applies the limits of one skill to commands (and optionally torques), logging clips."""

    def __init__(self, safety: Mapping[str, Any], command_names: Sequence[str], state_slots: Mapping[str, int],
                 dt: float, torque_low: np.ndarray | None = None, torque_high: np.ndarray | None = None):
        self.dt = dt
        cmds = safety.get("commands", {})
        self._bounds = [(i, f"command {c} bounds", cmds[c].get("min", -np.inf), cmds[c].get("max", np.inf))
                        for i, c in enumerate(command_names) if c in cmds]
        self._rates = [(i, f"command {c} rate", cmds[c]["rate"] * dt)
                       for i, c in enumerate(command_names) if c in cmds and "rate" in cmds[c]]
        cidx = {c: i for i, c in enumerate(command_names)}
        self._workspace = [(state_slots[v], cidx[s["command"]], f"workspace {v}", s["min"], s["max"])
                           for v, s in safety.get("workspace", {}).items()]
        self.divergence = float(safety.get("divergence", 1e6))
        self._tlo = None if torque_low is None else np.asarray(torque_low, dtype=float)
        self._thi = None if torque_high is None else np.asarray(torque_high, dtype=float)
        self._tlo_list = [] if self._tlo is None else self._tlo.tolist()
        self._thi_list = [] if self._thi is None else self._thi.tolist()
        self.reset()

    def reset(self) -> None:
        self.log = ClipLog()
        self._last: list[float] | None = None

    def command(self, cmd: list[float], values: Sequence[float], tick: int) -> list[float]:
        """Clip ``cmd`` (a list, changed in place and returned): bounds, then workspace, then rate.

        The rate limit comes last so that even a workspace stop decelerates within the limit.
        """
        log = self.log
        for i, name, lo, hi in self._bounds:
            c = cmd[i]
            if c > hi:
                log.add(name, tick, c - hi)
                cmd[i] = hi
            elif c < lo:
                log.add(name, tick, lo - c)
                cmd[i] = lo
        for slot, i, name, lo, hi in self._workspace:
            x = values[slot]
            if (x >= hi and cmd[i] > 0) or (x <= lo and cmd[i] < 0):
                log.add(name, tick, abs(cmd[i]))
                cmd[i] = 0.0
        last = self._last
        if last is not None:
            for i, name, step in self._rates:
                d = cmd[i] - last[i]
                if d > step:
                    log.add(name, tick, (d - step) / self.dt)
                    cmd[i] = last[i] + step
                elif d < -step:
                    log.add(name, tick, (-step - d) / self.dt)
                    cmd[i] = last[i] - step
        self._last = list(cmd)
        return cmd

    def torque(self, tau: np.ndarray, tick: int) -> np.ndarray:
        """Clip joint torques to the actuator limits (in place)."""
        if self._tlo is None:
            return tau
        # plain floats: on six values numpy's .any()/.clip dispatch costs more than the comparisons
        excess = 0.0
        for t, lo, hi in zip(tau.tolist(), self._tlo_list, self._thi_list):
            if t > hi:
                excess = max(excess, t - hi)
            elif t < lo:
                excess = max(excess, lo - t)
        if excess > 0.0:
            self.log.add("joint torque", tick, excess)
            np.clip(tau, self._tlo, self._thi, out=tau)
        return tau

    def diverged(self, values: Sequence[float], n_state: int) -> bool:
        """True if a state variable is not finite or beyond the divergence threshold."""
        lim = self.divergence
        for k in range(n_state):
            v = values[k]
            if not (-lim < v < lim):          # also catches NaN
                return True
        return False
