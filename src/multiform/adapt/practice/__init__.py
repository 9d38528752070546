"""Practice: trials from P0, graded by the judges; on constant failure, diagnose and repair; while
learning, refit the laws from the robot's own graded experience and the mentor's help.

The parts, one module each:

* :mod:`.config` — :class:`PracticeConfig`: when practice counts as constant failure, what it
  learns, when it is done;
* :mod:`.state` — :class:`PracticeState` and its typed records, ``state.json`` read back checked;
* :mod:`.loop` — :class:`Practice`: the trial loop and what is due after each trial;
* :mod:`.repairs` — repair with revert, and the definition held against the demonstrations
  before the first trial (``check_demonstrations``);
* :mod:`.learning` — learning from practice: own segments, the mentor's grades and takeovers,
  refits of the laws (``learn``);
* :mod:`.watch` — every revision made while learning is watched, paired (``exam``) or not, and
  reverted if it made things worse;
* :mod:`.floors` — the ways back's floor examined once at the end (``floor_exam``);
* :mod:`.switches` — a learned switch's smoothest setting examined at the first shortfall (``switch_exam``);
* :mod:`.ranges` — a learned switch held to where the mentor switched, where its own firings
  outside that range fail, examined at a shortfall (``range_exam``).

With ``learn`` the loop also explores on every ``explore_every``-th trial (:mod:`..explore`), so its
own data holds variations of its maneuvers and not only their repetition; the other trials measure
the skill as it is, and it stops when its own success rate over the last ``target_window`` plain
trials reaches ``target_rate``. A refit that passed its exam gives the repair candidates tried
before it a new chance: they were judged with the old laws.
"""

from .config import REPAIR_ONLY, PracticeConfig
from .loop import Practice
from .state import (MentorGrade, PracticeState, RevisionRecord, Takeover, TrialRecord, Trying, Watch,
                    state_from_json, state_to_json)

__all__ = ["REPAIR_ONLY", "MentorGrade", "Practice", "PracticeConfig", "PracticeState", "RevisionRecord", "Takeover", "TrialRecord",
           "Trying", "Watch", "state_from_json", "state_to_json"]
