"""``multiform/Nunchaku-v0``: a hand flips a nunchaku (the paper's second task, Figs. 9-11).

The model (``assets/nunchaku.xml``) is a hand on an actuated 6-DoF base — three slides and three
hinges with servo speed and force limits — holding one rod of a nunchaku (two 0.30 m, 0.20 kg rods,
a 0.12 m chain of six capsule links on ball joints) with a switchable magnet. Why a base and not the
AUBO-like arm: the flip needs wrist roll rates of 10-17 rad/s and hand accelerations of 30-60 m/s^2
(see ``benchmarks/bench_nunchaku.py``); the AUBO i5's wrist joints are limited to 2.6 rad/s and its
shoulder to 3.14 rad/s, so the arm cannot perform it. The base stands for the arm's flange with a
fast wrist, with limits of 3 m/s, 20 rad/s, 150 N and 10 N m.

Physics: 1 ms step with MuJoCo's ``implicit`` integrator. ``implicitfast`` (the usual choice for
chains) diverged in 7 of 60 trials of the released nunchaku spinning in free flight (the ball-joint
chain's gyroscopic terms, which only ``implicit`` linearises); ``implicit`` diverged in none of 150
and costs about 25 µs more per step. The hand's servo forces are computed explicitly in Python, so
the simulated wrist F/T agrees with the motion actually integrated (an implicit actuator damping
would make it read 20 % of the hand's inertia wrong).

The flip happens in the world x-z plane. The hand's x axis lies across the palm (a held rod lies
along it), its y axis points out of the plane (where the forearm is), its z axis is the back-of-hand
normal, so the palm faces hand -z. At ``hand_q = 0`` the palm faces down.

Commands (``command_names``, the action): ``vx``, ``vz`` hand velocity in the flip plane [m/s];
``wq`` wrist angular velocity in the flip plane [rad/s], positive turns the hand's x axis towards
world +z; ``magnet`` > 0.5 switches the palm magnet on. The base servos track the commanded
velocities (force = kp (reference - q) + kv (command - qdot), the reference integrated from the
command); the out-of-plane joints are held at zero. The magnet grips a rod only when its axis passes
within ``capture`` (3 cm) of the palm and lies roughly along the palm; it then pulls the rod onto
the palm (a weld equality switched on with its target pose set at that moment) and holds it until
the command drops to 0.5 or below. The nunchaku starts with rod A held and rod B hanging.

Observations (``observation_names``) are the robot's own sensors and what it estimates from them,
never simulator ground truth:

==========  ==================================================================================
hand_x      hand position along world x from the workspace centre [m]
hand_z      hand position along world z from the workspace centre [m]
hand_q      wrist angle in the flip plane [rad]; 0 palm down, +pi/2 palm facing -x
hand_vx     hand velocity along x [m/s]
hand_vz     hand velocity along z [m/s]
hand_wq     wrist angular velocity [rad/s]
ft_fx       wrist force along the hand's x axis [N] (with sensor noise)
ft_fz       wrist force along the hand's z axis [N]
ft_ty       wrist torque in the flip plane [N m], positive in the sense of hand_q
grip        1 while the magnet holds a rod, else 0 (the magnet's own flux sensing)
touch       normal force on the back of the hand [N] (a touch pad there)
prox        distance from the palm to the nearest object along three palm rangefinders [m],
            0.1 when nothing is within 0.1 m
phi         estimated angle of the free part (chain and free rod) relative to the hand [rad]:
            0 along the palm normal (straight down when the palm faces down), +pi/2 along hand +x;
            from the wrist load (:mod:`multiform.envs.load_estimator`); held at its last value
            while no rod is held
omega       its estimated angular velocity relative to the hand [rad/s]; 0 while no rod is held
load        magnitude of the estimated pull of the free part on the held rod [N]
==========  ==================================================================================

``info["scene"]`` holds what a person watching sees (rod poses, which rod is held, the true angle of
the free rod); scripted mentors may read it, the robot never does. ``info["truth"]`` holds the true
values of the estimated quantities (``phi``, ``omega``) for error reports.

At reset the robot has just picked the nunchaku up: it holds still for ``settle`` seconds (0.25 by
default, not counted in the episode) and weighs the nunchaku from the wrist load, so that the
estimator's masses fit the randomised rods.

Reset options (each one fixes that quantity; unspecified ones are drawn from ``np_random`` unless
``randomize=False``, which gives the nominal value): ``rod_mass`` (scale, 0.9-1.1), ``rod_length``
(scale, 0.93-1.07), ``chain_damping`` (N m s/rad, 0.0005-0.002), ``friction`` (scale, 0.8-1.2),
``hand_x``, ``hand_z`` (m, +-0.03), ``hand_q`` (rad, +-0.08), ``swing`` (initial angle of the chain
and rod B, rad, +-0.15), ``grip_offset`` (rod A's position along the palm, m, +-0.01),
``ft_noise`` (force noise standard deviation, N, default 0.05; torque noise is 1/25 of it in N m).

Termination: a non-finite or exploding simulation ends the episode with ``terminated=True`` and
``info["diverged"] = True`` (never an exception); a nunchaku that falls away from the hand (no rod
held and both rods more than 0.6 m below the hand) ends it with ``info["dropped"] = True``.
Episodes are truncated after ``max_duration`` seconds (``gymnasium.make`` also registers 15,000
steps as ``max_episode_steps``; pass a larger one with a longer ``max_duration``).

Reward and success (for Gymnasium tooling; multiform's own runs grade trials with the skill's judges
and never read them): ``info["is_success"]`` is True once the flip is done, the check the nunchaku
task's evaluation applies: the first rod was let go, the chain then pressed on the back of the hand
(touch > 0.5 N), and the other rod (B) has been held in the palm for 0.5 s. The reward is 1 on the
step the flip becomes done, else 0.

``normalize_actions=True`` gives the action space [-1, 1] per entry, mapped linearly onto the limits
above (magnet on for a positive last entry); the default keeps the physical units.
"""

