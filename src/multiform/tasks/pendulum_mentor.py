"""A scripted mentor that demonstrates the pendulum skill like a person at a joystick.

The mentor drives ``multiform/ArmPendulum-v0`` in end-effector mode (``v_cmd``, the stick's
deflection is the hand's velocity along the swing axis). It knows what a person would: the nominal
pendulum (0.4 m), not the length or mass of this episode, and it sees only the observations.

Its skill:

* **Swing-up** (tag ``t0`` for the first stroke — a 0.3 s push of the hand that starts the swing
  of a pendulum at rest, then pumping until the pendulum's first turning point — then ``t2``):
  energy pumping. Moving the hand against the pendulum's lateral displacement,
  ``v = -c sin(theta)``, gives the hand an acceleration ``-c omega cos(theta)`` and the pendulum's
  energy ``E = lambda omega^2 / 2 + g (cos(theta) - 1)`` a rate ``c (omega cos(theta))^2 >= 0``. Like a
  person, the mentor judges the energy by how high the pendulum swings (``E = g (cos - 1)`` at each
  turning point) or how fast it passes the top, sets ``c`` in proportion to the deficit
  (saturated; negative when there is too much, and then steeper: braking a pendulum that races
  over the top is urgent), anticipates by 80 ms (``sin(theta + 0.08 omega)``)
  and pulls the hand gently back to the centre.
* **Switch** (tag ``t1``, the first ``catch_time`` = 0.5 s): when the pendulum is seen rising
  towards upright, near it (``|theta| < switch_angle``), slow (``|omega| < switch_rate``) and with
  the energy to get within 0.2 rad of upright, the mentor switches to balancing.
* **Balancing** (``t1`` then ``t3``): a static feedback ``v = K . (theta, omega, x, xdot)`` on what it
  perceives, with gains chosen (by minimising the worst closed-loop decay rate of the linearised
  loop) to be stable for reaction delays of 1-120 ms, joystick rates of 50-100 Hz and pendulum
  lengths of ±20 %.

Its limits as a person: a reaction delay (default drawn from 40-80 ms per demo), perception noise,
a joystick read at ``rate`` Hz (zero-order hold), quantised to ``resolution`` m/s, with motor noise,
and a hand that moves the stick no faster than ``stick_accel`` m/s² (the skill's command-rate limit).

Its mistakes (with probability ``mistake_rate`` a demo contains one, kind drawn by
``mistake_weights``); each shows in the commands of the segment it ruins:

* ``wrong_phase``: from some moment on (0.5-3 s), the mentor pumps in the wrong phase — moves the
  hand with the pendulum instead of against it — so the swing dies down and the swing-up times out
  (``t2`` fails).
* ``over_pump``: pumps too much energy, and tries to catch the pendulum racing over the top
  (``t2`` ends too fast, ``t1`` fails).
* ``early_switch``: switches to balancing far from upright (``t1`` fails).
* ``lapse``: an attention lapse while balancing freezes the stick for 0.4-1.0 s (``t3`` fails).

It finishes after ``hold_time`` s of balancing after the catch (success) or when it gives up: the
swing-up has not succeeded within ``give_up`` s of its start. When the pendulum is seen beyond
``fall_angle`` while balancing (a slip, or an experimenter's push), the mentor swings it up again,
as a person would, up to ``recover`` times per demo (tag ``t2``, a fresh ``give_up`` clock; its
definition has no transition for that: the robot must find one); after that it gives up.

:meth:`PendulumMentor.label` judges each segment from the recorded observations, as the person
would, with its own tolerances: ``t0`` succeeded if the swing's energy grew by 2 % of the
hanging-to-upright energy; ``t2`` if it ended near upright and slow (``|theta| < switch_angle +
0.1``, ``|omega| < switch_rate + 0.5``) or the catch that followed held; ``t1`` if the pendulum
stayed within ``fall_angle`` of upright through the catch and the second after it; ``t3`` if it
stayed there for ``hold_time`` s.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ..angles import wrap_angle
from ..envs.arm_pendulum import NOMINAL, equivalent_length
from ..demos.episode import Episode, SegmentLabel
from .mistakes import draw_mistake

G = 9.81
BALANCE_GAINS = (4.385, 0.8646, 0.9542, 1.882)   # v = K . (theta, omega, x, xdot)
MISTAKES = ("wrong_phase", "over_pump", "early_switch", "lapse")



class PendulumMentor:
    """A person with a joystick demonstrating swing-up and balancing (see the module docstring).

    Times in seconds, speeds in m/s, angles in rad.

    * The person: ``delay`` (range a demo's reaction delay is drawn from), ``rate`` (joystick
      reads per second), ``resolution`` (command quantum), ``stick_accel`` (fastest change of the
      command, m/s²), ``v_max`` (full stick), perception noise ``angle_noise``, ``rate_noise``,
      ``position_noise``, ``velocity_noise`` (standard deviations) and ``motor_noise``.
    * Mistakes: ``mistake_rate`` (probability per demo), ``mistake_weights`` (of ``wrong_phase``,
      ``over_pump``, ``early_switch``, ``lapse``), or ``mistake`` to force one kind (``"none"``
      forbids them).
    * Swing-up: ``kick`` and ``kick_time`` (the first push), ``stroke_max`` (longest first
      stroke), ``pump_gain`` (largest pumping amplitude), ``energy_gain`` (pumping per unit of
      energy deficit, in units of g), ``brake_gain`` (braking per unit of energy excess: a person
      who sees the pendulum race over the top brakes it firmly), ``energy_margin`` (energy aimed
      for above upright at rest, in units of g), ``lead`` (anticipation), ``centring`` (pull back
      to the centre, 1/s).
    * Switch and balance: ``switch_angle``, ``switch_rate``, ``catch_time`` (length of ``t1``),
      ``hold_time`` (balance wanted), ``give_up`` (longest swing-up), ``fall_angle`` (the pendulum
      has fallen), ``recover`` (how often per demo it swings a fallen pendulum up again).
    * Habits (none by default): ``balance_scale`` (balance gains times this), ``balance_noise``
      (motor noise while balancing), ``hesitation`` (it switches a time drawn from [0, 2 h] after it
      sees the moment), ``switch_jitter`` (the switch angle times a factor from [1 - j, 1 + j], drawn
      at every turn), ``label_flip`` (chance of a label or grade the wrong way round). ``name``: who.
    """

    def __init__(self, delay: tuple[float, float] = (0.04, 0.08), rate: float = 100.0, resolution: float = 0.02,
                 stick_accel: float = 25.0, v_max: float = 1.5, angle_noise: float = 0.01,
                 rate_noise: float = 0.05, position_noise: float = 0.003, velocity_noise: float = 0.02,
                 motor_noise: float = 0.02, mistake_rate: float = 0.28,
                 mistake_weights: tuple[float, float, float, float] = (1.0, 1.0, 1.0, 1.0),
                 mistake: str | None = None, kick: float = 0.5, kick_time: float = 0.3, stroke_max: float = 2.0,
                 pump_gain: float = 1.2, energy_gain: float = 0.4, brake_gain: float = 1.5,
                 energy_margin: float = 0.03,
                 lead: float = 0.08, centring: float = 1.0, switch_angle: float = 0.4, switch_rate: float = 2.5,
                 catch_time: float = 0.5, hold_time: float = 5.0, give_up: float = 20.0, fall_angle: float = 0.8,
                 recover: int = 1, dt: float = 0.001, name: str = "scripted-pendulum",
                 balance_scale: tuple[float, float, float, float] = (1.0, 1.0, 1.0, 1.0),
                 balance_noise: float | None = None, hesitation: float = 0.0, switch_jitter: float = 0.0,
                 label_flip: float = 0.0):
        if mistake is not None and mistake not in MISTAKES + ("none",):
            raise ValueError(f"mistake must be one of {MISTAKES + ('none',)} or None, not {mistake!r}")
        self.name = name
        self.balance_gains = tuple(k * a for k, a in zip(BALANCE_GAINS, balance_scale))
        self.balance_noise = motor_noise if balance_noise is None else balance_noise
        self.hesitation, self.switch_jitter, self.label_flip = hesitation, switch_jitter, label_flip
        self.delay = delay
        self.rate = rate
        self.resolution = resolution
        self.stick_accel = stick_accel
        self.v_max = v_max
        self.angle_noise, self.rate_noise = angle_noise, rate_noise
        self.position_noise, self.velocity_noise = position_noise, velocity_noise
        self.motor_noise = motor_noise
        self.mistake_rate = mistake_rate
        self.mistake_weights = mistake_weights
        self.mistake = mistake
        self.pump_gain = pump_gain
        self.energy_gain = energy_gain
        self.brake_gain = brake_gain
        self.lead = lead
        self.energy_margin = energy_margin
        self.centring = centring
        self.switch_angle, self.switch_rate = switch_angle, switch_rate
        self.kick, self.kick_time = kick, kick_time
        self.stroke_max = stroke_max
        self.catch_time, self.hold_time, self.give_up = catch_time, hold_time, give_up
        self.fall_angle = fall_angle
        self.recover = int(recover)
        self.dt = dt
        self.lam = equivalent_length(NOMINAL["length"])     # what the person believes
        self._buf = np.zeros((512, 4))
        self.reset(np.zeros(4), np.random.default_rng(0))

    # ----------------------------------------------------------------- episode
    def reset(self, obs: np.ndarray, rng: np.random.Generator) -> None:
        self.rng = rng
        lo, hi = self.delay
        self.delay_steps = int(round(rng.uniform(lo, hi) / self.dt))
        self.period = max(1, int(round(1.0 / (self.rate * self.dt))))
        kind = draw_mistake(rng, MISTAKES, self.mistake, self.mistake_rate, self.mistake_weights)
        self.mistake_kind = kind
        # the parameters of the mistake, drawn now so that a demo is fixed by its generator
        self._wrong_from = float(rng.uniform(0.5, 3.0))
        self._overpump = float(rng.uniform(1.0, 1.6))        # energy aimed for, in g: races over the top
        self._early_angle = float(rng.uniform(0.8, 1.1))
        self._lapse_at = float(rng.uniform(1.0, 3.5))
        self._lapse_len = float(rng.uniform(0.4, 1.0))
        self.k = 0
        self.phase = "t0"
        self.phase_start = 0
        self.swing_start = 0
        self.recoveries = 0
        self.cmd = 0.0
        self.target = 0.0
        self._prev_omega_sign = 0.0
        self._swinging = False
        self._kick_dir: float | None = None
        self._energy = -2.0 * G
        self._done = False
        self.outcome = ""
        self.switch_step = -1
        self.balance_start = -1
        self._buf[:] = 0.0
        if len(obs) >= 4:
            self._buf[:] = np.asarray(obs[:4], dtype=float)
        self._switch_angle = self.switch_angle
        self._seen_switch = -1                               # the step it first saw the moment to switch
        self._wait = 0.0

    def act(self, obs: np.ndarray, info: dict[str, Any], t: float) -> tuple[np.ndarray, str]:
        k = self.k
        n = len(self._buf)
        self._buf[k % n] = obs[:4]
        if k % self.period == 0 and not self._done:
            self.target = self._decide(k)
        step = self.stick_accel * self.dt
        self.cmd += min(max(self.target - self.cmd, -step), step)
        self.k = k + 1
        return np.array([self.cmd]), self.phase

    def finished(self) -> bool:
        return self._done

    # --------------------------------------------------------------- decisions
    def _perceive(self, k: int) -> tuple[float, float, float, float, float]:
        """What the person sees now: the state ``delay`` ago, with noise; also its energy."""
        j = max(0, k - self.delay_steps)
        th, om, x, xd = self._buf[j % len(self._buf)]
        r = self.rng.standard_normal(4)
        th = wrap_angle(th + self.angle_noise * r[0])
        om += self.rate_noise * r[1]
        x += self.position_noise * r[2]
        xd += self.velocity_noise * r[3]
        e = 0.5 * self.lam * om * om + G * (math.cos(th) - 1.0)
        return th, om, x, xd, e

    def _decide(self, k: int) -> float:
        th, om, x, xd, e = self._perceive(k)
        t = k * self.dt
        phase = self.phase
        if phase in ("t0", "t2"):
            s = 1.0 if om > 0 else -1.0
            turned = s != self._prev_omega_sign
            self._prev_omega_sign = s
            if turned:                                       # how high did it swing?
                self._energy = G * (math.cos(th) - 1.0)
                if self.switch_jitter > 0:
                    j = self.switch_jitter
                    self._switch_angle = self.switch_angle * float(self.rng.uniform(1.0 - j, 1.0 + j))
            elif abs(th) < 0.3:                              # how fast does it pass the top?
                self._energy = e
            if phase == "t0":
                if abs(om) > 1.0:
                    self._swinging = True
                if (self._swinging and turned) or t >= self.stroke_max:
                    self._enter("t2", k)
            if (k - self.swing_start) * self.dt >= self.give_up:
                self._finish("failure")
                return self.cmd
            if self._switch_now(k, th, om):
                self._enter("t1", k)
                self.switch_step = k
                return self._command(self._balance(th, om, x, xd), self.balance_noise)
            if phase == "t0" and t < self.kick_time:       # the push that starts a swing from rest
                if self._kick_dir is None:
                    self._kick_dir = 0.0 if abs(om) > 1.0 else (-1.0 if math.sin(th) > 0 else 1.0)
                if self._kick_dir:
                    return self._command(self.kick * self._kick_dir)
            return self._command(self._pump(th, om, x, xd, self._energy))
        if abs(th) > self.fall_angle:
            if self.recoveries >= self.recover:
                self._finish("failure")
                return self.cmd
            self._enter("t2", k)                             # it fell: swing it up again
            self.swing_start = k
            self.recoveries += 1
            self._prev_omega_sign = 1.0 if om > 0 else -1.0
            self._energy = e
            return self._command(self._pump(th, om, x, xd, e))
        if phase == "t1" and (k - self.phase_start) * self.dt >= self.catch_time:
            self._enter("t3", k)
            self.balance_start = k
        if self.phase == "t3":
            held = (k - self.phase_start) * self.dt
            if held >= self.hold_time:
                self._finish("success")
                return self.cmd
            if self.mistake_kind == "lapse" and self._lapse_at <= held < self._lapse_at + self._lapse_len:
                return self.target                           # attention elsewhere: the stick stays put
        return self._command(self._balance(th, om, x, xd), self.balance_noise)

    def _switch_now(self, k: int, th: float, om: float) -> bool:
        """Whether it switches now: at once when it sees the moment, or after its hesitation."""
        if self._seen_switch < 0:
            if not self._should_switch(th, om):
                return False
            if self.hesitation <= 0:
                return True
            self._seen_switch, self._wait = k, float(self.rng.uniform(0.0, 2.0 * self.hesitation))
        if (k - self._seen_switch) * self.dt < self._wait:
            return False
        self._seen_switch = -1
        return True

    def _should_switch(self, th: float, om: float) -> bool:
        if th * om >= 0.0:                                   # not rising towards upright
            return False
        kind = self.mistake_kind
        if kind == "early_switch":
            return abs(th) < self._early_angle
        if kind == "over_pump":
            return abs(th) < self._switch_angle
        reach = 0.5 * self.lam * om * om + G * (math.cos(th) - 1.0)        # will it get near upright?
        return abs(th) < self._switch_angle and abs(om) < self.switch_rate and reach > G * (math.cos(0.2) - 1.0)

    def _pump(self, th: float, om: float, x: float, xd: float, e: float) -> float:
        target = self.energy_margin * G
        if self.mistake_kind == "over_pump":
            target = self._overpump * G
        gain = self.energy_gain if e < target else self.brake_gain
        c = min(max(gain * (target - e) / G, -1.0), 1.0) * self.pump_gain
        if self.mistake_kind == "wrong_phase" and self.k * self.dt >= self._wrong_from:
            c = -c                                           # moves with the pendulum, not against it
        return -c * math.sin(th + self.lead * om) - self.centring * x

    def _balance(self, th: float, om: float, x: float, xd: float) -> float:
        k1, k2, k3, k4 = self.balance_gains
        return k1 * th + k2 * om + k3 * x + k4 * xd

    def _command(self, v: float, noise: float | None = None) -> float:
        v += (self.motor_noise if noise is None else noise) * float(self.rng.standard_normal())
        q = self.resolution
        v = round(v / q) * q if q > 0 else v
        return min(max(v, -self.v_max), self.v_max)

    def _enter(self, phase: str, k: int) -> None:
        self.phase = phase
        self.phase_start = k

    def _finish(self, outcome: str) -> None:
        self._done = True
        self.outcome = outcome

    # ----------------------------------------------------------------- labels
    def label(self, episode: Episode) -> list[SegmentLabel]:
        """Success or failure of every segment, judged from the recorded observations."""
        th = episode.column("theta")
        om = episode.column("omega")
        lam = self.lam
        energy = 0.5 * lam * om * om + G * (np.cos(th) - 1.0)
        n = episode.num_samples
        dt = episode.dt
        segments = episode.segments()

        def caught(start: int, end: int) -> bool:       # held through the catch and the second after it
            after = end + int(round(1.0 / dt))
            return after <= n and bool(np.all(np.abs(th[start:after]) < self.fall_angle))

        labels = []
        for i, (start, end, tag) in enumerate(segments):
            last = end - 1
            if tag == "t0":
                ok = energy[last] > energy[start] + 0.02 * G
            elif tag == "t2":
                near = abs(th[last]) < self.switch_angle + 0.1 and abs(om[last]) < self.switch_rate + 0.5
                nxt = segments[i + 1] if i + 1 < len(segments) else None
                ok = end < n and (near or (nxt is not None and nxt[2] == "t1" and caught(nxt[0], nxt[1])))
            elif tag == "t1":
                ok = caught(start, end)
            elif tag == "t3":
                held = (end - start) * dt >= self.hold_time - 1e-9
                ok = held and bool(np.all(np.abs(th[start:end]) < self.fall_angle))
            else:
                ok = False
            labels.append(SegmentLabel(start, end, tag, self._say(bool(ok)), self.name))
        return labels

    def _say(self, verdict: bool) -> bool:
        """The verdict it records: the wrong way round with probability ``label_flip``."""
        return (not verdict) if self.label_flip > 0 and self.rng.random() < self.label_flip else verdict

    def grade_trial(self, episode: Episode, swung_up: str = "P1", balanced: str = "P2") -> list[SegmentLabel]:
        """The person's verdict on each stay of a robot's trial, from the trial's trace alone.

        ``episode`` is the trial seen by place (its tags are the place the robot's token was in, as
        :func:`multiform.learn.views.place_episode` gives). A swing-up stay succeeded when the robot
        went on to balancing and the catch held (within ``fall_angle`` of upright for a second after
        it); a balancing stay when the pendulum stayed within ``fall_angle`` for ``hold_time`` s.
        The same tolerances as :meth:`label`; no simulator state is read.
        """
        return [SegmentLabel(s, e, place, self._say(ok), self.name)
                for s, e, place, ok in stay_verdicts(episode, self.fall_angle, self.hold_time, swung_up, balanced)]



def stay_verdicts(episode: Episode, fall_angle: float, hold_time: float, swung_up: str = "P1",
                  balanced: str = "P2") -> list[tuple[int, int, str, bool]]:
    """(start, end, place, verdict) of each swung-up and balanced stay of a trial seen by place, as
    :meth:`PendulumMentor.grade_trial` describes."""
    th = episode.column("theta")
    n, dt = episode.num_samples, episode.dt
    second = int(round(1.0 / dt))
    segments = episode.segments()
    out = []
    for i, (start, end, place) in enumerate(segments):
        nxt = segments[i + 1] if i + 1 < len(segments) else None
        if place == swung_up:
            ok = (nxt is not None and nxt[2] == balanced and end + second <= n
                  and bool(np.all(np.abs(th[end:end + second]) < fall_angle)))
        elif place == balanced:
            ok = (end - start) * dt >= hold_time - 1e-9 and bool(np.all(np.abs(th[start:end]) < fall_angle))
        else:
            continue
        out.append((start, end, place, bool(ok)))
    return out
