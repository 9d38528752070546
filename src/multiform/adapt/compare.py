"""Diagnosis that compares the robot with the mentor: where the net disagrees with the demonstrations.

Each rule holds the robot's failed trials against :class:`~.mentor.MentorEvidence` and returns
findings, each naming one transition, what is wrong and the evidence:

* ``starved`` — λ = 0 (or under 1 % of its choice group): its condition held in failed trials but
  it never fired, and the mentor took it successfully;
* ``dead_branch`` — a maneuver fired in failed trials and in no successful one, that the mentor
  never took successfully, while a sibling could take the token instead;
* ``too_strict`` — the condition holds at few of the moments the mentor switched into it, and
  the robot's failed trials ended waiting in its input place without firing it;
* ``too_loose`` — the condition holds at many states where the mentor chose not to switch, and the
  robot fired it in the failed trials;
* ``limit_too_tight`` — a give-up rule (a transition into a failure place) ended trials that the
  mentor's own timing or states say were still going well: the robot had stayed in the place for
  less than the mentor's successful stays there, or at a state inside what those stays show;
* ``stop_too_late`` — a stop rule into success asks the place to hold longer than the mentor's
  successful stays there ever lasted, and the robot's trials ended in that place without it;
* ``wrong_law`` — the robot's stays after firing a transition ended in failure, and another law of
  the skill explains the mentor's commands in that transition's segments clearly better than the
  law it runs (held-out error, :func:`~.mentor.law_errors`);
* ``missing_transition`` — the mentor's tags name a maneuver the net has no transition for, and the
  robot's failed trials ended waiting in the place the mentor took it from (a stop into success is
  timed by the mentor's holds, like ``missing_stop``);
* ``missing_stop`` — the mentor's successful demonstrations ended in a place from which the net has
  no way to success, and the robot's failed trials ended there after holding it as long as the
  mentor did.
"""

from __future__ import annotations

import math
import operator
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any


from ..petri.analysis import success_reachable
from ..petri.guard import to_text
from ..petri.guard_tree import GREATER, atoms, normal, replace_at, subtree, value_at, variables, with_constant
from ..petri.net import APN, is_clock
from ..runtime.trace import Trace
from .mentor import TIMED_LOOSE, MentorEvidence

STARVED = 0.01          # λ below this share of its choice group counts as starved
STRICT = 0.5            # a condition holding at fewer of the mentor's switch moments is too strict
LOOSE = 0.05            # one holding at more of the mentor's non-switch states is too loose (a timed
                        # clock-only switch: at more than mentor.TIMED_LOOSE of the clock where it held off)
SLACK = 2.0             # a limit moved to the mentor's longest successful stay leaves this much room: the robot's
                        # maneuvers run slower than the mentor's (nunchaku swing-up, 1.25: 87/100 against the sound 97/100)
LAW_RATIO = 0.7         # another law explains a transition's segments when its error is under this share
EXPLAINS = 0.7          # ... and under this held-out NRMSE itself (half the commands' variance or more): a law
                        # near the mean command (NRMSE ~1) explains nothing, even beside one that extrapolates
                        # worse (ball-in-cup: hold at 0.98 beside pump's 1.74 on the mentor's repeated pumping)
BLIND = 0.9             # a condition holding at this much of the mentor's non-switch states switches at once
MIN_USES = 3            # the mentor's successful uses needed to judge a transition's law or put one back
_LT = (operator.lt, operator.le)


@dataclass
class Finding:
    """One disagreement between the robot's trials and the mentor's demonstrations."""

    kind: str
    transition: str
    reason: str
    evidence: dict[str, Any] = field(default_factory=dict)
    condition: str | None = None      # the moved condition, for limit findings, or a missing stop's
    law: str | None = None            # the law that explains the mentor's segments, for wrong_law
    spec: dict[str, Any] | None = None   # the transition to add, for missing_transition and missing_stop

    def to_json(self) -> dict[str, Any]:
        out = {"kind": self.kind, "transition": self.transition, "reason": self.reason, "evidence": self.evidence}
        for k in ("condition", "law", "spec"):
            if getattr(self, k) is not None:
                out[k] = getattr(self, k)
        return out


