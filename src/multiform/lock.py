"""Exclusive locks on the folders and files a command writes (model directories, run folders,
demonstration files), so that a second writer is refused at once instead of losing the first
one's work.

The lock is an advisory ``flock`` on a small file named for the target's absolute path, in a
per-user folder of the machine's temporary directory (never in the user's folders: a refused
command leaves them exactly as they were); it holds the owner's PID. The kernel releases it when
the process ends, however it ends, so a killed run never leaves a stale lock. A process may take
the same lock again while it holds it (a job that practises in its own model directory). Locks
serialise commands on one machine; a folder shared between machines is not covered.
"""

from __future__ import annotations

import contextlib
import fcntl
import hashlib
import os
import tempfile
from collections.abc import Iterator
from pathlib import Path

from .errors import InvalidInput

_held: dict[Path, tuple[int, int]] = {}      # lock file -> (fd, depth) held by this process


def lock_file(target: str | os.PathLike) -> Path:
    """The lock file of ``target`` (a folder or a file, by its absolute path)."""
    key = hashlib.sha256(str(Path(target).resolve()).encode()).hexdigest()[:32]
    folder = Path(tempfile.gettempdir()) / f"multiform-locks-{os.getuid()}"
    folder.mkdir(mode=0o700, exist_ok=True)
    return folder / f"{key}.lock"


@contextlib.contextmanager
def exclusive(target: str | os.PathLike, wait: bool = False) -> Iterator[None]:
    """Hold the exclusive lock of ``target`` (a folder or a file) for the ``with`` block.

    Raises :class:`InvalidInput` naming ``target`` and the PID that holds it when another process
    does (or, with ``wait``, waits for it).
    """
    path = lock_file(target)
    if path in _held:
        fd, depth = _held[path]
        _held[path] = (fd, depth + 1)
        try:
            yield
        finally:
            fd, depth = _held[path]
            _held[path] = (fd, depth - 1)
        return
    fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o600)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | (0 if wait else fcntl.LOCK_NB))
    except BlockingIOError:
        owner = os.pread(fd, 32, 0).decode(errors="replace").strip() or "unknown"
        os.close(fd)
        raise InvalidInput(f"in use by PID {owner} (another multiform command is writing it); try again "
                           f"when it has finished", file=str(target)) from None
    os.ftruncate(fd, 0)
    os.pwrite(fd, str(os.getpid()).encode(), 0)
    _held[path] = (fd, 1)
    try:
        yield
    finally:
        fd, depth = _held[path]
        if depth > 1:
            _held[path] = (fd, depth - 1)
        else:
            del _held[path]
            fcntl.flock(fd, fcntl.LOCK_UN)
            os.close(fd)


def check_writable(path: str | os.PathLike) -> None:
    """Refuse early (before any work) a file whose folder does not exist or cannot be written."""
    path = Path(path)
    parent = path.parent if str(path.parent) else Path(".")
    if not parent.is_dir():
        raise InvalidInput(f"its folder {parent} does not exist", file=str(path))
    if not os.access(parent, os.W_OK | os.X_OK) or (path.exists() and not os.access(path, os.W_OK)):
        raise InvalidInput("cannot write here (permission denied)", file=str(path))
