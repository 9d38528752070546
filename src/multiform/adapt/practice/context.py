"""What every part of practice shares: the model, the config, the scenario's name, the learners and
the robot's own experience, and the one way a revision is recorded."""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

from ...model import SkillModel
from ..learners import ModelLearners
from ...petri.revision import Revision
from ..experience import Experience
from .config import PracticeConfig
from .state import PracticeState, RevisionRecord


@dataclass
class Context:
    """One scenario's practice on one model."""

    model: SkillModel
    config: PracticeConfig
    name: str
    learners: ModelLearners
    experience: Experience

    def record(self, state: PracticeState, rev: Revision, diagnosis: dict[str, Any] | None = None) -> int:
        """Record ``rev`` in the model's history (tagged with the scenario) and in ``state``; returns
        its version."""
        rev = self.model.history.record(replace(rev, evidence={**rev.evidence, "scenario": self.name}))
        state.revisions.append(RevisionRecord(version=rev.version, operator=rev.operator, target=rev.target,
                                              reason=rev.reason, after_trial=state.trial - 1, scenario=self.name,
                                              diagnosis=diagnosis))
        return rev.version

    def room_to_watch(self, state: PracticeState) -> bool:
        """Whether enough trials are left to watch a revision made now."""
        return self.config.max_trials - state.trial >= self.config.watch_trials()

    def source(self, k: int) -> str:
        """The id of trial ``k`` in the label store and the experience store."""
        return f"{self.name}_{k}"