from __future__ import annotations

import math
from importlib import resources
from typing import Any

import gymnasium as gym
import mujoco
import numpy as np

from ..angles import wrap_angle
from .load_estimator import LoadEstimator
from .rendering import FramedEnv, check_frame_skip

OBSERVATION_NAMES = ("hand_x", "hand_z", "hand_q", "hand_vx", "hand_vz", "hand_wq", "ft_fx", "ft_fz",
                     "ft_ty", "grip", "touch", "prox", "phi", "omega", "load")
COMMAND_NAMES = ("vx", "vz", "wq", "magnet")
ROD_RADIUS = 0.0125
ROD_LENGTH = 0.30
PALM_Z = -0.015                    # palm surface in the hand frame
HELD_Z = PALM_Z - ROD_RADIUS       # a held rod's axis in the hand frame
KP_LIN, KV_LIN = 20000.0, 400.0      # hand servo gains, N/m and N s/m
KP_ROT, KV_ROT = 100.0, 2.0          # wrist servo gains, N m/rad and N m s/rad
HOME = (0.0, 1.0)                  # workspace centre (world x, z) [m]
WORKSPACE = 0.5                    # |hand_x|, |hand_z| limit of the reference [m]
PROX_RANGE = 0.1
FLIP_TOUCH = 0.5                   # N on the back of the hand: the chain rolled over it
FLIP_HOLD = 0.5                    # s the caught rod must stay in the palm
_Q, _FX, _FZ, _TOUCH = (OBSERVATION_NAMES.index(n) for n in ("hand_q", "ft_fx", "ft_fz", "touch"))
_BAD = tuple(int(w) for w in (mujoco.mjtWarning.mjWARN_BADQPOS, mujoco.mjtWarning.mjWARN_BADQVEL,
                                mujoco.mjtWarning.mjWARN_BADQACC))

