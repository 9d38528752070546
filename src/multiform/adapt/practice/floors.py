"""The ways back's floor, examined once at the end of practice (``floor_exam``).

A way back (a transition that leaves a place for another once the state has left the place's
region: :class:`~multiform.learn.region.RegionCondition` with ``rather_than``) fires below a leave
floor, the lowest logit the mentor's successful stays there reached. From few demonstrations that
region is narrow, and the floor stops a law that would have recovered. At the end of practice (its
target reached, or no room left for another revision), every way back whose floor lies above
``floor_exam`` gets that floor, and the trials of the net as it is in which a way back fired are
replayed with it; it is kept only if it wins (a change no failure asked for, see
:class:`~.watch.RevisionWatch`). Only trials in which a way back fired can change: below its old
floor the state never went.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from ...learn.region import RegionCondition
from ...petri.net import APN
from .config import EXAM_MARGIN
from .context import Context
from .state import PracticeState
from .watch import RevisionWatch


@dataclass(frozen=True)
class WayBack:
    """A transition whose learned condition leaves ``place`` below ``floor`` (a calibrated logit)."""

    transition: str
    condition: str          # the learned condition's name
    place: str
    floor: float


def ways_back(apn: APN, conditions: Mapping[str, Any]) -> list[WayBack]:
    """The net's ways back: transitions whose learned condition is a region condition that leaves
    a place (``rather_than``)."""
    out = []
    for t in apn.transitions:
        c = conditions.get(t.condition.model) if t.condition.is_learned else None
        if isinstance(c, RegionCondition) and c.rather_than is not None and c.rather_than in t.inputs:
            out.append(WayBack(t.id, t.condition.model, c.rather_than, c.leave_below))
    return out


class FloorExam:
    """The floor exam of one scenario."""

    def __init__(self, ctx: Context, watch: RevisionWatch):
        self.ctx, self.watch = ctx, watch

    def examine(self, state: PracticeState, then_stop: str | None = None) -> bool:
        """Once: give every way back whose floor lies above ``floor_exam`` that floor and watch it on
        the (at most ``revert_window``) last plain trials of the net as it is in which a way back
        fired. Returns whether the exam started (``then_stop``: practice stops after it)."""
        ctx, cfg = self.ctx, self.ctx.config
        if not (cfg.learn and cfg.exam and cfg.floor_exam < 0.0) or state.floor_examined or state.watch is not None:
            return False
        state.floor_examined = True
        ways = [w for w in ways_back(ctx.model.apn, ctx.model.conditions()) if w.floor > cfg.floor_exam]
        names = {w.transition for w in ways}
        room = min(cfg.revert_window, cfg.max_trials - state.trial)
        replay = [t for t in state.plain_of(ctx.model.version) if names & set(t.fired)][-room:] if room > 0 else []
        if not ways or len(replay) < EXAM_MARGIN:
            return False
        first = ctx.model.version
        for w in ways:
            self.set_floor(state, w, cfg.floor_exam,
                           f"the end of practice: {len(replay)} trials in which a way back fired are replayed with "
                           f"{w.transition}'s floor at {cfg.floor_exam:.2f} instead of {w.floor:.2f}; kept only if "
                           f"it wins {EXAM_MARGIN} more of them than it loses, or some and loses none",
                           {"replayed_trials": [t.trial for t in replay]})
        self.watch.start(state, first, ctx.model.version, replay, must_win=True, then_stop=then_stop)
        return True

    def set_floor(self, state: PracticeState, way: WayBack, floor: float, reason: str, evidence: dict[str, Any]) -> None:
        """A ``set_condition`` revision: way back ``way`` leaves its place below ``floor`` from now on."""
        name, info = self.ctx.learners.with_floor(way.condition, floor)
        self.ctx.set_learned_condition(state, way.transition, name, reason,
                                       {**info, "floor_before": round(way.floor, 4), **evidence,
                                        "after_trial": state.trial - 1})
