"""The demonstration dataset: HDF5 through h5py in robomimic's layout, written atomically.

Layout (format version 3; robomimic's ``SequenceDataset`` and ``get_dataset_info.py`` read it)::

    /data                      attrs: format_version, skill, env_args (JSON: env_name, type, env_kwargs),
                                      observation_names (JSON), command_names (JSON), dt, total,
                                      transition_names (JSON: the tag codes' names),
                                      action_low, action_high (n_cmd,) when the actions are normalised,
                                      teaching (optional): "kinesthetic" when the mentor guided the arm by
                                      hand and the commands were recovered from the arm's motion
    /data/demo_0               attrs: num_samples, seed, reset_options (JSON), outcome, mentor (who
                                      demonstrated it; "" if unknown)
        obs/<name>             (T, 1) float32 (float64 if so written), one dataset per observation entry
                               (identical entries are one dataset under two names)
        next_obs/<name>        (T, 1) the observation after each sample (the last one repeated): a
                               virtual dataset over obs/<name>, so it takes no space
        actions                (T, n_cmd) float64: what the env that env_args describes takes
        commands               (T, n_cmd) float64, with action_low/high only: the mentor's commands in
                               the env's own units, exactly (actions = clip(2 (commands - action_low) /
                               (action_high - action_low) - 1, -1, 1))
        rewards                (T,) float64, 1 on the last sample of a successful demo, else 0
        dones                  (T,) uint8, 1 on the last sample
        transition             (T,) uint8/uint16 codes into transition_names: the transition the
                               mentor was executing
        labels                 (k,) compound: start, end, transition, success, labeller
    /mask/success, /mask/failure   demo names (bytes), by the demo's outcome
    /mask/train, /mask/valid       a seeded split (10 % valid, as robomimic's split_train_val.py)
    /mask/mentor_<name>            demo names, one filter key per mentor (robomimic's multi-human
                                   datasets keep one per operator); characters other than letters,
                                   digits, ``_ . -`` in the name become ``_``

Actions mean what they say, as robomimic's datasets do: in [-1, 1], for an env that takes them.
When the env (registered with Gymnasium where the file is written) offers ``normalize_actions``, as
the bundled ones do, ``env_args.env_kwargs`` has ``normalize_actions: true``, which maps [-1, 1]
linearly onto the env's own action limits (``action_low``..``action_high``, e.g. ±1.5 m/s), and ``commands`` keeps
the exact commands that multiform trains on. Otherwise ``actions`` are the env's raw commands and
``env_args`` the env as recorded. :attr:`Dataset.env_kwargs` is always the env that takes the
commands (without ``normalize_actions``).

``env_args.type`` is 2, robomimic's ``EnvType.GYM_TYPE``: the env is a Gymnasium env made by
``gymnasium.make(env_name, **env_kwargs)``. There are no simulator ``states``: a demo is replayed
from its seed and reset options. Version 2 files (actions divided by a power of two,
``action_scale``) and version 1 files (uncompressed, tags as strings) are still read.

Reading validates the version, every demo's fields, their shapes, dtypes and finite values, and
names the demo and field at fault.
"""

from __future__ import annotations

import json
import os
import re
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from ..errors import InvalidInput, MissingInput, Problem
from ..io import (MAX_MAGNITUDE, check_regular_file, json_default, loads_json, memory_file,
                  plain_data_problems)
from .episode import Episode, SegmentLabel, mentors_of

FORMAT_VERSION = 3
READABLE_VERSIONS = (1, 2, 3)
VALID_FRACTION = 0.1             # robomimic's split_train_val.py default
ENV_TYPE_GYM = 2                 # robomimic's EnvType.GYM_TYPE
COMPRESSION = {"compression": "gzip", "compression_opts": 4, "shuffle": True}
CHUNK = 16384                    # samples per chunk
LABEL_DTYPE = np.dtype([("start", "<i8"), ("end", "<i8"), ("transition", "S64"), ("success", "u1"),
                        ("labeller", "S64")])


