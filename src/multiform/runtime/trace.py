"""The compact record of one trial: states, commands, marking, place clocks, firings, clips."""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..demos.episode import Episode
from ..errors import InvalidInput
from ..io import load_npz, save_npz
from ..petri.firing import Choice, Firing

TRACE_KIND = "trial_trace"
TRACE_VERSION = 1


@dataclass
class Trace:
    """What happened in one trial, one row per control tick (float32 where precision allows)."""

    seed: int
    dt: float
    obs: np.ndarray                 # (T, n_obs) float32, what the robot's sensors gave
    observation_names: tuple[str, ...]
    values: np.ndarray              # (T, n_vars) float32, the skill's declared + derived variables
    value_names: tuple[str, ...]
    commands: np.ndarray            # (T, n_cmd) float32, commands after the safety limits
    raw_commands: np.ndarray        # (T, n_cmd) float32, what the laws asked for
    command_names: tuple[str, ...]
    marking: np.ndarray             # (T, n_places) int16
    dwell: np.ndarray               # (T, n_places) float32, place clocks
    place_ids: tuple[str, ...]
    firings: list[Firing]
    outcome: str                    # success | failure | timeout | diverged | fault
    choices: list[Choice] = field(default_factory=list)
    net_version: int = 0
    options: dict[str, Any] = field(default_factory=dict)
    clips: dict[str, Any] = field(default_factory=dict)
    enabled_ticks: dict[str, int] = field(default_factory=dict)
    held_ticks: dict[str, int] = field(default_factory=dict)
    qpos: np.ndarray | None = None  # (F, nq) simulator poses for rendering only, every `qpos_every` ticks
    qpos_every: int = 0
    wall_time: float = 0.0
    final_info: dict[str, Any] = field(default_factory=dict)  # env info at the end, for the experimenter's
    # physical success check (never read by the robot; not saved)
    fault: str = ""                 # outcome "fault": where a non-finite value arose (never repair evidence)

    @property
    def num_ticks(self) -> int:
        return int(self.obs.shape[0])

    @property
    def duration(self) -> float:
        return self.num_ticks * self.dt

    @property
    def success(self) -> bool:
        return self.outcome == "success"

    @property
    def time(self) -> np.ndarray:
        return np.arange(self.num_ticks) * self.dt

    def tags(self) -> np.ndarray:
        """Per tick, the transition being executed: the last one fired so far ("" before any)."""
        tags = np.full(self.num_ticks, "", dtype=object)
        for f in self.firings:
            if f.tick < self.num_ticks:
                tags[f.tick:] = f.transition
        return tags.astype(str)

    def value(self, name: str) -> np.ndarray:
        if name in self.value_names:
            return self.values[:, self.value_names.index(name)]
        return self.obs[:, self.observation_names.index(name)]

    def stays(self, place: str) -> list[tuple[int, int]]:
        """The tick ranges [s, e) during which ``place`` held a token; a stay ended by a firing
        ends at that firing's tick (none if the net has no such place)."""
        if place not in self.place_ids:
            return []
        held = (self.marking[:, list(self.place_ids).index(place)] > 0).astype(np.int8)
        edges = np.diff(np.concatenate([[0], held, [0]]))
        return [(int(s), int(e)) for s, e in zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1))]

    def fired(self) -> list[str]:
        return [f.transition for f in self.firings]

    def to_episode(self) -> Episode:
        """The trial as an :class:`Episode` (obs + derived variables), so judges grade trials and
        demonstrations through the same code."""
        names = tuple(self.observation_names) + tuple(n for n in self.value_names if n not in self.observation_names)
        extra = [self.value_names.index(n) for n in self.value_names if n not in self.observation_names]
        obs = np.concatenate([self.obs, self.values[:, extra]], axis=1).astype(np.float64)
        return Episode(obs=obs, actions=self.commands.astype(np.float64), transitions=self.tags(),
                       observation_names=names, command_names=self.command_names, dt=self.dt, seed=self.seed,
                       reset_options=dict(self.options), outcome="success" if self.success else "failure")

    # -- persistence --------------------------------------------------------------------------------
    def save(self, path: str | os.PathLike) -> None:
        arrays = {"obs": self.obs, "values": self.values, "commands": self.commands,
                  "raw_commands": self.raw_commands, "marking": self.marking, "dwell": self.dwell,
                  "firing_ticks": np.array([f.tick for f in self.firings], dtype=np.int64),
                  "firing_transitions": np.array([f.transition for f in self.firings], dtype="U64")}
        if self.qpos is not None:
            arrays["qpos"] = self.qpos
        meta = {"seed": self.seed, "dt": self.dt, "observation_names": list(self.observation_names),
                "value_names": list(self.value_names), "command_names": list(self.command_names),
                "place_ids": list(self.place_ids), "outcome": self.outcome, "net_version": self.net_version,
                "options": self.options, "clips": self.clips, "enabled_ticks": self.enabled_ticks,
                "held_ticks": self.held_ticks,
                "choices": [[c.tick, c.chosen, list(c.candidates)] for c in self.choices], "qpos_every": self.qpos_every, "wall_time": self.wall_time,
                "fault": self.fault}
        save_npz(path, arrays, meta, TRACE_KIND, TRACE_VERSION)

    @classmethod
    def load(cls, path: str | os.PathLike) -> Trace:
        """Read a saved trace, checking that arrays and names agree."""
        arrays, meta = load_npz(path, TRACE_KIND, TRACE_VERSION, required={
            "obs": (None, None), "values": (None, None), "commands": (None, None), "raw_commands": (None, None),
            "marking": (None, None), "dwell": (None, None), "firing_ticks": (None,), "firing_transitions": (None,)})
        n = arrays["obs"].shape[0]
        checks = {"obs": ("observation_names", 1), "values": ("value_names", 1), "commands": ("command_names", 1),
                  "marking": ("place_ids", 1), "dwell": ("place_ids", 1)}
        for key, (names, axis) in checks.items():
            if arrays[key].shape[0] != n or arrays[key].shape[axis] != len(meta.get(names, [])):
                raise InvalidInput(f"array {key!r} has shape {arrays[key].shape}, which does not match "
                                   f"{n} ticks and {len(meta.get(names, []))} {names}", file=str(path))
        dt = float(meta["dt"])
        firings = [Firing(int(k), int(k) * dt, str(t))
                   for k, t in zip(arrays["firing_ticks"], arrays["firing_transitions"])]
        return cls(seed=int(meta["seed"]), dt=dt, obs=arrays["obs"], observation_names=tuple(meta["observation_names"]),
                   values=arrays["values"], value_names=tuple(meta["value_names"]), commands=arrays["commands"],
                   raw_commands=arrays["raw_commands"], command_names=tuple(meta["command_names"]),
                   marking=arrays["marking"], dwell=arrays["dwell"], place_ids=tuple(meta["place_ids"]),
                   firings=firings, outcome=str(meta["outcome"]),
                   choices=[Choice(int(a), str(b), tuple(c)) for a, b, c in meta.get("choices", [])],
                   net_version=int(meta.get("net_version", 0)),
                   options=meta.get("options", {}), clips=meta.get("clips", {}),
                   enabled_ticks=meta.get("enabled_ticks", {}), held_ticks=meta.get("held_ticks", {}),
                   qpos=arrays.get("qpos"), qpos_every=int(meta.get("qpos_every", 0)),
                   wall_time=float(meta.get("wall_time", 0.0)), fault=str(meta.get("fault", "")))
