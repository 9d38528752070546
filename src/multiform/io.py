"""Atomic, pickle-free persistence: JSON, JSON lines and ``.npz`` arrays with a versioned header.

Every saved artifact goes through here so that (1) a crash never leaves a half-written file — we
write a temporary file in the same directory and ``os.replace`` it — and (2) nothing saved can run
code when loaded: arrays are read with ``allow_pickle=False`` and metadata is plain JSON.
"""

from __future__ import annotations

import contextlib
import json
import os
import tempfile
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from .errors import InvalidInput, MissingInput

FORMAT_KEY = "__format__"


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike, suffix: str = "") -> Iterator[Path]:
    """Yield a temporary path beside ``path``; on success it replaces ``path``, on error it vanishes."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=suffix or ".tmp", dir=path.parent)
    os.close(fd)
    umask = os.umask(0)
    os.umask(umask)
    os.chmod(tmp, 0o666 & ~umask)          # mkstemp makes 0600; a saved artifact gets the usual mode
    tmp_path = Path(tmp)
    try:
        yield tmp_path
        os.replace(tmp_path, path)
    finally:
        if tmp_path.exists():
            tmp_path.unlink()


def write_text(path: str | os.PathLike, text: str) -> None:
    """Write ``text`` to ``path`` atomically."""
    with atomic_path(path) as tmp:
        tmp.write_text(text, encoding="utf-8")


def write_json(path: str | os.PathLike, obj: Any) -> None:
    """Write ``obj`` as indented JSON, atomically."""
    write_text(path, json.dumps(obj, indent=2, sort_keys=False, default=json_default) + "\n")


def append_jsonl(path: str | os.PathLike, record: Mapping[str, Any]) -> None:
    """Append one record to a JSON-lines file; the whole new file replaces the old one atomically."""
    path = Path(path)
    old = path.read_text(encoding="utf-8") if path.exists() else ""
    line = json.dumps(record, sort_keys=False, default=json_default)
    write_text(path, old + line + "\n")


def read_json(path: str | os.PathLike, what: str = "file") -> Any:
    """Read JSON, turning decoding errors into :class:`InvalidInput` naming the file."""
    path = Path(path)
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise MissingInput(f"{what} not found", file=str(path)) from None
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise InvalidInput(f"not valid JSON ({exc})", file=str(path)) from None


def read_jsonl(path: str | os.PathLike) -> list[dict[str, Any]]:
    """Read a JSON-lines file; a bad line is reported with its line number."""
    path = Path(path)
    out = []
    for i, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
        if not line.strip():
            continue
        try:
            out.append(json.loads(line))
        except json.JSONDecodeError as exc:
            raise InvalidInput(f"not valid JSON ({exc})", file=str(path), element=f"line {i}") from None
    return out


def save_npz(path: str | os.PathLike, arrays: Mapping[str, np.ndarray], meta: Mapping[str, Any],
             kind: str, version: int) -> None:
    """Save named arrays plus JSON metadata (stored as a string array) in one ``.npz``, atomically.

    ``kind`` and ``version`` form the header checked by :func:`load_npz`.
    """
    header = {"kind": kind, "version": version, "meta": dict(meta)}
    payload = {k: np.asarray(v) for k, v in arrays.items()}
    for k, v in payload.items():
        if v.dtype == object:
            raise TypeError(f"array {k!r} has dtype object; it would need pickle")
    payload[FORMAT_KEY] = np.array(json.dumps(header, default=json_default))
    with atomic_path(path, suffix=".npz") as tmp:
        with open(tmp, "wb") as fh:
            np.savez(fh, **payload)


def load_npz(path: str | os.PathLike, kind: str, version: int,
             required: Mapping[str, tuple[int | None, ...]] | None = None
             ) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
    """Load a file written by :func:`save_npz`, checking kind, version and array shapes.

    ``required`` maps array names to expected shapes (``None`` = any length on that axis).
    Returns ``(arrays, meta)``. Problems raise :class:`InvalidInput` naming the file and array.
    """
    path = Path(path)
    try:
        with np.load(path, allow_pickle=False) as npz:
            arrays = {k: npz[k] for k in npz.files}
    except FileNotFoundError:
        raise MissingInput("file not found", file=str(path)) from None
    except ValueError as exc:  # includes "Object arrays cannot be loaded when allow_pickle=False"
        raise InvalidInput(f"cannot read arrays ({exc})", file=str(path)) from None
    except Exception as exc:  # zipfile.BadZipFile, OSError, EOFError on truncation
        raise InvalidInput(f"not a valid .npz file ({type(exc).__name__}: {exc})", file=str(path)) from None
    if FORMAT_KEY not in arrays:
        raise InvalidInput("missing format header; not written by multiform", file=str(path))
    try:
        header = json.loads(str(arrays.pop(FORMAT_KEY)))
    except json.JSONDecodeError as exc:
        raise InvalidInput(f"format header is not JSON ({exc})", file=str(path)) from None
    if header.get("kind") != kind:
        raise InvalidInput(f"holds a {header.get('kind')!r}, expected a {kind!r}", file=str(path))
    if header.get("version") != version:
        raise InvalidInput(f"format version {header.get('version')!r}, this multiform reads version "
                           f"{version}", file=str(path))
    problems = []
    for name, shape in (required or {}).items():
        if name not in arrays:
            problems.append(f"array {name!r} is missing")
            continue
        got = arrays[name].shape
        if len(got) != len(shape) or any(s is not None and s != g for s, g in zip(shape, got)):
            problems.append(f"array {name!r} has shape {got}, expected {_shape_str(shape)}")
        elif arrays[name].dtype.kind in "fc" and not np.all(np.isfinite(arrays[name])):
            problems.append(f"array {name!r} has non-finite values")
    if problems:
        from .errors import Problem
        raise InvalidInput([Problem(str(path), "", p) for p in problems])
    return arrays, header.get("meta", {})


def _shape_str(shape: tuple[int | None, ...]) -> str:
    return "(" + ", ".join("n" if s is None else str(s) for s in shape) + (",)" if len(shape) == 1 else ")")


def json_default(obj: Any) -> Any:
    """``json.dumps``' ``default`` for numpy scalars and arrays and paths."""
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, Path):
        return str(obj)
    raise TypeError(f"{type(obj).__name__} is not JSON serialisable")