def write_dataset(path: str | os.PathLike, episodes: Sequence[Episode], skill: str, env_name: str,
                  env_kwargs: dict[str, Any] | None = None, mentor: str = "",
                  obs_dtype: str = "float32", split_seed: int = 0, teaching: str = "") -> Path:
    """Write ``episodes`` to ``path`` (temporary file + rename: readers never see half a file).

    Observations are stored as float32 by default, as robomimic's and LeRobot's low-dimensional
    observations are (rounding error at most 6e-8 of the value, far below what the laws can resolve;
    the file is about half the size: float64 physics data barely compresses); ``obs_dtype="float64"``
    keeps them exact. Commands are always exact. ``split_seed`` draws the ``mask/train`` /
    ``mask/valid`` split. The actions are normalised when the env offers it (module docstring).
    Each demo's mentor is its episode's ``mentor``, else ``mentor``; every mentor gets a filter key.
    ``teaching`` (``"kinesthetic"``) says the mentor guided the arm: the commands are those recovered
    from its motion, for the env ``env_kwargs`` make."""
    if obs_dtype not in ("float64", "float32"):
        raise InvalidInput(f"obs_dtype must be float64 or float32, got {obs_dtype!r}", file=str(path))
    if not episodes:
        raise InvalidInput("no episodes to write", file=str(path))
    first = episodes[0]
    for i, ep in enumerate(episodes):
        if ep.observation_names != first.observation_names or ep.command_names != first.command_names:
            raise InvalidInput("episodes disagree on observation or command names", file=str(path),
                               element=f"demo_{i}")
    tag_names = sorted({str(t) for ep in episodes for t in np.unique(ep.transitions)})
    code = {t: k for k, t in enumerate(tag_names)}
    code_dtype = np.uint8 if len(tag_names) <= 256 else np.uint16
    env_kwargs = dict(env_kwargs or {})
    unit = env_action_limits(env_name, env_kwargs, len(first.command_names))
    file_env_kwargs = {**env_kwargs, "normalize_actions": True} if unit is not None else env_kwargs
    path = Path(path)
    with memory_file(path) as buffer:       # h5py writes to memory: a full disk fails one plain write
        with h5py.File(buffer, "w") as f:
            data = f.create_group("data")
            data.attrs["format_version"] = FORMAT_VERSION
            data.attrs["skill"] = skill
            data.attrs["env_args"] = json.dumps({"env_name": env_name, "type": ENV_TYPE_GYM,
                                                 "env_kwargs": file_env_kwargs})
            data.attrs["observation_names"] = json.dumps(list(first.observation_names))
            data.attrs["command_names"] = json.dumps(list(first.command_names))
            data.attrs["dt"] = float(first.dt)
            data.attrs["total"] = int(sum(ep.num_samples for ep in episodes))
            if unit is not None:
                data.attrs["action_low"], data.attrs["action_high"] = unit
            data.attrs["transition_names"] = json.dumps(tag_names)
            if teaching:
                data.attrs["teaching"] = str(teaching)
            names: dict[str, list[str]] = {"success": [], "failure": []}
            for i, ep in enumerate(episodes):
                _write_demo(data.create_group(f"demo_{i}"), ep, unit, code, code_dtype, np.dtype(obs_dtype),
                            ep.mentor or mentor)
                names["success" if ep.outcome == "success" else "failure"].append(f"demo_{i}")
            names.update(train_valid_split([f"demo_{i}" for i in range(len(episodes))], split_seed))
            names.update(mentor_filter_keys([ep.mentor or mentor for ep in episodes], str(path)))
            mask = f.create_group("mask")
            for key, vals in names.items():
                mask.create_dataset(key, data=np.asarray(vals, dtype="S32"))
    return path


