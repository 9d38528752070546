"""A scripted mentor that teaches ball-in-a-cup by guiding the arm by hand.

The person holds the arm of ``multiform/BallInCup-v0`` in hand-guiding mode
(``action_mode="kinesthetic"``) and moves the cup; :class:`BallInCupMentor` is what the person
decides — the hand's intended velocity in the swing plane — and :func:`guiding_mentor` puts a
person's arm behind it (:class:`~multiform.teach.kinesthetic.GuidingHand`), so the env receives
forces. The person sees the ball and feels the hand move (the observation's ball and hand
entries), knows the toy only roughly (it judges the string's length from the hanging ball at the
start, with a 2 % error) and never reads the simulator's state.

Its skill, each stretch tagged with the transition of the skill file it performs:

* **Pumping** (``t0`` from rest until the ball first turns back, then ``t1``; ``t6`` for the first
  second of pumping again after a miss): the cup moves against the ball's swing,
  ``v = -c sin(phi + lead omega)``, which feeds the swing's energy
  ``e = 1 + z / L + |v|^2 / (2 g L)`` (0 hanging, 1 level with the anchor) with ``c`` in proportion to
  what is missing to the energy the person aims for (drawn per attempt, 0.45-0.55), and pulls the hand
  back to the centre. A ball at rest gets a first push.
* **Pull up** (``t2``, 0.15 s): when the swing has the energy and the ball passes under the cup,
  the hand jerks up and against the ball's motion (1.0 m/s back, 1.3 m/s up): the string throws
  the ball up over the cup.
* **Catch** (``t3``): the person watches the flying ball and, once it is on its way up past the
  rim's height, moves the cup to where it will fall through that height (the ball's time to fall
  there, from its height and vertical speed); until then the hand waits. The hand comes back to its
  height meanwhile.
* **Hold** (``t4``): the ball in the cup, the hand drifts gently back to the centre; after
  ``hold_time`` s the demonstration ends, caught.

A miss (the ball falls below the cup again, its string taut) is followed by pumping again, up to
``retries`` times; the person gives up ``give_up`` s after starting. The person watches the swing for
at least ``settle`` s after starting and after a miss before pulling (the snap of the string leaves
the swing's energy unclear), and judges its energy only while the string is taut.

Its limits as a person: a reaction delay (drawn per demo in ``delay``), perception noise on the
ball's and the hand's position and speed, decisions ``rate`` times a second, timing jitter on
the pull (``pull_jitter`` s) and the strength of each stroke varying by ``stroke_noise``. Its
mistakes (each attempt, with probability ``mistake_rate``; kind by ``mistake_weights``):
``early_pull`` / ``late_pull`` (anticipating the bottom of the swing by 60-120 ms too much, or
hesitating 100-180 ms after seeing it), ``weak_pull``
(half to two thirds of the stroke) and ``slow_catch`` (the person starts following the flying ball
0.15-0.25 s late).

:meth:`BallInCupMentor.label` judges each segment from the recorded observations with the person's
own tolerances: pumping succeeded if the swing's energy grew (or was already near the aim); the
pull if the ball then rose well above the cup's rim (0.12 m) and fell back where the hand can reach; the catch if
it ended with the ball in the cup;
holding if the ball stayed there for ``hold_time`` s.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ..envs.ball_in_cup import CUP_FLOOR, CUP_HALF_WIDTH, CUP_RIM, GAINS, OBSERVATION_NAMES
from ..demos.episode import Episode, SegmentLabel
from ..teach.kinesthetic import GuidingHand
from .mistakes import draw_mistake

G = 9.81
MISTAKES = ("early_pull", "late_pull", "weak_pull", "slow_catch")
_SEEN = tuple(OBSERVATION_NAMES.index(n) for n in
              ("ball_x", "ball_z", "ball_vx", "ball_vz", "hand_x", "hand_z", "hand_vx", "hand_vz"))
HAND_VELOCITY = (OBSERVATION_NAMES.index("hand_vx"), OBSERVATION_NAMES.index("hand_vz"))
RIM_CLEAR = CUP_RIM + 0.01        # the ball's centre above the rim
REACH = GAINS.x_limit             # the hand's stroke either side of the centre
THROW_HEIGHT = CUP_RIM + 0.12     # a good throw lifts the ball's centre this high above the anchor


def guiding_mentor(**kwargs: Any) -> GuidingHand:
    """The scripted person guiding the arm: :class:`BallInCupMentor` (``kwargs``) behind a hand."""
    return GuidingHand(BallInCupMentor(**kwargs), HAND_VELOCITY)


def swing_energy(bx: Any, bz: Any, bvx: Any, bvz: Any, length: float) -> Any:
    """The swing's energy in units of ``g length``: 0 hanging at rest, 1 level with the anchor."""
    return 1.0 + bz / length + (bvx * bvx + bvz * bvz) / (2.0 * G * length)


