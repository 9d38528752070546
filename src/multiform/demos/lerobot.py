"""Demonstrations to and from LeRobot's dataset format (v3.0), without LeRobot itself.

A LeRobot v3 dataset is a folder::

    meta/info.json                       codebase_version "v3.0", fps, features, paths, totals
    meta/tasks.parquet                   task text (index) -> task_index
    meta/subtasks.parquet                subtask name (index) -> subtask_index
    meta/stats.json                      per feature: min, max, mean, std, count
    meta/episodes/chunk-000/file-000.parquet   one row per episode: length, tasks, where its frames are
    data/chunk-000/file-000.parquet      one row per frame

multiform writes, per frame: ``observation.state`` (the env's observation, names in the feature's
``names``), ``action`` (the mentor's command in the env's own units, as LeRobot's datasets hold
actions), ``subtask_index`` (the transition the mentor was executing, named in
``meta/subtasks.parquet``), ``next.done``, ``next.success`` and ``next.reward`` (on the last frame
of a successful demo), ``segment.success`` (the mentor's label of the segment the frame lies in: 1
success, 0 failure, -1 unlabelled; what LeRobot's reward classifier trains on), and LeRobot's
``timestamp``, ``frame_index``, ``episode_index``, ``index``, ``task_index``. Every episode row also
carries its outcome, mentor (who demonstrated it), seed, reset options and labels (``multiform/...``
columns) and, as LeRobot's
own writer adds them, the episode's statistics of every feature (``stats/<feature>/<min|max|mean|
std|count|q01|q10|q50|q90|q99>``); ``meta/stats.json`` has the same over the whole dataset, and
``info.json`` a ``multiform`` block (skill, env). Values stay float64 so frames equal the source
bit for bit. No videos: the robot's sensors are the state.

At the control rate (the default) an export imports back exactly. ``fps`` lower than the control
rate (a whole divisor of it, e.g. 50 of 1000) downsamples for policies that run at 30-100 Hz:
frame ``k`` covers the control ticks ``[k s, (k+1) s)`` (``s`` = rate / fps; the last frame the
ticks that remain); its state, subtask and segment label are those at its first tick, its action
the mean command over its ticks (the constant command that, held for the frame, moves the hand as
far as the mentor did), and the labels in ``multiform/labels`` are in frames.

Reading takes any LeRobot v3 dataset with a state and an action vector; the caller names the
variables (``state_names``), or the feature's own ``names`` are used when they are valid names.
"""

from __future__ import annotations

import json
import math
import os
import re
import shutil
import tempfile
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import InvalidInput, MissingInput
from ..io import json_default
from .episode import Episode, SegmentLabel

CODEBASE_VERSION = "v3.0"
CHUNKS_SIZE = 1000
FILE_MB = 100
DATA_PATH = "data/chunk-{chunk_index:03d}/file-{file_index:03d}.parquet"
EPISODES_PATH = "meta/episodes/chunk-{chunk_index:03d}/file-{file_index:03d}.parquet"
NAME = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")


def _pa():
    try:
        import pyarrow as pa
        import pyarrow.parquet as pq
    except ImportError:
        raise InvalidInput("LeRobot datasets need pyarrow: pip install 'multiform[lerobot]'") from None
    return pa, pq


def _feature(dtype: str, shape: int, names: Sequence[str] | None = None) -> dict[str, Any]:
    return {"dtype": dtype, "shape": [shape], "names": list(names) if names is not None else None}


STATS = ("min", "max", "mean", "std", "count", "q01", "q10", "q50", "q90", "q99")


def _stats(x: np.ndarray) -> dict[str, Any]:
    """LeRobot's statistics of one feature over frames (per entry; ``count`` the frames)."""
    x = np.asarray(x, dtype=np.float64).reshape(len(x), -1)
    q = np.quantile(x, [0.01, 0.10, 0.50, 0.90, 0.99], axis=0)
    return {"min": x.min(0).tolist(), "max": x.max(0).tolist(), "mean": x.mean(0).tolist(),
            "std": x.std(0).tolist(), "count": [len(x)], "q01": q[0].tolist(), "q10": q[1].tolist(),
            "q50": q[2].tolist(), "q90": q[3].tolist(), "q99": q[4].tolist()}


