"""Where independent work runs: a local process pool (fork or spawn), or a Ray cluster.

The core never imports Ray; :func:`ray_backend` loads :mod:`multiform.cluster` only when a Ray
address is given.
"""

from __future__ import annotations

import multiprocessing as mp
import sys
from types import ModuleType

from .errors import InvalidInput

START_METHODS = ("fork", "spawn", "forkserver")


def default_start_method() -> str:
    """``fork`` on Linux (workers start at once and share the parent's imports), else ``spawn``."""
    return "fork" if sys.platform.startswith("linux") else "spawn"


def mp_context(start_method: str | None = None) -> mp.context.BaseContext:
    """The multiprocessing context of a local pool; ``None`` is :func:`default_start_method`."""
    method = start_method or default_start_method()
    if method not in START_METHODS or method not in mp.get_all_start_methods():
        raise InvalidInput(f"unknown or unavailable start method {method!r}; this platform has: "
                           f"{', '.join(mp.get_all_start_methods())}", element="start_method")
    return mp.get_context(method)


def ray_backend() -> ModuleType:
    """:mod:`multiform.cluster` (which imports Ray), or a clear error if Ray is not installed."""
    try:
        from . import cluster
    except ImportError as exc:
        if getattr(exc, "name", "") != "ray":
            raise
        raise InvalidInput("Ray is not installed; pip install 'multiform[ray]'", element="--ray") from None
    return cluster