RANGES = {"rod_mass": (0.9, 1.1), "rod_length": (0.93, 1.07), "chain_damping": (0.0005, 0.002),
          "friction": (0.8, 1.2), "hand_x": (-0.03, 0.03), "hand_z": (-0.03, 0.03),
          "hand_q": (-0.08, 0.08), "swing": (-0.15, 0.15), "grip_offset": (-0.01, 0.01)}
NOMINAL = {"rod_mass": 1.0, "rod_length": 1.0, "chain_damping": 0.001, "friction": 1.0, "hand_x": 0.0,
           "hand_z": 0.0, "hand_q": 0.0, "swing": 0.0, "grip_offset": 0.0}


def model_path() -> str:
    """Path of the bundled MJCF model."""
    return str(resources.files("multiform") / "envs" / "assets" / "nunchaku.xml")


class NunchakuHand:
    """The MuJoCo scene of a hand on a 6-DoF base, with a magnet palm and a wrist F/T sensor, and a
    nunchaku: the episode's parameters (rod length and mass, friction, chain damping), the start
    pose, and the magnet that grips a rod within ``capture`` [m] of the palm. :class:`NunchakuEnv`
    is its Gymnasium API."""

    def __init__(self, capture: float = 0.03):
        self.capture = float(capture)
        self.model = mujoco.MjModel.from_xml_path(model_path())
        # no silent reset on bad values: a non-finite state ends the step as ``non_finite``
        self.model.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_AUTORESET)
        self.data = mujoco.MjData(self.model)
        self._h = float(self.model.opt.timestep)          # one physics step
        m = self.model
        self._hand = m.body("hand").id
        self._rods = (m.body("rod_a").id, m.body("rod_b").id)
        self._links = tuple(m.body(f"link{i}").id for i in range(1, 7))
        self._welds = (m.equality("magnet_a").id, m.equality("magnet_b").id)
        jq = {n: int(m.joint(n).qposadr[0]) for n in ("hand_x", "hand_y", "hand_z", "hand_rz", "hand_rx", "hand_q")}
        jv = {n: int(m.joint(n).dofadr[0]) for n in jq}
        self._qx, self._qz, self._qq = jq["hand_x"], jq["hand_z"], jq["hand_q"]
        self._vx, self._vz, self._vq = jv["hand_x"], jv["hand_z"], jv["hand_q"]
        self._qa = int(m.joint("rod_a").qposadr[0])
        self._ball = [int(m.joint(f"link{i}").qposadr[0]) for i in range(1, 7)] + [int(m.joint("rod_b").qposadr[0])]
        self._ball_dof = [int(m.joint(f"link{i}").dofadr[0]) for i in range(1, 7)] + [int(m.joint("rod_b").dofadr[0])]
        act = {m.actuator(i).name: i for i in range(m.nu)}
        self._act = (act["f_x"], act["f_z"], act["t_q"])
        self._sens = {n: int(m.sensor(n).adr[0]) for n in ("wrist_force", "wrist_torque", "back_touch",
                                                            "prox_c", "prox_p", "prox_t")}
        self._geom_rod = (m.geom("rod_a").id, m.geom("rod_b").id)
        self._nominal = {
            "geom_size": m.geom_size.copy(), "geom_pos": m.geom_pos.copy(), "body_pos": m.body_pos.copy(),
            "body_mass": m.body_mass.copy(), "body_inertia": m.body_inertia.copy(),
            "body_ipos": m.body_ipos.copy(), "geom_friction": m.geom_friction.copy(),
            "dof_damping": m.dof_damping.copy()}
        self.estimator = LoadEstimator()
        self.params: dict[str, float] = dict(NOMINAL)
        self._ref = [0.0, 0.0, 0.0]
        self._half = [ROD_LENGTH / 2, ROD_LENGTH / 2]
        self._held = -1
        self._grip_time = 0.0
        self._phi = 0.0
        self._omega = 0.0
        self._load = 0.0
        self._prev_v = (0.0, 0.0, 0.0)

    def _apply_params(self, p: dict[str, float]) -> None:
        m, nom = self.model, self._nominal
        for k in ("geom_size", "geom_pos", "body_pos", "body_mass", "body_inertia", "body_ipos",
                  "geom_friction", "dof_damping"):
            getattr(m, k)[:] = nom[k]
        s, ms = p["rod_length"], p["rod_mass"]
        half = ROD_LENGTH / 2 * s
        self._half = [half, half]
        ga, gb = self._geom_rod
        ra, rb = self._rods
        m.geom_size[ga, 1] = m.geom_size[gb, 1] = half - ROD_RADIUS
        m.geom_pos[gb, 2] = -half
        m.body_ipos[rb, 2] = -half
        m.body_pos[self._links[0], 0] = half
        for b in (ra, rb):
            m.body_mass[b] = nom["body_mass"][b] * ms
            inertia = nom["body_inertia"][b] * ms
            order = np.argsort(inertia)
            inertia[order[1:]] *= s * s
            m.body_inertia[b] = inertia
        m.geom_friction[:, 0] = nom["geom_friction"][:, 0] * p["friction"]
        for dof in self._ball_dof:
            m.dof_damping[dof:dof + 3] = p["chain_damping"]

    def _place(self, p: dict[str, float]) -> None:
        """The hand where ``p`` puts it, rod A held on the palm (welded), rod B hanging at ``swing``;
        the grip and the estimator reset."""
        m, d = self.model, self.data
        mujoco.mj_resetData(m, d)
        q0 = p["hand_q"]
        d.qpos[self._qx], d.qpos[self._qz], d.qpos[self._qq] = p["hand_x"], p["hand_z"], q0
        # rod A on the palm, its chain end just past the hand's +x edge
        half = self._half[0]
        cx = 0.065 + p["grip_offset"] - half
        rel_pos = np.array([cx, 0.0, HELD_Z])
        hand_quat = np.array([math.cos(q0 / 2), 0.0, -math.sin(q0 / 2), 0.0])
        hx, hz = HOME[0] + p["hand_x"], HOME[1] + p["hand_z"]
        cq, sq = math.cos(q0), math.sin(q0)
        d.qpos[self._qa:self._qa + 3] = [hx + cx * cq - HELD_Z * sq, 0.0, hz + cx * sq + HELD_Z * cq]
        d.qpos[self._qa + 3:self._qa + 7] = hand_quat
        # chain and rod B hang at world angle `swing` (a rotation about -y relative to rod A)
        a = p["swing"] - q0
        d.qpos[self._ball[0]:self._ball[0] + 4] = [math.cos(a / 2), 0.0, -math.sin(a / 2), 0.0]
        for e in self._welds:
            d.eq_active[e] = 0
        m.eq_data[self._welds[0], 3:6] = rel_pos
        m.eq_data[self._welds[0], 6:10] = [1.0, 0.0, 0.0, 0.0]
        m.eq_solref[self._welds[0], 0] = 0.002
        d.eq_active[self._welds[0]] = 1
        self._held = 0
        self._grip_time = 0.0
        self._ref = [p["hand_x"], p["hand_z"], q0]
        mujoco.mj_forward(m, d)
        self._prev_v = (0.0, 0.0, 0.0)
        self.estimator.weigh(9.81 * 0.46)          # nominal masses until the nunchaku is weighed
        self.estimator.reset(pivot=(0.065 + p["grip_offset"], HELD_Z), held_com=(cx, HELD_Z),
                             angle=0.0, angle_std=0.25)
        self._phi, self._omega, self._load = 0.0, 0.0, 0.0

    # ------------------------------------------------------------------ magnet
    def _magnet(self, on: bool) -> None:
        m, d = self.model, self.data
        if not on:
            if self._held >= 0:
                d.eq_active[self._welds[self._held]] = 0
                self._held = -1
            return
        if self._held >= 0:
            tau = d.time - self._grip_time
            e = self._welds[self._held]
            if m.eq_solref[e, 0] > 0.002:
                m.eq_solref[e, 0] = max(0.002, 0.02 - 0.36 * tau)
            return
        for i in (0, 1):
            pose = self._rod_in_hand(i)
            if pose is not None and self._capturable(pose):
                self._grip(i, pose)
                return

    def _rod_in_hand(self, i: int):
        """Rod ``i``'s axis (unit), centre and body pose in the hand frame."""
        d = self.data
        rh = d.xmat[self._hand].reshape(3, 3)
        b = self._rods[i]
        rb = rh.T @ d.xmat[b].reshape(3, 3)
        pos = rh.T @ (d.xpos[b] - d.xpos[self._hand])
        axis = rb[:, 0] if i == 0 else -rb[:, 2]
        centre = pos if i == 0 else pos + axis * self._half[1]
        return axis, centre, pos, rb

    def _capturable(self, pose) -> bool:
        axis, centre, _, _ = pose
        if abs(axis[2]) > 0.5:
            return False
        # does the rod's axis segment enter the capture box below the palm? (slab test)
        lo = (-0.06, -0.05, HELD_Z - self.capture)
        hi = (0.06, 0.05, PALM_Z + 0.005)
        h = self._half[0]
        t0, t1 = -h, h
        for k in range(3):
            a, c = axis[k], centre[k]
            if abs(a) < 1e-9:
                if c < lo[k] or c > hi[k]:
                    return False
                continue
            u, w = (lo[k] - c) / a, (hi[k] - c) / a
            if u > w:
                u, w = w, u
            t0, t1 = max(t0, u), min(t1, w)
            if t0 > t1:
                return False
        return True

    def _grip(self, i: int, pose) -> None:
        m, d = self.model, self.data
        axis, centre, pos, rb = pose
        target = np.array([1.0 if axis[0] >= 0 else -1.0, 0.0, 0.0])
        cross = np.cross(axis, target)
        s = float(np.linalg.norm(cross))
        corr = np.eye(3)
        if s > 1e-9:
            k = cross / s
            ang = math.atan2(s, float(axis @ target))
            kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
            corr = np.eye(3) + math.sin(ang) * kx + (1 - math.cos(ang)) * kx @ kx
        rt = corr @ rb
        half = self._half[i]
        cx = min(max(float(centre[0]), -(half - 0.03)), half - 0.03)
        ct = np.array([cx, 0.0, HELD_Z])
        offset = np.zeros(3) if i == 0 else rt @ np.array([0.0, 0.0, -half])
        quat = np.zeros(4)
        mujoco.mju_mat2Quat(quat, rt.ravel())
        e = self._welds[i]
        m.eq_data[e, 3:6] = ct - offset
        m.eq_data[e, 6:10] = quat
        m.eq_solref[e, 0] = 0.02
        d.eq_active[e] = 1
        self._held = i
        self._grip_time = d.time
        # the pivot is the held rod's chain end: rod A's local +x end, rod B's body origin
        chain_end = ct + rt @ np.array([half, 0.0, 0.0]) if i == 0 else ct - offset
        self.estimator.reset(pivot=(float(chain_end[0]), HELD_Z), held_com=(cx, HELD_Z), angle=None)



