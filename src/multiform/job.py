"""The main job: from nothing to a report, for one task (``multiform demo pendulum``).

Stages, each timed and each resumable (a finished stage's output on disk is reused):

1. **record** the scripted mentor's demonstrations (``demos.h5``);
2. **train** the skill model from the mentor's definition: GP laws (successful segments only),
   SVM judges (the mentor's labels), place regions, and the auxiliary inverse model (the robot's
   own babbling);
3. **practise** through the task's scenarios; constant failure triggers diagnosis and repair (a task
   whose baselines need only the trained model has their trials run beside practice);
4. **evaluate** the final skill on randomised trials (Wilson interval), and the ablations on the
   same seeds and demonstrations;
5. **report**: nets before/after each revision, plots, videos, ``metrics.json``, ``report.html``.
"""

from __future__ import annotations

import contextlib
import statistics
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field, fields, replace
from pathlib import Path
from typing import Any

from tqdm import tqdm

from .evaluation import Evaluator, Variant
from .demos.dataset import read_dataset, write_dataset
from .demos.episode import Episode
from .teach.kinesthetic import KINESTHETIC, check_kinesthetic
from .teach.record import demo_push, record_by_mentors, record_many
from .errors import InvalidInput, Problem
from .io import write_json
from .lock import exclusive
from .model import SkillModel, staged_model_dir
from .parallel import fitting
from .trainer import train_model
from . import __version__
from .stats import evaluation_split, rate
from .runtime.perturb import TrialSpec
from .task import Task, load_task

Log = Callable[[str], None]


@dataclass
class JobConfig:
    """Sizes of the main job (defaults: the README's `make demo`)."""

    demos: int | None = None         # None: the task's DEMOS
    eval_trials: int = 200
    ablation_trials: int = 50        # the first of the evaluation trials, per ablation: two of the pendulum's four
                                     # never succeed and run to their time limit, so at 100 the ablations took twice
                                     # the robot time of the 200 evaluation trials (about 80 s of the main job)
    practice_max_trials: int = 30    # per repair scenario
    practice_budget: int = 100       # trials of all scenarios together; learning from practice gets the rest
    learn: bool = True               # run the task's scenarios that learn from practice (own experience, the
                                     # mentor's grades and takeovers); False: practice repairs the net only
    workers: int = 2
    seed: int = 0
    push_fraction: float = 0.5
    videos: bool = True
    inverse_model: bool = True
    ray: str | None = None           # record and evaluate as Ray tasks: "auto", "local" or a cluster address
    start_method: str | None = None  # of the local pool (default: fork on Linux)
    mentors: tuple[tuple[str, int], ...] = ()   # the task's named mentors and how many demos each records, in
                                     # order (their counts add up to ``demos``); (): the task's default mentor
    fusion: bool = True              # with several mentors, weigh them by estimated trust; False: pool them
    practice: dict[str, Any] = field(default_factory=dict)   # PracticeConfig fields over every scenario's own,
                                     # e.g. {"deliberate": True, "max_robot_seconds": 900}
    kinesthetic: bool | None = None  # the mentor guides the arm by hand (True) or sends commands (False);
                                     # None: the task's KINESTHETIC
    practice_seed: int | None = None  # the seed of practice's trial draws (scenario i: this + i); None: ``seed``.
                                     # Another value with all else the same shows how much a result owes to
                                     # the trials practice happened to draw