def train_valid_split(demos: Sequence[str], seed: int = 0,
                      valid_fraction: float = VALID_FRACTION) -> dict[str, list[str]]:
    """robomimic's ``mask/train`` and ``mask/valid`` filter keys, as its ``split_train_val.py``
    makes them (``int(valid_fraction * n)`` demos valid, the rest train, over the names in sorted
    order), with the shuffle drawn from ``seed`` so that the same demos give the same split."""
    names = sorted(demos)
    n_valid = int(valid_fraction * len(names))
    valid = set(np.random.default_rng(seed).permutation(len(names))[:n_valid].tolist())
    return {"train": [d for i, d in enumerate(names) if i not in valid],
            "valid": [d for i, d in enumerate(names) if i in valid]}


def mentor_key(mentor: str) -> str:
    """The filter key (``mask/<key>``) of a mentor's demos: ``mentor_`` and the name, characters other
    than letters, digits, ``_ . -`` replaced by ``_``."""
    return "mentor_" + re.sub(r"[^A-Za-z0-9_.-]", "_", mentor)


def mentor_filter_keys(mentors: Sequence[str], file: str = "") -> dict[str, list[str]]:
    """One filter key per named mentor: the names of the demos (``demo_<i>``, ``i`` the index in
    ``mentors``) each mentor made; two names that share a key are refused."""
    keys: dict[str, list[str]] = {}
    owner: dict[str, str] = {}
    for i, m in enumerate(mentors):
        if not m:
            continue
        key = mentor_key(m)
        if owner.setdefault(key, m) != m:
            raise InvalidInput(f"mentors {owner[key]!r} and {m!r} would share the filter key mask/{key}; rename one",
                               file=file, element=f"data/demo_{i}")
        keys.setdefault(key, []).append(f"demo_{i}")
    return keys


def env_action_limits(env_name: str, env_kwargs: dict[str, Any], n_cmd: int
                      ) -> tuple[np.ndarray, np.ndarray] | None:
    """The env's own action limits (``action_space.low``, ``.high``) when the env, as registered
    with Gymnasium here, takes ``normalize_actions`` (mapping [-1, 1] linearly onto them) and
    ``env_kwargs`` do not set it already; None otherwise (the actions are then stored as the env's
    raw commands)."""
    import inspect

    import gymnasium

    from ..registry import register_envs
    register_envs()             # the bundled envs, so the file does not depend on what was imported before
    if not env_name or "normalize_actions" in env_kwargs or env_name not in gymnasium.registry:
        return None
    try:
        env = gymnasium.make(env_name, disable_env_checker=True, **env_kwargs)
    except Exception:            # an env that cannot be made here: the file stores raw commands
        return None
    try:
        base = env.unwrapped
        if "normalize_actions" not in inspect.signature(type(base).__init__).parameters:
            return None
        low = np.asarray(getattr(base.action_space, "low", np.nan), dtype=np.float64).reshape(-1)
        high = np.asarray(getattr(base.action_space, "high", np.nan), dtype=np.float64).reshape(-1)
    finally:
        env.close()
    if high.shape != (n_cmd,) or low.shape != (n_cmd,) or not np.all(np.isfinite(high - low)) or np.any(high <= low):
        return None
    return low, high


def normalised(commands: np.ndarray, low: np.ndarray, high: np.ndarray) -> np.ndarray:
    """Commands mapped linearly from ``[low, high]`` onto [-1, 1] (clipped), as ``normalize_actions``
    maps them back."""
    return np.clip(2.0 * (commands - low) / (high - low) - 1.0, -1.0, 1.0)


