"""Evaluation: many seeded trials of the variants of a skill, on several processes, success rates
with Wilson intervals.

A trial is described by plain data (:class:`TrialSpec`) so it crosses process boundaries; each
worker opens the model directory itself (a local pool's worker reads it from disk, a Ray worker gets
its bytes through the object store, see :mod:`multiform.cluster`), allowing the same env modules
the caller allowed (:attr:`Variant.env_modules`, the command line's ``--env-module``): a forked,
spawned or Ray worker never allows more, nor less. Success is the task's physical
check on the trace (the same check for every variant, so a baseline without a net is judged like
the full skill); the robot's own verdict (net outcome + judges) is kept beside it.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from concurrent.futures import Future, ProcessPoolExecutor
from dataclasses import dataclass
from typing import Any

from .parallel import WorkerState, mp_context, ray_backend, task_key
from .stats import rate
from .runtime.perturb import TrialSpec, run_spec


@dataclass(frozen=True)
class Variant:
    """What runs: a model directory, which net version (None = latest), inverse model or not, and
    the modules its env id may import (``module:Env-v0``; see :class:`~multiform.model.SkillModel`)."""

    name: str
    model_dir: str
    net_version: int | None = None
    use_inverse_model: bool = True
    use_judges: bool = True
    notes: str = ""
    env_modules: tuple[str, ...] = ()


def _setup(task: Any, env_overrides: dict[str, Any]) -> dict[str, Any]:
    from .task import load_task
    return {"task": load_task(task) if isinstance(task, str) else task, "env_overrides": env_overrides,
            "variants": {}}


def _close(state: dict[str, Any]) -> None:
    for v in state["variants"].values():
        v["env"].close()


_WORKER = WorkerState(_setup, _close)


def _init(task: Any, env_overrides: dict[str, Any]) -> None:
    _WORKER.ensure((task_key(task), repr(env_overrides)), task, env_overrides)


def _pool_init(task: Any, env_overrides: dict[str, Any]) -> None:
    _WORKER.start((task_key(task), repr(env_overrides)), task, env_overrides)


def _variant(variant: Variant) -> dict[str, Any]:
    """The worker's model, env and executor of ``variant``, opened on its first trial."""
    w = _WORKER.state
    got = w["variants"].get(variant)
    if got is None:
        from .model import SkillModel
        model = SkillModel(variant.model_dir, env_modules=variant.env_modules)
        apn = model.history.version(variant.net_version) if variant.net_version is not None else model.apn
        env = model.make_env(**w["env_overrides"])
        got = w["variants"][variant] = {
            "model": model, "env": env,
            "executor": model.executor(env, apn, use_inverse_model=variant.use_inverse_model),
            "judges": model.judges() if variant.use_judges else {}}
    return got


def _run(variant: Variant, spec: TrialSpec) -> dict[str, Any]:
    w = _variant(variant)
    trace, _ = run_spec(w["executor"], spec)
    grade = (w["model"].grade(trace, f"eval_{spec.seed}", w["judges"], apn=w["executor"].apn)
             if w["judges"] else None)
    ok = bool(_WORKER.state["task"].physical_success(trace))
    return {"seed": spec.seed, "success": ok, "outcome": trace.outcome,
            "self_success": bool(trace.success and (grade is None or grade.success)),
            "judge_score": None if grade is None else round(grade.score, 4), "duration": round(trace.duration, 3),
            "pushed": spec.push is not None, "fired": trace.fired(), "wall": round(trace.wall_time, 3),
            "clips": {c: v["count"] for c, v in trace.clips.items()}, "trace_digest": _digest(trace),
            **({"fault": trace.fault} if trace.fault else {})}


def trial_in_worker(task: str, env_overrides: dict[str, Any], variant: Variant, spec: TrialSpec) -> dict[str, Any]:
    """One evaluation trial in a worker that may run many (a Ray worker): set up for ``task`` unless
    it already is, then the trial's record."""
    _init(task, env_overrides)
    return _run(variant, spec)


def _digest(trace: Any) -> str:
    """The trial's fingerprint: SHA-256 (first 16 hex digits) of what the robot sensed, commanded
    and marked, tick by tick (equal digests: the same trial, wherever it ran)."""
    import hashlib
    h = hashlib.sha256()
    for a in (trace.obs, trace.commands, trace.marking):
        h.update(a.tobytes())
    return h.hexdigest()[:16]