def compare_with_mentor(apn: APN, traces: Sequence[Trace], mentor: MentorEvidence,
                        succeeded_fired: Sequence[Sequence[str]] = ()) -> list[Finding]:
    """The findings of every rule over ``traces`` (trials of ``apn``) and the firing sequences of
    successful trials not among them (``succeeded_fired``)."""
    failed = [tr for tr in traces if not tr.success]
    if not failed:
        return []
    succeeded = [tr.fired() for tr in traces if tr.success] + [list(f) for f in succeeded_fired]
    out: list[Finding] = []
    for rule in (_starved, _dead_branches, _strictness, _limits, _late_stops, _wrong_laws, _missing_transitions,
                 _missing_stops):
        out += rule(apn, failed, succeeded, mentor)
    return out


def demonstration_findings(apn: APN, mentor: MentorEvidence) -> list[Finding]:
    """What the demonstrations alone show wrong before any trial: a switch condition that holds
    nearly everywhere the mentor chose not to switch (:data:`BLIND`: the robot would switch at
    once), a transition with no weight that the mentor took successfully, and a transition whose
    mentor's segments another law explains far better than the one it runs. Give-up rules that end
    the mentor's own successful stays are :func:`~.replay.replay_limits`'."""
    out = []
    for tid, fit in mentor.conditions.items():
        t = apn.transition(tid) if tid in apn.transition_ids else None
        if t is None or t.condition.is_learned or t.lam == 0 or fit.loose < BLIND:
            continue
        out.append(Finding("too_loose", tid,
                           f"'{t.condition}' holds at {100 * fit.loose:.1f} % of the {fit.negatives} states where the "
                           f"mentor chose not to switch into {tid}: the robot would switch at once", fit.to_json()))
    for t in apn.transitions:
        if t.lam == 0 and mentor.took_success.get(t.id, 0) >= MIN_USES:
            out.append(Finding("starved", t.id,
                               f"λ({t.id}) = 0: it can never fire, but the mentor took it successfully "
                               f"{mentor.took_success[t.id]} time(s)",
                               {"lambda": 0.0, "mentor_took_successfully": mentor.took_success[t.id]}))
        law = _better_law(apn, t.id, mentor)
        if law is not None:
            best, errors = law
            out.append(Finding("wrong_law", t.id,
                               f"the mentor's commands in its {mentor.took_success[t.id]} successful segments of "
                               f"{t.id} are explained by {best} (held-out NRMSE {errors[best]:.2f}) far better than "
                               f"by {t.law}, the law it runs ({errors[t.law]:.2f})",
                               {"heldout_nrmse": {k: round(v, 4) for k, v in errors.items()},
                                "mentor_took_successfully": mentor.took_success[t.id]}, law=best))
    return out


def _better_law(apn: APN, tid: str, mentor: MentorEvidence) -> tuple[str, dict[str, float]] | None:
    """The law that explains the mentor's successful segments of ``tid`` far better (held-out NRMSE
    under :data:`LAW_RATIO` of its own law's, and under :data:`EXPLAINS`) than the law it runs, with every law's
    error; None if its own law is about as good, or there is too little to tell."""
    t = apn.transition(tid)
    if not t.law or mentor.took_success.get(tid, 0) < MIN_USES:
        return None
    errors = mentor.law_errors(apn, tid)
    own = errors.get(t.law)
    others = {k: v for k, v in errors.items() if k != t.law}
    if own is None or not others:
        return None
    best = min(others, key=others.get)
    return None if others[best] >= LAW_RATIO * own or others[best] >= EXPLAINS else (best, errors)


# -- facts about one trial ----------------------------------------------------------------------------

def _end_place(apn: APN, tr: Trace) -> str | None:
    """The non-final place the token was in when the trial ended (its last failure transition's input)."""
    last = tr.firings[-1] if tr.firings else None
    if last is not None and last.transition in apn.transition_ids:
        t = apn.transition(last.transition)
        if any(apn.place(p).final for p in t.outputs):
            return next(iter(t.inputs), None)
    row = tr.marking[-1] if len(tr.marking) else None
    if row is None:
        return None
    for p, n in zip(tr.place_ids, row):
        if n > 0 and p in apn.place_ids and not apn.place(p).final:
            return p
    return None


def _end_tick(apn: APN, tr: Trace) -> int:
    """The tick the trial's last stay ended: its firing into a final place, else the last tick."""
    last = tr.firings[-1] if tr.firings else None
    if last is not None and last.transition in apn.transition_ids and _into_final(apn, last.transition):
        return last.tick
    return tr.num_ticks - 1


def _stay(tr: Trace, place: str, tick: int) -> float:
    """Seconds the token had been in ``place`` without a break at ``tick`` (repeats count as staying)."""
    if place not in tr.place_ids:
        return 0.0
    marked = tr.marking[:, tr.place_ids.index(place)] > 0
    tick = min(tick, len(marked) - 1)
    start = tick
    while start > 0 and marked[start - 1]:
        start -= 1
    return (tick - start) * tr.dt


