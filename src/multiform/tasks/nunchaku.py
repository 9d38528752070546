"""The nunchaku task: a hand flips a nunchaku — swing-up, release, chain rolling over the back of the
palm, regrasp of the other rod (the paper's second test, Figs. 9-11).

Everything here is the *experiment*: the env and the scripted mentor, how trials are randomised,
the physical success check used to evaluate every variant alike, the practice scenario and the
ablations. The robot itself reads only its own sensors and the free rod's motion estimated from the
wrist load (``phi``, ``omega``, ``load``); the physical check below is the experimenter watching.

The env takes the hand's velocity and wrist-rate commands directly (its servos are the robot's
low-level controller), so this task has no auxiliary inverse model.
"""

from __future__ import annotations

from typing import Any

from ..runtime.trace import Trace
from ..task import Scenario, Task

HOLD_TIME = 0.5                    # s the caught rod must stay in the palm
TOUCH = 0.5                        # N on the back of the hand: the chain rolled over it
BASELINE_WAIT = 6.0                # s: the demo-only harness stops a trial holding a rod after this (twice
                                   # the mentor's flip), so the single law has time to finish a flip
CONSTANT_FAILURE = {"failures_in_a_row": 6, "window": 10}
"""A flip that works most of the time fails now and then (a weak flick, a late catch), and three such
trials in a row are not a flaw in the definition: a repair made on them replaced t4's grip condition
with a switch condition that fired before the catch (observed with 16 demonstrations). Constant
failure is 6 failures in a row or 8 of the last 10 trials."""