class Job:
    """One run folder for one task."""

    def __init__(self, task: str | Task, out: str | Path, config: JobConfig | None = None,
                 log: Log = print, progress: bool = True, view: str | None = None):
        self.task = load_task(task)
        self.out = Path(out)
        self.cfg = config or JobConfig()
        if self.cfg.demos is None:
            self.cfg = replace(self.cfg, demos=int(sum(n for _, n in self.cfg.mentors) or self.task.DEMOS))
        if self.cfg.kinesthetic is None:
            self.cfg = replace(self.cfg, kinesthetic=bool(getattr(self.task, "KINESTHETIC", False)))
        if self.cfg.mentors:
            for name, _ in self.cfg.mentors:
                self.task.mentor_kwargs(name)             # an unknown mentor is refused before anything runs
            if sum(n for _, n in self.cfg.mentors) != self.cfg.demos:
                raise InvalidInput(f"the mentors' demonstrations {[n for _, n in self.cfg.mentors]} do not add up to "
                                   f"{self.cfg.demos}", element="mentors")
        if self.cfg.practice:
            _check_practice_overrides(self.cfg.practice)
        self.log = log
        self.progress = progress
        self.view = view            # None, or where the picked trials stream (see multiform.view.stream.viewer_url)
        self.timings: dict[str, float] = {}
        self.metrics: dict[str, Any] = {}

    @property
    def _worker_task(self) -> Any:
        """What workers load the task from: its spec if it has one (spawned and Ray workers need
        it), else the task itself (forked workers inherit it)."""
        return self.task.spec or self.task

    def _bar(self, total: int, desc: str, unit: str = "trial", position: int | None = None) -> tqdm:
        return tqdm(total=total, desc=desc, unit=unit, position=position,
                    disable=not self.progress, leave=False, dynamic_ncols=True)

    def _stage(self, name: str, fn: Callable[[], Any]) -> Any:
        t0 = time.perf_counter()
        self.log(f"[{name}] ...")
        out = fn()
        self.timings[f"{name}_s"] = round(time.perf_counter() - t0, 1)
        self.log(f"[{name}] done in {self.timings[f'{name}_s']:.0f} s")
        return out

    # -- 1. demonstrations -----------------------------------------------------------------------
    def record(self) -> Path:
        path = self.out / "demos.h5"
        seeds = [self.cfg.seed * 100_000 + i for i in range(self.cfg.demos)]
        if path.exists():
            try:        # reused only if it is the set this job would record (same seeds, start options, pushes,
                ds = read_dataset(path)     # way of teaching)
                old, teaching = ds.episodes, ds.meta.get("teaching", "")
            except InvalidInput:
                old, teaching = [], ""
            if len(old) == len(seeds) and teaching == self._teaching and all(
                    self._recorded_as_planned(e, s, m) for e, s, m in zip(old, seeds, self._planned_mentors())):
                self.log(f"  reusing {path}")
                return path
        guided = bool(self.cfg.kinesthetic)
        if guided:
            check_kinesthetic(self.task.ENV_ID, self.task.DEMO_ENV_KWARGS, self.task.TASK)
        with self._bar(len(seeds), "recording demos", unit="demo") as bar:
            if self.cfg.mentors:
                eps = record_by_mentors(self._worker_task, seeds, self.cfg.mentors, self.task.DEMO_ENV_KWARGS,
                                        workers=self.cfg.workers, progress=lambda i, n: bar.update(1),
                                        start_method=self.cfg.start_method, ray=self.cfg.ray, kinesthetic=guided)
            else:
                eps = record_many(self._worker_task, seeds, self.task.DEMO_ENV_KWARGS, workers=self.cfg.workers,
                                  progress=lambda i, n: bar.update(1), start_method=self.cfg.start_method,
                                  ray=self.cfg.ray, kinesthetic=guided)
        write_dataset(path, eps, self.task.SKILL, self.task.ENV_ID, self.task.DEMO_ENV_KWARGS, teaching=self._teaching)
        for who in dict.fromkeys(e.mentor for e in eps):
            mine = [e for e in eps if e.mentor == who]
            ok = sum(e.outcome == "success" for e in mine)
            self.log(f"  {len(mine)} demos by {who or 'the mentor'}, who succeeded in {ok} ({100 * ok / len(mine):.0f} %)")
        return path

    @property
    def _teaching(self) -> str:
        """How the mentor teaches in this job: ``"kinesthetic"`` (guiding the arm), else ``""``."""
        return KINESTHETIC if self.cfg.kinesthetic else ""

    def _planned_mentors(self) -> list[str | None]:
        """The name of the mentor each demo is to be recorded by (None: the task's default)."""
        if not self.cfg.mentors:
            return [None] * int(self.cfg.demos or 0)
        return [name for name, n in self.cfg.mentors for _ in range(n)]

    def _recorded_as_planned(self, episode: Episode, seed: int, mentor: str | None = None) -> bool:
        options = dict(episode.reset_options)
        pulses = options.pop("disturbances", None)
        who = self.task.mentor_kwargs(mentor).get("name") if mentor is not None else None
        return (episode.seed == seed and options == self.task.demo_options(seed)
                and (pulses is not None) == (demo_push(self.task, seed) is not None)
                and (who is None or episode.mentor == who))

    # -- 2. training ------------------------------------------------------------------------------
    def train(self, demos: Path) -> SkillModel:
        final = self.out / "model"
        if final.exists():                # trained by an earlier run of this job
            return SkillModel(final)
        # built beside and moved into place when complete; a killed job resumes the partial one
        with staged_model_dir(final, keep_on_error=True) as partial:
            # a task without an inverse-model trainer runs in direct-command mode
            use_inverse = self.cfg.inverse_model and self.task.train_inverse_model is not None
            model = SkillModel.create(partial, self.task.SKILL, demos, self.task.ENV_ID,
                                      self.task.robot_env_kwargs(use_inverse))
            inverse = self.task.train_inverse_model if use_inverse else None
            with fitting(self.cfg.workers):
                train_model(model, seed=self.cfg.seed, log=self.log, inverse_trainer=inverse,
                            beside=self.cfg.workers > 1, fusion=self.cfg.fusion)
        return SkillModel(final)

    # -- 3. practice ------------------------------------------------------------------------------
    @property
    def practice_seed(self) -> int:
        """The seed of the first scenario's practice draws (the next scenarios': one more each)."""
        return self.cfg.seed if self.cfg.practice_seed is None else self.cfg.practice_seed

    def practise(self, model: SkillModel) -> dict[str, Any]:
        results = {}
        used = 0
        for index, sc in enumerate(self.task.scenarios()):
            if sc.learn and not self.cfg.learn:
                continue
            folder = self.out / "practice" / sc.name
            limit = self.cfg.practice_max_trials if not sc.learn else self.cfg.practice_budget - used
            if limit <= 0:
                continue
            graders = tuple(dict.fromkeys(name for name, _ in self.cfg.mentors)) if len(self.cfg.mentors) > 1 else ()
            if self.cfg.practice:
                sc = sc.with_config(self.cfg.practice)
            practice = sc.practice(model, folder, limit, self.practice_seed + index, mentors=graders)
            cfg = practice.config
            with self._bar(cfg.max_trials, f"practice {sc.name}") as bar:
                bar.update(practice.load_state().trial)
                with fitting(self.cfg.workers):
                    state = practice.run(progress=lambda st, tr: bar.update(1))
            used += len(state.trials)
            revs = [r for r in state.revisions if r.operator != "none"]
            first_ok = next((t.trial for t in state.trials if t.success), None)
            results[sc.name] = {
                "title": sc.title, "trials": len(state.trials), "stop_reason": state.stop_reason,
                "successes": sum(t.success for t in state.trials), "first_success_trial": first_ok,
                "revisions": [{"version": r.version, "operator": r.operator, "target": r.target, "reason": r.reason,
                               "after_trial": r.after_trial} for r in revs],
                "outcomes": [t.outcome for t in state.trials], "state": str(folder / "state.json"),
                "robot_seconds": round(sum(t.duration for t in state.trials), 1),
                **(_learning_summary(state) if cfg.learn else {})}
            self.log(f"  {sc.name}: {len(state.trials)} trials, revisions: "
                     + (", ".join(f"{r.operator} {r.target}" for r in revs) or "none")
                     + f"; {state.stop_reason}")
        return results

    # -- 4. evaluation ----------------------------------------------------------------------------
    def _specs(self) -> list[TrialSpec]:
        return self.task.evaluation_specs(self.cfg.eval_trials, self.cfg.seed, self.cfg.push_fraction)

    def baselines(self, model: SkillModel, ev: Evaluator) -> list[tuple[Variant, list, tqdm]]:
        """Build the task's ablations and queue their trials (the first ``ablation_trials`` of the
        evaluation trials) on ``ev``; collected by :meth:`evaluate`. With ``ablation_trials`` 0 there
        are none: no ablation is reported rather than one of zero trials."""
        if not self.cfg.ablation_trials:
            return []
        sub = self._specs()[: self.cfg.ablation_trials]
        queued = []
        for i, variant in enumerate(self.task.ablations(model, self.out, self.cfg)):
            bar = self._bar(len(sub), f"ablation: {variant.name[:30]}", position=1 + i)
            queued.append((variant, ev.submit(variant, sub, lambda bar=bar: bar.update(1)), bar))
        return queued

    def repair_only(self, model: SkillModel, ev: Evaluator) -> list[tuple[Variant, list, tqdm]]:
        """With learning from practice: the skill as the repair scenarios left it (the net and laws
        before learning; the same model directory at that net version), on the ablation trials."""
        if not self.cfg.learn or not self.cfg.ablation_trials:
            return []
        first = self._first_learned(model)
        if first is None:
            return []
        v = first - 1
        sub = self._specs()[: self.cfg.ablation_trials]
        variant = Variant("practice repairs the net only (no learning from practice)", str(model.path), net_version=v,
                          use_inverse_model=self.cfg.inverse_model,
                          notes=f"net version {v} and its laws: no refit from its own experience")
        bar = self._bar(len(sub), "ablation: practice repairs only", position=1)
        return [(variant, ev.submit(variant, sub, lambda: bar.update(1)), bar)]

    def _first_learned(self, model: SkillModel) -> int | None:
        """The first net version a learning scenario recorded (None: learning revised nothing)."""
        learning = {sc.name for sc in self.task.scenarios() if sc.learn}
        return next((r.version for r in model.history.revisions() if r.evidence.get("scenario") in learning), None)

    def evaluate(self, model: SkillModel, ev: Evaluator, queued: list[tuple[Variant, list, tqdm]] | None = None
                 ) -> tuple[dict[str, Any], list[dict[str, Any]]]:
        """The final skill on the evaluation trials, then the ablations (queued now unless
        :meth:`baselines` queued them earlier)."""
        specs = self._specs()
        notes = "the robot's revised net" if model.version else "the mentor's net: practice revised nothing"
        if self.cfg.learn and self._first_learned(model) is None:
            notes += "; learning from practice revised nothing, so it is also the skill practice that repairs only leaves"
        final = Variant("multiform (definition + demonstration + evaluation, with repair)", str(model.path),
                        notes=notes, use_inverse_model=self.cfg.inverse_model)
        with self._bar(len(specs), "evaluating") as bar:
            main = ev.collect(final, ev.submit(final, specs, lambda: bar.update(1)))
        self.log(f"  final success rate {100 * main['rate']:.1f} % ({main['successes']}/{main['trials']}, "
                 f"95 % CI {100 * main['low']:.1f}-{100 * main['high']:.1f} %)")
        rows = [main]
        queued = list(queued if queued is not None else self.baselines(model, ev)) + self.repair_only(model, ev)
        for variant, futures, bar in queued:
            r = ev.collect(variant, futures)
            bar.close()
            rows.append(r)
            self.log(f"  {variant.name}: {100 * r['rate']:.1f} % ({r['successes']}/{r['trials']})")
        return main, rows

    # -- the whole job ----------------------------------------------------------------------------
    def run(self) -> dict[str, Any]:
        """The whole job, holding the run folder's lock (a second job on it is refused). A run folder
        this call made is removed again if the job fails before anything is in it."""
        made = not self.out.exists()
        try:
            self.out.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise InvalidInput(f"cannot create the run folder ({exc.strerror})", file=str(self.out)) from None
        try:
            with exclusive(self.out):
                return self._run()
        except BaseException:
            if made:
                with contextlib.suppress(OSError):
                    self.out.rmdir()          # only if empty: what a failed job made is kept to resume from
            raise

    def _run(self) -> dict[str, Any]:
        t0 = time.perf_counter()
        demos = self._stage("record", self.record)
        model = self._stage("train", lambda: self.train(demos))
        with Evaluator(self._worker_task, self.cfg.workers, start_method=self.cfg.start_method, ray=self.cfg.ray) as ev:
            # baselines built from the trained model alone run while the robot practises, on the
            # core practice leaves idle; the others once practice has revised the net
            early = not self.task.ABLATIONS_AFTER_PRACTICE
            queued = self._stage("baselines", lambda: self.baselines(model, ev)) if early else None
            scenarios = self._stage("practice", lambda: self.practise(model))
            main, rows = self._stage("evaluate", lambda: self.evaluate(model, ev, queued))
        from .report.artifacts import RunSettings, write_artifacts
        ds = read_dataset(demos)
        ok = sum(e.outcome == "success" for e in ds)
        mentor = rate(ok, len(ds))
        self.log(f"  beside: the mentor's own rate over its {len(ds)} demonstrations {100 * mentor['rate']:.1f} % "
                 f"(95 % CI {100 * mentor['low']:.1f}-{100 * mentor['high']:.1f} %)"
                 + "".join(f"; {r['name'].split(' (')[0]} {100 * r['rate']:.1f} % "
                           f"({100 * r['low']:.1f}-{100 * r['high']:.1f} %)" for r in rows[1:]))
        revisions = []
        for name, s in scenarios.items():
            for r in s["revisions"]:
                revisions.append({**r, "scenario": name})
        m = self.metrics
        trust = model.fusion()
        if trust is not None:
            m["mentors"] = {"estimates": trust.table(), "history": trust.history}
        by_mentor = ds.summary()["mentors"]
        m.update(skill=self.task.SKILL, task=self.task.TASK, task_spec=self.task.spec or self.task.TASK, description=self.task.DESCRIPTION,
                 config=asdict(self.cfg), demos={"count": len(ds), "file": "demos.h5", "mentor_success_rate": rate(ok, len(ds)),
                                                 **{k: v for k, v in ds.summary().items() if k in ("samples", "samples_per_transition", "duration_s")},
                                                 **({"mentors": by_mentor} if len(by_mentor) > 1 else {})},
                 training=model.manifest.get("training", {}),
                 practice_trials=sum(s["trials"] for s in scenarios.values()),
                 practice_robot_seconds=round(sum(s["robot_seconds"] for s in scenarios.values()), 1),
                 mentor_labelled_trials=sum(s.get("mentor_labelled_trials", 0) for s in scenarios.values()),
                 scenarios=scenarios, revisions=revisions,
                 success_rate={k: main[k] for k in ("successes", "trials", "rate", "low", "high")},
                 self_assessed=main["self_assessed"], agreement_with_physical_check=main["agreement"],
                 pushed=main["pushed"], target_success_rate=self.task.TARGET_SUCCESS_RATE,
                 version=__version__, net_version=model.version,
                 **{k: v for k, v in evaluation_split(main["trials_detail"]).items() if k != "pushed"},
                 ablation=[{k: r[k] for k in ("name", "notes", "successes", "trials", "rate", "low", "high")} for r in rows])
        # the host's speed beside the stage times: the same job takes 20 % longer in a busy hour
        # of a shared machine, and this median says whether a slow run was a slow host
        per_ms = [1e3 * t["wall"] / t["duration"] for r in rows for t in r["trials_detail"] if t["duration"] > 0]
        if per_ms:
            self.timings["closed_loop_us_per_sim_ms"] = round(float(statistics.median(per_ms)), 1)
        picked = ("success_trial", "recovery_trial") if self.view is not None else ()
        settings = RunSettings(eval_trials=self.cfg.eval_trials, seed=self.cfg.seed, push_fraction=self.cfg.push_fraction,
                               inverse_model=self.cfg.inverse_model, videos=self.cfg.videos)
        self._stage("report", lambda: write_artifacts(self.out, self.task, model, m, main, settings, picked, self.view))
        self.timings["total_s"] = round(time.perf_counter() - t0, 1)
        m["timings"] = dict(self.timings)
        write_json(self.out / "metrics.json", m)
        from .report.page import build_report
        build_report(self.out, m)
        write_json(self.out / "evaluation_trials.json", {r["name"]: r["trials_detail"] for r in rows})
        self.log(f"wrote {self.out / 'report.html'} (total {self.timings['total_s']:.0f} s)")
        return m