def _segment_labels(ep: Episode) -> np.ndarray:
    out = np.full(ep.num_samples, -1, dtype=np.int64)
    for lab in ep.labels:
        out[lab.start:lab.end] = int(lab.success)
    return out


def write_lerobot(out: str | os.PathLike, episodes: Sequence[Episode], skill: str, env_name: str,
                  env_kwargs: dict[str, Any] | None = None, task: str = "", fps: float | None = None) -> Path:
    """Write ``episodes`` as a LeRobot v3 dataset folder ``out`` (built beside it, then moved into
    place; an existing non-empty ``out`` is refused), at the control rate or at ``fps`` frames per
    second, a whole divisor of it (module docstring: how frames aggregate the ticks)."""
    pa, pq = _pa()
    out = Path(out)
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        raise InvalidInput("exists and is not an empty folder; choose a new one", file=str(out))
    if not episodes:
        raise InvalidInput("no episodes to export", file=str(out))
    first = episodes[0]
    rate = 1.0 / first.dt
    if abs(rate - round(rate)) > 1e-6:
        raise InvalidInput(f"LeRobot needs a whole number of frames per second; dt = {first.dt}", file=str(out))
    rate = int(round(rate))
    want = rate if fps is None else fps
    if not (want == int(want) and 0 < int(want) <= rate and rate % int(want) == 0):
        raise InvalidInput(f"must be a whole number that divides the control rate {rate} Hz (e.g. "
                           f"{', '.join(str(rate // d) for d in (1, 10, 20, 40) if rate % d == 0)}), got {fps:g}",
                           element="fps")
    fps = int(want)
    step = rate // fps
    subtasks = sorted({str(t) for ep in episodes for t in np.unique(ep.transitions)})
    task = task or f"{skill}: the skill as the mentor demonstrated it"
    features = _features(first)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.", dir=out.parent))
    try:
        total = _write_frames(tmp, out, episodes, features, {t: k for k, t in enumerate(subtasks)}, task, step, pa, pq)
        _write_meta(tmp, total, len(episodes), features, task, subtasks, fps, first.dt, skill, env_name, env_kwargs)
        if out.exists():
            out.rmdir()
        os.replace(tmp, out)
    finally:
        if tmp.exists():
            shutil.rmtree(tmp)
    return out


def _features(first: Episode) -> dict[str, Any]:
    """The dataset's features (``info.json``), in the order of the data files' columns."""
    return {
        "observation.state": _feature("float64", len(first.observation_names), first.observation_names),
        "action": _feature("float64", len(first.command_names), first.command_names),
        "subtask_index": _feature("int64", 1),
        "segment.success": _feature("int64", 1),
        "next.reward": _feature("float32", 1),
        "next.done": _feature("bool", 1),
        "next.success": _feature("bool", 1),
        "timestamp": _feature("float32", 1),
        "frame_index": _feature("int64", 1),
        "episode_index": _feature("int64", 1),
        "index": _feature("int64", 1),
        "task_index": _feature("int64", 1),
    }


