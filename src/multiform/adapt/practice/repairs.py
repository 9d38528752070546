"""Repair with revert: on constant failure, diagnose the failed trials and repair the net; a repair
that did not help goes back.

A repair is on trial until the next constant failure: if no trial since it succeeded and none
reached a place the failed trials before it never reached, it did not help — the net goes back to
the version before it (a ``revert`` revision) and the next candidate the diagnosis supports is
tried; a candidate is never tried twice under the same laws. A way back is judged only by the
failures that reached the place it leaves: if none of them ended as the failures it was added for, it
stays (:meth:`Repairs._not_refuted`). Trials that ended for a reason outside
the net (a fault, a diverged simulation; see :data:`~..diagnosis.EVIDENCE_OUTCOMES`) are recorded
but are no evidence: they neither count as failures nor enter a diagnosis.

Before the first trial the definition is held against the mentor's demonstrations
(:meth:`Repairs.check_definition`): a give-up rule that would have ended the mentor's own successful
stays is moved (:mod:`..replay`), a recorded revision, so a limit that ends only some trials, and so
never makes practice fail constantly, does not stay.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace
from pathlib import Path
from typing import Any

from ...petri.net import APN
from ...petri.revision import revert
from ...runtime.trace import Trace
from ..diagnosis import diagnose
from ..compare import demonstration_findings
from ..repair import move_limit, relearn_from_mentor, repair, restore_lambda, set_law_from_mentor
from ..replay import replay_limits
from .context import Context
from .state import PracticeState, RevisionRecord, Trying
from .watch import RevisionWatch


_FIX = {"too_loose": relearn_from_mentor,
        "starved": lambda apn, f, learners: restore_lambda(apn, f),
        "wrong_law": lambda apn, f, learners: set_law_from_mentor(apn, f)}


class Repairs:
    """Constant failure, diagnosis and repair of one scenario's net; ``trace_path(k)`` is where the
    failed trial ``k``'s trace was kept."""

    def __init__(self, ctx: Context, watch: RevisionWatch, trace_path: Callable[[int], Path]):
        self.ctx, self.watch, self.trace_path = ctx, watch, trace_path

    def constant_failure(self, state: PracticeState) -> bool:
        """``failures_in_a_row`` failures in a row since the last repair, or (with ``window``) at
        least ``failure_rate`` of the last ``window`` trials since it."""
        cfg = self.ctx.config
        _, fail = state.streak
        if fail >= cfg.failures_in_a_row and len(state.failed_since_repair) >= cfg.failures_in_a_row:
            return True
        if cfg.window > 0:
            first = state.revisions[-1].after_trial + 1 if state.revisions else 0
            since = [t for t in state.trials[-cfg.window:] if t.trial >= first]
            if len(since) >= cfg.window:
                return sum(not t.success for t in since) / len(since) >= cfg.failure_rate
        return False

    def check_definition(self, state: PracticeState) -> None:
        """Before the first trial, what the demonstrations alone show wrong, each a recorded revision
        with the candidate key ``demonstrations:...``: give-up rules that would have ended the
        mentor's own successful stays are moved (:func:`~..replay.replay_limits`); a switch condition
        that holds nearly everywhere the mentor held off is relearned from its switches, a weight of
        0 on a maneuver the mentor took is restored, and a maneuver runs the law that explains the
        mentor's segments of it (:func:`~..compare.demonstration_findings`). Not put on trial like a
        repair from failures: the demonstrations are the evidence, and a later failure need not be
        the definition's."""
        ctx = self.ctx
        mentor = ctx.learners.mentor(ctx.model.apn)
        if mentor is not None:
            for f in replay_limits(ctx.model.apn, mentor):
                self._record_fix(state, move_limit(ctx.model.apn, f), f"demonstrations:{f.transition}", f)
            done: set[str] = set()
            while True:
                apn = ctx.model.apn
                mentor = ctx.learners.mentor(apn)
                found = [f for f in demonstration_findings(apn, mentor) if f"{f.kind}:{f.transition}" not in done]
                if not found:
                    break
                f = found[0]
                done.add(f"{f.kind}:{f.transition}")
                fix = _FIX[f.kind](apn, f, ctx.learners)
                if fix is not None:
                    self._record_fix(state, fix, f"demonstrations:{f.kind}:{f.transition}", f)
        state.checked = True

    def _record_fix(self, state: PracticeState, fix: Any, key: str, finding: Any) -> None:
        for rev in fix.revisions:
            self.ctx.record(state, replace(rev, evidence={**rev.evidence, "candidate": key}),
                            {"findings": [finding.to_json()]})

    def repair(self, state: PracticeState) -> None:
        """Diagnose the failures since the last revision; revert the repair on trial if it did not
        help; then try the next candidate (or record why none applies)."""
        ctx = self.ctx
        model = ctx.model
        apn = model.apn
        # every failed trial kept so far: those since the last repair are diagnosed; all of them
        # lower the leave floors, so a resumed loop lowers them exactly as an uninterrupted one did
        kept = {k: Trace.load(self.trace_path(k)) for k in range(state.trial) if self.trace_path(k).exists()}
        regions = model.regions()
        scorer = regions.scores if regions is not None else None
        names = tuple(regions.input_names) if regions is not None else ()
        leave = ctx.learners.include_own_stays(list(kept.values())) if regions is not None else None

        def diagnosis(net: APN, trials: list[int]) -> Any:
            ok = [t.fired for t in state.trials if t.success and t.trial in set(trials)]
            return diagnose(net, [kept[k] for k in trials if k in kept], scorer, names, leave_below=leave,
                            mentor=ctx.learners.mentor(net), succeeded_fired=ok)

        last = state.last_revision_trial()
        d = diagnosis(apn, [t.trial for t in state.trials if t.trial > last])
        if state.trying is not None:
            trying, state.trying = state.trying, None
            helped = any(t.success for t in state.trials if t.trial > trying.after_trial) \
                or bool(d.visited - set(trying.visited))
            if not helped and model.version == trying.version and not self._not_refuted(state, trying):
                failures = [t.trial for t in state.trials if t.trial > trying.after_trial and not t.success]
                _, rev = revert(apn, trying.before_version, model.history.version(trying.before_version),
                                f"{trying.key} did not help: {len(failures)} failed trial(s) since it, none reached a "
                                f"place the failures before it had not; back to version {trying.before_version} to try "
                                f"the next candidate", {"reverted": trying.version, "candidate": trying.key,
                                                       "failed_trials": failures})
                ctx.record(state, rev, d.to_json())
                apn = model.apn
                d = diagnosis(apn, trying.failed)
        if ctx.config.learn and not ctx.room_to_watch(state):
            # a repair nobody can check would go into the skill untried (a place added 9 trials before
            # the end of a trial run made every pushed evaluation trial alternate between its two transitions)
            left = ctx.config.max_trials - state.trial
            self._no_repair(state, d, f"{left} trials are left, fewer than the {ctx.config.watch_trials()} it takes "
                                      "to check a repair; the net stays as it is")
            return
        fix = repair(apn, d, ctx.learners, exhausted=frozenset(state.lambda_exhausted), skip=frozenset(state.tried))
        if fix is None:
            state.repairs_without_effect += 1
            self._no_repair(state, d, "no repair operator applies"
                            + (f" that was not tried already ({', '.join(state.tried)})" if state.tried else ""))
            return
        first = model.version
        for rev in fix.revisions:
            ctx.record(state, replace(rev, evidence={**rev.evidence, "candidate": fix.key}), d.to_json())
        state.tried.append(fix.key)
        state.trying = Trying(key=fix.key, before_version=first, version=model.version, after_trial=state.trial - 1,
                              visited=sorted(d.visited), failed=list(state.failed_since_repair))
        self.watch.start(state, first, model.version)
        state.failed_since_repair = []

    def _not_refuted(self, state: PracticeState, trying: Trying) -> bool:
        """A way back (``back:``) is refuted only by a failure since it that reached the place it
        leaves and still ended as the failures it was added for did. A failure that never reached
        that place says nothing about it; one that took it and failed further on (in the maneuver
        it leads back to, from states that maneuver's law has not learned yet) shows it doing its
        part, and what is left is for learning from practice and the mentor's takeovers."""
        if not trying.key.startswith("back:"):
            return False
        apn = self.ctx.model.apn
        added = {r.target for r in state.revisions if r.operator == "add_transition" and r.version is not None
                 and trying.before_version < r.version <= trying.version and r.target in apn.transition_ids}
        sources = {p for t in added for p in apn.transition(t).inputs}
        if not sources or sources & set(apn.initial_marking):
            return False
        into = {t.id for t in apn.transitions if sources & set(t.outputs)}
        by_trial = {t.trial: t for t in state.trials}
        ended = {by_trial[k].fired[-1] for k in trying.failed if k in by_trial and by_trial[k].fired}
        since = [t for t in state.trials if t.trial > trying.after_trial and not t.success and t.evidence]
        return not any(into & set(t.fired) and t.fired[-1] in ended for t in since)

    def _no_repair(self, state: PracticeState, d: Any, why: str) -> None:
        """Constant failure that changes nothing: recorded with ``why`` and the diagnosis."""
        state.revisions.append(RevisionRecord(version=None, operator="none", after_trial=state.trial - 1,
                                              scenario=self.ctx.name, reason=f"constant failure, but {why}",
                                              diagnosis=d.to_json()))
        state.failed_since_repair = []
