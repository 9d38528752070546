"""The ball-in-a-cup task: the arm catches a ball on a string in the cup it holds, taught by a person
who guides the arm by hand.

Written as a user writes a task (a :class:`multiform.Task` subclass, through the public API only):
the env, the scripted mentor who teaches it kinesthetically, how demonstrations and trials start,
the experimenter's success check, and the skill file. It sets no practice or learning constants:
how the robot practises and learns is the method's default.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import numpy as np

import multiform

HOLD = 1.0                 # s the ball must rest in the cup
CUP_HALF_WIDTH = 0.04      # m: the ball's centre this close to the cup's axis
CUP_FLOOR, CUP_RIM = 0.015, 0.10   # m: and between these heights above the string's anchor
REST_SPEED = 0.5           # m/s relative to the cup
HAND_START = 0.3           # m: the hand starts anywhere this far either side of the centre
HEIGHT_START = (-0.1, 0.15)  # m: and anywhere in this range of heights about it
HIGH_START = 0.25          # the share of starts with the ball already swinging high
HIGH_ANGLE = (1.2, 1.5)    # rad from hanging, the string taut, the ball at rest: more energy than a pull wants


class BallInCup(multiform.Task):
    """Ball-in-a-cup with the 6-axis arm (``multiform/BallInCup-v0``), from kinesthetic demonstrations."""

    TASK = "ball_in_cup"
    SKILL = "ball_in_cup"                       # the bundled definition, as the mentor wrote it (t2 over-strict)
    ENV_ID = "multiform/BallInCup-v0"
    DEMO_ENV_KWARGS = {"action_mode": "ee"}     # the demonstrations' commands: the hand's velocity in the plane
    KINESTHETIC = True                          # the mentor guides the compliant arm; commands recovered from it
    DEMOS = 10
    DESCRIPTION = ("A 6-axis arm (AUBO i5 kinematics, MuJoCo) learns ball-in-a-cup — pump the ball on its string, "
                   "pull it up over the cup, catch it — from a person who guides the arm by hand (kinesthetic "
                   "demonstrations: the robot keeps only its own sensing), the person's labels and a definition "
                   "with one wrong condition.")
    TARGET_SUCCESS_RATE = 0.9
    ABLATIONS_AFTER_PRACTICE = False            # the baselines are copies of the trained model: run while it practises
    PLOT_VARIABLES = [("ball_x", "ball x [m]"), ("ball_z", "ball z [m]"), ("hand_x", "hand x [m]"),
                      ("hand_z", "hand z [m]")]
    REPORT = {"motion_figure": "ball and hand",
              "success_trial": "a caught ball: pumping (t0, t1), the pull up (t2), the cup under the ball (t3), "
                               "caught (t4)"}

    def make_mentor(self, **kwargs: Any) -> Any:
        """The scripted person who guides the arm (:mod:`multiform.tasks.ball_in_cup_mentor`): its
        decisions are the hand's intended velocity; on the arm in hand-guiding mode the recorder puts
        a person's hand behind them (:class:`multiform.teach.kinesthetic.GuidingHand`)."""
        from multiform.tasks.ball_in_cup_mentor import BallInCupMentor
        return BallInCupMentor(**kwargs)

    def demo_options(self, seed: int) -> dict[str, Any]:
        """String length and ball mass ±10 %; the hand's start anywhere within ±0.3 m of the centre and
        -0.1 to +0.15 m about its height, and
        in a quarter of the starts the ball held out high (70-86° from hanging) instead of hanging: so
        the mentor also shows pumping from where a miss leaves the hand, and braking a swing that has
        too much energy, as after a miss."""
        rng = np.random.default_rng([seed, 11])
        opts: dict[str, Any] = {"randomize": True, "x0": float(rng.uniform(-HAND_START, HAND_START)),
                                "z0": float(rng.uniform(*HEIGHT_START))}
        if rng.random() < HIGH_START:
            opts.update(phi0=float(rng.choice([-1.0, 1.0]) * rng.uniform(*HIGH_ANGLE)), omega0=0.0)
        return opts

    def trial_options(self, seed: int) -> dict[str, Any]:
        """The toy and the ball's start randomised as in the demonstrations; the hand starts at the
        centre (the demonstrations' other hand starts teach what a miss leaves behind)."""
        opts = self.demo_options(seed)
        opts.update(x0=0.0, z0=0.0)
        return opts

    def physical_success(self, trace: Any) -> bool:
        """The ball rested in the cup (its centre inside, moving less than 0.5 m/s relative to the cup)
        for a second without a break."""
        if trace.outcome == "diverged":
            return False
        bx, bz = trace.value("ball_x"), trace.value("ball_z")
        speed2 = trace.value("ball_vx") ** 2 + trace.value("ball_vz") ** 2
        resting = (np.abs(bx) < CUP_HALF_WIDTH) & (bz > CUP_FLOOR) & (bz < CUP_RIM) & (speed2 < REST_SPEED ** 2)
        need = int(np.ceil(HOLD / trace.dt - 1e-9))
        run = 0
        for ok in resting:
            run = run + 1 if ok else 0
            if run >= need:
                return True
        return False

    def ablations(self, model: Any, out: Any, cfg: Any) -> Iterator:
        """The baselines on the same trials and demonstrations, each in a model directory of its own made
        from the trained model, so they run while it practises: the mentor's net as written (with the
        laws, judges and inverse model learned from the demonstrations, no repair), and single-form
        learning from demonstration (one GP law on every demonstration sample, no net). The job adds
        the third, the skill as the repairs left it before learning from practice."""
        from multiform.evaluation import Variant
        from multiform.tasks.baselines import demo_only_model, same_laws_model
        inv = cfg.inverse_model
        as_written = same_laws_model(model, out / "baselines" / "as_written", self.SKILL)
        yield Variant("definition + demonstration, no repair (the mentor's net as written)", str(as_written.path),
                      use_inverse_model=inv, notes="t2 as the mentor wrote it: the pull waits for a swing that "
                                                   "reaches the cup's height")
        demo_only = demo_only_model(
            model, out / "baselines" / "demonstration_only", seed=cfg.seed, hold_time=HOLD,
            hold_condition=f"abs(ball_x) < {CUP_HALF_WIDTH} and ball_z > {CUP_FLOOR} and ball_z < {CUP_RIM}")
        yield Variant("demonstration only (one GP law on all demonstration data, no net)", str(demo_only.path),
                      use_inverse_model=inv, use_judges=False,
                      notes="one law for all phases, failed demonstrations included")
