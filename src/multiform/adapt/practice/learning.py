"""Learning from practice (the paper's third form in full): the robot's own graded successes, the
mentor's grades of some trials and its takeovers of failed ones, and refits of the laws from them.

* Own segments: the stays a trial's judges grade successful with a margin join the laws' own
  training data (:mod:`..experience`).
* The mentor grades every ``mentor_every``-th trial from the trial's trace alone (each stay the
  judges graded); the labels revise the judges, and each label that contradicts the robot's own
  grade is counted.
* The mentor takes over failed trials (:mod:`..takeover`): a demonstration from where the robot
  knew least, learned from at the next refit. Grades and takeovers share the mentor's time,
  ``mentor_trials`` (:meth:`~.config.PracticeConfig.budgets`).
* With several mentors, every graded trial and every mentor's grade updates how far each mentor is
  trusted (:mod:`multiform.learn.fusion`), which the next refits and judge revisions use.
* Every ``refit_every`` trials, while the plain trials show the skill falls short of
  ``target_rate`` (read off at least ``shortfall_after`` plain trials of the net as it is now),
  each law with new own data is refitted from the mentor's and its own data (a ``refit_law``
  revision, watched like every other).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

from scipy.stats import binomtest

from ...demos.episode import Episode, SegmentLabel
from ...learn.gp import GPLaw
from ...learn.judge import TrialGrade
from ...learn.labels import is_mentor, records_from_episode
from ...learn.training import LawSettings, fit_law
from ...learn.views import is_demonstration, place_episode
from ...model import SkillModel
from ...petri.net import APN
from ...petri.revision import refit_law
from ...runtime.trace import Trace
from ..diagnosis import is_evidence
from ..experience import select_segments
from ..learners import refit_judges
from ..takeover import stuck_tick
from .config import REVERT_P
from .context import Context
from .state import MentorGrade, PracticeState, Takeover, TrialRecord
from .watch import RevisionWatch

MentorGrader = Callable[[Episode, APN], list[SegmentLabel]]
TakeoverFn = Callable[[Trace, int], "Episode | None"]


class Learning:
    """One scenario's learning from practice; ``mentor`` grades a trial (its trace as an episode and
    the net that ran it → one label per stay), ``takeover`` demonstrates from a tick of a failed
    trial."""

    def __init__(self, ctx: Context, watch: RevisionWatch, mentor: MentorGrader | None = None,
                 takeover: TakeoverFn | None = None):
        self.ctx, self.watch = ctx, watch
        self.mentor, self.takeover = mentor, takeover
        self.mentor_budget, self.takeover_budget = ctx.config.budgets(takeover is not None)

    # -- after each trial --------------------------------------------------------------------------
    def learn_from(self, state: PracticeState, record: TrialRecord, trace: Trace, grade: TrialGrade,
                   apn: APN) -> None:
        """The mentor's grade (on schedule), then the own segments the trial adds; the mentor takes
        over a failed trial. Fills ``record``'s ``mentor``, ``takeover`` and ``own_segments``."""
        cfg, k = self.ctx.config, record.trial
        source = self.ctx.source(k)
        verdicts: dict[tuple[int, int], bool] = {}
        graded = {g.trial for g in state.mentor_graded}
        if (self.mentor is not None and cfg.mentor_every > 0 and k % cfg.mentor_every == cfg.mentor_every - 1
                and len(graded) < self.mentor_budget and k not in graded):
            verdicts, record.mentor = self.mentor_grades(k, trace, grade, apn)
            state.mentor_graded.append(record.mentor)
        taken = {t.trial for t in state.takeovers}
        if (self.takeover is not None and not record.success and is_evidence(trace.outcome) and k not in taken
                and len(taken) < self.takeover_budget):
            record.takeover = self._take_over(k, trace, apn)
            state.takeovers.append(record.takeover)
        own = select_segments(apn, trace, grade, source, self.ctx.name, k, cfg.margin, verdicts)
        if own:
            self.ctx.experience.add(trace, own, source)
        record.own_segments = len(own)
        self._weigh_mentors(k, trace, grade, apn)

    def _weigh_mentors(self, k: int, trace: Trace, grade: TrialGrade, apn: APN) -> None:
        """With several mentors: the trial, as the robot graded it, is evidence on the mentors whose
        demonstrated maneuvers it reproduced (:meth:`~multiform.learn.fusion.Fusion.observe_trial`)."""
        model = self.ctx.model
        fusion = model.fusion()
        if fusion is None:
            return
        stays = {(g.start, g.end): bool(g.success) for g in grade.segments}
        if fusion.observe_trial(apn, model.raw_episodes, trace.to_episode(), stays, model.history.version(0)):
            fusion.snapshot(f"trial {k}", scenario=self.ctx.name, trial=k)
            model.save_fusion(fusion)

    def mentor_grades(self, k: int, trace: Trace, grade: TrialGrade, apn: APN
                      ) -> tuple[dict[tuple[int, int], bool], MentorGrade]:
        """The mentor labels every stay of trial ``k`` the judges graded; the labels go to the label
        store and revise the judges. Returns the verdicts by stay and the grade's account."""
        ctx = self.ctx
        source = ctx.source(k)
        ep = trace.to_episode()
        placed = place_episode(apn, ep)
        robot = {(g.start, g.end): g.success for g in grade.segments}
        labels = [lab for lab in self.mentor(placed, apn) if (lab.start, lab.end) in robot]
        verdicts = {(lab.start, lab.end): bool(lab.success) for lab in labels}
        records = records_from_episode(source, labels, lambda p: p)
        account = MentorGrade(trial=k, stays=len(verdicts), agree=int(sum(robot.get(key) == v for key, v in verdicts.items())),
                              mentor_success=int(sum(verdicts.values())),
                              robot_success=int(sum(robot.get(key, False) for key in verdicts)))
        fusion = ctx.model.fusion()
        if fusion is not None and labels:       # several mentors: the grades join what their trust rests on
            fusion.observe_grades(apn, ep, source, labels)
            ctx.model.save_fusion(fusion)
        if records:
            ctx.experience.keep_trace(trace, source)
            ctx.model.labels.add_many(records)
            graded = {s: ctx.experience.episode(s) for s in self._mentor_sources()
                      if ctx.experience.trace_path(s).exists()}
            info = refit_judges(ctx.model, sorted({r.place for r in records}), {**graded, source: ep},
                                seed=ctx.config.seed)
            account.revised = {p: {key: v for key, v in d.items() if key in ("segments", "cv_score", "kernel")}
                               for p, d in info.items()}
        return verdicts, account

    def _take_over(self, k: int, trace: Trace, apn: APN) -> Takeover:
        """The mentor demonstrates from where the failed trial got stuck (:mod:`..takeover`)."""
        tick = stuck_tick(trace, apn, self.ctx.model.laws(apn))
        if tick is None:
            return Takeover(trial=k)
        ep = self.takeover(trace, tick)
        if ep is None:
            return Takeover(trial=k, tick=tick)
        self.ctx.experience.add_takeover(ep, self.ctx.source(k), apn.name, apn.env)
        return Takeover(trial=k, tick=tick, time=round(tick * trace.dt, 3), samples=int(ep.num_samples),
                        outcome=ep.outcome)

    def _mentor_sources(self) -> list[str]:
        return sorted({r.source for r in self.ctx.model.labels if not is_demonstration(r.source)
                       and is_mentor(r.labeller)})

    # -- refits ------------------------------------------------------------------------------------
    def refit_due(self, state: PracticeState) -> bool:
        """Every ``refit_every`` trials (while no exam runs), or at once after a reverted switch exam
        (``refit_now``), with room left to watch the refit."""
        cfg = self.ctx.config
        return (cfg.learn and (state.watch is None or not cfg.exam)
                and (state.refit_now or state.trial - state.last_refit_trial - 1 >= cfg.refit_every)
                and self.ctx.room_to_watch(state))

    def falls_short(self, state: PracticeState) -> bool:
        """The plain trials of the net as it is now fail more often than the target allows: the
        chance of that many failures at a success rate of ``target_rate`` is below
        :data:`~.config.REVERT_P` (one-sided binomial test), read off at least ``shortfall_after`` of
        them: a failure or two in a skill's first few trials is mostly chance when it succeeds nine
        times in ten or more."""
        cfg = self.ctx.config
        current = state.plain_of(self.ctx.model.version)
        if len(current) < cfg.shortfall_after:
            return False
        failures = sum(not t.success for t in current)
        if failures == 0 or cfg.target_rate >= 1.0:
            return failures > 0
        p = binomtest(failures, len(current), 1.0 - cfg.target_rate, alternative="greater").pvalue
        return bool(p < REVERT_P)

    def refit(self, state: PracticeState) -> None:
        """Refit each law that has new own segments since its fit, of which some samples are new to
        the law (:func:`~multiform.learn.training.fit_law`, ``own_required``); one ``refit_law``
        revision each, watched together. Only a skill whose plain trials show it falls short of the
        target is refitted (:meth:`falls_short`): an exam of ``revert_window`` replayed trials cannot see a
        refit cost a few points, so a skill already near its target has more to lose than to gain. After a
        reverted switch exam (``refit_now``) the shortfall that called the exam stands for the net it
        returned to, whose own plain trials are yet to come."""
        ctx, cfg = self.ctx, self.ctx.config
        model = ctx.model
        state.last_refit_trial = state.trial - 1
        shown, state.refit_now = state.refit_now, False
        if cfg.target_rate > 0 and not shown and not self.falls_short(state):
            return
        apn = model.apn
        segments = ctx.experience.segments()
        takeovers = ctx.experience.takeovers() if self.takeover_budget else {}
        made = []
        for law in apn.laws:
            mine = [s for s in segments if law in s.laws]
            seen = self._fitted_sources(law)
            new = [s for s in mine if s.source not in seen]
            new_takeovers = sorted(set(takeovers) - self._fitted_sources(law, "takeovers"))
            if len(new) < cfg.refit_min_segments and not new_takeovers:
                continue
            own = ctx.experience.law_episodes(law, mine)
            refitted, info = fit_refit(model, law, own, list(takeovers.values()), apn, cfg.seed, cfg.novelty,
                                       current=model.laws(apn).get(law), own_required=not new_takeovers)
            if refitted is None:        # none of its own samples is new to the law: nothing to refit on
                continue
            fit = ctx.learners.fresh_law(law)
            model.save_law(fit, refitted)
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
                                              f"and its own data", evidence)
            made.append(ctx.record(state, rev, {"refit": info}))
            apn = model.apn
        if made:
            self.watch.start(state, made[0] - 1, made[-1])

    def _fitted_sources(self, law: str, key: str = "sources") -> set[str]:
        """The trials whose own segments (``key`` "takeovers": whose takeovers) the last recorded
        refit of ``law`` learned from."""
        for r in reversed(self.ctx.model.history.revisions()):
            if r.operator == "refit_law" and r.target == law:
                return set(r.evidence.get(key, ()))
        return set()


def fit_refit(model: SkillModel, law: str, own: Sequence[Episode], takeovers: Sequence[Episode], own_apn: APN,
              seed: int, novelty: float, **kw: Any) -> tuple[GPLaw | None, dict[str, Any]]:
    """``law`` fitted as practice refits it: from the mentor's demonstrations, its ``takeovers`` and
    the robot's ``own`` episodes (run by ``own_apn``), whose samples join where the mentor-only law is
    unsure by ``novelty``; ``kw`` go to :func:`~multiform.learn.training.fit_law`."""
    mentor_net = model.history.version(0)
    return fit_law(mentor_net, model.episodes + list(takeovers), law, seed=seed, own=own, own_apn=own_apn,
                   mentor_law=model.laws(mentor_net).get(law), settings=LawSettings(own_novelty=novelty),
                   fusion=model.fusion(), **kw)


def _round(x: float | None) -> float | None:
    return None if x is None else round(float(x), 4)
