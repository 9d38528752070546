"""Watching revisions: a revision made while practice learns is compared, over the plain trials that
follow it, with the plain trials before it, and reverted if it made things worse.

Unpaired (``exam`` off): reverted if the robot's own success rate over the next ``revert_window``
plain trials is clearly worse than over the ``revert_window`` before (one-sided Fisher test at
:data:`~.config.REVERT_P`). Paired (``exam``): the ``revert_window`` trials after a revision replay
the draws (seed, start, push) of the plain trials before it, without exploring, and the revision is
reverted if it lost at least :data:`~.config.EXAM_MARGIN` more of those same trials than it won.
Paired, ten trials see a drop that two independent windows of ten cannot (a fall from 8/10 to 6/10
is p ≈ 0.3 unpaired).
"""

from __future__ import annotations

from scipy.stats import fisher_exact

from ...petri.revision import revert
from .config import EXAM_MARGIN, REVERT_P
from .context import Context
from .state import PracticeState, TrialRecord, Watch


class RevisionWatch:
    """Starts, follows and judges the watch of a scenario's revisions."""

    def __init__(self, ctx: Context):
        self.ctx = ctx

    def start(self, state: PracticeState, before_version: int, version: int,
              trials: list[TrialRecord] | None = None, must_win: bool = False, then_stop: str | None = None,
              by_margin: bool = False, refit_on_revert: bool = False) -> None:
        """Watch the revisions up to ``version``: compared over the next plain trials with the plain
        trials before them (``trials``: these instead of the last ``revert_window``); with
        ``refit_on_revert`` a paired exam that reverts them makes the laws' refit due at once. Only
        while practice learns."""
        cfg = self.ctx.config
        if not cfg.learn:
            return
        last = state.plain()[-cfg.revert_window:] if trials is None else trials
        state.watch = Watch(before_version=before_version, version=version, after_trial=state.trial - 1,
                            before=[bool(t.success) for t in last], must_win=must_win, by_margin=by_margin,
                            then_stop=then_stop, refit_on_revert=refit_on_revert,
                            draws=[t.drawn for t in last] if cfg.exam else None)

    @staticmethod
    def exam_draw(state: PracticeState) -> int | None:
        """The draw the next trial replays while a revision is examined (None: a fresh trial)."""
        w = state.watch
        if w is None or w.draws is None:
            return None
        i = state.trial - w.after_trial - 1
        return w.draws[i] if 0 <= i < len(w.draws) else None

    def check(self, state: PracticeState) -> None:
        """Judge the watched revision once its trials are in: keep it or revert it."""
        w, cfg = state.watch, self.ctx.config
        if w is None:
            return
        after = [bool(t.success) for t in state.plain() if t.trial > w.after_trial]
        if w.draws is not None:
            if len(after) < len(w.draws):
                return
            state.watch = None
            state.last_refit_trial = max(state.last_refit_trial, state.trial - 1)
            if self.ctx.model.version == w.version and w.draws:
                if not self._paired_verdict(state, w, after[:len(w.draws)]) and w.refit_on_revert:
                    state.refit_now = True
            self._after_exam(state, w)
            if w.then_stop:
                state.done, state.stop_reason = True, f"{w.then_stop}, then the ways back's floor examined"
            return
        if len(after) < cfg.revert_window:
            return
        state.watch = None
        before = w.before
        if len(before) < cfg.revert_window // 2 or self.ctx.model.version != w.version:
            return
        table = [[sum(before), len(before) - sum(before)], [sum(after), len(after) - sum(after)]]
        p = float(fisher_exact(table, alternative="greater")[1])
        if p >= REVERT_P:
            return
        self._revert(state, w, f"own success rate fell from {sum(before)}/{len(before)} to {sum(after)}/{len(after)} "
                                f"plain trials after version {w.version} (one-sided Fisher p = {p:.3f})",
                     {"before": table[0], "after": table[1], "p": round(p, 4)})

    def _after_exam(self, state: PracticeState, w: Watch) -> None:
        """A refit that passed its exam gives the repair candidates tried before it a new chance:
        they were judged with the old laws (a way back after a push does not help while the swing-up
        law cannot recover from where the push leaves the pendulum; after takeovers there it may)."""
        refitted = any(r.operator == "refit_law" and r.version is not None
                       and w.before_version < r.version <= w.version for r in state.revisions)
        if refitted and self.ctx.model.version == w.version:
            state.tried = []

    def _paired_verdict(self, state: PracticeState, w: Watch, after: list[bool]) -> bool:
        """Revert the examined revision if it lost :data:`~.config.EXAM_MARGIN` more of the replayed
        trials than it won; one that must win (``must_win``: a change no failure asked for) unless
        it won that many more than it lost, or (unless ``by_margin``) won some and lost none.
        Returns whether it was kept."""
        before = w.before
        lost = sum(b and not a for b, a in zip(before, after))
        won = sum(a and not b for b, a in zip(before, after))
        if w.must_win:
            kept = won - lost >= EXAM_MARGIN or bool(won and not lost and not w.by_margin)
        else:
            kept = lost - won < EXAM_MARGIN
        if kept:
            return True
        self._revert(state, w, f"the same {len(after)} trials replayed after version {w.version}: {sum(before)} -> "
                               f"{sum(after)} successes ({lost} lost, {won} won)",
                     {"before": [sum(before), len(before) - sum(before)],
                      "after": [sum(after), len(after) - sum(after)], "lost": lost, "won": won, "draws": w.draws})
        return False

    def _revert(self, state: PracticeState, w: Watch, reason: str, evidence: dict) -> None:
        model = self.ctx.model
        _, rev = revert(model.apn, w.before_version, model.history.version(w.before_version), reason,
                        {**evidence, "reverted": w.version})
        self.ctx.record(state, rev)
