"""The practice loop: trials from P0, graded by the judges; on constant failure, diagnose and repair.

Before the first trial the definition is held against the mentor's demonstrations (with
``check_demonstrations``): a give-up rule that would have ended the mentor's own successful stays is
moved (:mod:`.replay`), a recorded revision, so a limit that ends only some trials, and so never
makes practice fail constantly, does not stay.

A repair is on trial until the next constant failure: if no trial since it succeeded and none
reached a place the failed trials before it never reached, it did not help — the net goes back to
the version before it (a ``revert`` revision) and the next candidate the diagnosis supports is
tried; a candidate is never tried twice under the same laws. Trials that ended for a reason outside
the net (a fault, a diverged simulation; see :data:`~.diagnosis.EVIDENCE_OUTCOMES`) are recorded
but are no evidence: they neither count as failures nor enter a diagnosis.

With ``learn`` (learning from practice, the paper's third form in full) the loop also
* keeps the stays it grades successful with a margin as the laws' own training data
  (:mod:`.experience`) and refits the laws from the mentor's and its own data every
  ``refit_every`` trials (a ``refit_law`` revision) while its plain trials show it falls short of
  ``target_rate``, read off at least ``shortfall_after`` plain trials of the net as it is now;
* explores on every ``explore_every``-th trial (:mod:`.explore`), so its own data holds variations
  of its maneuvers and not only their repetition; the other trials measure the skill as it is;
* has the mentor grade every ``mentor_every``-th trial, up to ``mentor_budget`` trials, from the
  trial's trace alone (each stay the judges graded); the labels revise the judges, and each label
  that contradicts the robot's own grade is counted;
* has the mentor take over failed trials, up to ``takeover_budget`` (:mod:`.takeover`): a
  demonstration from where the robot knew least, learned from at the next refit;
* on every ``hold_off_every``-th exploring trial the experimenter pushes, takes each way back once
  and then holds it off down to the logit ``hold_off_floor`` (:mod:`.hold_off`): each later stay in
  the way back's place records how far out the way back would have fired again and whether the law
  went on; a trial in which it would have is a probe, no evidence for repair. Where the probes
  favour it over the way back's own success rate when it fires again, its floor is lowered (a
  ``set_condition`` revision, watched like every other);
* with ``floor_exam``, examines a deeper floor of its ways back once at its end (its target
  reached, or no room left for another revision): the trials in which a way back fired are
  replayed with it, and it is kept only if it wins (:meth:`Practice._examine_floors`);
* gives the repair candidates it tried a new chance once new laws have passed their exam: they
  were judged with the old ones (:meth:`Practice._after_exam`);
* watches every revision: if the robot's own success rate over the next ``revert_window`` plain
  trials is clearly worse than over the ``revert_window`` before it (one-sided Fisher test at
  ``revert_p``), the net goes back to the version before (a ``revert`` revision). With ``exam``
  the comparison is paired: the ``revert_window`` trials after a revision replay the draws (seed,
  start, push) of the plain trials before it, without exploring, and the revision is reverted if
  it lost at least ``exam_margin`` more of those same trials than it won. Paired, ten trials see a
  drop that two independent windows of ten cannot (a fall from 8/10 to 6/10 is p ≈ 0.3 unpaired);
* stops when its own success rate over the last ``target_window`` plain trials reaches
  ``target_rate``.

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
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any

from ..demos.episode import Episode, SegmentLabel
from ..errors import InvalidInput
from ..io import read_json, write_json
from ..lock import exclusive
from ..learn.labels import is_mentor, records_from_episode
from ..learn.training import LawSettings, fit_law
from ..learn.views import is_demonstration, place_episode
from ..model import ModelLearners, SkillModel
from ..petri.net import APN, Condition
from ..petri.revision import Revision, refit_law, revert, set_condition
from ..runtime.executor import Executor
from ..runtime.trace import Trace
from .diagnosis import diagnose, is_evidence
from .hold_off import choose_floor, held_off, probe_stays, ways_back
from .experience import DEFAULT_MARGIN, Experience, select_segments
from .explore import ExploringLaw, law_noise
from .repair import move_limit, repair
from .replay import replay_limits

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
    learn: bool = False
    margin: float = DEFAULT_MARGIN
    explore: float = 0.0
    explore_every: int = 2
    explore_tau: float = 0.1
    refit_every: int = 10
    refit_min_segments: int = 5
    mentor_every: int = 0
    mentor_budget: int = 0
    target_rate: float = 0.0
    target_window: int = 20
    shortfall_after: int = 0
    revert_window: int = 10
    revert_p: float = 0.1
    exam: bool = False
    exam_margin: int = 2
    novelty: float = 0.0
    takeover_budget: int = 0
    hold_off_every: int = 0
    hold_off_floor: float = -10.0
    floor_exam: float = 0.0
    check_demonstrations: bool = True

    def __post_init__(self) -> None:
        counts = {"failures_in_a_row": 1, "window": 0, "success_streak": 1, "max_trials": 1, "seed": 0,
                  "explore_every": 0, "refit_every": 1, "refit_min_segments": 1, "mentor_every": 0,
                  "mentor_budget": 0, "takeover_budget": 0, "target_window": 1, "shortfall_after": 0,
                  "revert_window": 1, "exam_margin": 1, "hold_off_every": 0}
        for name, low in counts.items():
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or not low <= v <= 1_000_000:
                raise InvalidInput(f"must be a whole number in {low}..1000000, got {v!r}", element=name)
        for name in ("hold_off_floor", "floor_exam"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not -1e6 <= v <= 0.0:
                raise InvalidInput(f"must be a logit in -1000000..0, got {v!r}", element=name)
        for name in ("failure_rate", "margin", "target_rate", "revert_p", "explore", "explore_tau", "novelty"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and 0.0 <= v <= (10.0 if name.startswith("explore")
                                                                                       else 1.0)):
                raise InvalidInput(f"out of range: {v!r}", element=name)

    def explores(self, k: int) -> bool:
        return self.explore > 0 and self.explore_every > 0 and k % self.explore_every == self.explore_every - 1

    def trial_seed(self, k: int) -> int:
        return 1_000_003 * (self.seed + 1) + k


@dataclass
class PracticeState:
    """What the loop has done so far (``state.json``; files that still hold the ``lambda_exhausted``
    it now derives from ``revisions`` load as before, the entry ignored)."""

    trial: int = 0
    trials: list[dict[str, Any]] = field(default_factory=list)
    revisions: list[dict[str, Any]] = field(default_factory=list)
    failed_since_repair: list[int] = field(default_factory=list)
    repairs_without_effect: int = 0
    mentor_graded: list[dict[str, Any]] = field(default_factory=list)
    takeovers: list[dict[str, Any]] = field(default_factory=list)
    watch: dict[str, Any] | None = None
    trying: dict[str, Any] | None = None       # the repair on trial: its key, versions, what it must beat
    tried: list[str] = field(default_factory=list)
    last_refit_trial: int = -1
    checked: bool = False                      # the definition was held against the demonstrations
    floor_examined: bool = False               # the ways back's deeper floor was considered (``floor_exam``)
    done: bool = False
    stop_reason: str = ""
    format_version: int = STATE_VERSION

    @property
    def lambda_exhausted(self) -> list[str]:
        """Transitions whose λ was already lowered without curing the failures (:func:`~.repair.adjust_lambda`
        tries Λ on them no more), read off ``revisions``: a λ repair of a transition whose λ a repair
        set before exhausts it; a repair of anything else (a condition, a law, the structure) starts
        afresh; reverts and refits change nothing."""
        exhausted: set[str] = set()
        lowered: set[str] = set()
        for r in self.revisions:
            if r["operator"] == "set_lambda":
                if r["target"] in lowered:
                    exhausted.add(r["target"])
                lowered.add(r["target"])
            elif r["operator"] not in ("revert", "refit_law", "none"):
                exhausted = set()
        return sorted(exhausted)

    @property
    def streak(self) -> tuple[int, int]:
        """(successes, failures) in a row at the end; trials that are no evidence are passed over."""
        s = f = 0
        for tr in reversed(self.trials):
            if not tr.get("evidence", True) or tr.get("probe"):
                continue
            if tr["success"] and not f:
                s += 1
            elif not tr["success"] and not s:
                f += 1
            else:
                break
        return s, f


MentorGrader = Callable[[Episode, APN], list[SegmentLabel]]
Takeover = Callable[[Trace, int], "Episode | None"]


class Practice:
    """Runs the loop for one model in ``folder`` (state, failed traces), with trial ``options``
    (reset options per trial index), an optional ``perturb`` factory (the experimenter's pushes,
    per trial index; see :meth:`multiform.runtime.executor.Executor.run`) and, for learning from
    practice, the ``mentor``'s grader of a trial (its trace as an episode and the net that ran it →
    one label per stay)."""

    def __init__(self, model: SkillModel, folder: str | Path, config: PracticeConfig | None = None,
                 options: Options | None = None, perturb: Perturb | None = None, name: str = "practice",
                 mentor: MentorGrader | None = None, observe: Callable[[int, Executor], Any] | None = None,
                 takeover: Takeover | None = None):
        self.model = model
        self.observe = observe          # trial index, executor -> an executor observer (e.g. the live view) or None
        self.folder = Path(folder)
        self.config = config or PracticeConfig()
        self.options = options or (lambda k: {})
        self.perturb = perturb
        self.name = name
        self.mentor = mentor
        self.takeover = takeover
        self.learners = ModelLearners(model, seed=self.config.seed)
        self.experience = Experience(model.path)

    @classmethod
    def for_scenario(cls, model: SkillModel, folder: str | Path, scenario: Mapping[str, Any], max_trials: int,
                     seed: int = 0, observe: Callable[[int, Executor], Any] | None = None) -> Practice:
        """Practice through one of a task's scenarios (``Task.scenarios()``: name, options, perturb,
        config, seed offset, and the mentor's grader and takeover factories where it learns)."""
        sc = scenario
        cfg = PracticeConfig(max_trials=max_trials, seed=seed + sc.get("seed", 0), **sc.get("config", {}))
        mentor = sc["mentor"]() if sc.get("mentor") else None
        takeover = sc["takeover"]() if sc.get("takeover") and cfg.takeover_budget else None
        return cls(model, folder, cfg, options=sc["options"], perturb=sc.get("perturb"), name=sc["name"],
                   mentor=mentor, observe=observe, takeover=takeover)

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
        # A revision this scenario recorded just before a kill, after the state was last saved: adopt
        # it (a finished scenario adopts nothing, and no scenario adopts another's revisions).
        recorded = self.model.history.revisions()
        mine = {r["version"] for r in state.revisions if r.get("version") is not None}
        for r in recorded:
            if state.done or r.evidence.get("scenario", self.name) != self.name:
                continue
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

    def source(self, k: int) -> str:
        """The id of trial ``k`` in the label store and the experience store."""
        return f"{self.name}_{k}"

    # -- the loop ----------------------------------------------------------------------------------
    def run(self, progress: Callable[[PracticeState, dict[str, Any]], None] | None = None,
            stop_after: int | None = None) -> PracticeState:
        """Practise until done (or ``stop_after`` more trials); returns the final state.

        Holds the model directory's lock throughout, and checks the model before the first trial."""
        with exclusive(self.model.path):
            self.model.verify()
            return self._run(progress, stop_after)

    def _run(self, progress: Callable[[PracticeState, dict[str, Any]], None] | None,
             stop_after: int | None) -> PracticeState:
        cfg = self.config
        self.folder.mkdir(parents=True, exist_ok=True)
        state = self.load_state()
        env = self.model.make_env()
        executor, explorer, prober, version = None, None, None, -1
        judges = self.model.judges() if cfg.use_judges else {}
        if cfg.check_demonstrations and state.trial == 0 and not state.checked:
            self._check_definition(state)
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
                explorer = self._explorer(executor) if cfg.explore > 0 else None
                prober = self._prober(explorer) if explorer is not None and cfg.hold_off_every else None
                judges = self.model.judges() if cfg.use_judges else {}
            k = state.trial
            t0 = time.perf_counter()
            trace, draw, explores, probing, view = self._trial(state, executor, explorer, prober)
            if trace.outcome == "fault":
                # a non-finite value is the model's or the simulator's fault, not the skill's: nothing
                # is learned or repaired from it, and practice stops until someone looks
                trace.save(self.folder / "faults" / f"trial_{k:04d}.npz")
                state.stop_reason = f"fault in trial {k}: {trace.fault}; nothing was learned from it"
                break
            grade = self.model.grade(trace, self.source(k), judges, apn=executor.apn) if judges else None
            success = trace.success and (grade is None or grade.success)
            if view is not None:
                if grade is not None:
                    view.grade(grade, success)
                view.close()
            summary = self._summary(k, draw, version, trace, grade, success, explores, t0)
            if probing:
                summary.update(self._probed(trace, prober.apn))
            if cfg.learn and grade is not None:
                summary.update(self._learn_from(state, k, trace, grade, executor.apn, success,
                                                bool(summary.get("probe"))))
                if "revised" in summary.get("mentor", {}):
                    judges = self.model.judges()
            state.trials.append(summary)
            if not success and is_evidence(trace.outcome) and not summary.get("probe"):
                trace.save(self._trace_path(k))
                state.failed_since_repair.append(k)
            state.trial += 1
            ran += 1
            self._after_trial(state)
            self.save_state(state)
            if progress:
                progress(state, summary)
        self.save_state(state)
        env.close()
        return state

    def _trial(self, state: PracticeState, executor: Executor, explorer: Executor | None,
               prober: Executor | None = None) -> tuple[Trace, int, bool, bool, Any]:
        """Run trial ``state.trial`` on its own draw, or on the draw an exam replays; exploring when
        due and not replaying, with the ways back held off when due (``prober``). Returns its trace,
        the draw, whether it explored, whether it held the ways back off, and its view (or None)."""
        cfg = self.config
        k = state.trial
        draw = self._exam_draw(state)
        explores = explorer is not None and cfg.explores(k) and draw is None
        draw = k if draw is None else draw
        runner = executor
        probing = explores and prober is not None and self._holds_off(k)
        if explores:
            for i, law in enumerate(sorted(explorer.laws)):
                explorer.laws[law].reseed(cfg.trial_seed(k) * 31 + i)
            runner = prober if probing else explorer
        view = self.observe(k, executor) if self.observe else None
        trace = runner.run(seed=cfg.trial_seed(draw), options=self.options(draw),
                           perturb=self.perturb(draw) if self.perturb else None, observer=view)
        return trace, draw, explores, probing, view

    def _summary(self, k: int, draw: int, version: int, trace: Trace, grade: Any, success: bool, explores: bool,
                 t0: float) -> dict[str, Any]:
        """Trial ``k``'s entry in the state (``trials``), run on the draw (seed, start, push) of
        trial ``draw``."""
        cfg = self.config
        summary = {"trial": k, "seed": cfg.trial_seed(draw), "net_version": version, "outcome": trace.outcome,
                   "success": bool(success), "judge_score": None if grade is None else round(grade.score, 4),
                   "judge_places": None if grade is None else {p: round(v, 4) for p, v in grade.places.items()},
                   "duration": round(trace.duration, 3), "fired": trace.fired(),
                   "clips": {c: v["count"] for c, v in trace.clips.items()},
                   "wall": round(time.perf_counter() - t0, 3),
                   "time": time.strftime("%Y-%m-%dT%H:%M:%S", time.gmtime())}
        if not is_evidence(trace.outcome):
            summary["evidence"] = False
        if cfg.explore > 0:
            summary["explored"] = explores
        if draw != k:
            summary["draw"] = draw
        return summary

    def _after_trial(self, state: PracticeState) -> None:
        """After a trial: check a watched revision; stop on a success streak or the target rate (after
        the ways back's floor exam, if due); repair on constant failure; refit the laws when due;
        examine the ways back's floor once no room is left for another revision."""
        cfg = self.config
        succ, _ = state.streak
        if cfg.learn:
            self._check_watch(state)
        if state.done:                  # the floor exam that ended practice
            return
        if succ >= cfg.success_streak:
            state.done, state.stop_reason = True, f"{succ} successes in a row"
        elif self._reached_target(state):
            reason = (f"own success rate {self._plain_rate(state, cfg.target_window):.2f} over the last "
                      f"{cfg.target_window} plain trials")
            if not self._examine_floors(state, then_stop=reason):
                state.done, state.stop_reason = True, reason
        elif self._constant_failure(state) and not (state.watch or {}).get("must_win"):
            self._repair(state)
        if not state.done and cfg.learn and cfg.hold_off_every and state.watch is None and self._room_to_watch(state):
            self._lower_floors(state)
        if not state.done and cfg.learn and (state.watch is None or not cfg.exam) \
                and state.trial - state.last_refit_trial - 1 >= cfg.refit_every and self._room_to_watch(state):
            self._refit(state)
        if not state.done and state.watch is None and cfg.max_trials - state.trial <= self._watch_trials():
            self._examine_floors(state)

    # -- learning from practice ----------------------------------------------------------------------
    def _explorer(self, executor: Executor) -> Executor:
        """An executor of the same net whose laws explore (reseeded per trial)."""
        cfg = self.config
        laws = {name: ExploringLaw(law, cfg.explore * law_noise(law), cfg.explore_tau, executor.dt, 0)
                for name, law in executor.laws.items()}
        return Executor(executor.apn, executor.env, laws, self.model.conditions(), executor.inverse_model,
                        net_version=executor.net_version)

    def _prober(self, explorer: Executor) -> Executor | None:
        """The explorer with the net's ways back held off (None if the net has none)."""
        conditions = self.model.conditions()
        ways = ways_back(explorer.apn, conditions)
        if not ways:
            return None
        held = held_off(conditions, ways, self.config.hold_off_floor)
        return Executor(explorer.apn, explorer.env, explorer.laws, held,
                        explorer.inverse_model, net_version=explorer.net_version)

    def _holds_off(self, k: int) -> bool:
        """Trial ``k`` holds the ways back off: every ``hold_off_every``-th exploring trial with a push."""
        cfg = self.config
        if not cfg.hold_off_every or self.perturb is None or not cfg.explores(k) or self.perturb(k) is None:
            return False
        pushed = sum(1 for j in range(k) if cfg.explores(j) and self.perturb(j) is not None)
        return pushed % cfg.hold_off_every == cfg.hold_off_every - 1

    def _probed(self, trace: Trace, apn: APN) -> dict[str, Any]:
        """What a trial with the ways back held off shows: per way back, each stay in its place
        (:func:`~.hold_off.probe_stays`); ``probe`` if a way back would have fired."""
        conditions = self.model.conditions()
        apn0 = self.model.history.version(0)
        held, probe = [], False
        for w in ways_back(apn, conditions):
            c = conditions[w.condition]
            stays = probe_stays(apn0, trace, w, c)
            probe = probe or any(m is not None and m < w.floor for m, _ in stays)
            held.append({"transition": w.transition, "place": w.place, "towards": c.into or "outside",
                         "floor": round(w.floor, 4), "stays": stays})
        return {"held_off": held, "probe": probe}

    def _lower_floors(self, state: PracticeState) -> None:
        """Lower a way back's floor where the probes favour letting the law go on over the way back
        (:func:`~.hold_off.choose_floor`): one ``set_condition`` revision, watched. The way back's own
        success rate is read off the trials, no probes, that fired it again (twice or more) in a net
        where it left the same place for the same place."""
        apn = self.model.apn
        conditions = self.model.conditions()
        nets = self.model.history.versions()
        for w in ways_back(apn, conditions):
            c = conditions[w.condition]
            towards = c.into or "outside"
            stays = [s for t in state.trials for h in t.get("held_off", ())
                     if h["place"] == w.place and h["towards"] == towards for s in h["stays"]]
            same = []
            for t in state.trials:
                if t.get("probe") or t["fired"].count(w.transition) < 2 or not t.get("evidence", True):
                    continue
                net = nets[t["net_version"]]
                if w.transition in net.transition_ids and \
                        net.transition(w.transition).inputs == apn.transition(w.transition).inputs:
                    same.append(bool(t["success"]))
            if len(same) < 3:
                continue
            rate = sum(same) / len(same)
            best = choose_floor(stays, w.floor, rate)
            if best is None:
                continue
            floor, gain = best
            key = f"floor:{w.transition}:{floor:.3f}"
            if key in state.tried:
                continue
            below = [s for s in stays if s[0] is not None and s[0] < w.floor]
            probes = sorted({t["trial"] for t in state.trials if t.get("probe")})
            first = self.model.version
            self._set_floor(
                state, w, floor,
                f"with the way back held off once taken, {sum(h for _, h in below)} of {len(below)} stays in "
                f"{w.place} that it would have ended went on; firing again, it saved {sum(same)} of {len(same)} "
                f"trials: floor {w.floor:.2f} -> {floor:.2f}",
                {"stays_below": len(below), "went_on": int(sum(h for _, h in below)), "way_fired_trials": len(same),
                 "way_success": int(sum(same)), "gain": round(gain, 3), "probe_trials": probes})
            state.tried.append(key)
            self._watch(state, first, self.model.version)
            return

    def _set_floor(self, state: PracticeState, way: Any, floor: float, reason: str, evidence: dict[str, Any]) -> None:
        """A ``set_condition`` revision: way back ``way`` (:class:`~.hold_off.WayBack`) leaves its
        place below ``floor`` from now on."""
        apn = self.model.apn
        name, info = self.learners.with_floor(way.condition, floor)
        ref = Condition.learned(name, apn.transition(way.transition).condition.unless).to_data()
        _, rev = set_condition(apn, way.transition, ref, reason,
                               {**info, "floor_before": round(way.floor, 4), **evidence, "after_trial": state.trial - 1})
        self._record(state, rev)

    def _examine_floors(self, state: PracticeState, then_stop: str | None = None) -> bool:
        """At the end of practice (its target reached, or no room left for another revision), once:
        every way back whose floor lies above ``floor_exam`` gets that floor, and the trials of the net
        as it is in which a way back fired are replayed with it. A deeper floor lets the balance law go
        on with a catch the way back would have ended, which from five demonstrations saved most
        pushed trials (job seeds 0 and 2: 24 and 21 of 30 on the final model, 30 with the floor at -4)
        and from ten lost some (26 → 23). Only trials in which a way back fired can change: below its old floor the state
        never went. Kept if it won ``exam_margin`` more than it lost, or won some and lost none
        (:meth:`_paired_verdict`). Returns whether the exam started (``then_stop``: practice stops
        after it)."""
        cfg = self.config
        if not (cfg.learn and cfg.exam and cfg.floor_exam < 0.0) or state.floor_examined or state.watch is not None:
            return False
        state.floor_examined = True
        ways = [w for w in ways_back(self.model.apn, self.model.conditions()) if w.floor > cfg.floor_exam]
        names = {w.transition for w in ways}
        room = min(cfg.revert_window, cfg.max_trials - state.trial)
        replay = [t for t in self._current_plain(state) if names & set(t["fired"])][-room:] if room > 0 else []
        if not ways or len(replay) < cfg.exam_margin:
            return False
        first = self.model.version
        for w in ways:
            self._set_floor(state, w, cfg.floor_exam,
                            f"the end of practice: {len(replay)} trials in which a way back fired are replayed with "
                            f"{w.transition}'s floor at {cfg.floor_exam:.2f} instead of {w.floor:.2f}; kept only if "
                            f"it wins {cfg.exam_margin} more of them than it loses, or some and loses none",
                            {"replayed_trials": [t["trial"] for t in replay]})
        self._watch(state, first, self.model.version, replay, must_win=True, then_stop=then_stop)
        return True

    def _learn_from(self, state: PracticeState, k: int, trace: Trace, grade: Any, apn: APN,
                    success: bool = True, probe: bool = False) -> dict[str, Any]:
        """The mentor's grade (on schedule), then the own segments the trial adds; the mentor takes
        over a failed trial that was no probe."""
        cfg, out = self.config, {}
        source = self.source(k)
        verdicts: dict[tuple[int, int], bool] = {}
        graded = {g["trial"] for g in state.mentor_graded}
        if (self.mentor is not None and cfg.mentor_every > 0 and k % cfg.mentor_every == cfg.mentor_every - 1
                and len(graded) < cfg.mentor_budget and k not in graded):
            verdicts, account = self._mentor_grades(source, trace, grade, apn)
            state.mentor_graded.append({"trial": k, **account})
            out["mentor"] = account
        taken = {t["trial"] for t in state.takeovers}
        if (self.takeover is not None and not success and is_evidence(trace.outcome) and k not in taken
                and len(taken) < cfg.takeover_budget and not probe):
            out["takeover"] = self._take_over(source, trace, apn)
            state.takeovers.append({"trial": k, **out["takeover"]})
        own = select_segments(apn, trace, grade, source, self.name, k, cfg.margin, verdicts)
        if own:
            self.experience.add(trace, own, source)
        out["own_segments"] = len(own)
        return out

    def _mentor_grades(self, source: str, trace: Trace, grade: Any, apn: APN
                       ) -> tuple[dict[tuple[int, int], bool], dict[str, Any]]:
        """The mentor labels every stay of the trial the judges graded; the labels go to the label
        store and revise the judges; returns the verdicts by stay and an account (agreement with the
        robot)."""
        from ..demos.labelling import refit_judges
        ep = trace.to_episode()
        placed = place_episode(apn, ep)
        robot = {(g.start, g.end): g.success for g in grade.segments}
        labels = [lab for lab in self.mentor(placed, apn) if (lab.start, lab.end) in robot]
        verdicts = {(lab.start, lab.end): bool(lab.success) for lab in labels}
        records = records_from_episode(source, labels, lambda p: p)
        agree = sum(robot.get(key) == v for key, v in verdicts.items())
        account = {"stays": len(verdicts), "agree": int(agree), "mentor_success": int(sum(verdicts.values())),
                   "robot_success": int(sum(robot.get(key, False) for key in verdicts))}
        if records:
            self.experience.keep_trace(trace, source)
            self.model.labels.add_many(records)
            graded = {s: self.experience.episode(s) for s in self._mentor_sources()
                      if self.experience.trace_path(s).exists()}
            info = refit_judges(self.model, sorted({r.place for r in records}), {**graded, source: ep},
                                seed=self.config.seed)
            account["revised"] = {p: {k: v for k, v in d.items() if k in ("segments", "cv_score", "kernel")}
                                  for p, d in info.items()}
        return verdicts, account

    def _take_over(self, source: str, trace: Trace, apn: APN) -> dict[str, Any]:
        """The mentor demonstrates from where the failed trial got stuck (:mod:`.takeover`)."""
        from .takeover import stuck_tick
        tick = stuck_tick(trace, apn, self.model.laws(apn))
        if tick is None:
            return {"tick": None}
        ep = self.takeover(trace, tick)
        if ep is None:
            return {"tick": tick}
        self.experience.add_takeover(ep, source, apn.name, apn.env)
        return {"tick": tick, "time": round(tick * trace.dt, 3), "samples": int(ep.num_samples),
                "outcome": ep.outcome}

    def _mentor_sources(self) -> list[str]:
        return sorted({r.source for r in self.model.labels if not is_demonstration(r.source)
                       and is_mentor(r.labeller)})

    def _refit(self, state: PracticeState) -> None:
        """Refit each law that has new own segments since its fit; one ``refit_law`` revision each.

        Called every ``refit_every`` trials while enough trials are left to watch the refit. Only a
        skill whose plain trials show it falls short of the target is refitted (:meth:`_falls_short`):
        an exam of ``revert_window`` replayed trials cannot see a refit cost a few points, so a skill
        already near its target has more to lose than to gain (10 demos, job seed 0: one failure in
        18 plain trials set off refits that took the evaluation from 95.0 % to 90.0 %)."""
        cfg = self.config
        state.last_refit_trial = state.trial - 1
        if cfg.target_rate > 0 and not self._falls_short(state):
            return
        apn = self.model.apn
        segments = self.experience.segments()
        takeovers = self.experience.takeovers() if cfg.takeover_budget else {}
        made = []
        for law in apn.laws:
            mine = [s for s in segments if law in s.laws]
            seen = self._fitted_sources(law)
            new = [s for s in mine if s.source not in seen]
            new_takeovers = sorted(set(takeovers) - self._fitted_sources(law, "takeovers"))
            if len(new) < cfg.refit_min_segments and not new_takeovers:
                continue
            own = self.experience.law_episodes(law, mine)
            current = self.model.laws(apn).get(law)
            mentor_net = self.model.history.version(0)
            refitted, info = fit_law(mentor_net, self.model.episodes + list(takeovers.values()), law,
                                     seed=cfg.seed, own=own, own_apn=apn,
                                     current=current, mentor_law=self.model.laws(mentor_net).get(law),
                                     settings=LawSettings(own_novelty=cfg.novelty))
            fit = self.learners.fresh_law(law)
            self.model.save_law(fit, refitted)
            evidence = {"own_segments": len(mine), "new_own_segments": len(new), "own_trials": len(own),
                        "own_samples": info.get("n_own"), "own_samples_offered": info.get("n_own_offered"),
                        "mentor_samples": info.get("n_mentor"),
                        "heldout_nrmse_before": _round(info.get("heldout_nrmse_current")),
                        "heldout_nrmse_after": _round(info.get("heldout_nrmse")),
                        "sources": sorted({s.source for s in mine}), "after_trial": state.trial - 1,
                        **({"takeovers": sorted(takeovers)} if takeovers else {})}
            taken = f" and {len(new_takeovers)} new takeovers by the mentor" if new_takeovers else ""
            _, rev = refit_law(apn, law, fit, f"{len(new)} new segments of its own graded successful "
                                              f"(score >= {0.5 + cfg.margin:.2f}){taken}; refit from the mentor's "
                                              f"and its own data",
                               evidence)
            made.append(self._record(state, rev, {"refit": info}))
            apn = self.model.apn
        if made:
            self._watch(state, made[0] - 1, made[-1])

    def _fitted_sources(self, law: str, key: str = "sources") -> set[str]:
        """The trials whose own segments (``key`` "takeovers": whose takeovers) the last recorded
        refit of ``law`` learned from."""
        for r in reversed(self.model.history.revisions()):
            if r.operator == "refit_law" and r.target == law:
                return set(r.evidence.get(key, ()))
        return set()

    def _record(self, state: PracticeState, rev: Revision, diagnosis: dict[str, Any] | None = None) -> int:
        rev = self.model.history.record(replace(rev, evidence={**rev.evidence, "scenario": self.name}))
        v = rev.version
        state.revisions.append({"version": v, "operator": rev.operator, "target": rev.target, "reason": rev.reason,
                                "after_trial": state.trial - 1, "scenario": self.name,
                                **({"diagnosis": diagnosis} if diagnosis is not None else {})})
        return v

    # -- watching revisions ----------------------------------------------------------------------------
    def _watch_trials(self) -> int:
        """Trials it takes to see ``revert_window`` plain ones."""
        cfg = self.config
        if cfg.exam:
            return cfg.revert_window
        return cfg.revert_window * (cfg.explore_every if cfg.explore > 0 and cfg.explore_every > 1 else 1)

    def _room_to_watch(self, state: PracticeState) -> bool:
        """Whether enough trials are left to watch a revision made now (:meth:`_watch_trials`)."""
        return self.config.max_trials - state.trial >= self._watch_trials()

    def _plain(self, state: PracticeState) -> list[dict[str, Any]]:
        return [t for t in state.trials if not t.get("explored")]

    def _plain_rate(self, state: PracticeState, n: int) -> float:
        last = self._plain(state)[-n:]
        return sum(t["success"] for t in last) / len(last) if last else 0.0

    def _current_plain(self, state: PracticeState) -> list[dict[str, Any]]:
        """The plain trials the net as it is now ran."""
        return [t for t in self._plain(state) if t.get("net_version") == self.model.version]

    def _falls_short(self, state: PracticeState) -> bool:
        """The plain trials of the net as it is now fail more often than the target allows: the
        chance of that many failures at a success rate of ``target_rate`` is below ``revert_p``
        (one-sided binomial test), read off at least ``shortfall_after`` of them: a failure or two in
        a skill's first few trials is mostly chance when it succeeds nine times in ten or more
        (nunchaku, 10 demonstrations, job seed 2: 1 failure in 5 plain trials at a target of 98 %
        set off refits that took the evaluation from 97.0 % to 88.5 %)."""
        from scipy.stats import binomtest
        cfg = self.config
        current = self._current_plain(state)
        if len(current) < cfg.shortfall_after:
            return False
        failures = sum(not t["success"] for t in current)
        if failures == 0 or cfg.target_rate >= 1.0:
            return failures > 0
        p = binomtest(failures, len(current), 1.0 - cfg.target_rate, alternative="greater").pvalue
        return bool(p < cfg.revert_p)

    def _reached_target(self, state: PracticeState) -> bool:
        """The last ``target_window`` plain trials, all of the net as it is now, reach the target (a
        window reaching back before a refit would credit the new laws with the old ones' successes)."""
        cfg = self.config
        return cfg.target_rate > 0 and len(self._current_plain(state)) >= cfg.target_window \
            and self._plain_rate(state, cfg.target_window) >= cfg.target_rate

    def _watch(self, state: PracticeState, before_version: int, version: int,
               trials: list[dict[str, Any]] | None = None, **extra: Any) -> None:
        """Watch the revisions up to ``version``: compared over the next plain trials with the plain
        trials before them (``trials``: these instead of the last ``revert_window``); ``extra`` goes
        into the watch (``must_win``, ``then_stop``: see :meth:`_examine_floors`)."""
        if not self.config.learn:
            return
        last = self._plain(state)[-self.config.revert_window:] if trials is None else trials
        state.watch = {"before_version": before_version, "version": version, "after_trial": state.trial - 1,
                       "before": [bool(t["success"]) for t in last], **extra}
        if self.config.exam:
            state.watch["draws"] = [int(t.get("draw", t["trial"])) for t in last]

    def _exam_draw(self, state: PracticeState) -> int | None:
        """The draw the next trial replays while a revision is examined (None: a fresh trial)."""
        w = state.watch
        if w is None or "draws" not in w:
            return None
        i = state.trial - w["after_trial"] - 1
        return w["draws"][i] if 0 <= i < len(w["draws"]) else None

    def _check_watch(self, state: PracticeState) -> None:
        w, cfg = state.watch, self.config
        if w is None:
            return
        after = [bool(t["success"]) for t in self._plain(state) if t["trial"] > w["after_trial"]]
        if "draws" in w:
            if len(after) < len(w["draws"]):
                return
            state.watch = None
            state.last_refit_trial = max(state.last_refit_trial, state.trial - 1)
            if self.model.version == w["version"] and w["draws"]:
                self._paired_verdict(state, w, after[:len(w["draws"])])
            self._after_exam(state, w)
            if w.get("then_stop"):
                state.done, state.stop_reason = True, f"{w['then_stop']}, then the ways back's floor examined"
            return
        if len(after) < cfg.revert_window:
            return
        state.watch = None
        before = w["before"]
        if len(before) < cfg.revert_window // 2 or self.model.version != w["version"]:
            return
        from scipy.stats import fisher_exact
        table = [[sum(before), len(before) - sum(before)], [sum(after), len(after) - sum(after)]]
        p = float(fisher_exact(table, alternative="greater")[1])
        if p >= cfg.revert_p:
            return
        target = self.model.history.version(w["before_version"])
        _, rev = revert(self.model.apn, w["before_version"], target,
                        f"own success rate fell from {sum(before)}/{len(before)} to {sum(after)}/{len(after)} plain "
                        f"trials after version {w['version']} (one-sided Fisher p = {p:.3f})",
                        {"before": table[0], "after": table[1], "p": round(p, 4), "reverted": w["version"]})
        self._record(state, rev)

    def _after_exam(self, state: PracticeState, w: dict[str, Any]) -> None:
        """A refit that passed its exam gives the repair candidates tried before it a new chance:
        they were judged with the old laws (a way back after a push does not help while the swing-up
        law cannot recover from where the push leaves the pendulum; after takeovers there it may)."""
        refitted = any(r["operator"] == "refit_law" and r.get("version") is not None
                       and w["before_version"] < r["version"] <= w["version"] for r in state.revisions)
        if refitted and self.model.version == w["version"]:
            state.tried = []

    def _paired_verdict(self, state: PracticeState, w: dict[str, Any], after: list[bool]) -> None:
        """Revert the examined revision if it lost ``exam_margin`` more of the replayed trials than it won
        (one trial's difference is what chaos in a swing-up gives a law that changed at all); one that
        must win (``must_win``: a change no failure asked for) unless it won that many more than it
        lost, or won some and lost none."""
        before = w["before"]
        lost = sum(b and not a for b, a in zip(before, after))
        won = sum(a and not b for b, a in zip(before, after))
        margin = self.config.exam_margin
        if (won - lost >= margin or (won and not lost)) if w.get("must_win") else (lost - won < margin):
            return
        target = self.model.history.version(w["before_version"])
        _, rev = revert(self.model.apn, w["before_version"], target,
                        f"the same {len(after)} trials replayed after version {w['version']}: {sum(before)} -> "
                        f"{sum(after)} successes ({lost} lost, {won} won)",
                        {"before": [sum(before), len(before) - sum(before)],
                         "after": [sum(after), len(after) - sum(after)], "lost": lost, "won": won,
                         "draws": w["draws"], "reverted": w["version"]})
        self._record(state, rev)

    def _constant_failure(self, state: PracticeState) -> bool:
        cfg = self.config
        _, fail = state.streak
        if fail >= cfg.failures_in_a_row and len(state.failed_since_repair) >= cfg.failures_in_a_row:
            return True
        if cfg.window > 0:
            since = [t for t in state.trials[-cfg.window:]
                     if t["trial"] >= (state.revisions[-1]["after_trial"] + 1 if state.revisions else 0)
                     and not t.get("probe")]
            if len(since) >= cfg.window:
                rate = sum(not t["success"] for t in since) / len(since)
                return rate >= cfg.failure_rate
        return False

    def _check_definition(self, state: PracticeState) -> None:
        """Before the first trial: move the give-up rules that would have ended the mentor's own
        successful demonstrations (:func:`~.replay.replay_limits`), each a recorded revision. Not put
        on trial like a repair from failures: the demonstrations are the evidence, and a later
        failure need not be the limit's."""
        mentor = self.learners.mentor(self.model.apn)
        if mentor is not None:
            for f in replay_limits(self.model.apn, mentor):
                fix = move_limit(self.model.apn, f)
                key = f"demonstrations:{f.transition}"
                for rev in fix.revisions:
                    self._record(state, replace(rev, evidence={**rev.evidence, "candidate": key}),
                                 {"findings": [f.to_json()]})
        state.checked = True
        self.save_state(state)

    def _repair(self, state: PracticeState) -> None:
        apn = self.model.apn
        # every failed trial kept so far: those since the last repair are diagnosed; all of them
        # lower the leave floors, so a resumed loop lowers them exactly as an uninterrupted one did
        kept = {k: Trace.load(self._trace_path(k)) for k in range(state.trial) if self._trace_path(k).exists()}
        regions = self.model.regions()
        scorer = regions.scores if regions is not None else None
        names = tuple(regions.input_names) if regions is not None else ()
        leave = self.learners.include_own_stays(list(kept.values())) if regions is not None else None

        def diagnosis(net: APN, trials: list[int]) -> Any:
            ok = [t["fired"] for t in state.trials if t["success"] and t["trial"] in set(trials)]
            return diagnose(net, [kept[k] for k in trials if k in kept], scorer, names, leave_below=leave,
                            mentor=self.learners.mentor(net), succeeded_fired=ok)

        last = max((r["after_trial"] for r in state.revisions), default=-1)
        d = diagnosis(apn, [t["trial"] for t in state.trials if t["trial"] > last])
        if state.trying is not None:
            trying, state.trying = state.trying, None
            helped = any(t["success"] for t in state.trials if t["trial"] > trying["after_trial"]) \
                or bool(d.visited - set(trying["visited"]))
            if not helped and self.model.version == trying["version"]:
                target = self.model.history.version(trying["before_version"])
                failures = [t["trial"] for t in state.trials if t["trial"] > trying["after_trial"] and not t["success"]]
                _, rev = revert(apn, trying["before_version"], target,
                                f"{trying['key']} did not help: {len(failures)} failed trial(s) since it, none reached a "
                                f"place the failures before it had not; back to version {trying['before_version']} to try "
                                f"the next candidate", {"reverted": trying["version"], "candidate": trying["key"],
                                                       "failed_trials": failures})
                self._record(state, rev, d.to_json())
                apn = self.model.apn
                d = diagnosis(apn, trying["failed"])
        if self.config.learn and not self._room_to_watch(state):
            # a repair nobody can check would go into the skill untried (a place added 9 trials before
            # the end of a trial run made every pushed evaluation trial alternate between its two transitions)
            left = self.config.max_trials - state.trial
            self._no_repair(state, d, f"{left} trials are left, fewer than the {self._watch_trials()} it takes to "
                                      "check a repair; the net stays as it is")
            return
        fix = repair(apn, d, self.learners, exhausted=frozenset(state.lambda_exhausted), skip=frozenset(state.tried))
        if fix is None:
            state.repairs_without_effect += 1
            self._no_repair(state, d, "no repair operator applies"
                            + (f" that was not tried already ({', '.join(state.tried)})" if state.tried else ""))
            return
        first = self.model.version
        for rev in fix.revisions:
            self._record(state, replace(rev, evidence={**rev.evidence, "candidate": fix.key}), d.to_json())
        state.tried.append(fix.key)
        state.trying = {"key": fix.key, "before_version": first, "version": self.model.version,
                        "after_trial": state.trial - 1, "visited": sorted(d.visited),
                        "failed": list(state.failed_since_repair)}
        self._watch(state, first, self.model.version)
        state.failed_since_repair = []

    def _no_repair(self, state: PracticeState, d: Any, why: str) -> None:
        """Constant failure that changes nothing: recorded with ``why`` and the diagnosis."""
        state.revisions.append({"version": None, "operator": "none", "target": "", "after_trial": state.trial - 1,
                                "scenario": self.name, "reason": f"constant failure, but {why}",
                                "diagnosis": d.to_json()})
        state.failed_since_repair = []


def _round(x: float | None) -> float | None:
    return None if x is None else round(float(x), 4)