def _frame_table(ep: Episode, e: int, index: int, sub_index: dict[str, int], step: int) -> dict[str, np.ndarray]:
    """Episode ``e``'s frames, column by column, one per ``step`` control ticks (state, subtask and
    label at the frame's first tick, the mean command over its ticks); its first frame is the
    dataset's frame ``index``."""
    starts = np.arange(0, ep.num_samples, step)
    n = len(starts)
    ticks = np.diff(np.append(starts, ep.num_samples)).reshape(n, 1)
    actions = np.asarray(ep.actions, dtype=np.float64)
    mean_cmd = actions[starts] if step == 1 else np.add.reduceat(actions, starts, axis=0) / ticks
    last = np.zeros(n, dtype=bool)
    last[-1:] = True
    ok = ep.outcome == "success"
    return {
        "observation.state": ep.obs[starts].astype(np.float64), "action": mean_cmd,
        "subtask_index": np.array([sub_index[str(t)] for t in ep.transitions[starts]], dtype=np.int64),
        "segment.success": _segment_labels(ep)[starts],
        "next.reward": (last & ok).astype(np.float32), "next.done": last, "next.success": last & ok,
        "timestamp": (np.arange(n) * (ep.dt * step)).astype(np.float32),
        "frame_index": np.arange(n, dtype=np.int64), "episode_index": np.full(n, e, dtype=np.int64),
        "index": np.arange(index, index + n, dtype=np.int64), "task_index": np.zeros(n, dtype=np.int64),
    }


def _write_frames(tmp: Path, out: Path, episodes: Sequence[Episode], features: dict[str, Any],
                  sub_index: dict[str, int], task: str, step: int, pa, pq) -> int:
    """The data files (a new one each ``FILE_MB``), the episodes' rows with their statistics, and
    the dataset's statistics of every feature, into ``tmp``; returns the number of frames."""
    first = episodes[0]
    rows, index, file_index, file_bytes = [], 0, 0, 0
    ep_rows: list[dict[str, Any]] = []
    columns: dict[str, list[np.ndarray]] = {key: [] for key in features}
    for e, ep in enumerate(episodes):
        if ep.observation_names != first.observation_names or ep.command_names != first.command_names:
            raise InvalidInput("episodes disagree on observation or command names", file=str(out),
                               element=f"episode {e}")
        table = _frame_table(ep, e, index, sub_index, step)
        n = len(table["index"])
        size = sum(v.nbytes for v in table.values())
        if rows and file_bytes + size > FILE_MB * 2**20:
            _write_data(tmp, rows, features, file_index, pa, pq)
            rows, file_index, file_bytes = [], file_index + 1, 0
        rows.append(table)
        file_bytes += size
        for key in features:
            columns[key].append(table[key])
        ep_rows.append({
            "episode_index": e, "tasks": [task], "length": n,
            "data/chunk_index": file_index // CHUNKS_SIZE, "data/file_index": file_index % CHUNKS_SIZE,
            "dataset_from_index": index, "dataset_to_index": index + n,
            "meta/episodes/chunk_index": 0, "meta/episodes/file_index": 0,
            "multiform/outcome": ep.outcome, "multiform/mentor": ep.mentor, "multiform/seed": int(ep.seed),
            "multiform/reset_options": json.dumps(ep.reset_options, default=json_default),
            "multiform/labels": json.dumps([[lab.start // step, -(-lab.end // step), lab.transition,
                                             bool(lab.success), lab.labeller] for lab in ep.labels]),
            **{f"stats/{key}/{name}": value for key in features for name, value in _stats(table[key]).items()},
        })
        index += n
    _write_data(tmp, rows, features, file_index, pa, pq)
    path = tmp / EPISODES_PATH.format(chunk_index=0, file_index=0)
    path.parent.mkdir(parents=True)
    pq.write_table(pa.Table.from_pylist(ep_rows), path)
    stats = {key: _stats(np.concatenate(parts)) for key, parts in columns.items()}
    (tmp / "meta/stats.json").write_text(json.dumps(stats, indent=2))
    return index