class Nunchaku(Task):
    """A hand flips a nunchaku, taught by a scripted mentor's demonstrations and labels from the
    mentor's definition ``nunchaku`` (the paper's Fig. 10)."""

    TASK = "nunchaku"
    ENV_ID = "multiform/Nunchaku-v0"
    SKILL = "nunchaku"                 # the bundled definition (paper Fig. 10), as the mentor wrote it
    DEMOS = 10                         # the fewest with which job seeds 0-2 flip >= 90 %, learning from practice
    DESCRIPTION = ("A hand on a fast 6-DoF base (MuJoCo) learns to flip a nunchaku — swing-up, release, the chain "
                   "rolling over the back of the palm, regrasp of the other rod with a magnet palm — from a scripted "
                   "mentor's demonstrations and labels, sensing the free rod only through the wrist load.")
    TARGET_SUCCESS_RATE = 0.8
    EVALUATION_SEEDS = 70_000_000      # the nunchaku's evaluation trials were always drawn from here
    REPORT = {          # the report's words for this task's pictures (the paper's figure numbers)
        "motion_figure": "Fig. 11",
        "success_trial": "a successful flip: swing-up, release, the chain over the back of the hand, regrasp",
    }
    MENTORS = {         # people of unequal skill (NunchakuMentor's arguments)
        "expert": {"name": "expert", "noise": 0.5, "failure_rate": 0.1},   # steady hands, seldom a fumble
        "average": {"name": "average"},                                     # the default mentor's skill
        # pumps as well as anyone, but flicks and lets go late and unevenly, strokes and turns sloppily
        # after the release, and labels carelessly (three labels in ten the wrong way round)
        "poor": {"name": "poor", "flick_jitter": 0.12, "release_lag": 0.03, "stroke_jitter": 0.35,
                 "label_flip": 0.3},
    }
    PLOT_VARIABLES = [("phi", "φ est. [rad]"), ("omega", "ω est. [rad/s]"), ("hand_q", "wrist q [rad]"),
                      ("hand_x", "hand x [m]"), ("touch", "back touch [N]"), ("grip", "grip")]

    def make_mentor(self, **kwargs: Any):
        """The scripted mentor standing in for a person showing the flip (with fumbles)."""
        from .nunchaku_mentor import NunchakuMentor
        return NunchakuMentor(**kwargs)

    def demo_options(self, seed: int) -> dict[str, Any]:
        """Reset options of demonstration ``seed``: rod mass ±10 %, length ±7 %, chain damping, friction,
        grip position and start pose randomised by the env."""
        return {"randomize": True}

    def trial_options(self, seed: int) -> dict[str, Any]:
        """Reset options of practice and evaluation trials (same randomisation as the demos)."""
        return {"randomize": True}

    def physical_success(self, trace: Trace) -> bool:
        """The whole flip, judged on the nunchaku itself: the held rod was let go, the chain then pressed
        on the back of the hand, and the trial ends with the *other* rod (B) caught in the palm and held
        for at least 0.5 s."""
        if trace.outcome == "diverged":
            return False
        ev = flip_events(trace)
        return (ev["held"] == "b" and ev["release"] is not None and ev["touch"] is not None
                and ev["catch"] is not None and ev["held_for"] >= HOLD_TIME - 1e-9)

    def scenarios(self) -> list[Scenario]:
        """Practice from the mentor's definition on randomised nunchakus (nobody pushes a nunchaku), then
        practice as evaluated that also learns from its own graded experience. Where it departs from the
        method's settings, and why:

        * constant failure is :data:`CONSTANT_FAILURE`, in both;
        * learning aims at 20 plain flips in a row (``target_rate`` 0.98) and refits only on a
          shortfall read off 20 plain trials of the net as it is (``shortfall_after``): a flip that
          fails one time in ten makes 19 of 20 now and then, so at 0.95 practice stopped there without
          learning (10 demos, job seed 0: 88.0 %); and one failure in the first five trials set off
          refits that cost a skill that flipped 97 % nine points (job seed 2);
        * ``explore`` 0.3 and ``novelty`` 0 are the settings its learning from practice was measured
          with (job seeds 0-2)."""
        return [
            Scenario("a_practice", "(a) practice from the mentor's definition on randomised nunchakus",
                     self.trial_options, config=CONSTANT_FAILURE),
            Scenario("b_keep", "(b) practice as evaluated, learning from its own graded experience",
                     self.trial_options, learn=True, mentor=self.mentor_grader,
                     config={**CONSTANT_FAILURE, "target_rate": 0.98, "shortfall_after": 20, "explore": 0.3,
                             "novelty": 0.0}),
        ]

    def ablations(self, model, out, cfg) -> list:
        """The baselines on the same seeds and demonstrations: the unrevised net (if practice revised
        it), and single-form learning from demonstration (one GP law on all demonstration data)."""
        from ..evaluation import Variant
        from .baselines import demo_only_model
        rows = []
        if model.version > 0:
            rows.append(Variant("definition + demonstration, no repair (the mentor's net as written)",
                                str(model.path), net_version=0, notes="before practice revised it"))
        demo_only = demo_only_model(model, out / "baselines" / "demonstration_only",
                                    hold_condition=f"grip > 0.5 and time > {BASELINE_WAIT}", hold_time=HOLD_TIME,
                                    seed=cfg.seed)
        rows.append(Variant("demonstration only (one GP law on all demonstration data, no net)", str(demo_only.path),
                            use_judges=False, notes="one law for all phases, failed demonstrations included"))
        return rows


def flip_events(trace: Trace) -> dict[str, Any]:
    """What the experimenter saw: first release, back touch, the final catch and how long it held,
    and which rod ends in the palm (the env's ``info["scene"]`` at the end of the trial)."""
    from .nunchaku_mentor import release_touch_catch
    grip = trace.value("grip") > 0.5
    scene = trace.final_info.get("scene") or {}
    out: dict[str, Any] = {"held": scene.get("held", ""), "release": None, "touch": None, "catch": None,
                           "held_for": 0.0}
    first, hit, catch = release_touch_catch(grip, trace.value("touch") > TOUCH)
    if first is None:
        return out
    out["release"] = first * trace.dt
    if catch is not None:
        out["catch"] = catch * trace.dt
        out["held_for"] = (len(grip) - catch) * trace.dt
    if hit is not None:
        out["touch"] = hit * trace.dt
    return out