def _write_demo(g: h5py.Group, ep: Episode, unit: tuple[np.ndarray, np.ndarray] | None, code: dict[str, int],
                code_dtype: type,
                obs_dtype: np.dtype, mentor: str) -> None:
    """One episode's group: its attributes, observations, actions (and exact commands when the
    actions are normalised), robomimic's rewards and dones, transition codes and labels."""
    n = ep.num_samples
    g.attrs["num_samples"] = n
    g.attrs["seed"] = int(ep.seed)
    g.attrs["reset_options"] = json.dumps(ep.reset_options, default=json_default)
    g.attrs["outcome"] = ep.outcome
    g.attrs["mentor"] = mentor
    _write_obs(g, ep, obs_dtype)
    commands = np.asarray(ep.actions, dtype=np.float64)
    if unit is None:
        _array(g, "actions", commands)
    else:
        _array(g, "actions", normalised(commands, *unit))
        _array(g, "commands", commands)
    rewards = np.zeros(n, dtype=np.float64)
    dones = np.zeros(n, dtype=np.uint8)
    if n:
        dones[-1] = 1
        rewards[-1] = float(ep.outcome == "success")
    _array(g, "rewards", rewards)
    _array(g, "dones", dones)
    tags = np.asarray(ep.transitions)
    codes = np.zeros(n, dtype=code_dtype)
    for t in np.unique(tags):
        codes[tags == t] = code[str(t)]
    _array(g, "transition", codes)
    g.create_dataset("labels", data=labels_array(ep.labels))


def _array(g: h5py.Group, name: str, arr: np.ndarray) -> h5py.Dataset:
    if len(arr) == 0:
        return g.create_dataset(name, data=arr)
    chunks = (min(len(arr), CHUNK),) + arr.shape[1:]
    return g.create_dataset(name, data=arr, chunks=chunks, **COMPRESSION)


def _write_obs(g: h5py.Group, ep: Episode, dtype: np.dtype) -> None:
    """obs/<name> as (T, 1) columns, identical columns stored once (hard links), and next_obs/<name>
    as virtual datasets over them."""
    obs, nxt = g.create_group("obs"), g.create_group("next_obs")
    n = ep.num_samples
    stored: dict[bytes, str] = {}
    for k, key in enumerate(ep.observation_names):
        col = np.ascontiguousarray(ep.obs[:, k], dtype=dtype).reshape(n, 1)
        digest = col.tobytes()
        if digest in stored:
            obs[key] = obs[stored[digest]]
        else:
            _array(obs, key, col)
            stored[digest] = key
        layout = h5py.VirtualLayout(shape=(n, 1), dtype=dtype)
        if n:
            src = h5py.VirtualSource(".", obs[key].name, shape=(n, 1))
            layout[: n - 1] = src[1:]
            layout[n - 1:] = src[n - 1:]
        nxt.create_virtual_dataset(key, layout)


def labels_array(labels: Iterable[SegmentLabel]) -> np.ndarray:
    labels = list(labels)
    arr = np.zeros(len(labels), dtype=LABEL_DTYPE)
    for i, lab in enumerate(labels):
        arr[i] = (lab.start, lab.end, lab.transition.encode(), int(lab.success), lab.labeller.encode())
    return arr



class Dataset:
    """A validated demonstration file, read fully into :class:`Episode` objects (``episodes``; their
    ``actions`` are the commands in the env's own units), with the file's attributes in ``meta``
    (``env_args`` as stored, ``observation_names``, ``command_names``, ``dt``, ``format_version``,
    ``obs_dtype``, ``action_limits``, ``teaching``: ``"kinesthetic"`` or ``""``). ``skill``,
    ``env_name`` and ``env_kwargs`` name what recorded it; iterating gives the episodes."""

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
        """``gymnasium.make`` arguments of the env that takes the episodes' commands (the file's
        ``env_args`` without the ``normalize_actions`` its actions were written for)."""
        kwargs = dict(self.meta["env_args"].get("env_kwargs", {}))
        if self.meta.get("action_limits") is not None:
            kwargs.pop("normalize_actions", None)
        return kwargs

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
            "teaching": self.meta.get("teaching") or "commands",
            "success": sum(ep.outcome == "success" for ep in eps),
            "success_fraction": float(np.mean([ep.outcome == "success" for ep in eps])) if eps else 0.0,
            "duration_s": {"total": float(durations.sum()), "mean": float(durations.mean()),
                           "min": float(durations.min()), "max": float(durations.max())},
            "samples": int(sum(ep.num_samples for ep in eps)),
            "samples_per_transition": dict(sorted(per_transition.items())),
            "segments": len(labels), "segments_success": sum(lab.success for lab in labels),
            "mentors": {m or "(unnamed)": {"demos": sum(ep.mentor == m for ep in eps),
                                           "success": sum(ep.mentor == m and ep.outcome == "success" for ep in eps)}
                        for m in mentors_of(eps)},
        }