class BallInCupMentor:
    """A person's decisions while guiding the cup (see the module docstring). Times in s, speeds in m/s."""

    name = "scripted-ball-in-cup"

    def __init__(self, delay: tuple[float, float] = (0.04, 0.08), rate: float = 100.0,
                 position_noise: float = 0.004, velocity_noise: float = 0.04, length_error: float = 0.02,
                 energy_aim: tuple[float, float] = (0.45, 0.55), pump_gain: float = 1.0, lead: float = 0.04,
                 centring: float = 1.5, kick: float = 0.4, kick_time: float = 0.25,
                 pull_back: float = 1.0, pull_up: float = 1.3, pull_time: float = 0.15, pull_window: float = 0.15,
                 pull_jitter: float = 0.015, stroke_noise: float = 0.08, catch_height: float = 0.13,
                 height_gain: float = 3.0, hold_time: float = 1.3, give_up: float = 11.0, retries: int = 1,
                 settle: float = 0.8,
                 mistake_rate: float = 0.5, mistake_weights: tuple[float, ...] = (1.0, 1.0, 1.0, 1.0),
                 mistake: str | None = None, dt: float = 0.001):
        if mistake is not None and mistake not in MISTAKES + ("none",):
            raise ValueError(f"mistake must be one of {MISTAKES + ('none',)} or None, not {mistake!r}")
        self.delay, self.rate = delay, rate
        self.position_noise, self.velocity_noise, self.length_error = position_noise, velocity_noise, length_error
        self.energy_aim, self.pump_gain, self.lead, self.centring = energy_aim, pump_gain, lead, centring
        self.kick, self.kick_time = kick, kick_time
        self.pull_back, self.pull_up, self.pull_time = pull_back, pull_up, pull_time
        self.pull_window, self.pull_jitter, self.stroke_noise = pull_window, pull_jitter, stroke_noise
        self.catch_height, self.height_gain = catch_height, height_gain
        self.hold_time, self.give_up, self.retries, self.settle = hold_time, give_up, int(retries), settle
        self.mistake_rate, self.mistake_weights, self.mistake = mistake_rate, mistake_weights, mistake
        self.dt = dt
        self._buf = np.zeros((256, len(_SEEN)))
        self.reset(np.zeros(len(OBSERVATION_NAMES)), np.random.default_rng(0))

    # ----------------------------------------------------------------- episode
    def reset(self, obs: np.ndarray, rng: np.random.Generator) -> None:
        self.rng = rng
        self.delay_steps = int(round(rng.uniform(*self.delay) / self.dt))
        self.period = max(1, int(round(1.0 / (self.rate * self.dt))))
        seen = np.asarray(obs, dtype=float)[list(_SEEN)]
        self._buf[:] = seen
        self.length = max(0.05, math.hypot(seen[0], seen[1]) * (1.0 + self.length_error * float(rng.standard_normal())))
        self.k = 0
        self.cmd = np.zeros(2)
        self.phase, self.phase_start = "t0", 0
        self.attempts = 0
        self._prev_sign = 0.0
        self._kick_dir: float | None = None
        self._done = False
        self.outcome = ""
        self.mistakes: list[str] = []
        self._new_attempt()

    def _new_attempt(self) -> None:
        rng = self.rng
        kind = draw_mistake(rng, MISTAKES, self.mistake, self.mistake_rate, self.mistake_weights)
        self.mistake_kind = kind
        self.mistakes.append(kind)
        self._aim = float(rng.uniform(*self.energy_aim))
        self._jitter = float(rng.normal(0.0, self.pull_jitter))
        self._hesitate = 0.0
        if kind == "early_pull":
            self._jitter += float(rng.uniform(0.06, 0.12))
        elif kind == "late_pull":
            self._hesitate = float(rng.uniform(0.1, 0.18))
        self._pull_at = -1
        strength = 1.0 + self.stroke_noise * float(rng.standard_normal())
        if kind == "weak_pull":
            strength *= float(rng.uniform(0.5, 0.67))
        self._stroke = (self.pull_back * strength, self.pull_up * strength,
                        self.pull_time * (1.0 + 0.5 * self.stroke_noise * float(rng.standard_normal())))
        self._catch_late = float(rng.uniform(0.15, 0.25)) if kind == "slow_catch" else 0.0
        self._pull_dir = 1.0

    def act(self, obs: np.ndarray, info: dict[str, Any], t: float) -> tuple[np.ndarray, str]:
        k = self.k
        self._buf[k % len(self._buf)] = np.asarray(obs, dtype=float)[list(_SEEN)]
        if k % self.period == 0 and not self._done:
            self.cmd = self._decide(k)
        self.k = k + 1
        return self.cmd.copy(), self.phase

    def finished(self) -> bool:
        return self._done

    # --------------------------------------------------------------- decisions
    def _perceive(self, k: int) -> tuple[float, ...]:
        """What the person sees and feels now: the state ``delay`` ago, with noise."""
        j = max(0, k - self.delay_steps)
        s = self._buf[j % len(self._buf)].copy()
        r = self.rng.standard_normal(len(s))
        s[[0, 1, 4, 5]] += self.position_noise * r[[0, 1, 4, 5]]
        s[[2, 3, 6, 7]] += self.velocity_noise * r[[2, 3, 6, 7]]
        return tuple(float(v) for v in s)

    def _decide(self, k: int) -> np.ndarray:
        bx, bz, bvx, bvz, hx, hz, hvx, hvz = self._perceive(k)
        L = self.length
        phi = math.atan2(bx, -bz)
        r2 = max(bx * bx + bz * bz, 1e-6)
        om = (-bz * bvx + bx * bvz) / r2
        e = swing_energy(bx, bz, bvx, bvz, L)
        t, since = k * self.dt, (k - self.phase_start) * self.dt
        phase = self.phase
        if t >= self.give_up and phase in ("t0", "t1", "t6"):
            return self._finish("failure")
        if phase in ("t0", "t1", "t6"):
            sign = 1.0 if om > 0 else -1.0
            turned = sign != self._prev_sign
            self._prev_sign = sign
            if phase == "t0" and turned and since > 0.3:
                self._enter("t1", k)
            elif phase == "t6" and since >= 1.0:
                self._enter("t1", k)
            settled = phase == "t1" or since >= self.settle             # a swing or two before the first pull
            if self._pull_at < 0 and settled and e >= self._aim and r2 > (0.95 * L) ** 2 and bz < -0.5 * L \
                    and abs(wrap(phi + om * (self.lead + self._jitter))) < self.pull_window:
                self._pull_at = k + int(round(self._hesitate / self.dt))
                self._pull_dir = sign
            if 0 <= self._pull_at <= k:
                self._enter("t2", k)
                return self._pull()
            if phase == "t0" and t < self.kick_time and abs(om) < 1.0:
                if self._kick_dir is None:
                    self._kick_dir = -1.0 if bx > 0 else 1.0
                return np.array([self.kick * self._kick_dir, -self.height_gain * hz])
            return self._pump(phi, om, e, hx, hz)
        if phase == "t2":
            if since >= self._stroke[2]:
                self._enter("t3", k)
                return self._catch(bx, bz, bvx, bvz, hx, hz, hvx, 0.0)
            return self._pull()
        if phase == "t3":
            if abs(bx) < CUP_HALF_WIDTH and CUP_FLOOR < bz < CUP_RIM:
                self._enter("t4", k)
                return self._hold(hx, hz)
            if bz < -0.7 * L and bvz < 0.0:                       # missed: the ball fell below the cup again
                if self.attempts >= self.retries or t >= self.give_up - 3.0:
                    return self._finish("failure")
                self.attempts += 1
                self._new_attempt()
                self._enter("t6", k)
                self._prev_sign = 1.0 if om > 0 else -1.0
                return self._pump(phi, om, e, hx, hz)
            return self._catch(bx, bz, bvx, bvz, hx, hz, hvx, since)
        if phase == "t4":
            if not (abs(bx) < CUP_HALF_WIDTH + 0.02 and 0.0 < bz < RIM_CLEAR + 0.02):
                return self._finish("failure")                   # it jumped out
            if since >= self.hold_time:
                return self._finish("success")
            return self._hold(hx, hz)
        return self.cmd

    def _pump(self, phi: float, om: float, e: float, hx: float, hz: float) -> np.ndarray:
        c = min(1.0, 1.5 * (self._aim + 0.1 - e)) * self.pump_gain
        return np.array([-c * math.sin(phi + self.lead * om) - self.centring * hx, -self.height_gain * hz])

    def _pull(self) -> np.ndarray:
        back, up, _ = self._stroke
        return np.array([-self._pull_dir * back, up])

    def _catch(self, bx: float, bz: float, bvx: float, bvz: float, hx: float, hz: float, hvx: float,
               since: float) -> np.ndarray:
        vz = -self.height_gain * hz
        if since < self._catch_late:
            return np.array([hvx, vz])                             # not looking yet: the hand coasts on
        h = self.catch_height
        disc = bvz * bvz + 2.0 * G * (bz - h)
        if disc <= 0.0 or (bz < h and bvz < 0.0):
            return np.array([0.0, vz])          # it will not come down through the rim's height: wait and see
        tf = (bvz + math.sqrt(disc)) / G
        return np.array([hvx + (bx + bvx * tf) / max(tf, 0.1), vz])

    def _hold(self, hx: float, hz: float) -> np.ndarray:
        return np.array([-1.0 * hx, -1.0 * hz])

    def _enter(self, phase: str, k: int) -> None:
        self.phase, self.phase_start = phase, k

    def _finish(self, outcome: str) -> np.ndarray:
        self._done = True
        self.outcome = outcome
        return np.zeros(2)

    # ----------------------------------------------------------------- labels
    def label(self, episode: Episode) -> list[SegmentLabel]:
        """Success or failure of every segment, judged from the recorded observations."""
        bx, bz, hx = episode.column("ball_x"), episode.column("ball_z"), episode.column("hand_x")
        e = swing_energy(bx, bz, episode.column("ball_vx"), episode.column("ball_vz"), self.length)
        dt = episode.dt
        inside = (np.abs(bx) < CUP_HALF_WIDTH) & (bz > CUP_FLOOR) & (bz < CUP_RIM)
        out = []
        segs = episode.segments()
        for i, (start, end, tag) in enumerate(segs):
            nxt = segs[i + 1][2] if i + 1 < len(segs) else None
            if tag in ("t0", "t1", "t6"):
                grew = e[end - 1] > e[start] + 0.02 or e[end - 1] >= self.energy_aim[0] - 0.1
                ok = grew and nxt is not None
            elif tag == "t2":
                ok = catchable(bx[start:], bz[start:], hx[start:], dt)
            elif tag == "t3":
                ok = nxt == "t4"
            elif tag == "t4":
                ok = (end - start) * dt >= self.hold_time - 1e-9 and bool(np.all(inside[start:end]))
            else:
                ok = False
            out.append(SegmentLabel(start, end, tag, bool(ok), self.name))
        return out


def catchable(bx: np.ndarray, bz: np.ndarray, hx: np.ndarray, dt: float, within: float = 0.8) -> bool:
    """Whether a throw (the samples from the pull on) was good: within ``within`` s the ball rose
    well above the rim (``THROW_HEIGHT``) and came down through the rim's height where the hand can
    reach (``REACH`` m either side of the centre)."""
    n = min(len(bz), int(round(within / dt)))
    if not np.any(bz[:n] > THROW_HEIGHT):
        return False
    over = np.flatnonzero(bz[:n] > RIM_CLEAR)
    k = over[0]
    down = np.flatnonzero(bz[k:] <= RIM_CLEAR)
    if not len(down):
        return False
    j = k + down[0]
    return bool(abs(bx[j] + hx[j]) <= REACH)


def wrap(a: float) -> float:
    """``a`` wrapped to (-pi, pi]."""
    return math.remainder(a, 2.0 * math.pi)
