"""A learned switch's setting, examined on the robot's own trials at the first shortfall (``switch_exam``).

A switch condition the repair learned from the mentor's switches (an SVM, its C, γ and window of
positives chosen by cross-validation over whole demonstrations: :func:`~multiform.learn.training.fit_switch_condition`)
decides, more than anything cross-validation can see, how often the robot's own catches succeed:
on held-out switches most settings hold equally often, and the per-sample false-positive rate that
breaks the tie favours tight regions the robot's own trajectories pass beside. Only the closed loop
tells the settings apart. So the first time the plain trials show that the skill falls short of
its target (the test a refit waits for) with ten plain trials to replay and a failure among them,
in place of that refit, each such condition is refitted with the smoothest setting that holds at
as many held-out switches as any, and those trials are replayed with it. No failure pointed at the
condition, so it must win its exam by :data:`~.config.EXAM_MARGIN` trials (one replayed trial won or
lost is what chaos in a swing-up gives); otherwise it is reverted and the refit it stood in for is
made at once (the shortfall that called the exam holds for the net it returns to).
"""

from __future__ import annotations

from typing import Any

from .config import EXAM_MARGIN
from .context import Context
from .state import PracticeState
from .watch import RevisionWatch


def learned_switches(ctx: Context) -> dict[str, dict[str, Any]]:
    """The net's transitions whose condition is a switch condition learned from the mentor's switches,
    with the evidence of the revision that learned it (its setting and cross-validation)."""
    evidence = {r.evidence.get("model"): r.evidence for r in ctx.model.history.revisions()
                if "cv" in r.evidence and "window" in r.evidence}
    out = {}
    for t in ctx.model.apn.transitions:
        if t.condition.is_learned and t.condition.model in evidence:
            out[t.id] = evidence[t.condition.model]
    return out


class SwitchExam:
    """The switch exam of one scenario."""

    def __init__(self, ctx: Context, watch: RevisionWatch):
        self.ctx, self.watch = ctx, watch

    def examine(self, state: PracticeState) -> bool:
        """Once, when called at the skill's first shortfall: give every learned switch whose
        smoothest setting differs from its own that setting, and watch it on the last
        ``revert_window`` plain trials (they must hold a failure: the exam has to win). Returns whether
        the exam started."""
        ctx, cfg = self.ctx, self.ctx.config
        if not (cfg.learn and cfg.exam and cfg.switch_exam) or state.switch_examined or state.watch is not None:
            return False
        replay = state.plain()[-cfg.revert_window:]
        if len(replay) < cfg.revert_window or all(t.success for t in replay):
            return False
        state.switch_examined = True
        first, made = ctx.model.version, []
        for tid, old in learned_switches(ctx).items():
            if old.get("prefer") == "smooth":
                continue
            cond, info = ctx.learners.fit_switch(ctx.model.apn, tid, prefer="smooth")
            if info["window"] == old["window"] and info["params"] == old["params"]:
                continue
            made.append(self._set(state, tid, cond, info, old, [t.trial for t in replay]))
        if not made:
            return False
        state.last_refit_trial = state.trial - 1
        self.watch.start(state, first, ctx.model.version, replay, must_win=True, by_margin=True,
                         refit_on_revert=True)
        return True

    def _set(self, state: PracticeState, tid: str, cond: Any, info: dict[str, Any], old: dict[str, Any],
             replayed: list[int]) -> int:
        ctx = self.ctx
        name, evidence = ctx.learners.save_switch(tid, cond, info)
        reason = (f"the skill falls short of its target: {tid}'s switch condition refitted with the smoothest "
                  f"setting that holds at as many held-out switches as any (window {info['window']} s, "
                  f"C {info['params']['C']:g}, γ {info['params']['gamma']:g}; was window {old['window']} s, "
                  f"C {old['params']['C']:g}, γ {old['params']['gamma']:g}); {len(replayed)} plain trials are "
                  f"replayed, kept only if it wins {EXAM_MARGIN} more of them than it loses")
        return ctx.set_learned_condition(state, tid, name, reason,
                                         {**evidence, "before": {"model": old["model"], "window": old["window"],
                                                                 "params": old["params"]},
                                          "replayed_trials": replayed, "after_trial": state.trial - 1})
