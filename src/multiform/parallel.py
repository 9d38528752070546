"""Where independent work runs: a local process pool (fork or spawn) or a Ray cluster, and how many
processes fit a law (:func:`fitting`).

The core never imports Ray; :func:`ray_backend` loads :mod:`multiform.cluster` only when a Ray
address is given.
"""

from __future__ import annotations

import multiprocessing as mp
import os
import sys
from collections.abc import Callable, Hashable
from types import ModuleType
from typing import Any

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


def fitting(workers: int) -> Any:
    """The context in which the laws are fitted with ``workers`` processes (at most this machine's
    cores: with Ray, ``workers`` may count a cluster's): each law's hyperparameter subsets are
    optimised side by side (:class:`~multiform.learn.gp.GPLaw` ``n_jobs``, through joblib's
    :func:`~joblib.parallel_config`). Every fit runs on one BLAS thread wherever it runs, so the laws
    are the same bit for bit with any ``workers``."""
    from joblib import parallel_config
    return parallel_config(n_jobs=max(1, min(workers, os.cpu_count() or 1)))


def ray_backend() -> ModuleType:
    """:mod:`multiform.cluster` (which imports Ray), or a clear error if Ray is not installed."""
    try:
        from . import cluster
    except ImportError as exc:
        if getattr(exc, "name", "") != "ray":
            raise
        raise InvalidInput("Ray is not installed; pip install 'multiform[ray]'", element="--ray") from None
    return cluster


class WorkerState:
    """What a worker process keeps between calls (a task loaded, envs made), set up once per key: in
    a local pool's initializer or a Ray worker's first call with that key. ``setup(*args)`` makes
    the state (a dict), ``close(state)`` ends it when the key changes."""

    def __init__(self, setup: Callable[..., dict[str, Any]], close: Callable[[dict[str, Any]], None]):
        self._setup, self._close = setup, close
        self.key: Hashable | None = None
        self.state: dict[str, Any] = {}

    def ensure(self, key: Hashable, *args: Any) -> dict[str, Any]:
        """The state of ``key``, set up now unless it already is (one BLAS thread per worker: the
        1 kHz loop is single-threaded and the workers are the parallelism)."""
        if self.key != key or not self.state:
            self.clear()
            os.environ.setdefault("OMP_NUM_THREADS", "1")
            from threadpoolctl import threadpool_limits
            threadpool_limits(1)
            self.state = self._setup(*args)
            self.key = key
        return self.state

    def start(self, key: Hashable, *args: Any) -> dict[str, Any]:
        """A pool worker's initializer: set up afresh. What a forked worker inherited from its parent
        is dropped, not closed: it is the parent's to close."""
        self.key, self.state = None, {}
        return self.ensure(key, *args)

    def clear(self) -> None:
        """End the state (its envs closed)."""
        if self.state:
            self._close(self.state)
        self.key, self.state = None, {}


def task_key(task: Any) -> str:
    """How a worker tells tasks apart: a task's spec string, or its name."""
    return task if isinstance(task, str) else str(getattr(task, "TASK", id(task)))