def _read(path: Path) -> tuple[list[Episode], dict[str, Any]]:
    file = str(path)
    if not path.exists():
        raise MissingInput("file not found", file=file)
    check_regular_file(path, "demonstration file (.h5)")
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
        if int(version) not in READABLE_VERSIONS:
            raise InvalidInput(f"format version {int(version)}, this multiform reads versions "
                               f"{', '.join(map(str, READABLE_VERSIONS))}", file=file, element="data")
        version = int(version)
        meta: dict[str, Any] = {}
        for key in ("skill", "env_args", "observation_names", "command_names", "dt"):
            if key not in data.attrs:
                raise InvalidInput(f"missing attribute {key!r}", file=file, element="data")
        try:
            meta["skill"] = _str(data.attrs["skill"])
            meta["env_args"] = loads_json(_str(data.attrs["env_args"]), file, "data.env_args")
            obs_names = tuple(loads_json(_str(data.attrs["observation_names"]), file, "data.observation_names"))
            cmd_names = tuple(loads_json(_str(data.attrs["command_names"]), file, "data.command_names"))
        except TypeError as exc:
            raise InvalidInput(f"attributes are not valid JSON ({exc})", file=file, element="data") from None
        _check_env_args(meta["env_args"], obs_names, cmd_names, file)
        dt = float(data.attrs["dt"])
        if not np.isfinite(dt) or dt <= 0:
            raise InvalidInput(f"dt must be a positive number, got {dt}", file=file, element="data")
        meta.update(observation_names=obs_names, command_names=cmd_names, dt=dt, format_version=version,
                    teaching=_str(data.attrs.get("teaching", "")))
        scale, tag_names, unit = np.ones(len(cmd_names)), None, None
        if version == 2:
            scale, tag_names = _v2_attrs(data, len(cmd_names), file)
        elif version >= 3:
            unit, tag_names = _v3_attrs(data, len(cmd_names), file)
        meta["action_limits"] = unit
        names = sorted((k for k in data if k.startswith("demo_")), key=lambda k: int(k.split("_")[1]))
        episodes = []
        problems: list[Problem] = []
        for name in names:
            try:
                episodes.append(_read_demo(data[name], name, obs_names, cmd_names, dt, file, scale, tag_names,
                                           unit is not None))
            except InvalidInput as exc:
                problems.extend(exc.problems)
            except (OSError, KeyError, ValueError, TypeError) as exc:   # truncated chunks and the like
                problems.append(Problem(file, f"data/{name}", f"unreadable ({type(exc).__name__}: {exc})"))
        if problems:
            raise InvalidInput(problems)
        widths = {data[name]["obs"][key].dtype.itemsize for name in names for key in obs_names[:1]}
        meta["obs_dtype"] = "float32" if 4 in widths else "float64"
        return episodes, meta


def _v3_attrs(data: h5py.Group, n_cmd: int, file: str) -> tuple[tuple[np.ndarray, np.ndarray] | None, list[str]]:
    """Format 3's action limits (None: the actions are the commands) and transition names, checked."""
    unit = None
    if "action_low" in data.attrs or "action_high" in data.attrs:
        for key in ("action_low", "action_high"):
            if key not in data.attrs:
                raise InvalidInput(f"missing attribute {key!r} beside its pair", file=file, element="data")
        low, high = (np.asarray(data.attrs[k], dtype=np.float64).reshape(-1) for k in ("action_low", "action_high"))
        if low.shape != (n_cmd,) or high.shape != (n_cmd,) or not np.all(np.isfinite(high - low)) or np.any(high <= low):
            raise InvalidInput(f"action_low/action_high must be {n_cmd} finite limits each, low below high, got "
                               f"{low.tolist()[:8]} / {high.tolist()[:8]}", file=file, element="data")
        unit = (low, high)
    return unit, _transition_names(data, file)


