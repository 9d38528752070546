"""Atomic, pickle-free persistence: JSON, JSON lines and ``.npz`` arrays with a versioned header.

Every saved artifact goes through here so that (1) a crash never leaves a half-written file — we
write a temporary file in the same directory and ``os.replace`` it — and (2) nothing saved can run
code when loaded: arrays are read with ``allow_pickle=False`` and metadata is plain JSON. An error
while writing (a full disk) names the file being written, never the temporary one.

Reading is bounded: :func:`read_bytes` reads regular files only (a FIFO or a device named where a
file is expected would block or never end) up to a size cap, and JSON nested too deeply is an
:class:`~multiform.errors.InvalidInput` naming the file.
"""

from __future__ import annotations

import contextlib
import io
import json
import math
import os
import stat
import tempfile
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from .errors import InvalidInput, MissingInput

FORMAT_KEY = "__format__"
MAX_READ_BYTES = 256 << 20        # a JSON, YAML or text file read whole: far above any this library writes
MAX_NESTING = 64                  # lists and mappings in plain data (options, env arguments)
MAX_MAGNITUDE = 1e12              # a number entering from a file: far beyond any physical quantity in SI units


def _naming(exc: OSError, tmp: Path | None, path: Path) -> OSError:
    """``exc`` naming ``path`` if it named nothing or only the temporary file ``tmp``."""
    if exc.filename is None or (tmp is not None and str(exc.filename) == str(tmp)):
        return OSError(exc.errno, exc.strerror or str(exc), str(path))
    return exc


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike, suffix: str = "") -> Iterator[Path]:
    """Yield a temporary path beside ``path``; on success it replaces ``path``, on error it vanishes
    with the folders made for it.

    An :class:`OSError` (a full disk, a quota) names ``path``, the file the caller asked for."""
    path = Path(path)
    tmp_path: Path | None = None
    made = [d for d in (path.parent, *path.parent.parents) if not d.exists()]     # folders this write makes
    done = False
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=suffix or ".tmp", dir=path.parent)
        tmp_path = Path(tmp)
        os.close(fd)
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)          # mkstemp makes 0600; a saved artifact gets the usual mode
        yield tmp_path
        os.replace(tmp_path, path)
        done = True
    except OSError as exc:
        new = _naming(exc, tmp_path, path)
        if new is exc:
            raise
        raise new from exc
    finally:
        if tmp_path is not None and tmp_path.exists():
            tmp_path.unlink()
        if not done:                 # a failed write leaves no folder it made behind
            for d in made:
                with contextlib.suppress(OSError):
                    d.rmdir()


def write_bytes(path: str | os.PathLike, data: bytes) -> None:
    """Write ``data`` to ``path`` atomically, flushed to the disk before it replaces ``path``."""
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())


@contextlib.contextmanager
def memory_file(path: str | os.PathLike) -> Iterator[io.BytesIO]:
    """A file built in memory (a binary buffer; ``h5py.File(buffer, "w")`` takes it) and written
    to ``path`` atomically when the block ends without error.

    HDF5 writes much of its file at ``close``; on a full disk h5py's close fails inside a destructor
    and the process may crash with nothing saved or cleaned up. Built in memory, the file reaches the
    disk through one plain write, whose error (a full disk: :class:`OSError` naming ``path``) leaves
    no partial file behind."""
    buffer = io.BytesIO()
    yield buffer
    write_bytes(path, buffer.getbuffer())


def read_bytes(path: str | os.PathLike, what: str = "file", limit: int = MAX_READ_BYTES) -> bytes:
    """The whole of a regular file of at most ``limit`` bytes; anything else (missing, a folder, a
    FIFO or device, too large, unreadable) is an :class:`InvalidInput` naming the file."""
    path = Path(path)
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_CLOEXEC", 0))
    except FileNotFoundError:
        raise MissingInput(f"{what} not found", file=str(path)) from None
    except OSError as exc:
        raise InvalidInput(f"cannot read it ({exc.strerror or exc})", file=str(path)) from None
    try:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode):
            kind = "a folder" if stat.S_ISDIR(st.st_mode) else "not a regular file (a FIFO, socket or device)"
            raise InvalidInput(f"is {kind}; expected a {what}", file=str(path))
        if st.st_size > limit:
            raise InvalidInput(f"is {st.st_size} bytes; a {what} is at most {limit}", file=str(path))
        with os.fdopen(fd, "rb", closefd=False) as fh:
            data = fh.read(limit + 1)
    except OSError as exc:
        raise InvalidInput(f"cannot read it ({exc.strerror or exc})", file=str(path)) from None
    finally:
        os.close(fd)
    if len(data) > limit:
        raise InvalidInput(f"grew beyond {limit} bytes while read", file=str(path))
    return data