def _write_meta(tmp: Path, total_frames: int, total_episodes: int, features: dict[str, Any], task: str,
                subtasks: list[str], fps: int, dt: float, skill: str, env_name: str,
                env_kwargs: dict[str, Any] | None) -> None:
    """``meta/tasks.parquet``, ``meta/subtasks.parquet`` and ``meta/info.json``."""
    import pandas as pd
    pd.DataFrame({"task_index": [0]}, index=pd.Index([task], name="task")).to_parquet(tmp / "meta/tasks.parquet")
    pd.DataFrame({"subtask_index": list(range(len(subtasks)))},
                 index=pd.Index(subtasks, name="subtask")).to_parquet(tmp / "meta/subtasks.parquet")
    info = {
        "codebase_version": CODEBASE_VERSION, "robot_type": env_name, "total_episodes": total_episodes,
        "total_frames": total_frames, "total_tasks": 1, "chunks_size": CHUNKS_SIZE, "data_files_size_in_mb": FILE_MB,
        "video_files_size_in_mb": 200, "fps": fps, "splits": {"train": f"0:{total_episodes}"},
        "data_path": DATA_PATH, "video_path": None, "features": features,
        "multiform": {"skill": skill, "env_args": {"env_name": env_name, "env_kwargs": env_kwargs or {}},
                      "dt": dt},
    }
    (tmp / "meta/info.json").write_text(json.dumps(info, indent=4))


