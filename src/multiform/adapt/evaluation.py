"""Evaluation: many seeded trials of one variant of a skill, on several processes, success rates
with Wilson intervals.

A trial is described by plain data (:class:`TrialSpec`) so it crosses process boundaries; each
worker opens the model directory itself. Success is the task's physical check on the trace (the
same check for every variant, so a baseline without a net is judged like the full skill); the
robot's own verdict (net outcome + judges) is kept beside it.
"""

from __future__ import annotations

import multiprocessing as mp
import os
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field
from typing import Any

from ..stats import rate


@dataclass(frozen=True)
class TrialSpec:
    """One evaluation trial: seed, env reset options, and the experimenter's push (if any)."""

    seed: int
    options: dict[str, Any] = field(default_factory=dict)
    push: dict[str, Any] | None = None          # PushInPlace arguments


@dataclass(frozen=True)
class Variant:
    """What runs: a model directory, which net version (None = latest), inverse model or not."""

    name: str
    model_dir: str
    net_version: int | None = None
    use_inverse_model: bool = True
    use_judges: bool = True
    notes: str = ""


_WORKER: dict[str, Any] = {}


def _init(task: str, variant: Variant, env_overrides: dict[str, Any]) -> None:
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    from threadpoolctl import threadpool_limits

    from ..model import SkillModel
    from ..tasks import get_task
    threadpool_limits(1)
    model = SkillModel(variant.model_dir)
    apn = model.history.version(variant.net_version) if variant.net_version is not None else model.apn
    env = model.make_env(**env_overrides)
    _WORKER.update(task=get_task(task), model=model, env=env, apn=apn,
                   executor=model.executor(env, apn, use_inverse_model=variant.use_inverse_model),
                   judges=model.judges() if variant.use_judges else {})


def _run(spec: TrialSpec) -> dict[str, Any]:
    from .perturb import PushInPlace
    w = _WORKER
    push = PushInPlace(**spec.push) if spec.push else None
    trace = w["executor"].run(seed=spec.seed, options=spec.options, perturb=push)
    grade = w["model"].grade(trace, f"eval_{spec.seed}", w["judges"]) if w["judges"] else None
    ok = bool(w["task"].physical_success(trace))
    return {"seed": spec.seed, "success": ok, "outcome": trace.outcome,
            "self_success": bool(trace.success and (grade is None or grade.success)),
            "judge_score": None if grade is None else round(grade.score, 4), "duration": round(trace.duration, 3),
            "pushed": spec.push is not None, "fired": trace.fired(), "wall": round(trace.wall_time, 3),
            "clips": {c: v["count"] for c, v in trace.clips.items()}}


def evaluate(task: str, variant: Variant, trials: Sequence[TrialSpec], workers: int = 2,
             env_overrides: dict[str, Any] | None = None,
             progress: Callable[[int, int], None] | None = None) -> dict[str, Any]:
    """Run ``trials`` of ``variant``; returns the rate (Wilson interval), the robot's self-assessed
    rate, and one record per trial."""
    env_overrides = dict(env_overrides or {})
    results: list[dict[str, Any]] = []
    if workers <= 1:
        _init(task, variant, env_overrides)
        for i, spec in enumerate(trials):
            results.append(_run(spec))
            if progress:
                progress(i + 1, len(trials))
        _WORKER["env"].close()
        _WORKER.clear()
    else:
        ctx = mp.get_context("fork")
        with ProcessPoolExecutor(max_workers=workers, mp_context=ctx, initializer=_init,
                                 initargs=(task, variant, env_overrides)) as pool:
            # one trial per task: a trial takes about a second, its result is small, and larger chunks
            # left a worker idle for a whole chunk at the end of each evaluation
            for i, res in enumerate(pool.map(_run, trials)):
                results.append(res)
                if progress:
                    progress(i + 1, len(trials))
    ok = sum(r["success"] for r in results)
    self_ok = sum(r["self_success"] for r in results)
    agree = sum(r["success"] == r["self_success"] for r in results)
    pushed = [r for r in results if r["pushed"]]
    return {"name": variant.name, "notes": variant.notes, **rate(ok, len(results)),
            "self_assessed": rate(self_ok, len(results)), "agreement": agree / max(1, len(results)),
            "pushed": rate(sum(r["success"] for r in pushed), len(pushed)) if pushed else None,
            "trials_detail": results}
