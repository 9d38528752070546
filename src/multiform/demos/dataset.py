"""The demonstration dataset: HDF5 through h5py in the robomimic layout, written atomically.

Layout (format version 1)::

    /data                      attrs: format_version, skill, env_args (JSON: env_name, env_kwargs),
                                      observation_names (JSON), command_names (JSON), dt, total
    /data/demo_0               attrs: num_samples, seed, reset_options (JSON), outcome, mentor
        obs/<name>             (T,) float64, one dataset per observation entry
        actions                (T, n_cmd) float64, the mentor's end-effector command
        dones                  (T,) uint8, 1 on the last sample
        transition             (T,) bytes, the transition the mentor was executing
        labels                 (k,) compound: start, end, transition, success, labeller
    /mask/success, /mask/failure   demo names (bytes), robomimic's filter keys

Reading validates the version, every demo's fields, their shapes, dtypes and finite values, and
names the demo and field at fault.
"""

from __future__ import annotations

import json
import os
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from ..errors import InvalidInput, Problem
from ..io import atomic_path
from .episode import Episode, SegmentLabel

FORMAT_VERSION = 1
LABEL_DTYPE = np.dtype([("start", "<i8"), ("end", "<i8"), ("transition", "S64"), ("success", "u1"),
                        ("labeller", "S64")])


def write_dataset(path: str | os.PathLike, episodes: Sequence[Episode], skill: str, env_name: str,
                  env_kwargs: dict[str, Any] | None = None, mentor: str = "") -> Path:
    """Write ``episodes`` to ``path`` (temporary file + rename: readers never see half a file)."""
    if not episodes:
        raise InvalidInput("no episodes to write", file=str(path))
    first = episodes[0]
    for i, ep in enumerate(episodes):
        if ep.observation_names != first.observation_names or ep.command_names != first.command_names:
            raise InvalidInput("episodes disagree on observation or command names", file=str(path),
                               element=f"demo_{i}")
    path = Path(path)
    with atomic_path(path, suffix=".h5") as tmp:
        with h5py.File(tmp, "w") as f:
            data = f.create_group("data")
            data.attrs["format_version"] = FORMAT_VERSION
            data.attrs["skill"] = skill
            data.attrs["env_args"] = json.dumps({"env_name": env_name, "env_kwargs": env_kwargs or {}})
            data.attrs["observation_names"] = json.dumps(list(first.observation_names))
            data.attrs["command_names"] = json.dumps(list(first.command_names))
            data.attrs["dt"] = float(first.dt)
            data.attrs["total"] = int(sum(ep.num_samples for ep in episodes))
            names = {"success": [], "failure": []}
            for i, ep in enumerate(episodes):
                name = f"demo_{i}"
                g = data.create_group(name)
                g.attrs["num_samples"] = ep.num_samples
                g.attrs["seed"] = int(ep.seed)
                g.attrs["reset_options"] = json.dumps(ep.reset_options, default=_jsonable)
                g.attrs["outcome"] = ep.outcome
                g.attrs["mentor"] = mentor
                obs = g.create_group("obs")
                for k, key in enumerate(ep.observation_names):
                    obs.create_dataset(key, data=np.ascontiguousarray(ep.obs[:, k], dtype=np.float64))
                g.create_dataset("actions", data=np.asarray(ep.actions, dtype=np.float64))
                dones = np.zeros(ep.num_samples, dtype=np.uint8)
                if ep.num_samples:
                    dones[-1] = 1
                g.create_dataset("dones", data=dones)
                g.create_dataset("transition", data=np.asarray(ep.transitions).astype("S64"))
                g.create_dataset("labels", data=labels_array(ep.labels))
                names["success" if ep.outcome == "success" else "failure"].append(name)
            mask = f.create_group("mask")
            for key, vals in names.items():
                mask.create_dataset(key, data=np.asarray(vals, dtype="S32"))
    return path