def _learning_summary(state: Any) -> dict[str, Any]:
    """What a scenario that learned from practice did: own segments, the mentor's grades and how
    often they agreed with the robot's, plain (not exploring) trials' success, seconds of robot time."""
    plain = state.plain()
    graded = state.mentor_graded
    stays = sum(g.stays for g in graded)
    return {"own_segments": sum(t.own_segments for t in state.trials),
            "mentor_labelled_trials": len({g.trial for g in graded} | {t.trial for t in state.takeovers}),
            "mentor_takeovers": len(state.takeovers),
            "mentor_agreement": {"stays": stays, "agree": sum(g.agree for g in graded),
                                 "rate": round(sum(g.agree for g in graded) / stays, 4) if stays else None},
            "plain_trials": len(plain), "plain_successes": sum(t.success for t in plain),
            "curve": [[t.trial, bool(t.success), bool(t.explored)] for t in state.trials]}


def _check_practice_overrides(overrides: dict[str, Any]) -> None:
    """Refuse practice overrides that are not settings a job may change, or not valid values."""
    from .adapt.practice import PracticeConfig
    own = {"max_trials", "seed"}                    # the job sets these per scenario
    names = {f.name for f in fields(PracticeConfig)} - own
    for key in overrides:
        if key not in names:
            raise InvalidInput(f"not a practice setting a job may change (one of {', '.join(sorted(names))})",
                               element=f"practice.{key}")
    try:
        PracticeConfig(**overrides)
    except InvalidInput as exc:
        raise InvalidInput([Problem(p.file, f"practice.{p.element}", p.message) for p in exc.problems]) from None