def _v2_attrs(data: h5py.Group, n_cmd: int, file: str) -> tuple[np.ndarray, list[str]]:
    """Format 2's action scale and transition name table, checked."""
    if "action_scale" not in data.attrs:
        raise InvalidInput("missing attribute 'action_scale'", file=file, element="data")
    scale = np.asarray(data.attrs["action_scale"], dtype=np.float64).reshape(-1)
    mant, _ = np.frexp(scale)
    if scale.shape != (n_cmd,) or not np.all(np.isfinite(scale)) or np.any(scale <= 0) or np.any(mant != 0.5):
        raise InvalidInput(f"action_scale must be {n_cmd} positive powers of two, got {scale.tolist()[:8]}",
                           file=file, element="data")
    return scale, _transition_names(data, file)


def _transition_names(data: h5py.Group, file: str) -> list[str]:
    if "transition_names" not in data.attrs:
        raise InvalidInput("missing attribute 'transition_names'", file=file, element="data")
    try:
        names = json.loads(_str(data.attrs["transition_names"]))
    except (json.JSONDecodeError, TypeError, RecursionError) as exc:
        raise InvalidInput(f"transition_names is not valid JSON ({exc})", file=file, element="data") from None
    if not isinstance(names, list) or not all(isinstance(t, str) for t in names):
        raise InvalidInput("transition_names must be a JSON list of names", file=file, element="data")
    return names


def _str(v: Any) -> str:
    return v.decode() if isinstance(v, bytes) else str(v)


def _check_env_args(env_args: Any, obs_names: Any, cmd_names: Any, file: str) -> None:
    """The file's env arguments and names: the types the readers rely on, plain bounded data."""
    if not isinstance(env_args, dict) or not isinstance(env_args.get("env_name"), str) \
            or not isinstance(env_args.get("env_kwargs", {}), dict):
        raise InvalidInput("must be a JSON object with env_name (text) and env_kwargs (an object)", file=file,
                           element="data.env_args")
    problems = [Problem(file, f"data.env_args.{where}", msg)
                for where, msg in plain_data_problems(env_args.get("env_kwargs", {}), "env_kwargs")]
    for key, names in (("observation_names", obs_names), ("command_names", cmd_names)):
        if not all(isinstance(x, str) for x in names):
            problems.append(Problem(file, f"data.{key}", "must be a JSON list of names"))
    if problems:
        raise InvalidInput(problems)


def _check_values(values: np.ndarray, field: str, bad, when: str = "") -> None:
    """Every value finite and at most :data:`~multiform.io.MAX_MAGNITUDE` in size (a learner squares
    them: a value near the float range overflows on the way)."""
    ok = np.isfinite(values) & (np.abs(values) <= MAX_MAGNITUDE)
    if not ok.all():
        k = int(np.flatnonzero(~ok.reshape(len(values), -1).all(axis=1))[0])
        v = values.reshape(len(values), -1)[k][~ok.reshape(len(values), -1)[k]][0]
        what = "non-finite value" if not np.isfinite(v) else f"value {v:.3g} out of range (at most {MAX_MAGNITUDE:g})"
        raise bad(field, f"{what} at sample {k}" + (f" {when}" if when else ""))


def _read_obs(g: h5py.Group, n: int, obs_names: tuple[str, ...], shape: tuple[int, ...], bad) -> np.ndarray:
    """A demo's observations (n, variables) from one dataset of ``shape`` per variable in ``obs/``."""
    if "obs" not in g:
        raise bad("obs", "missing group")
    cols = []
    for key in obs_names:
        if key not in g["obs"]:
            raise bad(f"obs/{key}", "missing dataset")
        ds = g["obs"][key]
        if ds.shape != shape:
            raise bad(f"obs/{key}", f"shape {ds.shape}, expected {shape} from num_samples")
        if ds.dtype.kind != "f":
            raise bad(f"obs/{key}", f"dtype {ds.dtype}, expected a float type")
        col = ds[()].reshape(n).astype(np.float64)
        _check_values(col, f"obs/{key}", bad)
        cols.append(col)
    return np.stack(cols, axis=1) if cols else np.zeros((n, 0))