def _values_at(apn: APN, tr: Trace, tick: int, dwell_place: str | None) -> dict[str, float]:
    """Every condition variable as the net saw it when it fired at ``tick``: the recorded row of the
    tick before (the row of the firing tick holds the clocks after the firing), the counts before it."""
    row = max(0, min(tick, tr.num_ticks) - 1)
    env = {n: float(v) for n, v in zip(tr.value_names, tr.values[row])}
    env["time"] = tick * tr.dt
    for p in tr.place_ids:
        env[f"dwell_{p}"] = float(tr.dwell[row, tr.place_ids.index(p)]) + (tick - row) * tr.dt
    if dwell_place is not None:
        env["dwell"] = env.get(f"dwell_{dwell_place}", 0.0)
    for t in apn.transition_ids:
        env[f"fires_{t}"] = float(sum(1 for f in tr.firings if f.transition == t and f.tick < tick))
    return env


def _fired_in(trs: Sequence[Trace | Sequence[str]], tid: str) -> int:
    """In how many trials (traces or firing sequences) ``tid`` fired."""
    return sum(tid in (tr.fired() if isinstance(tr, Trace) else tr) for tr in trs)


def _into_final(apn: APN, tid: str, kind: str | None = None) -> bool:
    return any(apn.place(p).final and (kind is None or apn.place(p).final == kind)
               for p in apn.transition(tid).outputs)


# -- the rules -----------------------------------------------------------------------------------------

def _starved(apn: APN, failed: list[Trace], succeeded: list[list[str]], mentor: MentorEvidence) -> list[Finding]:
    out = []
    for t in apn.transitions:
        group = [t.id, *apn.siblings(t.id)]
        total = sum(apn.transition(g).lam for g in group)
        if not (t.lam == 0 or (total > 0 and t.lam / total < STARVED)):
            continue
        held = sum(tr.held_ticks.get(t.id, 0) > 0 for tr in failed)
        if held == 0 or _fired_in(failed, t.id) or not mentor.took_successfully(t.id):
            continue
        out.append(Finding("starved", t.id,
                           f"λ({t.id}) = {t.lam:.3g} of {total:.3g} in its choice group: its condition held in {held} "
                           f"failed trial(s) but it never fired; the mentor took it successfully "
                           f"{mentor.took_success[t.id]} time(s)",
                           {"lambda": t.lam, "group_total": total, "held_in_failed_trials": held,
                            "mentor_took_successfully": mentor.took_success[t.id]}))
    return out


def _dead_branches(apn: APN, failed: list[Trace], succeeded: list[list[str]], mentor: MentorEvidence) -> list[Finding]:
    out = []
    for t in apn.transitions:
        if t.lam == 0 or t.condition.is_learned or _into_final(apn, t.id) or mentor.took_successfully(t.id):
            continue
        n = _fired_in(failed, t.id)
        if n < 2 or _fired_in(succeeded, t.id) or not any(apn.transition(s).lam > 0 for s in apn.siblings(t.id)):
            continue
        took_failed = mentor.took_failure.get(t.id, 0)
        out.append(Finding("dead_branch", t.id,
                           f"{t.id} fired in {n} failed trial(s) and in none that succeeded; the mentor never took it "
                           f"successfully ({'only in ' + str(took_failed) + ' failed segment(s)' if took_failed else 'never at all'})"
                           f"; its siblings {', '.join(apn.siblings(t.id))} can take the token",
                           {"fired_in_failed_trials": n, "fired_in_successful_trials": 0,
                            "mentor_took_successfully": 0, "mentor_took_in_failed_segments": took_failed}))
    return out