def _write_data(root: Path, rows: list[dict[str, np.ndarray]], features: dict[str, Any], file_index: int,
                pa, pq) -> None:
    cols = {}
    for key, ft in features.items():
        arr = np.concatenate([r[key] for r in rows])
        if ft["shape"] == [1] or arr.ndim == 1:
            cols[key] = pa.array(arr.reshape(len(arr)))
        else:
            cols[key] = pa.FixedSizeListArray.from_arrays(pa.array(arr.reshape(-1)), arr.shape[1])
    path = root / DATA_PATH.format(chunk_index=file_index // CHUNKS_SIZE, file_index=file_index % CHUNKS_SIZE)
    path.parent.mkdir(parents=True, exist_ok=True)
    pq.write_table(pa.table(cols), path, compression="snappy")



def read_lerobot(root: str | os.PathLike, state_names: Sequence[str] | None = None,
                 command_names: Sequence[str] | None = None, state_key: str = "observation.state",
                 action_key: str = "action", transition: str = "t0") -> tuple[list[Episode], dict[str, Any]]:
    """Episodes of a LeRobot v3 dataset, and its metadata (skill and env when multiform wrote it).

    Transition tags come from ``subtask_index`` (named in ``meta/subtasks.parquet``), else every
    frame gets ``transition``. An episode's outcome and labels come from multiform's own columns,
    else from ``next.success`` on its last frame: a successful episode's segments are labelled
    successful (labeller ``lerobot``), an unsuccessful one's failed.
    """
    pa, pq = _pa()
    root = Path(root)
    info, fps = _read_info(root)
    features = info["features"]
    names = {what: _vector_names(features, key, given, what, str(root / "meta/info.json"))
             for what, key, given in (("state", state_key, state_names), ("action", action_key, command_names))}
    cat = _read_frames(root, features, (state_key, action_key), pa, pq)
    for c, what in ((state_key, "state"), (action_key, "action")):
        dim = len(names[what])
        if cat[c].shape[1] != dim:
            raise InvalidInput(f"column {c!r} has {cat[c].shape[1]} entries, info.json says {dim}", file=str(root))
        bad = ~np.isfinite(cat[c]).all(axis=1)
        if bad.any():
            k = int(np.flatnonzero(bad)[0])
            raise InvalidInput(f"column {c!r}: non-finite value in episode {int(cat['episode_index'][k])}, "
                               f"frame {int(cat['frame_index'][k])}", file=str(root))
    subtask_names = _subtask_names(root, pq) if "subtask_index" in cat else None
    ep_meta = _episode_meta(root, pq)
    episodes = []
    for e in np.unique(cat["episode_index"]):
        sel = np.flatnonzero(cat["episode_index"] == e)
        sel = sel[np.argsort(cat["frame_index"][sel], kind="stable")]
        episodes.append(_episode(root, int(e), sel, cat, state_key, action_key, names, 1.0 / float(fps),
                                 subtask_names, transition, ep_meta.get(int(e), {})))
    return episodes, info.get("multiform") if isinstance(info.get("multiform"), dict) else {}


def _read_info(root: Path) -> tuple[dict[str, Any], float]:
    """``meta/info.json`` of a v3 dataset with a ``features`` mapping, and its fps."""
    file = str(root / "meta/info.json")
    if not root.exists():
        raise MissingInput("no such folder", file=str(root))
    try:
        info = json.loads((root / "meta/info.json").read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise InvalidInput("not a LeRobot dataset (no meta/info.json)", file=str(root)) from None
    except (OSError, UnicodeDecodeError, json.JSONDecodeError, RecursionError) as exc:
        raise InvalidInput(f"not valid JSON ({exc})", file=file) from None
    if not isinstance(info, dict):
        raise InvalidInput("must be a JSON object", file=file)
    version = str(info.get("codebase_version", ""))
    if not version.startswith("v3"):
        raise InvalidInput(f"codebase_version {version!r}; this reader takes LeRobot v3 datasets", file=file)
    if not isinstance(info.get("features"), dict):
        raise InvalidInput("no 'features' mapping", file=file)
    fps = info.get("fps")
    if isinstance(fps, bool) or not isinstance(fps, (int, float)) or not math.isfinite(fps) or fps <= 0:
        raise InvalidInput(f"fps must be a positive number, got {fps!r}", file=file, element="fps")
    return info, fps


def _vector_names(features: dict[str, Any], key: str, given: Sequence[str] | None, what: str,
                  file: str) -> tuple[str, ...]:
    """The entry names of the 1-D ``what`` ("state" or "action") feature ``key``: ``given``, else
    the feature's own."""
    ft = features.get(key)
    if not isinstance(ft, dict) or not isinstance(ft.get("shape"), list) or len(ft["shape"]) != 1:
        raise InvalidInput(f"no 1-D {what} feature {key!r} (features: {', '.join(features)})", file=file)
    dim = ft["shape"][0]
    own = ft.get("names")
    if isinstance(own, dict):                         # LeRobot also writes {"motors": [...]}
        own = next(iter(own.values()), None)
    chosen = list(given) if given else own
    if not chosen or len(chosen) != dim or not all(isinstance(n, str) and NAME.match(n) for n in chosen):
        raise InvalidInput(f"{what} feature {key!r} has {dim} entries; name them "
                           f"({'--variables' if what == 'state' else '--commands'} a,b,...) with valid names, "
                           f"got {chosen!r}", file=file)
    if len(set(chosen)) != len(chosen):
        raise InvalidInput(f"duplicate {what} names {chosen!r}", file=file)
    return tuple(chosen)


def _read_frames(root: Path, features: dict[str, Any], vectors: tuple[str, str], pa, pq) -> dict[str, np.ndarray]:
    """Every data file's frames, concatenated per column: the state and action ``vectors`` as
    (frames, entries) float64, the indices and optional columns as they are."""
    data_files = sorted((root / "data").glob("chunk-*/file-*.parquet"))
    if not data_files:
        raise InvalidInput("no data/chunk-*/file-*.parquet files", file=str(root))
    columns = [*vectors, "episode_index", "frame_index"]
    optional = [c for c in ("subtask_index", "next.success", "segment.success") if c in features]
    frames: dict[str, list[np.ndarray]] = {c: [] for c in columns + optional}
    for path in data_files:
        try:
            table = pq.read_table(path, columns=columns + optional)
        except (OSError, ValueError, pa.ArrowException) as exc:
            raise InvalidInput(f"unreadable parquet ({exc})", file=str(path)) from None
        for c in frames:
            col = table.column(c).combine_chunks()
            if c in vectors:
                try:
                    flat = col.flatten() if pa.types.is_list(col.type) or pa.types.is_fixed_size_list(col.type) else col
                    arr = np.asarray(flat.to_numpy(zero_copy_only=False), dtype=np.float64).reshape(len(col), -1)
                except (ValueError, pa.ArrowException) as exc:
                    raise InvalidInput(f"column {c!r} is not a fixed-length number vector ({exc})",
                                       file=str(path)) from None
            else:
                arr = np.asarray(col.to_numpy(zero_copy_only=False))
            frames[c].append(arr)
    return {c: np.concatenate(v) for c, v in frames.items()}


def _episode(root: Path, e: int, sel: np.ndarray, cat: dict[str, np.ndarray], state_key: str, action_key: str,
             names: dict[str, tuple[str, ...]], dt: float, subtask_names: list[str] | None, transition: str,
             meta: dict[str, Any]) -> Episode:
    """Episode ``e`` from its frames ``sel`` (in frame order), tagged and labelled."""
    where = f"episode {e}"
    if not np.array_equal(cat["frame_index"][sel], np.arange(len(sel))):
        raise InvalidInput("frame_index is not 0, 1, 2, ... without gaps", file=str(root), element=where)
    if subtask_names is not None:
        codes = cat["subtask_index"][sel].astype(np.int64)
        if codes.min() < 0 or codes.max() >= len(subtask_names):
            raise InvalidInput(f"subtask_index {int(codes.max())} has no name in meta/subtasks.parquet",
                               file=str(root), element=where)
        tags = np.asarray(subtask_names, dtype=str)[codes]
    else:
        tags = np.full(len(sel), transition)
    ep = Episode(obs=cat[state_key][sel], actions=cat[action_key][sel], transitions=tags,
                 observation_names=names["state"], command_names=names["action"], dt=dt,
                 seed=int(meta.get("multiform/seed", e) or 0))
    if meta.get("multiform/outcome") is not None:
        ep.outcome = str(meta["multiform/outcome"])
        ep.mentor = str(meta.get("multiform/mentor") or "")
        ep.reset_options = _loads(meta.get("multiform/reset_options"), {}, root, where)
        try:
            ep.labels = [SegmentLabel(int(s), int(t), str(tr), bool(ok), str(who))
                         for s, t, tr, ok, who in _loads(meta.get("multiform/labels"), [], root, where)]
        except (TypeError, ValueError):
            raise InvalidInput("multiform/labels must be [start, end, transition, success, labeller] rows",
                               file=str(root), element=where) from None
        if any(not 0 <= lab.start < lab.end <= len(sel) for lab in ep.labels):
            raise InvalidInput("a label's segment lies outside the episode", file=str(root), element=where)
    elif "next.success" in cat:
        ep.outcome = "success" if bool(cat["next.success"][sel][-1]) else "failure"
        ep.labels = [SegmentLabel(s, t, tr, ep.outcome == "success", "lerobot") for s, t, tr in ep.segments()]
    return ep


def _subtask_names(root: Path, pq) -> list[str]:
    path = root / "meta/subtasks.parquet"
    if not path.exists():
        raise InvalidInput("frames have subtask_index but there is no meta/subtasks.parquet", file=str(root))
    import pandas as pd
    df = pd.read_parquet(path)
    if "subtask_index" not in df.columns:
        raise InvalidInput("no subtask_index column", file=str(path))
    order = np.argsort(df["subtask_index"].to_numpy())
    names = [str(n) for n in np.asarray(df.index)[order]]
    if not np.array_equal(df["subtask_index"].to_numpy()[order], np.arange(len(names))):
        raise InvalidInput("subtask_index must count 0, 1, 2, ...", file=str(path))
    return names


def _episode_meta(root: Path, pq) -> dict[int, dict[str, Any]]:
    out: dict[int, dict[str, Any]] = {}
    for path in sorted((root / "meta/episodes").glob("chunk-*/file-*.parquet")):
        for row in pq.read_table(path).to_pylist():
            if "episode_index" in row:
                out[int(row["episode_index"])] = row
    return out


def _loads(text: Any, default: Any, root: Path, where: str) -> Any:
    if text is None:
        return default
    try:
        return json.loads(text)
    except (TypeError, json.JSONDecodeError, RecursionError) as exc:
        raise InvalidInput(f"multiform column is not valid JSON ({exc})", file=str(root), element=where) from None