def labels_array(labels: Iterable[SegmentLabel]) -> np.ndarray:
    labels = list(labels)
    arr = np.zeros(len(labels), dtype=LABEL_DTYPE)
    for i, lab in enumerate(labels):
        arr[i] = (lab.start, lab.end, lab.transition.encode(), int(lab.success), lab.labeller.encode())
    return arr


def _jsonable(obj: Any) -> Any:
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    raise TypeError(f"{type(obj).__name__} is not JSON serialisable")


class Dataset:
    """A validated demonstration file, read fully into :class:`Episode` objects."""

    def __init__(self, path: str | os.PathLike):
        self.path = Path(path)
        self.episodes, self.meta = _read(self.path)

    @property
    def skill(self) -> str:
        return self.meta["skill"]

    @property
    def env_name(self) -> str:
        return self.meta["env_args"]["env_name"]

    @property
    def env_kwargs(self) -> dict[str, Any]:
        return dict(self.meta["env_args"].get("env_kwargs", {}))

    def __len__(self) -> int:
        return len(self.episodes)

    def __iter__(self):
        return iter(self.episodes)

    def summary(self) -> dict[str, Any]:
        """Counts, durations, success fraction and samples per transition."""
        eps = self.episodes
        durations = np.array([ep.duration for ep in eps])
        per_transition: dict[str, int] = {}
        for ep in eps:
            tags, counts = np.unique(ep.transitions, return_counts=True)
            for t, c in zip(tags, counts):
                per_transition[str(t)] = per_transition.get(str(t), 0) + int(c)
        labels = [lab for ep in eps for lab in ep.labels]
        return {
            "file": str(self.path), "skill": self.skill, "env": self.env_name, "demos": len(eps),
            "success": sum(ep.outcome == "success" for ep in eps),
            "success_fraction": float(np.mean([ep.outcome == "success" for ep in eps])) if eps else 0.0,
            "duration_s": {"total": float(durations.sum()), "mean": float(durations.mean()),
                           "min": float(durations.min()), "max": float(durations.max())},
            "samples": int(sum(ep.num_samples for ep in eps)),
            "samples_per_transition": dict(sorted(per_transition.items())),
            "segments": len(labels), "segments_success": sum(lab.success for lab in labels),
        }


def _read(path: Path) -> tuple[list[Episode], dict[str, Any]]:
    file = str(path)
    if not path.exists():
        raise InvalidInput("file not found", file=file)
    try:
        f = h5py.File(path, "r")
    except OSError as exc:
        raise InvalidInput(f"not a readable HDF5 file ({exc})", file=file) from None
    with f:
        if "data" not in f:
            raise InvalidInput("no 'data' group; not a demonstration file", file=file)
        data = f["data"]
        version = data.attrs.get("format_version")
        if version is None:
            raise InvalidInput("missing attribute 'format_version'", file=file, element="data")
        if int(version) != FORMAT_VERSION:
            raise InvalidInput(f"format version {int(version)}, this multiform reads version {FORMAT_VERSION}",
                               file=file, element="data")
        meta: dict[str, Any] = {}
        for key in ("skill", "env_args", "observation_names", "command_names", "dt"):
            if key not in data.attrs:
                raise InvalidInput(f"missing attribute {key!r}", file=file, element="data")
        try:
            meta["skill"] = _str(data.attrs["skill"])
            meta["env_args"] = json.loads(_str(data.attrs["env_args"]))
            obs_names = tuple(json.loads(_str(data.attrs["observation_names"])))
            cmd_names = tuple(json.loads(_str(data.attrs["command_names"])))
        except (json.JSONDecodeError, TypeError) as exc:
            raise InvalidInput(f"attributes are not valid JSON ({exc})", file=file, element="data") from None
        dt = float(data.attrs["dt"])
        if not np.isfinite(dt) or dt <= 0:
            raise InvalidInput(f"dt must be a positive number, got {dt}", file=file, element="data")
        meta.update(observation_names=obs_names, command_names=cmd_names, dt=dt)
        names = sorted((k for k in data if k.startswith("demo_")), key=lambda k: int(k.split("_")[1]))
        episodes = []
        problems: list[Problem] = []
        for name in names:
            try:
                episodes.append(_read_demo(data[name], name, obs_names, cmd_names, dt, file))
            except InvalidInput as exc:
                problems.extend(exc.problems)
            except (OSError, KeyError, ValueError, TypeError) as exc:   # truncated chunks and the like
                problems.append(Problem(file, f"data/{name}", f"unreadable ({type(exc).__name__}: {exc})"))
        if problems:
            raise InvalidInput(problems)
        return episodes, meta