def check_regular_file(path: str | os.PathLike, what: str = "file") -> Path:
    """``path`` if it names a regular file; a missing file, a folder, a FIFO or a device is an
    :class:`InvalidInput` (a reader given a FIFO would wait for a writer for ever)."""
    path = Path(path)
    try:
        st = os.stat(path)
    except FileNotFoundError:
        raise InvalidInput(f"{what} not found", file=str(path)) from None
    except OSError as exc:
        raise InvalidInput(f"cannot read it ({exc.strerror or exc})", file=str(path)) from None
    if not stat.S_ISREG(st.st_mode):
        kind = "a folder" if stat.S_ISDIR(st.st_mode) else "not a regular file (a FIFO, socket or device)"
        raise InvalidInput(f"is {kind}; expected a {what}", file=str(path))
    return path


def plain_data_problems(value: Any, element: str = "", max_depth: int = MAX_NESTING,
                        magnitude: float = MAX_MAGNITUDE) -> list[tuple[str, str]]:
    """What makes ``value`` (JSON-like data from a file: options, env arguments) unfit to use:
    nesting deeper than ``max_depth``, numbers not finite or above ``magnitude``, keys that are not
    text. Returns ``(element, message)`` pairs (at most 10), without recursion."""
    out: list[tuple[str, str]] = []
    stack: list[tuple[Any, str, int]] = [(value, element, 0)]
    while stack and len(out) < 10:
        v, where, depth = stack.pop()
        if depth > max_depth:
            out.append((where, f"nested more than {max_depth} levels deep"))
            continue
        if isinstance(v, bool) or v is None or isinstance(v, str):
            continue
        if isinstance(v, (int, float)):
            if (isinstance(v, float) and not math.isfinite(v)) or abs(v) > magnitude:
                out.append((where, f"number {_short(v)} is out of range (finite, at most {magnitude:g} in size)"))
        elif isinstance(v, Mapping):
            for k, x in v.items():
                if not isinstance(k, str):
                    out.append((where, f"key {_short(k)} is not text"))
                stack.append((x, f"{where}.{k}" if where else str(k), depth + 1))
        elif isinstance(v, (list, tuple)):
            stack.extend((x, f"{where}[{i}]", depth + 1) for i, x in enumerate(v))
        else:
            out.append((where, f"a {type(v).__name__} is not plain data"))
    return out


def _short(v: Any) -> str:
    if isinstance(v, int) and abs(v).bit_length() > 128:
        return f"a number of about {int(abs(v).bit_length() * 0.30103) + 1} digits"
    text = repr(v)
    return text if len(text) <= 40 else f"{text[:30]}...({len(text)} characters)"


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
    """Read JSON (a regular file, size-capped), turning every reading and decoding error into
    :class:`InvalidInput` naming the file."""
    path = Path(path)
    return loads_json(read_bytes(path, what), str(path))


def loads_json(data: bytes | str, file: str, element: str = "") -> Any:
    """JSON text from ``file`` decoded; bad JSON, bad UTF-8 and nesting too deep to decode are
    :class:`InvalidInput` naming the file (and ``element``)."""
    try:
        return json.loads(data)
    except ValueError as exc:           # bad JSON or UTF-8, a number of more digits than Python converts
        raise InvalidInput(f"not valid JSON ({str(exc)[:200]})", file=file, element=element) from None
    except RecursionError:
        raise InvalidInput("not valid here: lists or objects nested too deeply", file=file, element=element) from None


def read_jsonl(path: str | os.PathLike) -> list[dict[str, Any]]:
    """Read a JSON-lines file; a bad line is reported with its line number."""
    path = Path(path)
    try:
        text = read_bytes(path, "JSON-lines file").decode("utf-8")
    except UnicodeDecodeError as exc:
        raise InvalidInput(f"not valid UTF-8 ({exc})", file=str(path)) from None
    out = []
    for i, line in enumerate(text.splitlines(), 1):
        if line.strip():
            out.append(loads_json(line, str(path), f"line {i}"))
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
