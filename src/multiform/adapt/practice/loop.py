"""The practice loop: trials from P0, graded by the judges, and after each trial what is due —
a watched revision judged, a repair on constant failure, a refit, the floor exam, the stop.

State is saved after every trial (``state.json`` in the practice folder, written atomically), and
every revision goes to the model's history as soon as it is made, so a killed loop resumes where it
stopped: the trial that was running is run again with the same seed; finished trials, revisions and
learned conditions are kept. Trial seeds are a function of the trial index, so a resumed loop and
an uninterrupted one see the same trials.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

from ...errors import InvalidInput
from ...io import read_json, write_json
from ...lock import exclusive
from ...model import SkillModel
from ..learners import ModelLearners
from ...runtime.executor import Executor
from ...runtime.trace import Trace
from ..diagnosis import is_evidence
from ..experience import Experience
from ..explore import ExploringLaw, law_noise
from .config import EXPLORE_TAU, PracticeConfig
from .context import Context
from .floors import FloorExam
from .learning import Learning, MentorGrader, TakeoverFn
from .ranges import RangeExam, switch_states
from .repairs import Repairs
from .state import PracticeState, RevisionRecord, TrialRecord, state_from_json, state_to_json
from .switches import SwitchExam
from .watch import RevisionWatch

Options = Callable[[int], Mapping[str, Any]]
Perturb = Callable[[int], Any]
Observe = Callable[[int, Executor], Any]


class Practice:
    """Runs the loop for one model in ``folder`` (state, failed traces), with trial ``options``
    (reset options per trial seed, as evaluation draws them from a task's ``trial_options``), an
    optional ``perturb`` factory (the experimenter's pushes, per trial index; see
    :meth:`multiform.runtime.executor.Executor.run`) and, for learning from practice, the
    ``mentor``'s grader of a trial and its ``takeover`` of a failed one (:class:`~.learning.Learning`).
    Its parts: :attr:`repairs`, :attr:`watch`, :attr:`learning`, :attr:`floors`, :attr:`switches`,
    :attr:`ranges`."""

    def __init__(self, model: SkillModel, folder: str | Path, config: PracticeConfig | None = None,
                 options: Options | None = None, perturb: Perturb | None = None, name: str = "practice",
                 mentor: MentorGrader | None = None, observe: Observe | None = None,
                 takeover: TakeoverFn | None = None, push: Perturb | None = None):
        self.model = model
        self.folder = Path(folder)
        self.config = config or PracticeConfig()
        self.options = options or (lambda k: {})
        self.perturb = perturb
        self.push = push                # draw -> the experimenter's push, whether scheduled or not (deliberate practice)
        self.name = name
        self.observe = observe          # trial index, executor -> an executor observer (e.g. the live view) or None
        self.ctx = Context(model, self.config, name, ModelLearners(model, seed=self.config.seed),
                           Experience(model.path))
        self.watch = RevisionWatch(self.ctx)
        self.repairs = Repairs(self.ctx, self.watch, self.trace_path)
        self.learning = Learning(self.ctx, self.watch, mentor, takeover)
        self.floors = FloorExam(self.ctx, self.watch)
        self.switches = SwitchExam(self.ctx, self.watch)
        self.ranges = RangeExam(self.ctx, self.watch)

    # -- state -------------------------------------------------------------------------------------
    @property
    def state_path(self) -> Path:
        return self.folder / "state.json"

    def load_state(self) -> PracticeState:
        """The saved state (a fresh one if none), with any revision this scenario recorded just
        before a kill, after the state was last saved (a finished scenario adopts nothing, and no
        scenario adopts another's revisions)."""
        if not self.state_path.exists():
            return PracticeState()
        state = state_from_json(read_json(self.state_path, "practice state"), str(self.state_path))
        mine = {r.version for r in state.revisions if r.version is not None}
        for r in self.model.history.revisions():
            if state.done or r.evidence.get("scenario", self.name) != self.name:
                continue
            if r.version not in mine and r.version > max(mine, default=0) and state.trials \
                    and r.time >= state.trials[-1].time:
                state.revisions.append(RevisionRecord(version=r.version, operator=r.operator, target=r.target,
                                                      reason=r.reason, after_trial=state.trial - 1,
                                                      scenario=self.name, recovered=True))
                state.failed_since_repair = []
        return state

    def check_draws(self, state: PracticeState) -> None:
        """Refuse a saved state whose trials were drawn from another seed: resumed, it would stand for
        draws this practice never ran."""
        first = state.trials[0] if state.trials else None
        if first is not None and first.seed != self.config.trial_seed(first.drawn):
            raise InvalidInput(f"was practised on other draws (its first trial's seed {first.seed}, this practice's "
                               f"{self.config.trial_seed(first.drawn)}: another seed); practise in a new folder",
                               file=str(self.state_path), element="trials[0].seed")

    def save_state(self, state: PracticeState) -> None:
        write_json(self.state_path, state_to_json(state))

    def trace_path(self, k: int) -> Path:
        """Where failed trial ``k``'s trace is kept (the evidence of a later diagnosis)."""
        return self.folder / "traces" / f"trial_{k:04d}.npz"

    # -- the loop ----------------------------------------------------------------------------------
    def run(self, progress: Callable[[PracticeState, TrialRecord], None] | None = None,
            stop_after: int | None = None) -> PracticeState:
        """Practise until done (or ``stop_after`` more trials); returns the final state.

        Holds the model directory's lock throughout, and checks the model before the first trial."""
        with exclusive(self.model.path):
            self.model.verify()
            return self._run(progress, stop_after)

    def _run(self, progress: Callable[[PracticeState, TrialRecord], None] | None,
             stop_after: int | None) -> PracticeState:
        cfg = self.config
        self.folder.mkdir(parents=True, exist_ok=True)
        state = self.load_state()
        self.check_draws(state)
        env = self.model.make_env()
        executor, explorer, version = None, None, -1
        judges = self.model.judges()
        if cfg.check_demonstrations and state.trial == 0 and not state.checked:
            self.repairs.check_definition(state)
            self.save_state(state)
        ran = 0
        while not state.done:
            if state.trial >= cfg.max_trials:
                state.done, state.stop_reason = True, f"reached {cfg.max_trials} trials"
                break
            if cfg.max_robot_seconds and state.robot_seconds() >= cfg.max_robot_seconds:
                state.done, state.stop_reason = True, f"used {state.robot_seconds():.0f} s of robot time"
                break
            if stop_after is not None and ran >= stop_after:
                break
            if self.model.version != version:
                version = self.model.version
                executor = self.model.executor(env)
                explorer = self._explorer(executor) if cfg.explore > 0 else None
                judges = self.model.judges()
            k = state.trial
            t0 = time.perf_counter()
            trace, draw, explores, pushed, view = self._trial(state, executor, explorer)
            if trace.outcome == "fault":
                # a non-finite value is the model's or the simulator's fault, not the skill's: nothing
                # is learned or repaired from it, and practice stops until someone looks
                trace.save(self.folder / "faults" / f"trial_{k:04d}.npz")
                state.stop_reason = f"fault in trial {k}: {trace.fault}; nothing was learned from it"
                break
            grade = self.model.grade(trace, self.ctx.source(k), judges, apn=executor.apn) if judges else None
            success = trace.success and (grade is None or grade.success)
            if view is not None:
                if grade is not None:
                    view.grade(grade, success)
                view.close()
            record = self._record(k, draw, version, trace, grade, success, explores, t0)
            record.pushed = pushed
            record.switch_states = switch_states(executor.apn, trace,
                                                 {t.id for t in executor.apn.transitions if t.condition.is_learned})
            if cfg.learn and grade is not None:
                self.learning.learn_from(state, record, trace, grade, executor.apn)
                if record.mentor is not None and record.mentor.revised is not None:
                    judges = self.model.judges()
            state.trials.append(record)
            if not success and is_evidence(trace.outcome):
                trace.save(self.trace_path(k))
                state.failed_since_repair.append(k)
            state.trial += 1
            ran += 1
            self.after_trial(state)
            self.save_state(state)
            if progress:
                progress(state, record)
        self.save_state(state)
        env.close()
        return state

    def _trial(self, state: PracticeState, executor: Executor, explorer: Executor | None
               ) -> tuple[Trace, int, bool, bool, Any]:
        """Run trial ``state.trial`` on its own draw, or on the draw an exam replays; exploring when
        due and not replaying. Returns its trace, the draw, whether it explored, whether it was
        pushed, and its view (or None)."""
        cfg = self.config
        k = state.trial
        draw = self.watch.exam_draw(state)
        explores = explorer is not None and cfg.explores(k) and draw is None
        draw = k if draw is None else draw
        runner = executor
        if explores:
            for i, law in enumerate(sorted(explorer.laws)):
                explorer.laws[law].reseed(cfg.trial_seed(k) * 31 + i)
            runner = explorer
        view = self.observe(k, executor) if self.observe else None
        perturb = self.perturbation(state, draw, explores)
        seed = cfg.trial_seed(draw)
        trace = runner.run(seed=seed, options=self.options(seed), perturb=perturb, observer=view)
        return trace, draw, explores, perturb is not None, view

    def perturbation(self, state: PracticeState, draw: int, explores: bool) -> Any:
        """The experimenter's push in this trial: the scenario's (the evaluation's mix) on a plain
        trial; with ``deliberate``, on an exploring one wherever the robot is weaker: pushed if its
        plain trials fail more often pushed than not (Laplace estimates of the last
        ``target_window`` of each), not pushed if the other way round, as scheduled on a tie."""
        scheduled = self.perturb(draw) if self.perturb else None
        if not (explores and self.config.deliberate and self.push is not None):
            return scheduled
        n = self.config.target_window
        rates = {}
        for pushed in (True, False):
            last = [t.success for t in state.plain() if t.pushed == pushed][-n:]
            rates[pushed] = (sum(last) + 1) / (len(last) + 2)
        if rates[True] == rates[False]:
            return scheduled
        return self.push(draw) if rates[True] < rates[False] else None

    def _record(self, k: int, draw: int, version: int, trace: Trace, grade: Any, success: bool, explores: bool,
                t0: float) -> TrialRecord:
        """Trial ``k``'s record, run on the draw (seed, start, push) of trial ``draw``."""
        return TrialRecord(
            trial=k, seed=self.config.trial_seed(draw), net_version=version, outcome=trace.outcome,
            success=bool(success), judge_score=None if grade is None else round(grade.score, 4),
            judge_places=None if grade is None else {p: round(v, 4) for p, v in grade.places.items()},
            duration=round(trace.duration, 3), fired=trace.fired(),
            clips={c: v["count"] for c, v in trace.clips.items()}, wall=round(time.perf_counter() - t0, 3),
            time=time.strftime("%Y-%m-%dT%H:%M:%S", time.gmtime()), evidence=is_evidence(trace.outcome),
            explored=explores, draw=None if draw == k else draw)

    def after_trial(self, state: PracticeState) -> None:
        """After a trial: judge a watched revision; stop on a success streak or the target rate (after
        the ways back's floor exam, if due); repair on constant failure; refit the laws when due;
        examine the ways back's floor once no room is left for another revision."""
        cfg = self.config
        succ, _ = state.streak
        if cfg.learn:
            self.watch.check(state)
        if state.done:                  # the floor exam that ended practice
            return
        if cfg.stops_on_streak(succ):
            state.done, state.stop_reason = True, f"{succ} successes in a row"
        elif self.reached_target(state):
            reason = (f"own success rate {state.plain_rate(cfg.target_window):.2f} over the last "
                      f"{cfg.target_window} plain trials")
            if not self.floors.examine(state, then_stop=reason):
                state.done, state.stop_reason = True, reason
        elif self.repairs.constant_failure(state) and not (state.watch is not None and state.watch.must_win):
            self.repairs.repair(state)
        if not state.done and self.learning.refit_due(state):
            if not (self.learning.falls_short(state)
                    and (self.switches.examine(state) or self.ranges.examine(state))):
                self.learning.refit(state)
        if not state.done and state.watch is None and cfg.max_trials - state.trial <= cfg.watch_trials():
            self.floors.examine(state)

    def reached_target(self, state: PracticeState) -> bool:
        """The last ``target_window`` plain trials, all of the net as it is now, reach the target (a
        window reaching back before a refit would credit the new laws with the old ones' successes)."""
        cfg = self.config
        return cfg.target_rate > 0 and len(state.plain_of(self.model.version)) >= cfg.target_window \
            and state.plain_rate(cfg.target_window) >= cfg.target_rate

    def _explorer(self, executor: Executor) -> Executor:
        """An executor of the same net whose laws explore (reseeded per trial)."""
        laws = {name: ExploringLaw(law, self.config.explore * law_noise(law), EXPLORE_TAU, executor.dt, 0)
                for name, law in executor.laws.items()}
        return Executor(executor.apn, executor.env, laws, self.model.conditions(), executor.inverse_model,
                        net_version=executor.net_version)
