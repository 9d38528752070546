"""The mentor takes over a failed practice trial: a demonstration from where the robot got stuck.

A person watching a student practise does not only say "that failed": where the student got stuck,
the teacher takes the controls and shows what to do from there (interactive imitation learning:
Ross et al.'s DAgger, Kelly et al.'s HG-DAgger). The robot's laws fail where the mentor's
demonstrations never went (a pendulum spinning after a push, the hand at the end of its stroke);
its own graded successes cannot teach those states, since it rarely succeeds from them.

When a practice trial fails (up to the scenario's ``takeover_budget``), the mentor demonstrates
from the state of that trial where the robot knew least: the tick at which the law running then was least sure of its
command (its posterior standard deviation against its prior's, :func:`stuck_tick`). The task says
how a demonstration starts from a state (a ``takeover`` callable: the trial's trace and the tick →
an :class:`~multiform.demos.episode.Episode` recorded by the mentor, or None). The demonstration is
the mentor's data, kept apart from the demonstrations it was taught with (``experience/takeovers``)
and learned from at the next refit of the laws. A trial the mentor both grades and takes over
counts once against its time.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from ..learn.views import value_matrix
from ..petri.net import APN
from ..runtime.trace import Trace

STEP = 0.02          # s between the ticks weighed
MARGIN = 1.0         # s: not in the first or last second of the trial (no history to show, no time to act)


def stuck_tick(trace: Trace, apn: APN, laws: Mapping[str, Any]) -> int | None:
    """The tick of ``trace`` at which the law that ran was least sure of its command (posterior std
    over prior std), or None if no law ran long enough to weigh."""
    n = len(trace.obs)
    step = max(1, int(round(STEP / trace.dt)))
    lo, hi = int(MARGIN / trace.dt), n - int(MARGIN / trace.dt)
    firings = sorted((f.tick, f.transition) for f in trace.firings)
    if hi <= lo or not firings:
        return None
    ticks = np.arange(lo, hi, step)
    ran = [apn.transition(t).law if t in apn.transition_ids else None for _, t in firings]
    last = np.searchsorted([k for k, _ in firings], ticks, side="right") - 1     # the firing each tick runs under
    active = np.array([ran[i] if i >= 0 else None for i in last], dtype=object)
    episode = trace.to_episode()
    best, where = -1.0, None
    for name in sorted({a for a in active if a is not None and a in laws}):
        law = laws[name]
        at = ticks[active == name]
        X = value_matrix(apn, episode, apn.laws[name].inputs)[at]
        _, std = law.predict(X, return_std=True)
        prior = float(law.sigma_f_) * np.asarray(law.y_scale_, dtype=float).reshape(-1)
        rel = (np.asarray(std).reshape(len(at), -1) / prior).max(axis=1)
        i = int(np.argmax(rel))
        if rel[i] > best:
            best, where = float(rel[i]), int(at[i])
    return where
