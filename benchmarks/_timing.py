"""Shared timing helpers for the benchmarks: per-call latencies with one BLAS thread."""

from __future__ import annotations

import gc
import time
from collections.abc import Callable

import numpy as np


def latencies(fn: Callable[[], object], calls: int = 10_000, warmup: int = 500, batch: int = 1) -> np.ndarray:
    """Seconds per call of ``fn`` over ``calls`` calls (timed in batches to keep timer overhead out).

    The cyclic garbage collector is paused while timing, as ``timeit`` does and as the executor
    does during a trial (its collection passes are not the law's cost)."""
    for _ in range(warmup):
        fn()
    out = np.empty(calls // batch)
    clock = time.perf_counter
    was = gc.isenabled()
    gc.disable()
    try:
        for i in range(len(out)):
            t0 = clock()
            for _ in range(batch):
                fn()
            out[i] = (clock() - t0) / batch
    finally:
        if was:
            gc.enable()
    return out


def describe(name: str, seconds: np.ndarray, unit: float = 1e-6, unit_name: str = "µs") -> str:
    """``name: median X µs, p99 Y µs (n calls)``."""
    med, p99 = np.median(seconds) / unit, np.percentile(seconds, 99) / unit
    return f"{name}: median {med:.2f} {unit_name}, p99 {p99:.2f} {unit_name} ({len(seconds)} samples)"


def single_thread():
    """Context manager pinning BLAS/OpenMP pools to one thread (the 1 kHz loop runs on one core)."""
    from threadpoolctl import threadpool_limits
    return threadpool_limits(limits=1)
