"""What every part of practice shares: the model, the config, the scenario's name, the learners and
the robot's own experience, and the one way a revision is recorded."""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

from ...model import SkillModel
from ..learners import ModelLearners
from ...petri.net import Condition
from ...petri.revision import Revision, set_condition
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

    def set_learned_condition(self, state: PracticeState, transition: str, model: str, reason: str,
                              evidence: dict[str, Any]) -> int:
        """A recorded ``set_condition`` revision: ``transition`` fires on the learned condition
        ``model`` from now on, yielding to the same transitions and held to the same region as before;
        returns its version."""
        apn = self.model.apn
        old = apn.transition(transition).condition
        ref = Condition.learned(model, old.unless, old.within).to_data()
        _, rev = set_condition(apn, transition, ref, reason, evidence)
        return self.record(state, rev)

    def room_to_watch(self, state: PracticeState) -> bool:
        """Whether enough trials are left to watch a revision made now."""
        return self.config.max_trials - state.trial >= self.config.watch_trials()

    def source(self, k: int) -> str:
        """The id of trial ``k`` in the label store and the experience store."""
        return f"{self.name}_{k}"
