"""The nunchaku task: a hand flips a nunchaku — swing-up, release, chain rolling over the back of the
palm, regrasp of the other rod (the paper's second test, Figs. 9-11).

Everything here is the *experiment*: the env and the scripted mentor, how trials are randomised,
the physical success check used to evaluate every variant alike, the practice scenario and the
ablations. The robot itself reads only its own sensors and the free rod's motion estimated from the
wrist load (``phi``, ``omega``, ``load``); the physical check below is the experimenter watching.

The env takes the hand's velocity and wrist-rate commands directly (its servos are the robot's
low-level controller), so this task has no auxiliary inverse model (``train_inverse_model = None``).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ..runtime.trace import Trace

ENV_ID = "multiform/Nunchaku-v0"
SKILL = "nunchaku"                 # the bundled definition (paper Fig. 10), as the mentor wrote it
DEMO_ENV_KWARGS: dict[str, Any] = {}
HOLD_TIME = 0.5                    # s the caught rod must stay in the palm
TOUCH = 0.5                        # N on the back of the hand: the chain rolled over it
BASELINE_WAIT = 6.0                # s: the demo-only harness stops a trial holding a rod after this (twice
                                   # the mentor's flip), so the single law has time to finish a flip

TASK = "nunchaku"
DEMOS = 10                         # the main job's demonstrations: the fewest with which every job seed flips
                                   # >= 90 %, learning from practice (10: 95.0 / 100.0 / 97.0 % for seeds 0 / 1 / 2;
                                   # from 5, job seed 1's demonstrations reach the regrasp three times, too few
                                   # to teach its judge; seeds 0 and 2 flip 99.0 and 91.0 %; docs/measurements.md)
LEARN = True                       # the main job learns from practice (scenario b_keep)
DESCRIPTION = ("A hand on a fast 6-DoF base (MuJoCo) learns to flip a nunchaku — swing-up, release, the chain "
               "rolling over the back of the palm, regrasp of the other rod with a magnet palm — from a scripted "
               "mentor's demonstrations and labels, sensing the free rod only through the wrist load.")
TARGET_SUCCESS_RATE = 0.8
REPORT = {          # the report's words for this task's pictures (the paper's figure numbers)
    "motion_figure": "Fig. 11",
    "success_trial": "a successful flip: swing-up, release, the chain over the back of the hand, regrasp",
}
PLOT_VARIABLES = [("phi", "φ est. [rad]"), ("omega", "ω est. [rad/s]"), ("hand_q", "wrist q [rad]"),
                  ("hand_x", "hand x [m]"), ("touch", "back touch [N]"), ("grip", "grip")]

train_inverse_model = None         # the env takes the hand commands itself (see the module docstring)


def make_mentor(**kwargs: Any):
    """The scripted mentor standing in for a person showing the flip (with fumbles)."""
    from ..demos.nunchaku_mentor import NunchakuMentor
    return NunchakuMentor(**kwargs)


def demo_options(seed: int) -> dict[str, Any]:
    """Reset options of demonstration ``seed``: rod mass ±10 %, length ±7 %, chain damping, friction,
    grip position and start pose randomised by the env."""
    return {"randomize": True}


def trial_options(seed: int) -> dict[str, Any]:
    """Reset options of practice and evaluation trials (same randomisation as the demos)."""
    return {"randomize": True}


def robot_env_kwargs(inverse_model: bool) -> dict[str, Any]:
    """The robot runs on the same env as the mentor: it commands hand velocities and the magnet."""
    return {}


def flip_events(trace: Trace) -> dict[str, Any]:
    """What the experimenter saw: first release, back touch, the final catch and how long it held,
    and which rod ends in the palm (the env's ``info["scene"]`` at the end of the trial)."""
    from ..demos.nunchaku_mentor import release_touch_catch
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


def physical_success(trace: Trace) -> bool:
    """The whole flip, judged on the nunchaku itself: the held rod was let go, the chain then pressed
    on the back of the hand, and the trial ends with the *other* rod (B) caught in the palm and held
    for at least 0.5 s."""
    if trace.outcome == "diverged":
        return False
    ev = flip_events(trace)
    return (ev["held"] == "b" and ev["release"] is not None and ev["touch"] is not None
            and ev["catch"] is not None and ev["held_for"] >= HOLD_TIME - 1e-9)


MENTOR_EVERY = 3                   # the mentor grades every third trial of learning from practice
MENTOR_BUDGET = 20                 # and at most this many


def mentor_grader():
    """The scripted mentor watching a practice trial: one verdict per stay, from the trace alone."""
    mentor = make_mentor()
    return lambda episode, apn: mentor.grade_trial(episode)


def scenarios() -> list[dict[str, Any]]:
    """Practice from the mentor's definition on randomised nunchakus. Constant failure is 6 failures
    in a row or 8 of the last 10 trials: a flip that works most of the time fails now and then
    (a weak flick, a late catch), and three such trials in a row are not a flaw in the definition —
    a repair made on them replaced t4's grip condition with a switch condition that fired before the
    catch (observed with 16 demonstrations).

    Learning from practice (``b_keep``) aims at 20 plain flips in a row (target 0.98) and refits
    only on a shortfall read off 20 plain trials of the net as it is: a flip that fails one time in
    ten makes 19 of 20 now and then, so at 0.95 practice stopped there without learning (10 demos,
    job seed 0: 88.0 %); and one failure in the first five trials set off refits that cost a skill
    that flipped 97 % nine points (job seed 2)."""
    return [
        {"name": "a_practice", "title": "(a) practice from the mentor's definition on randomised nunchakus",
         "options": trial_options,
         "config": {"failures_in_a_row": 6, "window": 10, "failure_rate": 0.8, "success_streak": 5}},
        {"name": "b_keep", "title": "(b) practice as evaluated, learning from its own graded experience",
         "options": trial_options, "mentor": mentor_grader, "learn": True, "seed": 1,
         "config": {"failures_in_a_row": 6, "window": 10, "failure_rate": 0.8, "success_streak": 10**6,
                    "learn": True, "explore": 0.3, "explore_every": 2, "refit_every": 10,
                    "mentor_every": MENTOR_EVERY, "mentor_budget": MENTOR_BUDGET, "target_rate": 0.98,
                    "target_window": 20, "shortfall_after": 20, "revert_window": 10, "exam": True}},
    ]


def evaluation_specs(n: int, seed: int, push_fraction: float) -> list:
    """``n`` evaluation trials on randomised nunchakus and start poses (nobody pushes a nunchaku:
    ``push_fraction`` is ignored)."""
    from ..adapt.evaluation import TrialSpec
    return [TrialSpec(seed=s, options=trial_options(s)) for s in
            (70_000_000 + seed * 100_000 + i for i in range(n))]


def ablations(model, out, cfg) -> list:
    """The baselines on the same seeds and demonstrations: the unrevised net (if practice revised
    it), and single-form learning from demonstration (one GP law on all demonstration data)."""
    from ..adapt.evaluation import Variant
    from .baselines import demo_only_model
    rows = []
    if model.version > 0:
        rows.append(Variant("definition + demonstration, no repair (the mentor's net as written)", str(model.path),
                            net_version=0, notes="before practice revised it"))
    demo_only = demo_only_model(model, out / "baselines" / "demonstration_only",
                                hold_condition=f"grip > 0.5 and time > {BASELINE_WAIT}", hold_time=HOLD_TIME,
                                seed=cfg.seed)
    rows.append(Variant("demonstration only (one GP law on all demonstration data, no net)", str(demo_only.path),
                        use_judges=False, notes="one law for all phases, failed demonstrations included"))
    return rows


def mentor_rate(episodes) -> dict[str, Any]:
    """The mentor's own flip rate over its demonstrations (with its deliberate fumbles), Wilson interval."""
    from ..stats import rate
    return rate(sum(e.outcome == "success" for e in episodes), len(episodes))


def swing_estimation_error(seeds, mentor_kwargs: dict[str, Any] | None = None, skip: float = 0.3) -> dict[str, float]:
    """RMS error of the load estimate of the free rod's angle during the swing (t0/t1 after ``skip``
    seconds), against simulator ground truth, over mentor demonstrations with the given seeds."""
    import gymnasium as gym

    import multiform.envs  # noqa: F401
    from ..envs.nunchaku import OBSERVATION_NAMES
    env = gym.make(ENV_ID)
    mentor = make_mentor(**(mentor_kwargs or {}))
    iphi, iom = OBSERVATION_NAMES.index("phi"), OBSERVATION_NAMES.index("omega")
    err, rate_err = [], []
    try:
        for seed in seeds:
            obs, info = env.reset(seed=seed, options=demo_options(seed))
            mentor.reset(obs, np.random.default_rng([seed, 1]))
            t = 0.0
            while not mentor.finished():
                cmd, tag = mentor.act(obs, info, t)
                if tag not in ("t0", "t1"):
                    break
                obs, _, term, trunc, info = env.step(cmd)
                t += env.unwrapped.dt
                if term or trunc:
                    break
                if t > skip:
                    err.append(math.remainder(obs[iphi] - info["truth"]["phi"], 2 * math.pi))
                    rate_err.append(obs[iom] - info["truth"]["omega"])
    finally:
        env.close()
    e, r = np.asarray(err), np.asarray(rate_err)
    return {"angle_rms": float(np.sqrt(np.mean(e ** 2))), "angle_p95": float(np.percentile(np.abs(e), 95)),
            "rate_rms": float(np.sqrt(np.mean(r ** 2))), "samples": int(len(e))}