class NunchakuEnv(NunchakuHand, FramedEnv, gym.Env):
    """A hand on a 6-DoF base with a magnet palm and a wrist F/T sensor, holding a nunchaku.

    ``max_duration`` [s] truncates an episode; ``capture`` [m] is the magnet's reach from the palm;
    ``width``/``height`` size the ``rgb_array`` frames, ``shadows`` False renders them without
    shadows (much cheaper on a CPU renderer). ``dt`` is 0.001 s (one control step = one physics step)
    times ``frame_skip`` (default 1; physics steps per env step, the action held, as in
    :class:`multiform.envs.arm_pendulum.ArmPendulumEnv`: for control at a lower rate and videos).
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": 1000}       # one frame per step: 1000 / frame_skip
    observation_names = OBSERVATION_NAMES
    command_names = COMMAND_NAMES

    def __init__(self, render_mode: str | None = None, max_duration: float = 15.0, capture: float = 0.03,
                 settle: float = 0.25, width: int = 480, height: int = 360, shadows: bool = True,
                 normalize_actions: bool = False, frame_skip: int = 1):
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode must be one of {self.metadata['render_modes']} or None")
        self.frame_skip = check_frame_skip(frame_skip)
        self.render_mode = render_mode
        self.max_duration = float(max_duration)
        self.settle = float(settle)
        self.width, self.height = int(width), int(height)
        self.shadows = bool(shadows)
        NunchakuHand.__init__(self, capture)
        self.dt = self._h * self.frame_skip                # one env step
        self.metadata = {**type(self).metadata, "render_fps": int(round(1.0 / self.dt))}
        self.action_space = gym.spaces.Box(np.array([-3.0, -3.0, -20.0, 0.0]), np.array([3.0, 3.0, 20.0, 1.0]),
                                           dtype=np.float64)
        self.observation_space = gym.spaces.Box(-np.inf, np.inf, (len(OBSERVATION_NAMES),), dtype=np.float64)
        self._obs = np.zeros(len(OBSERVATION_NAMES))
        self._action_box: tuple[np.ndarray, np.ndarray] | None = None
        if normalize_actions:
            self._action_box = (self.action_space.low.copy(), self.action_space.high.copy())
            self.action_space = gym.spaces.Box(-1.0, 1.0, (len(COMMAND_NAMES),), dtype=np.float64)
        self._flip = {"released": False, "touched": False, "held_b": 0, "done": False}
        self._renderer: mujoco.Renderer | None = None
        self._camera: mujoco.MjvCamera | None = None
        self._ft_noise = 0.05
        self._steps = 0

    # ------------------------------------------------------------------ reset
    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        super().reset(seed=seed)
        p = self._draw_params(dict(options or {}))
        self.params = p
        self._apply_params(p)
        self._place(p)
        obs = self._observe(0.0, 0.0, 0.0, estimate=False)
        obs = self._settle(obs)
        self._steps = 0
        self._flip = {"released": False, "touched": False, "held_b": 0, "done": False}
        return obs, self._info(False)

    def _draw_params(self, options: dict[str, Any]) -> dict[str, float]:
        """This episode's parameters: those the reset options fix, the others drawn from ``RANGES``
        (or nominal without ``randomize``); sets the force sensor's noise (``ft_noise``)."""
        randomize = bool(options.pop("randomize", True))
        self._ft_noise = float(options.pop("ft_noise", 0.05))
        unknown = set(options) - set(RANGES)
        if unknown:
            raise ValueError(f"unknown reset option(s) {sorted(unknown)}; known: {sorted(RANGES)}, "
                             "randomize, ft_noise")
        p = {}
        for k, (lo, hi) in RANGES.items():
            if k in options:
                p[k] = float(options[k])
            elif randomize:
                p[k] = float(self.np_random.uniform(lo, hi))
            else:
                p[k] = NOMINAL[k]
        bad = {k: v for k, v in p.items() if not math.isfinite(v)
               or (k in ("rod_mass", "rod_length", "friction") and not v > 0) or (k == "chain_damping" and v < 0)}
        if bad or not (math.isfinite(self._ft_noise) and self._ft_noise >= 0):
            raise ValueError(f"reset options out of range: {bad or {'ft_noise': self._ft_noise}} (all finite; rod mass, "
                             "rod length and friction above 0; chain damping and ft_noise at least 0)")
        return p

    def _settle(self, obs: np.ndarray) -> np.ndarray:
        """The robot has just picked the nunchaku up and holds still for a moment; it weighs it (the
        wrist's vertical load minus the hand's own weight) so the estimator's masses fit. Returns
        the observation after."""
        n_settle = int(round(self.settle / self._h))
        load = 0.0
        hold = np.array([0.0, 0.0, 0.0, 1.0])
        for _ in range(n_settle):
            obs, _, terminated, _, _ = self._step(hold)
            if terminated:
                break
            load += self.wrist_vertical_load()
        if n_settle:
            hand_weight = self.model.body_mass[self._hand] * 9.81
            self.estimator.weigh(load / n_settle - hand_weight)
        return obs

    # ------------------------------------------------------------------- step
    def _physics_step(self, action):
        if self._action_box is not None:
            lo, hi = self._action_box
            action = lo + (np.clip(np.asarray(action, dtype=np.float64), -1.0, 1.0) + 1.0) * 0.5 * (hi - lo)
        obs, _, terminated, truncated, info = self._step(action)
        done_before = self._flip["done"]
        if not info["diverged"]:
            self._track_flip()
        info["is_success"] = self._flip["done"]
        return obs, float(self._flip["done"] and not done_before), terminated, truncated, info

    def _track_flip(self) -> None:
        f = self._flip
        if self._held < 0:
            f["released"] = True
            f["touched"] = f["touched"] or self.back_of_hand_touch() > FLIP_TOUCH
        f["held_b"] = f["held_b"] + 1 if self._held == 1 else 0
        if f["released"] and f["touched"] and f["held_b"] * self._h >= FLIP_HOLD - 1e-9:
            f["done"] = True

    def _step(self, action):
        m, d = self.model, self.data
        dt = self._h
        vx = min(max(float(action[0]), -3.0), 3.0)
        vz = min(max(float(action[1]), -3.0), 3.0)
        wq = min(max(float(action[2]), -20.0), 20.0)
        magnet = float(action[3]) > 0.5
        qpos = d.qpos
        rx, rz, rq = self._ref
        x, z, q = qpos[self._qx], qpos[self._qz], qpos[self._qq]
        rx = min(max(rx + vx * dt, x - 0.05, -WORKSPACE), x + 0.05, WORKSPACE)
        rz = min(max(rz + vz * dt, z - 0.05, -WORKSPACE), z + 0.05, WORKSPACE)
        rq = min(max(rq + wq * dt, q - 0.3), q + 0.3)
        self._ref = [rx, rz, rq]
        qvel = d.qvel
        ctrl = d.ctrl
        a = self._act
        ctrl[a[0]] = KP_LIN * (rx - x) + KV_LIN * (vx - qvel[self._vx])
        ctrl[a[1]] = KP_LIN * (rz - z) + KV_LIN * (vz - qvel[self._vz])
        ctrl[a[2]] = KP_ROT * (rq - q) + KV_ROT * (wq - qvel[self._vq])
        self._magnet(magnet)
        warn = d.warning
        nbad = warn[_BAD[0]].number + warn[_BAD[1]].number + warn[_BAD[2]].number
        mujoco.mj_step(m, d)
        self._steps += 1
        diverged = (warn[_BAD[0]].number + warn[_BAD[1]].number + warn[_BAD[2]].number != nbad
                    or not (np.isfinite(d.qvel).all() and abs(d.qvel).max() < 1e4))
        if diverged:
            obs = self._obs = np.zeros(len(OBSERVATION_NAMES))
            info = {"diverged": True, "non_finite": not np.isfinite(d.qvel).all(), "dropped": False,
                    "scene": {}, "truth": {}, "is_success": False}
            return obs, 0.0, True, False, info
        qvel = d.qvel
        v = (qvel[self._vx], qvel[self._vz], qvel[self._vq])
        pv = self._prev_v
        acc = ((v[0] - pv[0]) / dt, (v[1] - pv[1]) / dt, (v[2] - pv[2]) / dt)
        self._prev_v = v
        obs = self._observe(*acc)
        dropped = False
        if self._held < 0:
            hz = d.xpos[self._hand, 2]
            dropped = d.xpos[self._rods[0], 2] < hz - 0.6 and d.xpos[self._rods[1], 2] < hz - 0.6
        truncated = self._steps * dt >= self.max_duration - 1e-9
        return obs, 0.0, dropped, truncated, self._info(dropped)

    # ------------------------------------------------------------ observation
    def _observe(self, ax: float, az: float, alpha: float, estimate: bool = True) -> np.ndarray:
        d = self.data
        sd = d.sensordata
        rng = self.np_random
        s = self._sens
        fa, ta = s["wrist_force"], s["wrist_torque"]
        noise = self._ft_noise
        if noise > 0:
            n = rng.standard_normal(3)
            fx, fz, ty = sd[fa] + noise * n[0], sd[fa + 2] + noise * n[1], sd[ta + 1] + noise / 25 * n[2]
        else:
            fx, fz, ty = sd[fa], sd[fa + 2], sd[ta + 1]
        qpos, qvel = d.qpos, d.qvel
        x, z, q = qpos[self._qx], qpos[self._qz], qpos[self._qq]
        vx, vz, w = qvel[self._vx], qvel[self._vz], qvel[self._vq]
        if self._held >= 0 and estimate:
            self._phi, self._omega = self.estimator.update((fx, fz), q, w, alpha, ax, az, self._h)
            px, pz = self.estimator.pull
            self._load = math.hypot(px, pz)
        elif self._held < 0:
            self._omega = 0.0
            self._load = 0.0
        prox = PROX_RANGE
        for k in ("prox_c", "prox_p", "prox_t"):
            r = sd[s[k]]
            if 0.0 <= r < prox:
                prox = r
        self._obs = np.array([x, z, q, vx, vz, w, fx, fz, -ty, 1.0 if self._held >= 0 else 0.0,
                              sd[s["back_touch"]], prox, self._phi, self._omega, self._load])
        return self._obs

    # -- named views of the last observation (as dm_control's cartpole has physics.pole_angle_cosine())
    def wrist_vertical_load(self) -> float:
        """The wrist force sensor's reading along world z (hand frame turned by ``hand_q``) [N]."""
        o = self._obs
        return o[_FZ] * math.cos(o[_Q]) + o[_FX] * math.sin(o[_Q])

    def back_of_hand_touch(self) -> float:
        """The touch sensor on the back of the hand: the chain rolling over it [N]."""
        return self._obs[_TOUCH]

    def _info(self, dropped: bool) -> dict[str, Any]:
        d = self.data
        xm, xp = d.xmat, d.xpos
        ra, rb = self._rods
        h = self._hand
        q = d.qpos[self._qq]
        ang_a = math.atan2(xm[ra, 0], -xm[ra, 6])        # rod A's axis is its local x
        ang_b = math.atan2(-xm[rb, 2], xm[rb, 8])        # rod B's axis is its local -z
        held = "ab"[self._held] if self._held >= 0 else ""
        free = rb if self._held != 1 else ra
        free_ang = ang_b if self._held != 1 else ang_a
        # in-plane angular rate: rotation about world -y
        w_free = -d.cvel[free, 1] + d.cvel[h, 1]
        scene = {"hand": (xp[h, 0] - HOME[0], xp[h, 2] - HOME[1], q), "rod_a": (xp[ra, 0], xp[ra, 2], ang_a),
                 "rod_b": (xp[rb, 0], xp[rb, 2], ang_b), "held": held, "back_touch": float(d.sensordata[self._sens["back_touch"]]),
                 "free_angle": wrap_angle(free_ang - q), "free_rate": w_free, "hand_z_world": xp[h, 2]}
        truth = {"phi": scene["free_angle"], "omega": w_free}
        return {"diverged": False, "dropped": dropped, "scene": scene, "truth": truth,
                "is_success": self._flip["done"]}

    # ----------------------------------------------------------------- render
    def _render_camera(self):
        """A free camera beside the swing plane, following the hand."""
        if self._camera is None:
            cam = mujoco.MjvCamera()
            cam.type = mujoco.mjtCamera.mjCAMERA_FREE
            cam.azimuth, cam.elevation, cam.distance = 90.0, -5.0, 1.3
            self._camera = cam
        self._camera.lookat[:] = [self.data.xpos[self._hand, 0], 0.0, self.data.xpos[self._hand, 2] - 0.15]
        return self._camera