def _strictness(apn: APN, failed: list[Trace], succeeded: list[list[str]], mentor: MentorEvidence) -> list[Finding]:
    out = []
    for tid, fit in mentor.conditions.items():
        if tid not in apn.transition_ids or apn.transition(tid).condition.is_learned:
            continue
        t = apn.transition(tid)
        fired = _fired_in(failed, tid)
        waited = sum(_end_place(apn, tr) in t.inputs for tr in failed)
        ev = {**fit.to_json(), "fired_in_failed_trials": fired, "failed_trials": len(failed),
              "failed_waiting_in_" + "_".join(t.inputs): waited}
        if fit.hit < STRICT and 2 * waited >= len(failed) and 2 * fired < len(failed):
            out.append(Finding("too_strict", tid,
                               f"'{t.condition}' holds at {100 * fit.hit:.0f} % of the {fit.switches} moments the mentor "
                               f"switched into {tid}; {waited} of {len(failed)} failed trials ended waiting in "
                               f"{', '.join(t.inputs)}, {fired} fired it", ev))
        elif fit.loose > (TIMED_LOOSE if fit.timed else LOOSE) and 2 * fired >= len(failed):
            out.append(Finding("too_loose", tid,
                               f"'{t.condition}' holds at {100 * fit.loose:.1f} % of the states where the mentor chose "
                               f"not to switch into {tid} (over {fit.negatives}); the robot fired it in {fired} of "
                               f"{len(failed)} failed trials", ev))
    return out


def _limits(apn: APN, failed: list[Trace], succeeded: list[list[str]], mentor: MentorEvidence) -> list[Finding]:
    """Give-up rules that fired where the mentor was still doing well; each held atom's constant is
    moved: a clock scaled to the mentor's longest successful stay (with ``SLACK``), a state bound
    moved beyond the range of the mentor's successful stays."""
    moves: dict[str, dict[tuple, float]] = {}
    notes: dict[str, list[dict[str, Any]]] = {}
    for tr in failed:
        last = tr.firings[-1] if tr.firings else None
        if last is None or last.transition not in apn.transition_ids or not _into_final(apn, last.transition, "failure"):
            continue
        f = apn.transition(last.transition)
        g = f.condition.guard
        place = next(iter(f.inputs), None)
        if g is None or place is None:
            continue
        stay = _stay(tr, place, last.tick)
        mentor_stay = mentor.stay_seconds.get(place)
        env = _values_at(apn, tr, last.tick, place)
        for path, atom in atoms(g.tree):
            expr, op, c = normal(atom)
            names = variables(expr)
            if not names or value_at(atom, env) <= 0:
                continue
            moved = _moved_limit(apn, place, mentor, atom, expr, op, c, names, env, stay, mentor_stay)
            if moved is None:
                continue
            new, note = moved
            notes.setdefault(f.id, []).append(note)
            new = float(f"{new:.4g}")
            best = moves.setdefault(f.id, {})
            old = best.get(path)
            best[path] = new if old is None else (max(old, new) if op in GREATER else min(old, new))
    out = []
    for fid, changes in moves.items():
        text = moved_condition(apn, fid, changes)
        n = len(notes[fid])
        out.append(Finding("limit_too_tight", fid,
                           f"the give-up rule '{apn.transition(fid).condition}' ended {n} failed trial(s) where the "
                           f"mentor's successful stays were still going; moved to '{text}'",
                           {"trials": n, "examples": notes[fid][:3]}, condition=text))
    return out


def moved_condition(apn: APN, tid: str, changes: dict[tuple, float]) -> str:
    """``tid``'s guard with the constant of the atom at each path of ``changes`` set to its value."""
    tree = apn.transition(tid).condition.guard.tree
    for path, value in changes.items():
        tree = replace_at(tree, path, with_constant(subtree(tree, path), value))
    return to_text(tree)


def _moved_limit(apn: APN, place: str, mentor: MentorEvidence, atom: tuple, expr: tuple, op: Any, c: float,
                 names: set[str], env: dict[str, float], stay: float, mentor_stay: float | None
                 ) -> tuple[float, dict[str, Any]] | None:
    """The new constant of a held atom ``expr op c`` of a give-up rule, and the note on why, or None
    if the mentor's successful stays do not move it: a clock's constant scaled by the mentor's
    longest stay over the robot's, a state bound moved beyond the mentor's range. An atom that mixes
    clocks and state is left alone."""
    if all(is_clock(n) for n in names):
        if any(n.startswith("fires_") and not _repeats_in(apn, n[len("fires_"):], place) for n in names):
            return _moved_count(mentor, atom, expr, op, names, env)
        if mentor_stay is None or op not in GREATER or stay <= 0 or stay >= mentor_stay:
            return None
        new = c * SLACK * mentor_stay / stay
        if any(n.startswith("fires_") for n in names):
            new = float(math.ceil(new))
        return new, {"atom": to_text(atom), "robot_stay_s": round(stay, 3),
                     "mentor_longest_successful_stay_s": round(mentor_stay, 3)}
    if any(is_clock(n) for n in names):
        return None
    v = value_at(expr, env)
    moved = moved_state_bound(apn, place, mentor, expr, op, v)
    if moved is None:
        return None
    new, (lo, hi) = moved
    return new, {"atom": to_text(atom), "robot_value": round(v, 4),
                 "mentor_successful_range": [round(lo, 4), round(hi, 4)]}