def summarise(variant: Variant, results: Sequence[dict[str, Any]]) -> dict[str, Any]:
    """The rate (Wilson interval), the robot's self-assessed rate, and the trial records of ``variant``."""
    results = list(results)
    ok = sum(r["success"] for r in results)
    self_ok = sum(r["self_success"] for r in results)
    agree = sum(r["success"] == r["self_success"] for r in results)
    pushed = [r for r in results if r["pushed"]]
    return {"name": variant.name, "notes": variant.notes, **rate(ok, len(results)),
            "self_assessed": rate(self_ok, len(results)), "agreement": agree / max(1, len(results)),
            "pushed": rate(sum(r["success"] for r in pushed), len(pushed)) if pushed else None,
            "faults": sum(r["outcome"] == "fault" for r in results), "trials_detail": results}


class Evaluator:
    """Worker processes that run the trials of any number of variants; trials are queued in the order
    submitted. A job submits the trials it can before it has everything (the baselines' while the
    robot still practises, on the core practice leaves idle) and collects them when it needs them.

    ``task`` is a :class:`~multiform.task.Task` or its name (:func:`~multiform.task.load_task`); a
    task defined in memory reaches forked workers, while spawned and Ray workers need its name. Use
    as a context manager; ``workers`` ≤ 1 runs each trial in this process when collected.
    ``start_method`` is the local pool's (default: fork on Linux, spawn elsewhere). With ``ray``
    (``auto``, ``local`` or a cluster address) the trials are Ray tasks instead, on every CPU of
    the cluster (``local`` starts one with ``workers`` CPUs); the records are the same.
    """

    def __init__(self, task: Any, workers: int = 2, env_overrides: dict[str, Any] | None = None,
                 start_method: str | None = None, ray: str | None = None):
        self.task, self.workers = task, workers
        self.env_overrides = dict(env_overrides or {})
        self._pool: ProcessPoolExecutor | None = None
        self._ray: Any = None
        if ray:
            self._ray = ray_backend().RayTrials(trial_in_worker, task, self.env_overrides, ray,
                                                num_cpus=max(1, workers))
        elif workers > 1:
            self._pool = ProcessPoolExecutor(max_workers=workers, mp_context=mp_context(start_method),
                                             initializer=_pool_init, initargs=(task, self.env_overrides))

    def submit(self, variant: Variant, trials: Sequence[TrialSpec],
               progress: Callable[[], None] | None = None) -> list[Future | _Deferred]:
        """Queue ``trials`` of ``variant``; ``progress`` is called (from a pool thread) as each ends.
        Returns one handle per trial, with ``result()``."""
        if self._ray is not None:
            futures = self._ray.submit(variant, trials)
        elif self._pool is None:
            return [_Deferred(self, variant, spec, progress) for spec in trials]
        else:
            futures = [self._pool.submit(_run, variant, spec) for spec in trials]
        if progress is not None:
            for f in futures:
                f.add_done_callback(lambda _f: progress())
        return futures

    def collect(self, variant: Variant, futures: Sequence[Future | _Deferred]) -> dict[str, Any]:
        """Wait for ``futures`` (from :meth:`submit`) and summarise them."""
        return summarise(variant, [f.result() for f in futures])

    def _run_here(self, variant: Variant, spec: TrialSpec) -> dict[str, Any]:
        _init(self.task, self.env_overrides)
        return _run(variant, spec)

    def close(self) -> None:
        if self._ray is not None:
            self._ray.close()
            self._ray = None
        elif self._pool is not None:
            self._pool.shutdown(wait=True, cancel_futures=True)
            self._pool = None
        else:
            _WORKER.clear()

    def __enter__(self) -> Evaluator:
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()


class _Deferred:
    """A trial of a one-process evaluation: run when its result is asked for."""

    def __init__(self, ev: Evaluator, variant: Variant, spec: TrialSpec, progress: Callable[[], None] | None):
        self._args = (ev, variant, spec)
        self._progress = progress

    def result(self) -> dict[str, Any]:
        ev, variant, spec = self._args
        out = ev._run_here(variant, spec)
        if self._progress is not None:
            self._progress()
        return out


def evaluate(task: Any, variant: Variant, trials: Sequence[TrialSpec], workers: int = 2,
             env_overrides: dict[str, Any] | None = None,
             progress: Callable[[int, int], None] | None = None,
             start_method: str | None = None, ray: str | None = None) -> dict[str, Any]:
    """Run ``trials`` of ``variant`` (where: see :class:`Evaluator`); returns the rate (Wilson
    interval), the robot's self-assessed rate, and one record per trial."""
    done = [0]

    def tick() -> None:
        done[0] += 1
        if progress:
            progress(done[0], len(trials))

    with Evaluator(task, workers, env_overrides, start_method=start_method, ray=ray) as ev:
        return ev.collect(variant, ev.submit(variant, trials, tick))