def _read_demo(g: h5py.Group, name: str, obs_names: tuple[str, ...], cmd_names: tuple[str, ...], dt: float,
               file: str, scale: np.ndarray, tag_names: list[str] | None, has_commands: bool = False) -> Episode:
    def bad(field: str, msg: str) -> InvalidInput:
        return InvalidInput(msg, file=file, element=f"data/{name}/{field}")

    if "num_samples" not in g.attrs:
        raise bad("num_samples", "missing attribute")
    n = int(g.attrs["num_samples"])
    obs = _read_obs(g, n, obs_names, (n,) if tag_names is None else (n, 1), bad)
    for field in ("actions", "dones", "transition", "labels"):
        if field not in g:
            raise bad(field, "missing dataset")
    actions = g["actions"][()]
    if actions.shape != (n, len(cmd_names)):
        raise bad("actions", f"shape {actions.shape}, expected ({n}, {len(cmd_names)})")
    if actions.dtype.kind != "f" or not np.all(np.isfinite(actions)):
        raise bad("actions", "must hold finite floats")
    if has_commands:            # format 3 with normalised actions: the exact commands beside them
        if "commands" not in g:
            raise bad("commands", "missing dataset (the file has action_low/action_high)")
        actions = g["commands"][()]
        if actions.shape != (n, len(cmd_names)) or actions.dtype.kind != "f" or not np.all(np.isfinite(actions)):
            raise bad("commands", f"must hold finite floats of shape ({n}, {len(cmd_names)}), "
                                  f"got {actions.shape} {actions.dtype}")
    tags = g["transition"][()]
    if tag_names is None:
        if tags.shape != (n,) or tags.dtype.kind != "S":
            raise bad("transition", f"shape {tags.shape} dtype {tags.dtype}, expected ({n},) bytes")
        tags = tags.astype(str)
    else:
        if tags.shape != (n,) or tags.dtype.kind != "u":
            raise bad("transition", f"shape {tags.shape} dtype {tags.dtype}, expected ({n},) unsigned codes")
        if n and int(tags.max()) >= len(tag_names):
            raise bad("transition", f"code {int(tags.max())} has no name ({len(tag_names)} transition_names)")
        tags = np.asarray(tag_names, dtype=str)[tags] if tag_names else np.zeros(0, dtype=str)
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
    reset_options = loads_json(_str(g.attrs.get("reset_options", "{}")), file, f"data/{name}/reset_options")
    if not isinstance(reset_options, dict):
        raise bad("reset_options", f"must be a JSON object, got {type(reset_options).__name__}")
    for where, msg in plain_data_problems(reset_options, "reset_options")[:1]:
        raise bad(where, msg)
    seed = g.attrs.get("seed", 0)
    if not isinstance(seed, (int, np.integer)) or not 0 <= int(seed) < 2**63:
        raise bad("seed", f"must be a whole number in 0..2**63-1, got {seed!r}")
    with np.errstate(over="ignore"):            # an overflow is found (and named) just below
        actions = actions.astype(np.float64) * scale
    if has_commands:
        _check_values(actions, "commands", bad)
    else:
        _check_values(actions, "actions", bad, "after action_scale" if np.any(scale != 1.0) else "")
    return Episode(obs=obs, actions=actions, transitions=tags,
                   observation_names=obs_names, command_names=cmd_names, dt=dt,
                   seed=int(seed), reset_options=reset_options, labels=labels,
                   outcome=_str(g.attrs.get("outcome", "")), mentor=_str(g.attrs.get("mentor", "")))


def read_dataset(path: str | os.PathLike) -> Dataset:
    """Open and validate a demonstration file."""
    return Dataset(path)