def _repeats_in(apn: APN, tid: str, place: str) -> bool:
    """Whether ``tid`` loops on ``place``: its count grows with the time spent there, so a limit on
    it scales with the mentor's stay; any other transition's count grows with events, not time."""
    if tid not in apn.transition_ids:
        return False
    t = apn.transition(tid)
    return place in t.inputs and place in t.outputs


def _moved_count(mentor: MentorEvidence, atom: tuple, expr: tuple, op: Any, names: set[str], env: dict[str, float]
                 ) -> tuple[float, dict[str, Any]] | None:
    """A limit on how often a transition other than a repeat of the place fired (``fires_t6 >= 4``:
    four misses) moved just past the most the mentor's successful demonstrations took it, or None
    if the robot had gone past that (the mentor's successes never needed more) or the atom is not
    such a limit. A count of events is compared with counts, never scaled by stay times: a short
    stay since the last event says nothing about how many events the mentor needed."""
    if op not in GREATER or len(names) != 1 or expr[0] != "var":
        return None
    (name,) = names
    tid = name[len("fires_"):]
    done = [ep for ep in mentor.episodes if ep.outcome == "success"]
    if not done:
        return None
    top = max(sum(1 for _, _, t in ep.segments() if t == tid) for ep in done)
    if env.get(name, math.inf) > top:
        return None
    return float(top + 1 if op is operator.ge else top), {
        "atom": to_text(atom), "robot_count": env.get(name), "mentor_most_in_a_success": top}


def moved_state_bound(apn: APN, place: str, mentor: MentorEvidence, expr: tuple, op: Any, v: float
                      ) -> tuple[float, tuple[float, float]] | None:
    """A give-up rule's bound ``expr op c`` on state, held at value ``v``, moved a tenth beyond the range
    of ``expr`` over the mentor's successful stays in ``place`` (and that range); None if ``v`` lies
    outside that range or the mentor never stayed there successfully."""
    rng = mentor.stay_range(apn, place, expr)
    if rng is None or not math.isfinite(v):
        return None
    lo, hi = rng
    if op in GREATER and v <= hi:
        return hi + 0.1 * max(abs(hi), 1e-3), rng
    if op in _LT and v >= lo:
        return lo - 0.1 * max(abs(lo), 1e-3), rng
    return None



def _late_stops(apn: APN, failed: list[Trace], succeeded: list[list[str]], mentor: MentorEvidence) -> list[Finding]:
    """Stop rules into success whose clock asks for more than the mentor's successful stays lasted."""
    out = []
    for s in apn.transitions:
        g = s.condition.guard
        place = next(iter(s.inputs), None)
        if g is None or place is None or not _into_final(apn, s.id, "success") or _fired_in(failed, s.id):
            continue
        mentor_stay = mentor.stay_seconds.get(place)
        if mentor_stay is None:
            continue
        waited = [tr for tr in failed if _end_place(apn, tr) == place
                  and _stay(tr, place, tr.num_ticks - 1) > mentor_stay]
        if 2 * len(waited) < len(failed):
            continue
        tree, changed = g.tree, []
        for path, atom in atoms(g.tree):
            expr, op, c = normal(atom)
            names = variables(expr)
            if names and all(is_clock(n) for n in names) and not any(n.startswith("fires_") for n in names) \
                    and op in GREATER and c > mentor_stay:
                tree = replace_at(tree, path, with_constant(atom, float(f"{mentor_stay:.4g}")))
                changed.append(to_text(atom))
        if not changed:
            continue
        text = to_text(tree)
        out.append(Finding("stop_too_late", s.id,
                           f"'{s.condition}' asks {place} to last longer than the mentor's successful stays there "
                           f"({mentor_stay:.2f} s at most); {len(waited)} of {len(failed)} failed trials stayed longer "
                           f"and never stopped; moved to '{text}'",
                           {"mentor_longest_successful_stay_s": round(mentor_stay, 3), "trials": len(waited),
                            "atoms": changed}, condition=text))
    return out