def _str(v: Any) -> str:
    return v.decode() if isinstance(v, bytes) else str(v)


def _read_demo(g: h5py.Group, name: str, obs_names: tuple[str, ...], cmd_names: tuple[str, ...], dt: float,
               file: str) -> Episode:
    def bad(field: str, msg: str) -> InvalidInput:
        return InvalidInput(msg, file=file, element=f"data/{name}/{field}")

    if "num_samples" not in g.attrs:
        raise bad("num_samples", "missing attribute")
    n = int(g.attrs["num_samples"])
    if "obs" not in g:
        raise bad("obs", "missing group")
    cols = []
    for key in obs_names:
        if key not in g["obs"]:
            raise bad(f"obs/{key}", "missing dataset")
        ds = g["obs"][key]
        if ds.shape != (n,):
            raise bad(f"obs/{key}", f"shape {ds.shape}, expected ({n},) from num_samples")
        if ds.dtype.kind != "f":
            raise bad(f"obs/{key}", f"dtype {ds.dtype}, expected a float type")
        col = ds[()]
        if not np.all(np.isfinite(col)):
            k = int(np.flatnonzero(~np.isfinite(col))[0])
            raise bad(f"obs/{key}", f"non-finite value at sample {k}")
        cols.append(col)
    obs = np.stack(cols, axis=1) if cols else np.zeros((n, 0))
    for field in ("actions", "dones", "transition", "labels"):
        if field not in g:
            raise bad(field, "missing dataset")
    actions = g["actions"][()]
    if actions.shape != (n, len(cmd_names)):
        raise bad("actions", f"shape {actions.shape}, expected ({n}, {len(cmd_names)})")
    if actions.dtype.kind != "f" or not np.all(np.isfinite(actions)):
        raise bad("actions", "must hold finite floats")
    tags = g["transition"][()]
    if tags.shape != (n,) or tags.dtype.kind != "S":
        raise bad("transition", f"shape {tags.shape} dtype {tags.dtype}, expected ({n},) bytes")
    labels_raw = g["labels"][()]
    if labels_raw.dtype.names is None or not set(LABEL_DTYPE.names) <= set(labels_raw.dtype.names):
        raise bad("labels", f"expected fields {', '.join(LABEL_DTYPE.names)}")
    labels = []
    for k, row in enumerate(labels_raw):
        start, end = int(row["start"]), int(row["end"])
        if not 0 <= start < end <= n:
            raise bad("labels", f"label {k}: segment [{start}, {end}) outside the demo's {n} samples")
        labels.append(SegmentLabel(start, end, row["transition"].decode(), bool(row["success"]),
                                   row["labeller"].decode()))
    try:
        reset_options = json.loads(_str(g.attrs.get("reset_options", "{}")))
    except json.JSONDecodeError as exc:
        raise bad("reset_options", f"not valid JSON ({exc})") from None
    return Episode(obs=obs, actions=actions.astype(np.float64), transitions=tags.astype(str),
                   observation_names=obs_names, command_names=cmd_names, dt=dt,
                   seed=int(g.attrs.get("seed", 0)), reset_options=reset_options, labels=labels,
                   outcome=_str(g.attrs.get("outcome", "")))


def read_dataset(path: str | os.PathLike) -> Dataset:
    """Open and validate a demonstration file."""
    return Dataset(path)
