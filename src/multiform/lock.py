"""Exclusive locks on the folders and files a command writes (model directories, run folders,
demonstration files), so that a second writer is refused at once instead of losing the first
one's work.

The lock is an advisory ``flock`` on a small file named for the target's absolute path, in a lock
folder of the user's own (never in the user's data folders: a refused command leaves them exactly
as they were); it holds the owner's PID. The kernel releases it when the process ends, however it
ends, so a killed run never leaves a stale lock. A process may take the same lock again while it
holds it (a job that practises in its own model directory). Locks serialise one user's commands on
one machine; a folder shared between machines or users is not covered.

A lock cannot be turned against its user: the lock folder is used only if it is a real folder
(not a symlink) owned by the user with no access for anyone else (``$XDG_RUNTIME_DIR/multiform-locks``,
else ``multiform-locks-UID`` in the temporary directory, else ``~/.cache/multiform/locks``: a
folder another user made first is passed over, never trusted); lock files are opened without
following symlinks and must be regular files of the user's, and the PID is written over the
file's first bytes, never truncating it. This is what the maintained ``filelock`` library does
since CVE-2025-68146 (a symlinked lock file let another user truncate a victim file), plus the
checks on the folder that a lock folder in a shared temporary directory needs.
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import hashlib
import os
import stat
import tempfile
from collections.abc import Iterator
from pathlib import Path

from .errors import InvalidInput

_held: dict[Path, tuple[int, int]] = {}      # lock file -> (fd, depth) held by this process
PID_WIDTH = 20                               # bytes the PID is written in (space-padded): no truncation


def _candidates() -> list[Path]:
    """The lock folders to try, best first."""
    out = []
    runtime = os.environ.get("XDG_RUNTIME_DIR")
    if runtime and os.path.isabs(runtime) and os.path.isdir(runtime):
        out.append(Path(runtime) / "multiform-locks")
    out.append(Path(tempfile.gettempdir()) / f"multiform-locks-{os.geteuid()}")
    cache = os.environ.get("XDG_CACHE_HOME")
    home = Path(cache) if cache and os.path.isabs(cache) else Path.home() / ".cache"
    out.append(home / "multiform" / "locks")
    return out


def _private_folder(folder: Path) -> str:
    """Make ``folder`` (mode 0700) if it is missing; "" if it is the user's own private folder, else
    what is wrong with it."""
    try:
        folder.parent.mkdir(parents=True, exist_ok=True)
        folder.mkdir(mode=0o700)
    except FileExistsError:
        pass
    except OSError as exc:
        return f"cannot be made ({exc.strerror or exc})"
    try:
        st = os.lstat(folder)
    except OSError as exc:
        return f"cannot be read ({exc.strerror or exc})"
    if not stat.S_ISDIR(st.st_mode):
        return "is not a folder (a symlink or a file)"
    if st.st_uid != os.geteuid():
        return f"belongs to another user (uid {st.st_uid})"
    if st.st_mode & 0o077:
        return f"is open to other users (mode {stat.S_IMODE(st.st_mode):o}, must be 700)"
    return ""


def lock_folder() -> Path:
    """The first lock folder that is the user's own, private one (see the module docstring)."""
    refused = []
    for folder in _candidates():
        why = _private_folder(folder)
        if not why:
            return folder
        refused.append(f"{folder} {why}")
    raise InvalidInput("no private folder for the locks of multiform's commands: " + "; ".join(refused),
                       element="locks")


def lock_name(target: str | os.PathLike) -> str:
    """The name of ``target``'s lock file (from its absolute path) in the lock folder."""
    return hashlib.sha256(str(Path(target).resolve()).encode()).hexdigest()[:32] + ".lock"


def lock_file(target: str | os.PathLike) -> Path:
    """The lock file of ``target`` (a folder or a file)."""
    return lock_folder() / lock_name(target)


def _open_lock(path: Path, target: str | os.PathLike) -> int:
    """Open (or create) the lock file without following a symlink; it must be a regular file of the
    user's with one link."""
    try:
        fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_NOFOLLOW | os.O_CLOEXEC, 0o600)
    except OSError as exc:
        why = "is a symlink" if exc.errno == errno.ELOOP else (exc.strerror or str(exc))
        raise InvalidInput(f"its lock file {path} {why}; remove it (no multiform command made it so)",
                           file=str(target)) from None
    st = os.fstat(fd)
    if not stat.S_ISREG(st.st_mode) or st.st_uid != os.geteuid() or st.st_nlink != 1:
        os.close(fd)
        raise InvalidInput(f"its lock file {path} is not a plain file of yours; remove it", file=str(target))
    return fd


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
    fd = _open_lock(path, target)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | (0 if wait else fcntl.LOCK_NB))
    except BlockingIOError:
        owner = os.pread(fd, PID_WIDTH, 0).decode(errors="replace").strip() or "unknown"
        os.close(fd)
        raise InvalidInput(f"in use by PID {owner} (another multiform command is writing it); try again "
                           f"when it has finished", file=str(target)) from None
    os.pwrite(fd, str(os.getpid()).ljust(PID_WIDTH).encode(), 0)
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
