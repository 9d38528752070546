"""The practice loop: trials from P0, graded by the judges; on constant failure, diagnose and repair.

State is saved after every trial (``state.json`` in the practice folder, written atomically), and
every revision goes to the model's history as soon as it is made, so a killed loop resumes where it
stopped: the trial that was running is run again with the same seed; finished trials, revisions and
learned conditions are kept. Trial seeds are a function of the trial index, so a resumed loop and
an uninterrupted one see the same trials.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Mapping
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from ..io import read_json, write_json
from ..model import ModelLearners, SkillModel
from ..runtime.trace import Trace
from .diagnosis import diagnose
from .repair import repair

STATE_VERSION = 1
Options = Callable[[int], Mapping[str, Any]]
Perturb = Callable[[int], Any]


@dataclass
class PracticeConfig:
    """When practice counts as constant failure, and when it is done.

    Constant failure: ``failures_in_a_row`` failed trials in a row, or (if ``window`` > 0) at least
    ``failure_rate`` of the last ``window`` trials since the last repair. Done: ``success_streak``
    successes in a row, or ``max_trials`` trials.
    """

    failures_in_a_row: int = 3
    window: int = 0
    failure_rate: float = 0.8
    success_streak: int = 5
    max_trials: int = 40
    seed: int = 0
    use_judges: bool = True

    def trial_seed(self, k: int) -> int:
        return 1_000_003 * (self.seed + 1) + k


@dataclass
class PracticeState:
    """What the loop has done so far (``state.json``)."""

    trial: int = 0
    trials: list[dict[str, Any]] = field(default_factory=list)
    revisions: list[dict[str, Any]] = field(default_factory=list)
    failed_since_repair: list[int] = field(default_factory=list)
    lambda_exhausted: list[str] = field(default_factory=list)
    repairs_without_effect: int = 0
    done: bool = False
    stop_reason: str = ""
    format_version: int = STATE_VERSION

    @property
    def streak(self) -> tuple[int, int]:
        """(successes, failures) in a row at the end."""
        s = f = 0
        for tr in reversed(self.trials):
            if tr["success"] and not f:
                s += 1
            elif not tr["success"] and not s:
                f += 1
            else:
                break
        return s, f


class Practice:
    """Runs the loop for one model in ``folder`` (state, failed traces), with trial ``options``
    (reset options per trial index) and an optional ``perturb`` factory (the experimenter's pushes,
    per trial index; see :meth:`multiform.runtime.executor.Executor.run`)."""

    def __init__(self, model: SkillModel, folder: str | Path, config: PracticeConfig | None = None,
                 options: Options | None = None, perturb: Perturb | None = None, name: str = "practice"):
        self.model = model
        self.folder = Path(folder)
        self.config = config or PracticeConfig()
        self.options = options or (lambda k: {})
        self.perturb = perturb
        self.name = name
        self.learners = ModelLearners(model, seed=self.config.seed)

    # -- state -------------------------------------------------------------------------------------
    @property
    def state_path(self) -> Path:
        return self.folder / "state.json"

    def load_state(self) -> PracticeState:
        if not self.state_path.exists():
            return PracticeState()
        d = read_json(self.state_path, "practice state")
        known = PracticeState.__dataclass_fields__
        state = PracticeState(**{k: v for k, v in d.items() if k in known})
        # A revision recorded just before a kill, after the state was last saved: adopt it.
        recorded = self.model.history.revisions()
        mine = {r["version"] for r in state.revisions}
        for r in recorded:
            if r.version not in mine and r.version > max(mine, default=0) and state.trials \
                    and r.time >= state.trials[-1].get("time", ""):
                state.revisions.append({"version": r.version, "operator": r.operator, "target": r.target,
                                        "reason": r.reason, "after_trial": state.trial - 1, "scenario": self.name,
                                        "recovered": True})
                state.failed_since_repair = []
        return state

    def save_state(self, state: PracticeState) -> None:
        write_json(self.state_path, asdict(state))

    def _trace_path(self, k: int) -> Path:
        return self.folder / "traces" / f"trial_{k:04d}.npz"

    # -- the loop ----------------------------------------------------------------------------------
    def run(self, progress: Callable[[PracticeState, dict[str, Any]], None] | None = None,
            stop_after: int | None = None) -> PracticeState:
        """Practise until done (or ``stop_after`` more trials); returns the final state."""
        cfg = self.config
        self.folder.mkdir(parents=True, exist_ok=True)
        state = self.load_state()
        env = self.model.make_env()
        executor, version = None, -1
        judges = self.model.judges() if cfg.use_judges else {}
        ran = 0
        while not state.done:
            if state.trial >= cfg.max_trials:
                state.done, state.stop_reason = True, f"reached {cfg.max_trials} trials"
                break
            if stop_after is not None and ran >= stop_after:
                break
            if self.model.version != version:
                version = self.model.version
                executor = self.model.executor(env)
                judges = self.model.judges() if cfg.use_judges else {}
            k = state.trial
            t0 = time.perf_counter()
            trace = executor.run(seed=cfg.trial_seed(k), options=self.options(k),
                                 perturb=self.perturb(k) if self.perturb else None)
            grade = self.model.grade(trace, f"{self.name}_{k}", judges, apn=executor.apn) if judges else None
            success = trace.success and (grade is None or grade.success)
            summary = {"trial": k, "seed": cfg.trial_seed(k), "net_version": version, "outcome": trace.outcome,
                       "success": bool(success), "judge_score": None if grade is None else round(grade.score, 4),
                       "judge_places": None if grade is None else {p: round(v, 4) for p, v in grade.places.items()},
                       "duration": round(trace.duration, 3), "fired": trace.fired(),
                       "clips": {c: v["count"] for c, v in trace.clips.items()},
                       "wall": round(time.perf_counter() - t0, 3),
                       "time": time.strftime("%Y-%m-%dT%H:%M:%S", time.gmtime())}
            state.trials.append(summary)
            if not success:
                trace.save(self._trace_path(k))
                state.failed_since_repair.append(k)
            state.trial += 1
            ran += 1
            succ, fail = state.streak
            if succ >= cfg.success_streak:
                state.done, state.stop_reason = True, f"{succ} successes in a row"
            elif self._constant_failure(state):
                self._repair(state)
            self.save_state(state)
            if progress:
                progress(state, summary)
        self.save_state(state)
        env.close()
        return state

    def _constant_failure(self, state: PracticeState) -> bool:
        cfg = self.config
        _, fail = state.streak
        if fail >= cfg.failures_in_a_row and len(state.failed_since_repair) >= cfg.failures_in_a_row:
            return True
        if cfg.window > 0:
            since = [t for t in state.trials[-cfg.window:]
                     if t["trial"] >= (state.revisions[-1]["after_trial"] + 1 if state.revisions else 0)]
            if len(since) >= cfg.window:
                rate = sum(not t["success"] for t in since) / len(since)
                return rate >= cfg.failure_rate
        return False

    def _repair(self, state: PracticeState) -> None:
        apn = self.model.apn
        # every failed trial kept so far: those since the last repair are diagnosed; all of them
        # lower the leave floors, so a resumed loop lowers them exactly as an uninterrupted one did
        kept = {k: Trace.load(self._trace_path(k)) for k in range(state.trial) if self._trace_path(k).exists()}
        traces = [kept[k] for k in state.failed_since_repair if k in kept]
        regions = self.model.regions()
        scorer = regions.scores if regions is not None else None
        names = tuple(regions.input_names) if regions is not None else ()
        leave = None
        if regions is not None:
            self.learners.include_own_stays(list(kept.values()))
            leave = {p: float(1.0 / (1.0 + math.exp(-z))) for p, z in self.learners.leave_floors().items()}
        d = diagnose(apn, traces, scorer, names, leave_scores=leave)
        fix = repair(apn, d, self.learners, exhausted=frozenset(state.lambda_exhausted))
        if fix is None:
            state.repairs_without_effect += 1
            state.revisions.append({"version": None, "operator": "none", "target": "", "after_trial": state.trial - 1,
                                    "scenario": self.name, "reason": "constant failure, but no repair operator applies",
                                    "diagnosis": d.to_json()})
            state.failed_since_repair = []
            return
        for rev in fix.revisions:
            v = self.model.history.next_version()
            from dataclasses import replace as _replace
            rev = _replace(rev, version=v)
            self.model.history.record(rev)
            state.revisions.append({"version": v, "operator": rev.operator, "target": rev.target,
                                    "reason": rev.reason, "after_trial": state.trial - 1, "scenario": self.name,
                                    "diagnosis": d.to_json()})
        ops = {r.operator for r in fix.revisions}
        if ops == {"set_lambda"}:
            state.lambda_exhausted = sorted(set(state.lambda_exhausted) | {fix.revisions[0].target}) \
                if any(r["operator"] == "set_lambda" and r["target"] == fix.revisions[0].target
                       for r in state.revisions[:-1]) else state.lambda_exhausted
        else:
            state.lambda_exhausted = []
        state.failed_since_repair = []
