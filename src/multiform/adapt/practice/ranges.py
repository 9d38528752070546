"""A learned switch held to where the mentor switched, examined on the robot's own trials (``range_exam``).

A switch condition learned from the mentor's switches reads only the variables of the place it
leaves (and those the mentor's own condition read); the robot may meet it in states the mentor never
switched from in the other variables — the ball-in-cup's pull, after a miss, with the cup still far
out where the catch had chased the ball. When the skill falls short of its target, practice looks at
every firing of each learned switch in its trials so far, each counted a success if it was the
trial's last firing of that switch and the trial succeeded: for every state variable the condition
does not read, the firings inside the range of the mentor's switches (their mean ± :data:`SPREAD`
standard deviations) against those outside. Where the ones outside succeed clearly less often (a
one-sided Fisher test at :data:`EVIDENCE_P`, with at least :data:`MIN_OUTSIDE` of them), the
condition is held to that range (``within``), the clearest such variable first, and the last
``revert_window`` plain trials are replayed with it. The firings show where the switch fails, not
that holding it off there helps: the robot must come back into the range in time, and the pumping
or swing that brought it out may not bring it back (the nunchaku's flick held to the mentor's range
lost 8 of 200 flips that way). So it must win its exam by :data:`~.config.EXAM_MARGIN` trials, as
the switch exam must; reverted, the refit it stood in for is made at once. Each variable of a
switch is examined once.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from scipy.stats import fisher_exact

from ...learn.views import switch_data
from ...petri.guard import parse_guard
from ...petri.net import APN, Condition
from ...petri.revision import set_condition
from ...runtime.trace import Trace
from .config import EXAM_MARGIN
from .context import Context
from .state import PracticeState, TrialRecord
from .watch import RevisionWatch

SPREAD = 3.0          # the mentor's range: its switches' mean ± this many standard deviations
EVIDENCE_P = 0.01     # one-sided Fisher p below which firings outside the range fail clearly more often
MIN_OUTSIDE = 5       # firings outside the range needed to judge it
MIN_SWITCHES = 5      # the mentor's switches needed to have a range


def switch_states(apn: APN, trace: Trace, learned: set[str]) -> dict[str, list[dict[str, float]]]:
    """Per transition in ``learned`` that fired in ``trace``, the state (the net's variables and derived
    values, finite ones) at each of its firings."""
    cols = {n: trace.value_names.index(n) for n in (*apn.variables, *apn.derived) if n in trace.value_names}
    out: dict[str, list[dict[str, float]]] = {}
    for f in trace.firings:
        if f.transition in learned:
            row = {n: float(trace.values[f.tick, j]) for n, j in cols.items()}
            out.setdefault(f.transition, []).append({n: round(v, 6) for n, v in row.items() if math.isfinite(v)})
    return out


def firing_outcomes(trials: list[TrialRecord], transition: str) -> tuple[list[dict[str, float]], np.ndarray]:
    """The states at every firing of ``transition`` in ``trials`` and whether each led to success
    (the trial's last firing of it, in a successful trial)."""
    states, ok = [], []
    for t in trials:
        rows = t.switch_states.get(transition, [])
        for i, row in enumerate(rows):
            states.append(row)
            ok.append(bool(t.success and i == len(rows) - 1))
    return states, np.array(ok, dtype=bool)


def range_evidence(mentor: np.ndarray, x: np.ndarray, ok: np.ndarray) -> dict[str, Any] | None:
    """The mentor's range of one variable at its switches (``mentor``: their values; mean ±
    :data:`SPREAD` sd) and how the robot's firings at values ``x`` fared inside and outside it (``ok``:
    each firing's success): the one-sided Fisher p that those outside succeed less often, and both
    counts as [successes, failures]. None where it cannot be judged: fewer than :data:`MIN_SWITCHES`
    switches, non-finite values, fewer than :data:`MIN_OUTSIDE` firings outside or none inside."""
    if len(mentor) < MIN_SWITCHES or not np.all(np.isfinite(mentor)) or not np.all(np.isfinite(x)):
        return None
    mu, sd = float(np.mean(mentor)), float(np.std(mentor, ddof=1))
    lo, hi = mu - SPREAD * sd, mu + SPREAD * sd
    inside = (x >= lo) & (x <= hi)
    if (~inside).sum() < MIN_OUTSIDE or not inside.any():
        return None
    table = [[int(ok[inside].sum()), int((~ok[inside]).sum())], [int(ok[~inside].sum()), int((~ok[~inside]).sum())]]
    return {"low": lo, "high": hi, "p": float(fisher_exact(table, alternative="greater")[1]),
            "inside": table[0], "outside": table[1], "mentor_switches": int(len(mentor))}


class RangeExam:
    """The firing-range exam of one scenario."""

    def __init__(self, ctx: Context, watch: RevisionWatch):
        self.ctx, self.watch = ctx, watch

    def evidence(self, state: PracticeState) -> dict[str, Any] | None:
        """The clearest case of a learned switch whose firings outside the mentor's range, in a
        variable it does not read, fail more often than those inside (not examined before), or None."""
        ctx = self.ctx
        apn = ctx.model.apn
        conditions = ctx.model.conditions()
        best = None
        for t in apn.transitions:
            if not t.condition.is_learned or t.condition.model not in conditions:
                continue
            reads = set(conditions[t.condition.model].input_names)
            names = [n for n in (*apn.variables, *apn.derived)
                     if n not in reads and f"{t.id}:{n}" not in state.ranges_examined]
            trials = [r for r in state.trials if r.evidence and t.id in r.switch_states]
            states, ok = firing_outcomes(trials, t.id)
            if not names or len(ok) < 2 * MIN_OUTSIDE or ok.all() or not ok.any():
                continue
            mentor = switch_data(apn, ctx.learners.switch_episodes(t.id), t.id, names).switch_states
            for j, n in enumerate(names):
                x = np.array([s.get(n, np.nan) for s in states])
                got = range_evidence(mentor[:, j], x, ok)
                if got is not None and got["p"] < EVIDENCE_P and (best is None or got["p"] < best["p"]):
                    best = {"transition": t.id, "variable": n, **got, "firings": len(ok)}
        return best

    def examine(self, state: PracticeState) -> bool:
        """At a shortfall: hold the clearest case (:meth:`evidence`) to the mentor's range and watch it
        on the last ``revert_window`` plain trials (they must hold a failure). Returns whether the exam
        started."""
        ctx, cfg = self.ctx, self.ctx.config
        if not (cfg.learn and cfg.exam and cfg.range_exam) or state.watch is not None:
            return False
        replay = state.plain()[-cfg.revert_window:]
        if len(replay) < cfg.revert_window or all(t.success for t in replay):
            return False
        ev = self.evidence(state)
        if ev is None:
            return False
        tid, n = ev["transition"], ev["variable"]
        state.ranges_examined.append(f"{tid}:{n}")
        apn = ctx.model.apn
        old = apn.transition(tid).condition
        region = f"{n} > {ev['low']:.4g} and {n} < {ev['high']:.4g}"
        within = parse_guard(region if old.within is None else f"({old.within.text}) and {region}")
        (si, fi), (so, fo) = ev["inside"], ev["outside"]
        reason = (f"the skill falls short of its target: {tid} fired with {n} outside the mentor's range "
                  f"({ev['low']:.3g} to {ev['high']:.3g}, the mean ± {SPREAD:g} sd of its {ev['mentor_switches']} "
                  f"switches) {so + fo} times, {so} of them the trial's last and successful, against {si} of "
                  f"{si + fi} inside (one-sided Fisher p = {ev['p']:.2g}); held to that range, {len(replay)} plain "
                  f"trials are replayed, kept only if it wins {EXAM_MARGIN} more of them than it loses")
        first = ctx.model.version
        _, rev = set_condition(apn, tid, Condition.learned(old.model, old.unless, within).to_data(), reason,
                               {**{k: (round(v, 6) if isinstance(v, float) else v) for k, v in ev.items()},
                                "replayed_trials": [t.trial for t in replay], "after_trial": state.trial - 1})
        ctx.record(state, rev)
        state.last_refit_trial = state.trial - 1
        self.watch.start(state, first, ctx.model.version, replay, must_win=True, by_margin=True,
                         refit_on_revert=True)
        return True
