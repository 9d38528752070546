"""A scripted mentor that flips the nunchaku in ``multiform/Nunchaku-v0``, as a person would teach it.

It stands in for a person watching the scene: it reads the true rod angles from ``info["scene"]``
(the robot never does), acts with human-like imprecision — reaction delay, timing jitter, amplitude
noise, a little tremor — and sometimes fumbles on purpose so that the dataset holds failed
sub-procedures too. Every sample is tagged with the transition of the bundled skill
(``skills/nunchaku.yaml``) the mentor is executing, and every segment is labelled success or failure
from what the mentor saw happen next.

The maneuver (parameters in :class:`FlipParameters`) was found offline by CMA-ES over this
parameterisation, maximising the flip rate over randomised nunchaku and timing noise; the numbers
are committed here, nothing is searched at import or run time.

1. **t0 start** — phase-locked pumping: hand velocity ``-k sin(angle)`` (angle of the free rod in
   the world) while the swing energy is below a target, wrist held tilted at ``q_swing`` so the
   held rod points up, out of the free rod's way.
2. **t1 swing** — when the energy is high enough and the free rod passes ``flick_angle`` moving
   towards +x, a flick: a half-sine hand stroke towards -x with a wrist stroke, whipping the free
   rod up over the hand.
3. **t2 release** — when the free rod passes ``release_angle`` (relative to the hand) faster than
   ``release_rate``, the magnet lets go; the hand strokes and turns the wrist by ``turn`` (a
   minimum-jerk turn) so the back of the hand meets the chain, and the magnet is re-armed.
4. **t3 back-palm contact control** — from the first touch on the back of the hand the same stroke
   and turn continue while the chain rolls over the back of the palm.
5. **t4 regrasp** — the magnet catches the formerly free rod; the hand brakes and holds it.
6. **t5 success stop** — the rod has been held for ``hold_time``.

Failure transitions: **t6** (no release after the flick), **t7** (nothing caught after the
release), **t8** (the wrong rod caught, or the catch lost).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields, replace
from typing import Any

import numpy as np

from ..demos.episode import Episode, SegmentLabel

_OMEGA2 = 34.5        # small-oscillation frequency squared of the free part [1/s^2], for the energy


def release_touch_catch(grip: np.ndarray, pressed: np.ndarray) -> tuple[int | None, int | None, int | None]:
    """Sample indices, in a flip seen through the magnet's grip and the touch pad (boolean arrays), of
    the first release, the first press on the back of the hand after it and before the catch, and the
    final catch (the grip holding again to the end); None for what did not happen."""
    released = np.flatnonzero(~grip)
    if not len(released):
        return None, None, None
    first = int(released[0])
    catch = int(released[-1]) + 1 if grip[-1] else None
    hit = np.flatnonzero(pressed[first:len(grip) if catch is None else catch])
    return first, (first + int(hit[0]) if len(hit) else None), catch


@dataclass(frozen=True)
class FlipParameters:
    """The flip maneuver (found by CMA-ES in simulation; see the module docstring)."""

    pump_gain: float = 1.049          # hand speed per unit sin(angle) while pumping [m/s]
    flick_energy: float = 0.594       # normalised swing energy 1 - cos(a) + w^2/(2 W^2) that arms the flick
    q_swing: float = -1.165            # wrist angle held while swinging [rad]
    flick_angle: float = -0.439       # world angle of the free rod that starts the flick [rad]
    flick_speed: float = 3.0         # peak hand speed of the flick stroke, towards -x [m/s]
    flick_time: float = 0.283         # duration of the flick stroke [s]
    flick_wrist: float = 3.473        # peak wrist rate of the flick stroke [rad/s]
    release_angle: float = 2.314      # free-rod angle relative to the hand at release [rad]
    release_rate: float = 7.55        # least free-rod rate relative to the hand at release [rad/s]
    stroke_x: float = -1.82          # peak hand velocity along x after release [m/s]
    stroke_z: float = -0.322           # peak hand velocity along z after release [m/s]
    stroke_time: float = 0.328        # duration of the post-release stroke [s]
    turn_delay: float = 0.255         # wrist turn starts this long after release [s]
    turn_time: float = 0.316          # duration of the wrist turn [s]
    turn: float = -4.0              # wrist turn [rad]
    rearm: float = 0.238             # magnet re-armed this long after release [s]

    def vector(self) -> np.ndarray:
        return np.array([getattr(self, f.name) for f in fields(self)])


def half_sine(t: float, duration: float) -> float:
    """A half-sine stroke of unit peak over [0, duration]."""
    return math.sin(math.pi * t / duration) if 0.0 <= t <= duration else 0.0


def min_jerk_rate(t: float, duration: float) -> float:
    """Velocity of a minimum-jerk move of unit size over [0, duration]."""
    if t < 0.0 or t > duration:
        return 0.0
    s = t / duration
    return 30.0 * s * s * (1.0 - s) * (1.0 - s) / duration


class NunchakuMentor:
    """Scripted mentor for ``multiform/Nunchaku-v0`` implementing the :class:`~multiform.demos.episode.Mentor` protocol.

    ``failure_rate`` is the probability that a demonstration contains a deliberate fumble (an early
    or late release, a weak flick, a wrist turned the wrong way, a late re-arm of the magnet); ``noise`` scales
    all human-like imprecision (0 = a perfectly repeatable robot, 1 = the default person).
    ``accel`` and ``wrist_accel`` bound how fast the mentor's hand can change velocity [m/s^2,
    rad/s^2] — the bundled skill's safety section uses the same numbers.

    A person's habits (defaults: the default person's): ``stroke_jitter`` (relative spread of the
    stroke and wrist turn after the release, per demo; a sloppy release at 0.15), ``flick_jitter``
    (spread of the angle at which it flicks, rad), ``release_lag`` (s: it lets go a time drawn from
    [0, 2 ``release_lag``] later than it sees the release point), ``label_flip`` (the probability
    that it labels a segment, or grades a trial's stay, the wrong way round). ``name``: who it is.
    """

    FUMBLES = ("early_release", "late_release", "weak_flick", "wrong_turn", "late_rearm")

    def __init__(self, params: FlipParameters | None = None, failure_rate: float = 0.3, noise: float = 1.0,
                 accel: float = 40.0, wrist_accel: float = 400.0, hold_time: float = 0.5,
                 max_swing_time: float = 8.0, name: str = "nunchaku-scripted", stroke_jitter: float = 0.04,
                 flick_jitter: float = 0.04, release_lag: float = 0.0, label_flip: float = 0.0):
        self.name = name
        self.stroke_jitter, self.flick_jitter = float(stroke_jitter), float(flick_jitter)
        self.release_lag, self.label_flip = float(release_lag), float(label_flip)
        self.params = params or FlipParameters()
        self.failure_rate = float(failure_rate)
        self.noise = float(noise)
        self.accel = float(accel)
        self.wrist_accel = float(wrist_accel)
        self.hold_time = float(hold_time)
        self.max_swing_time = float(max_swing_time)
        self.reset(np.zeros(15), np.random.default_rng(0))

    # ---------------------------------------------------------------- protocol
    def reset(self, obs: np.ndarray, rng: np.random.Generator) -> None:
        """Draw this demonstration's imprecision and (maybe) its fumble."""
        n = self.noise
        p = self.params
        stroke = ("stroke_x", "stroke_z", "turn")
        jitter = {k: 1.0 + n * rng.normal(0.0, self.stroke_jitter if k in stroke else 0.04) for k in
                  ("flick_speed", "flick_wrist", "stroke_x", "stroke_z", "turn")}
        self.p = replace(p, **{k: getattr(p, k) * v for k, v in jitter.items()},
                         pump_gain=p.pump_gain * (1.0 + n * rng.normal(0.0, 0.08)),
                         flick_angle=p.flick_angle + n * rng.normal(0.0, self.flick_jitter),
                         turn_delay=p.turn_delay + n * rng.normal(0.0, 0.008),
                         rearm=max(0.02, p.rearm + n * rng.normal(0.0, 0.01)))
        self.reaction = n * rng.uniform(0.0, 0.025)
        if self.release_lag > 0:
            self.reaction += float(rng.uniform(0.0, 2.0 * self.release_lag))
        self.tremor_scale = 0.02 * n
        self.wobble_scale = 0.12 * n      # the wrist is held only roughly at its set point [rad]
        self.wobble = n * rng.normal(0.0, 0.12)
        self.fumble = ""
        if rng.random() < self.failure_rate:
            self.fumble = str(rng.choice(self.FUMBLES))
            p2 = self.p
            if self.fumble == "early_release":
                self.p = replace(p2, release_angle=p2.release_angle - rng.uniform(1.0, 1.6))
            elif self.fumble == "late_release":
                self.reaction += rng.uniform(0.08, 0.15)
            elif self.fumble == "weak_flick":
                self.p = replace(p2, flick_speed=p2.flick_speed * rng.uniform(0.2, 0.45))
            elif self.fumble == "wrong_turn":
                self.p = replace(p2, turn=-p2.turn * rng.uniform(0.4, 0.7))
            else:
                self.p = replace(p2, rearm=p2.rearm + rng.uniform(0.5, 0.9))
        self.rng = rng
        self.cmd = [0.0, 0.0, 0.0, 1.0]
        self.tremor = 0.0
        self.tag = "t0"
        self.phase = "pump"
        self.t_flick = None
        self.t_armed = None           # the mentor saw the release point and is about to let go
        self.t_release = None
        self.t_catch = None
        self.t_end = None
        self.prev_angle = None
        self.done = False
        self.events: dict[str, Any] = {"flick": None, "release": None, "back_touch": None, "catch": None,
                                       "caught": "", "held_until": None, "outcome": ""}

    def finished(self) -> bool:
        return self.done

    @property
    def outcome(self) -> str:
        """Its verdict on the whole attempt, given by a careless labeller (``label_flip`` > 0), who
        still saw whether the flip worked; "" otherwise: the recorder then calls a demo whose every
        segment it labelled a success a success (how the default mentor's demos always were)."""
        if self.label_flip <= 0 or not self.done:
            return ""
        return "success" if self.events["outcome"] == "success" else "failure"

    # One function on purpose: the mentor's decision procedure, phase by phase as the flip goes; a
    # phase that ends hands over to the next within the same tick, so the blocks read top to bottom.
    def act(self, obs: np.ndarray, info: dict[str, Any], t: float) -> tuple[np.ndarray, str]:
        """The command for this sample and the transition being executed."""
        p = self.p
        sc = info.get("scene") or {}
        if not sc:                     # diverged: nothing to see, stop
            self.done = True
            return np.array(self.cmd), self.tag
        x, z, q = float(obs[0]), float(obs[1]), float(obs[2])
        rel = sc["free_angle"]
        rate = sc["free_rate"]
        world = rel + q
        world = math.atan2(math.sin(world), math.cos(world))
        tx, tz, tq, tm = 0.0, -3.0 * z, 0.0, 1.0
        if self.phase == "pump":
            energy = 1.0 - math.cos(world) + rate * rate / (2.0 * _OMEGA2)
            gain = p.pump_gain * min(1.0, max(0.0, (p.flick_energy - energy) / 0.1 + 1.0)) \
                if energy < p.flick_energy else 0.0
            tx = -gain * math.sin(world) - 1.5 * x
            tq = -8.0 * (q - p.q_swing - self.wobble)
            crossed = self.prev_angle is not None and self.prev_angle < p.flick_angle <= world
            if energy >= 0.97 * p.flick_energy and crossed and rate > 0.0:
                self.phase, self.t_flick, self.tag = "flick", t, "t1"
                self.events["flick"] = t
            if t > self.max_swing_time:
                self._give_up("t6", t)
            self.prev_angle = world
        if self.phase == "flick":
            tau = t - self.t_flick
            tx = -p.flick_speed * half_sine(tau, p.flick_time) - 1.5 * x
            tq = -8.0 * (q - p.q_swing) + p.flick_wrist * half_sine(tau, p.flick_time)
            if self.t_armed is None and rel >= p.release_angle and sc["free_rate"] >= p.release_rate:
                self.t_armed = t
            if self.t_armed is not None and t - self.t_armed >= self.reaction:
                self.phase, self.t_release, self.tag = "release", t, "t2"
                self.events["release"] = t
            elif tau > p.flick_time + 0.8:
                self._give_up("t6", t)
        if self.phase == "release":
            tau = t - self.t_release
            tm = 1.0 if tau > p.rearm else 0.0
            tx = p.stroke_x * half_sine(tau, p.stroke_time) - 1.0 * x
            tz = p.stroke_z * half_sine(tau, p.stroke_time) - 1.0 * z
            tq = p.turn * min_jerk_rate(tau - p.turn_delay, p.turn_time)
            if sc["back_touch"] > 0.5 and self.events["back_touch"] is None:
                self.events["back_touch"] = t
                self.tag = "t3"
            held = sc["held"]
            if held and tau > p.rearm:
                self.events["catch"], self.events["caught"] = t, held
                self.t_catch = t
                self.phase, self.tag = "hold", "t4"          # the wrong rod too: the hold finds out
            elif tau > 1.5 or (not held and max(sc["rod_a"][1], sc["rod_b"][1]) < sc["hand_z_world"] - 0.35):
                self._give_up("t7", t)
        if self.phase == "hold":
            tx, tz, tq, tm = -2.0 * x, -2.0 * z, 0.0, 1.0
            held = sc["held"]
            if held != "b" and t - self.t_catch > 0.1:
                self.events["outcome"] = "wrong rod" if held else "dropped"
                self._give_up("t8", t)
            elif held == "b" and t - self.t_catch >= self.hold_time:
                self.events["held_until"] = t
                self.events["outcome"] = "success"
                self.phase, self.tag, self.t_end = "stop", "t5", t + 0.05
        if self.phase in ("stop", "gave_up"):
            tx, tz, tq = -2.0 * x, -2.0 * z, 0.0
            tm = self.cmd[3] if self.phase == "gave_up" else 1.0
            if t >= self.t_end:
                self.done = True
        # a person's hand: bounded acceleration, a slow tremor, a wandering wrist set point
        self.tremor += 0.002 * (self.rng.standard_normal() * self.tremor_scale * 30.0 - self.tremor)
        self.wobble += -0.002 * self.wobble + self.wobble_scale * 0.063 * self.rng.standard_normal()
        c = self.cmd
        a, wa = self.accel * 0.001, self.wrist_accel * 0.001
        c[0] += max(-a, min(a, tx + self.tremor - c[0]))
        c[1] += max(-a, min(a, tz - c[1]))
        c[2] += max(-wa, min(wa, tq - c[2]))
        c[3] = tm
        return np.array(c), self.tag

    def _give_up(self, tag: str, t: float) -> None:
        self.phase, self.tag, self.t_end = "gave_up", tag, t + 0.05
        if not self.events["outcome"]:
            self.events["outcome"] = {"t6": "no release", "t7": "nothing caught"}.get(tag, "failure")

    def grade_trial(self, episode: Episode, swung_up: str = "P1", rolled: str = "P2", regrasped: str = "P3",
                    touch: float = 0.5) -> list[SegmentLabel]:
        """The person's verdict on each stay of a robot's trial, from what the trial shows: the magnet
        letting go, the chain pressing on the back of the hand (above ``touch`` N), a rod caught and
        held for ``hold_time`` s to the end. ``episode`` is the trial seen by place (its tags are the
        place the robot's token was in, as :func:`multiform.learn.views.place_episode` gives). The
        swing-up stay succeeded when a release followed and the chain then rolled over the back of the
        hand; the two later stays when the flip ended with a rod held. No simulator state is read."""
        n, dt = episode.num_samples, episode.dt
        release, touched, caught = release_touch_catch(episode.column("grip") > 0.5, episode.column("touch") > touch)
        rolled_over = touched is not None
        flipped = rolled_over and caught is not None and (n - caught) * dt >= self.hold_time - 1e-9
        out = []
        for start, end, place in episode.segments():
            if place == swung_up:
                ok = rolled_over and release <= end + 1
            elif place in (rolled, regrasped):
                ok = flipped
            else:
                continue
            out.append(SegmentLabel(start, end, place, self._say(bool(ok)), self.name))
        return out

    def _say(self, verdict: bool) -> bool:
        """The verdict it records: the wrong way round with probability ``label_flip``."""
        if self.label_flip > 0 and self.rng.random() < self.label_flip:
            return not verdict
        return verdict

    def label(self, episode: Episode) -> list[SegmentLabel]:
        """Success or failure of every segment, judged from what happened next."""
        ev = self.events
        ok_flip = ev["outcome"] == "success"
        verdict = {
            "t0": ev["flick"] is not None,                       # the swing built up to the flick
            "t1": ev["release"] is not None,                     # the flick sent the rod over
            "t2": ev["back_touch"] is not None and ok_flip,      # released well: chain over the back
            "t3": ok_flip,                                       # contact control led to the catch
            "t4": ok_flip,                                       # the right rod, caught and held
            "t5": ok_flip,
            "t6": False, "t7": False, "t8": False,
        }
        return [SegmentLabel(s, e, tag, self._say(bool(verdict.get(tag, False))), labeller=self.name)
                for s, e, tag in episode.segments()]