def _wrong_laws(apn: APN, failed: list[Trace], succeeded: list[list[str]], mentor: MentorEvidence) -> list[Finding]:
    """Transitions after whose firing the robot's stays failed, whose segments in the demonstrations
    another law explains clearly better than the one they run."""
    out = []
    for t in apn.transitions:
        if not t.law or mentor.took_success.get(t.id, 0) < MIN_USES:
            continue
        ended = [tr for tr in failed if t.id in tr.fired() and _end_place(apn, tr) in t.outputs]
        law = _better_law(apn, t.id, mentor) if 2 * len(ended) >= len(failed) else None
        if law is None:
            continue
        best, errors = law
        out.append(Finding("wrong_law", t.id,
                           f"{len(ended)} of {len(failed)} failed trials ended in {', '.join(t.outputs)} after {t.id} "
                           f"fired; the mentor's commands in its {mentor.took_success[t.id]} successful segments are "
                           f"explained by {best} (held-out NRMSE {errors[best]:.2f}) far better than by {t.law}, the "
                           f"law it runs ({errors[t.law]:.2f})",
                           {"ended_after_it": len(ended), "failed_trials": len(failed),
                            "heldout_nrmse": {k: round(v, 4) for k, v in errors.items()},
                            "mentor_took_successfully": mentor.took_success[t.id]}, law=best))
    return out


def _missing_transitions(apn: APN, failed: list[Trace], succeeded: list[list[str]], mentor: MentorEvidence
                         ) -> list[Finding]:
    """Maneuvers the mentor's tags name that the net lacks, where the robot's failed trials waited."""
    out = []
    for m in mentor.missing.values():
        if m.tag in apn.transition_ids or m.tag in apn.place_ids or not set(m.inputs + m.outputs) <= set(apn.place_ids):
            continue
        waited = sum(_end_place(apn, tr) in m.inputs for tr in failed)
        if m.took_success < MIN_USES or 2 * waited < len(failed):
            continue
        # a stop ends the trial: the mentor stopped when the place had been held long enough, a time
        # a condition learned from states alone cannot see; it is timed like an untagged stop
        end = mentor.endings.get(m.inputs[0]) if len(m.inputs) == 1 and \
            all(apn.place(p).final == "success" for p in m.outputs) else None
        out.append(Finding("missing_transition", m.tag,
                           f"the mentor took {m.tag} from {', '.join(m.inputs)} to {', '.join(m.outputs)} in "
                           f"{m.took_success} successful segment(s), but the net has no {m.tag}; {waited} of "
                           f"{len(failed)} failed trials ended waiting in {', '.join(m.inputs)}",
                           {**m.to_json(), "failed_waiting": waited, "failed_trials": len(failed),
                            **({"mentor_shortest_stay_before_it_s": round(end.shortest_stay, 3)} if end else {})},
                           condition=end.stop_condition() if end else None,
                           spec={"in": list(m.inputs), "out": list(m.outputs)}))
    return out


def _missing_stops(apn: APN, failed: list[Trace], succeeded: list[list[str]], mentor: MentorEvidence) -> list[Finding]:
    """Places where the mentor's successful demonstrations ended and the net cannot reach success from:
    a stop is put back, firing once the place has been held as long as the mentor's shortest such
    stay, in the range of the place's judged variables the mentor ended in
    (:meth:`~.mentor.Ending.stop_condition`)."""
    out = []
    success = next((p for p, f in apn.final_places.items() if f == "success"), None)
    for place, end in mentor.endings.items():
        if success is None or place not in apn.place_ids or end.episodes < MIN_USES or success_reachable(apn, [place]) \
                or any(place in m.inputs and success in m.outputs for m in mentor.missing.values()):
            continue
        held = [tr for tr in failed if _end_place(apn, tr) == place
                and _stay(tr, place, _end_tick(apn, tr)) >= end.shortest_stay]
        if 2 * len(held) < len(failed):
            continue
        text = end.stop_condition()
        tid = apn.fresh_id("t")
        out.append(Finding("missing_stop", tid,
                           f"the mentor's {end.episodes} successful demonstrations ending in {place} ended after "
                           f"holding it {end.shortest_stay:.2f} s at least; the net has no way from {place} to "
                           f"success, "
                           f"and {len(held)} of {len(failed)} failed trials ended there after holding it as long; "
                           f"a stop {tid} from {place} to {success} when '{text}'",
                           {"mentor_endings": end.episodes, "mentor_shortest_final_stay_s": round(end.shortest_stay, 3),
                            "mentor_final_ranges": {k: [round(a, 4), round(b, 4)] for k, (a, b) in end.ranges.items()},
                            "failed_ending_there": len(held), "failed_trials": len(failed)},
                           condition=text, spec={"in": [place], "out": [success]}))
    return out

