"""What practice does and when it stops: :class:`PracticeConfig`."""

from __future__ import annotations

import math
from dataclasses import dataclass

from ...errors import InvalidInput
from ..experience import DEFAULT_MARGIN

REVERT_P = 0.1          # one-sided p below which a drop in the robot's own success rate reverts a revision
EXAM_MARGIN = 2         # replayed trials a revision may lose more than it wins (one is what chaos in a swing-up gives)
EXPLORE_TAU = 0.1       # s: how smooth an exploring law's deviation is (:class:`~multiform.adapt.explore.ExploringLaw`)


@dataclass
class PracticeConfig:
    """When practice counts as constant failure, what it learns, and when it is done.

    The defaults are the method's settings, used by every bundled task: practice that repairs the
    net and learns from its own graded experience (``learn``), exploring on every other trial,
    refitting every ten trials where the plain trials fall short of ``target_rate``, each revision
    examined on the same trials replayed (``exam``), the mentor's time (``mentor_trials``) split
    between grading trials and taking over failed ones, the ways back's floor examined at the end,
    a learned switch's smoothest setting examined at the first shortfall (``switch_exam``), and a learned
    switch held to where the mentor switched where its own firings outside that range fail (``range_exam``).
    :data:`REPAIR_ONLY` is practice that only repairs (the paper's two scenarios).

    Constant failure: ``failures_in_a_row`` failed trials in a row, or (if ``window`` > 0) at least
    ``failure_rate`` of the last ``window`` trials since the last repair. Done: ``success_streak``
    successes in a row (0: not a reason to stop), the target rate (``target_rate`` over
    ``target_window`` plain trials of the net as it is), or ``max_trials`` trials. The learning
    options are described in :mod:`multiform.adapt.practice`.
    """

    failures_in_a_row: int = 3
    window: int = 0
    failure_rate: float = 0.8
    success_streak: int = 0
    max_trials: int = 100
    seed: int = 0
    learn: bool = True
    margin: float = DEFAULT_MARGIN
    explore: float = 0.5                # an exploring law's deviation, in units of the law's own noise level
    explore_every: int = 2
    refit_every: int = 10
    refit_min_segments: int = 5
    mentor_every: int = 3               # the mentor grades every third trial ...
    mentor_trials: int = 20             # ... and gives at most this many trials of its time, half of them
                                        # taking over failed trials where the task lets it
    target_rate: float = 0.95
    target_window: int = 20
    shortfall_after: int = 0
    revert_window: int = 10
    exam: bool = True
    novelty: float = 0.5                # own samples join a law only where its mentor-only fit is this unsure
    floor_exam: float = -4.0            # a state σ(-4) ≈ 1/50 as likely to be in its place as at its boundary
    check_demonstrations: bool = True
    deliberate: bool = False            # exploring trials pushed or not as the robot's weaker condition asks
    switch_exam: bool = True            # at the first shortfall, the learned switches' smoothest setting examined
    range_exam: bool = True             # at a shortfall, a learned switch held to the mentor's range where it fails outside
    max_robot_seconds: float = 0.0      # practice stops once its trials add up to this much robot time (0: no limit)

    def budgets(self, takes_over: bool) -> tuple[int, int]:
        """(trials the mentor grades, failed trials it takes over) of ``mentor_trials``: half and
        half where it can take over (``takes_over``), else all graded."""
        takeovers = self.mentor_trials // 2 if takes_over else 0
        return self.mentor_trials - takeovers, takeovers

    def __post_init__(self) -> None:
        counts = {"failures_in_a_row": 1, "window": 0, "success_streak": 0, "max_trials": 1, "seed": 0,
                  "explore_every": 0, "refit_every": 1, "refit_min_segments": 1, "mentor_every": 0,
                  "mentor_trials": 0, "target_window": 1, "shortfall_after": 0, "revert_window": 1}
        for name, low in counts.items():
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or not low <= v <= 1_000_000:
                raise InvalidInput(f"must be a whole number in {low}..1000000, got {v!r}", element=name)
        v = self.floor_exam
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not -1e6 <= v <= 0.0:
            raise InvalidInput(f"must be a logit in -1000000..0, got {v!r}", element="floor_exam")
        for name in ("failure_rate", "margin", "target_rate", "explore", "novelty"):
            v = getattr(self, name)
            if isinstance(v, bool) or not (isinstance(v, (int, float)) and math.isfinite(v)
                                           and 0.0 <= v <= (10.0 if name == "explore" else 1.0)):
                raise InvalidInput(f"out of range: {v!r}", element=name)
        v = self.max_robot_seconds
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not (math.isfinite(v) and 0.0 <= v <= 1e7):
            raise InvalidInput(f"must be seconds in 0..10000000, got {v!r}", element="max_robot_seconds")
        for name in ("learn", "exam", "check_demonstrations", "deliberate", "switch_exam", "range_exam"):
            if not isinstance(getattr(self, name), bool):
                raise InvalidInput(f"must be true or false, got {getattr(self, name)!r}", element=name)

    def stops_on_streak(self, successes: int) -> bool:
        """``successes`` in a row end practice."""
        return 0 < self.success_streak <= successes

    def explores(self, k: int) -> bool:
        """Trial ``k`` explores (every ``explore_every``-th trial, when exploring at all)."""
        return self.explore > 0 and self.explore_every > 0 and k % self.explore_every == self.explore_every - 1

    def trial_seed(self, k: int) -> int:
        """The seed of draw ``k`` (a function of the index: a resumed loop sees the same trials)."""
        return 1_000_003 * (self.seed + 1) + k

    def watch_trials(self) -> int:
        """Trials it takes to see ``revert_window`` plain ones after a revision."""
        if self.exam:
            return self.revert_window
        return self.revert_window * (self.explore_every if self.explore > 0 and self.explore_every > 1 else 1)


REPAIR_ONLY = {"learn": False, "explore": 0.0, "target_rate": 0.0, "exam": False, "success_streak": 5,
               "floor_exam": 0.0}
"""The fields that make :class:`PracticeConfig` practice that only repairs: done after five successes
in a row."""
