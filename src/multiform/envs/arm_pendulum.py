"""``multiform/ArmPendulum-v0``: a 6-axis arm (AUBO i5 kinematics) swings up and balances a pendulum.

The model (``assets/arm_pendulum.xml``) is the arm on a pedestal with an unactuated pendulum on a
hinge at its flange. In the home posture the flange sits at the workspace centre (0, -0.55, 0.3) m
in front of the robot with the world's orientation; the hinge axis is world y, so moving the
end-effector along world x (the swing axis) swings the pendulum in the x-z plane — the cart-pole
analogue. One step is one 1 ms physics step (``dt = 0.001``, implicit-fast integrator).

Actions (``action_mode``):

* ``"ee"`` (default): ``[v_cmd]``, the desired end-effector velocity along the swing axis [m/s],
  clipped to ±1.5. The reference controller (:mod:`multiform.envs.osc`) turns it into joint
  torques: a 30 rad/s velocity servo with a soft wall at |x| = 0.35 m, holds of y, z and the
  orientation, computed-torque inverse dynamics, torque saturation.
* ``"torque"``: six joint torques [N m], clipped to ±150 (joints 1-3) and ±30 (joints 4-6).
* ``"kinesthetic"``: ``[f_x]``, a person's force on the flange along the swing axis [N], clipped to
  ±150; the arm is in its compliant hand-guiding mode (:mod:`multiform.envs.compliant`: gravity and
  friction compensated, a light damping along x, virtual walls at the servo's stroke, y, z and the
  orientation locked). :meth:`ArmPendulumEnv.command_from_motion` recovers the ``[v_cmd]`` under
  which the ``"ee"`` servo reproduces the guided motion (kinesthetic teaching,
  :mod:`multiform.teach.kinesthetic`).

Observations (``observation_names``, float64, the robot's own sensors: joint encoders and the
pendulum's hinge encoder, with forward kinematics):

==================  ===========================================================================
theta               pendulum angle in the swing plane [rad]; 0 upright, positive with the tip
                    towards +x, wrapped to (-pi, pi] (hanging = ±pi)
omega               its angular velocity [rad/s]
x, xdot             end-effector displacement along the swing axis from the workspace centre [m],
                    and its velocity [m/s]
ee_x, ee_y, ee_z    flange position in the world [m]
ee_vx, ee_vy, ee_vz flange linear velocity [m/s]
ee_rx, ee_ry, ee_rz flange orientation error from the home orientation, as a rotation vector [rad]
ee_wx, ee_wy, ee_wz flange angular velocity [rad/s]
q1..q6, qd1..qd6    joint positions [rad] and velocities [rad/s]
==================  ===========================================================================

``command_names`` is ``("v_cmd",)``.

Reset options (all optional):

* ``length`` [m, default 0.4] hinge-to-tip length, ``mass`` [kg, default 0.1] (rod 40 %, tip 60 %),
  ``damping`` [N m s/rad, default 2e-4] hinge friction. Inertia and centre of mass are recomputed.
* ``randomize`` (bool, default False): scale length and mass not given explicitly by U(0.8, 1.2).
* ``theta0`` [rad], ``omega0`` [rad/s]: initial pendulum state; default hanging,
  ``pi + U(-0.1, 0.1)`` and ``U(-0.1, 0.1)``.
* ``x0`` [m, default 0]: the hand's start along the swing axis, |x0| ≤ 0.35 (the arm starts at rest
  in the posture that puts the flange there with the home orientation, found by inverse kinematics).
* ``disturbances``: list of ``{"time": s, "duration": s, "torque": N m}`` torque pulses on the
  pendulum about the hinge axis (an external push: applied to the pendulum body, reacted by the
  world). :meth:`ArmPendulumEnv.push` injects one now.

The arm always starts at rest, in the home posture unless ``x0`` says otherwise. The episode's
pendulum parameters are in ``env.params`` (the mentor must not read them; a person does not know
them either).

Termination: a non-finite or exploding simulation ends the episode with ``terminated=True`` and
``info["diverged"] = True``; the flange leaving the workspace far beyond the servo's soft wall
(|x| > 0.6 m, y or z more than 0.25 m from the centre, or tilted more than 1 rad) ends it with
``info["out_of_workspace"] = True``. ``gymnasium.make`` adds a 60 s time limit (60,000 steps;
``max_episode_steps=`` changes it). ``info["disturbance"]`` is the torque applied in the last step.

Reward and success (for Gymnasium tooling; multiform's own runs grade trials with the skill's judges
and never read them): the reward is ``dt`` (0.001) for every step that ends with the pendulum
upright (|theta| < 0.5 rad), else 0, so an episode's return is its time upright in seconds;
``info["is_success"]`` is True once it has stayed upright for 5 s without a break, the check the
pendulum task's evaluation applies.

``normalize_actions=True`` gives the action space [-1, 1] per entry, scaled to the limits above
(±1.5 m/s, or the torque limits); the default keeps the physical units.

``frame_skip`` (default 1): physics steps per env step, the action held over them (the servo and
the pushes still run every 1 ms), as Gymnasium's MuJoCo envs have it: ``dt`` is ``0.001 *
frame_skip``, ``render_fps`` ``1000 / frame_skip``, the reward the sum over the skipped steps. Use it
to control at 25-100 Hz or to record videos: Gymnasium's ``RecordVideo`` keeps one frame per step
until the episode ends, so at 1 kHz a 60 s episode is 60,000 frames (31 GB at 480×360); with
``frame_skip=40, width=320, height=240`` it is 1,500 frames, about 350 MB (``max_episode_steps=1500``
keeps the 60 s limit, which ``gymnasium.make`` counts in steps). multiform's own runs use 1.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import gymnasium as gym
import mujoco
import numpy as np

from .arm_model import arm_posture, load_model
from .compliant import DEFAULT_COMPLIANCE, Compliance, apply_hand_force, command_from_motion, compliant_torques, wall_force
from .osc import DEFAULT_GAINS, OBSERVATION_NAMES, TORQUE_LIMITS, Gains, Workspace, task_acceleration_list, torques_for
from .rendering import FramedEnv, check_frame_skip

COMMAND_NAMES = ("v_cmd",)
NOMINAL = {"length": 0.4, "mass": 0.1, "damping": 2e-4}
ROD_FRACTION = 0.4          # share of the pendulum's mass in the rod; the rest is the tip ball
TIP_RADIUS = 0.0125
ROD_RADIUS = 0.005
ROD_OFFSET = -0.016         # the rod lies this far from the hinge along the pendulum frame's y (world y) [m]
TERMINATE_X = 0.6
TERMINATE_YZ = 0.25
TERMINATE_TILT = 1.0
SUCCESS_ANGLE = 0.5         # rad: "upright" for the reward and is_success
SUCCESS_HOLD = 5.0          # s upright without a break: is_success
_OBJ_SITE = int(mujoco.mjtObj.mjOBJ_SITE)
_THETA, _OMEGA, _X, _EY, _EZ, _RX, _RY, _RZ = (OBSERVATION_NAMES.index(n) for n in (
    "theta", "omega", "x", "ee_y", "ee_z", "ee_rx", "ee_ry", "ee_rz"))
_OPTIONS = ("length", "mass", "damping", "randomize", "theta0", "omega0", "x0", "disturbances")


# the largest pendulum the arm's simulation is meant for (the nominal one is 0.4 m, 0.1 kg, 2e-4 N m s/rad)
MAX_PARAMS = {"length": 2.0, "mass": 10.0, "damping": 10.0}


def pendulum_inertia(length: float, mass: float) -> tuple[float, float, float]:
    """Centre-of-mass distance from the hinge, transverse and axial inertia about the COM."""
    mr, mt = ROD_FRACTION * mass, (1.0 - ROD_FRACTION) * mass
    lc = (mr * length / 2 + mt * length) / mass
    transverse = mr * (length ** 2 / 12 + (length / 2 - lc) ** 2) + mt * ((length - lc) ** 2 + 0.4 * TIP_RADIUS ** 2)
    axial = mr * 0.5 * ROD_RADIUS ** 2 + 0.4 * mt * TIP_RADIUS ** 2
    return lc, transverse, axial


def equivalent_length(length: float, mass: float = 1.0) -> float:
    """Length of the simple pendulum with the same dynamics, ``J_hinge / (m l_c)`` [m]."""
    lc, it, _ = pendulum_inertia(length, mass)
    return (it + mass * lc * lc) / (mass * lc)


class ArmPendulumEnv(FramedEnv, gym.Env):
    """A 6-axis arm carrying a pendulum on its flange (see the module docstring).

    ``action_mode`` is ``"ee"``, ``"torque"`` or ``"kinesthetic"``; ``gains`` the reference controller's
    (:class:`multiform.envs.osc.Gains`), ``compliance`` the hand-guiding mode's; ``width``/``height``/``camera`` the ``rgb_array`` frames
    (cameras ``"front"`` and ``"side"``); ``shadows`` False renders without them (on a CPU renderer
    they are over half a frame's cost: 37 against 16 ms at 480×360).
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": 1000}       # one frame per step: 1000 / frame_skip
    observation_names = OBSERVATION_NAMES
    command_names = COMMAND_NAMES
    guided_velocity_names = ("xdot",)     # the hand velocity the command is, for a guiding hand
    action_modes = ("ee", "torque", "kinesthetic")

    def __init__(self, render_mode: str | None = None, action_mode: str = "ee", gains: Gains | None = None,
                 width: int = 480, height: int = 360, camera: str = "front", shadows: bool = True,
                 normalize_actions: bool = False, frame_skip: int = 1, compliance: Compliance | None = None):
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode must be one of {self.metadata['render_modes']} or None")
        self.frame_skip = check_frame_skip(frame_skip)
        if action_mode not in self.action_modes:
            raise ValueError(f"action_mode must be one of {self.action_modes}, not {action_mode!r}")
        self.render_mode = render_mode
        self.action_mode = action_mode
        self.gains = gains if gains is not None else DEFAULT_GAINS
        self.compliance = compliance if compliance is not None else DEFAULT_COMPLIANCE
        self.width, self.height, self.camera = int(width), int(height), camera
        self.shadows = bool(shadows)
        self.model = load_model()
        self.data = mujoco.MjData(self.model)
        m = self.model
        self._h = float(m.opt.timestep)                   # one physics step
        self.dt = self._h * self.frame_skip                # one env step
        self.metadata = {**type(self).metadata, "render_fps": int(round(1.0 / self.dt))}
        self.workspace_centre = tuple(self.gains.centre)
        self.x_limit = float(self.gains.x_limit)
        self.torque_limits = TORQUE_LIMITS
        self._neg_limits = -TORQUE_LIMITS
        if action_mode == "ee":
            v = self.gains.v_max
            self.action_space = gym.spaces.Box(-v, v, (1,), dtype=np.float64)
        elif action_mode == "kinesthetic":
            f = self.compliance.force_max
            self.action_space = gym.spaces.Box(-f, f, (1,), dtype=np.float64)
        else:
            self.action_space = gym.spaces.Box(-self.torque_limits, self.torque_limits, dtype=np.float64)
        self._action_unit: np.ndarray | None = None
        if normalize_actions:
            self._action_unit = self.action_space.high.copy()
            self.action_space = gym.spaces.Box(-1.0, 1.0, self._action_unit.shape, dtype=np.float64)
        self._hold_steps = int(math.ceil(SUCCESS_HOLD / self._h - 1e-9))
        self._upright = 0
        self.observation_space = gym.spaces.Box(-np.inf, np.inf, (len(OBSERVATION_NAMES),), dtype=np.float64)
        key = m.key("home").id
        self.home_qpos = m.key_qpos[key].copy()
        self._site = m.site("flange").id
        self._pend = m.body("pendulum").id
        self._hinge_q = int(m.joint("pendulum").qposadr[0])
        self._hinge_v = int(m.joint("pendulum").dofadr[0])
        self._rod = m.geom("rod").id
        self._tip = m.geom("tip").id
        d = self.data
        self._work = Workspace(m, d)
        self._vel6 = np.zeros(6)
        self._vel6_list = [0.0] * 6
        self._pxmat = d.xmat[self._pend]
        self._pcvel = d.cvel[self._pend]
        self._spos = d.site_xpos[self._site]
        self._smat = d.site_xmat[self._site]
        self._qpos6 = d.qpos[:6]
        self._qvel6 = d.qvel[:6]
        self._ctrl = d.ctrl
        self._tau = np.zeros(len(self._ctrl))
        self._xfrc = d.xfrc_applied[self._pend]
        self._quat = np.zeros(4)
        self._rv = np.zeros(3)
        self._obs_list: list[float] = [0.0] * len(OBSERVATION_NAMES)
        self._pulses: list[tuple[float, float, float]] = []
        self._applied = 0.0
        self.params: dict[str, float] = dict(NOMINAL)
        self._renderer: mujoco.Renderer | None = None

    # ------------------------------------------------------------------ reset
    def reset(self, *, seed: int | None = None, options: Mapping[str, Any] | None = None):
        super().reset(seed=seed)
        options = self._reset_options(options, _OPTIONS)
        rng = self.np_random
        randomize = bool(options.get("randomize", False))
        p = {}
        for k in ("length", "mass"):
            if options.get(k) is not None:
                p[k] = float(options[k])
            else:
                p[k] = NOMINAL[k] * (float(rng.uniform(0.8, 1.2)) if randomize else 1.0)
        p["damping"] = float(options["damping"]) if options.get("damping") is not None else NOMINAL["damping"]
        if not (0.05 < p["length"] <= MAX_PARAMS["length"] and 0.0 < p["mass"] <= MAX_PARAMS["mass"]
                and 0.0 <= p["damping"] <= MAX_PARAMS["damping"]):
            raise ValueError(f"pendulum parameters out of range: {p}; allowed: length in (0.05, "
                             f"{MAX_PARAMS['length']}] m, mass in (0, {MAX_PARAMS['mass']}] kg, damping in "
                             f"[0, {MAX_PARAMS['damping']}] N m s/rad")
        theta0 = options.get("theta0")
        theta0 = float(theta0) if theta0 is not None else math.pi + float(rng.uniform(-0.1, 0.1))
        omega0 = options.get("omega0")
        omega0 = float(omega0) if omega0 is not None else float(rng.uniform(-0.1, 0.1))
        if not (math.isfinite(theta0) and math.isfinite(omega0) and abs(omega0) <= 1e3):
            raise ValueError(f"theta0 and omega0 must be finite (|omega0| <= 1000 rad/s), got {theta0!r}, {omega0!r}")
        x0 = float(options.get("x0") or 0.0)
        if not (math.isfinite(x0) and abs(x0) <= self.x_limit):
            raise ValueError(f"x0 must be within ±{self.x_limit} m, got {options.get('x0')!r}")
        self._pulses = self._parse_pulses(options.get("disturbances") or [])
        self.params = p
        self._apply_params(p)
        m, d = self.model, self.data
        mujoco.mj_resetData(m, d)
        d.qpos[:] = self.home_qpos if x0 == 0.0 else self._arm_posture(x0)
        d.qpos[self._hinge_q] = theta0
        d.qvel[self._hinge_v] = omega0
        mujoco.mj_forward(m, d)
        self._applied = 0.0
        self._upright = 0
        obs = self._observe()
        return obs, {"diverged": False, "out_of_workspace": False, "disturbance": 0.0, "is_success": False}

    def _arm_posture(self, x0: float) -> np.ndarray:
        """Joint positions that put the flange ``x0`` along the swing axis from the workspace centre
        with the home orientation (:func:`multiform.envs.arm_model.arm_posture`)."""
        target = np.array(self.workspace_centre) + (x0, 0.0, 0.0)
        try:
            return arm_posture(self.model, self.data, self._site, self.home_qpos, target)
        except RuntimeError:
            raise RuntimeError(f"no arm posture reaches x0 = {x0} m") from None

    @staticmethod
    def _parse_pulses(items: Sequence[Mapping[str, Any]]) -> list[tuple[float, float, float]]:
        pulses = []
        for i, it in enumerate(items):
            try:
                t, dur, tau = float(it["time"]), float(it["duration"]), float(it["torque"])
            except (KeyError, TypeError, ValueError):
                raise ValueError(f"disturbances[{i}] must be a mapping with numeric time, duration and "
                                 f"torque, got {it!r}") from None
            if not (math.isfinite(t) and math.isfinite(dur) and math.isfinite(tau)) or dur < 0 or t < 0:
                raise ValueError(f"disturbances[{i}]: time and duration must be finite and >= 0, got {it!r}")
            pulses.append((t, t + dur, tau))
        return sorted(pulses)

    def _apply_params(self, p: Mapping[str, float]) -> None:
        m = self.model
        length, mass = p["length"], p["mass"]
        lc, it, ia = pendulum_inertia(length, mass)
        b = self._pend
        m.body_mass[b] = mass
        m.body_ipos[b] = (0.0, ROD_OFFSET, lc)
        m.body_inertia[b] = (it, it, ia)
        m.geom_size[self._rod, 1] = length / 2
        m.geom_pos[self._rod] = (0.0, ROD_OFFSET, length / 2)
        m.geom_pos[self._tip] = (0.0, ROD_OFFSET, length)
        m.dof_damping[self._hinge_v] = p["damping"]
        mujoco.mj_setConst(m, self.data)

    def push(self, torque: float, duration: float) -> None:
        """Apply a torque pulse [N m] about the hinge axis on the pendulum from now for ``duration`` s."""
        t = float(self.data.time)
        self._pulses.append((t, t + float(duration), float(torque)))
        self._pulses.sort()

    # ------------------------------------------------------------------- step
    def _physics_step(self, action):
        m, d = self.model, self.data
        if self._action_unit is not None:
            action = self._action_unit * np.clip(np.asarray(action, dtype=np.float64), -1.0, 1.0)
        if self.action_mode == "ee":
            a6 = task_acceleration_list(self._obs_list, float(action[0]), self.gains)
            tau = torques_for(a6, m, d, self.torque_limits, self._work)
        elif self.action_mode == "kinesthetic":
            tau = compliant_torques(m, d, self._work, self._impedance(), self.torque_limits)
            f = self.compliance.force_max
            fx = float(action[0])
            if fx - fx == 0.0:
                apply_hand_force(m, d, self._site, np.array([min(max(fx, -f), f), 0.0, 0.0]))
        else:     # np.minimum/np.maximum: np.clip's Python wrapper costs more than the clipping
            tau = self._tau
            np.minimum(action, self.torque_limits, out=tau)
            np.maximum(tau, self._neg_limits, out=tau)
        s = sum(tau.tolist())
        if not s - s:
            self._ctrl[:] = tau
        else:                      # a non-finite state or action: nothing non-finite goes into MuJoCo
            return np.zeros(len(OBSERVATION_NAMES)), 0.0, True, False, {
                "diverged": True, "non_finite": True, "out_of_workspace": False, "disturbance": self._applied}
        t = d.time
        if self._pulses:
            self._disturb(t)
        mujoco.mj_step2(m, d)
        mujoco.mj_step1(m, d)
        obs = self._observe()
        o = self._obs_list
        s = sum(o)
        non_finite = bool(s - s)                  # NaN or ±inf somewhere
        if non_finite or abs(self.pendulum_angular_velocity()) > 1e3:
            obs = np.zeros(len(OBSERVATION_NAMES))
            self._upright = 0
            return obs, 0.0, True, False, {"diverged": True, "non_finite": non_finite, "out_of_workspace": False,
                                           "disturbance": self._applied, "is_success": False}
        dx, dy, dz = self.flange_offset()
        out = (abs(dx) > TERMINATE_X or abs(dy) > TERMINATE_YZ or abs(dz) > TERMINATE_YZ
               or self.flange_tilt_squared() > TERMINATE_TILT ** 2)
        upright = abs(self.pendulum_angle()) < SUCCESS_ANGLE
        self._upright = self._upright + 1 if upright else 0
        return obs, self._h if upright else 0.0, out, False, {
            "diverged": False, "out_of_workspace": out, "disturbance": self._applied,
            "is_success": self._upright >= self._hold_steps}

    def _impedance(self) -> list[float]:
        """The compliant mode's wrench at the flange: light damping and walls along x; y, z and the
        orientation locked at the workspace centre's."""
        c, o, (_, cy, cz) = self.compliance, self._obs_list, self.workspace_centre
        fx = -c.damping * o[_X + 1] + wall_force(o[_X], o[_X + 1], -self.x_limit, self.x_limit, c)
        vy, vz = o[_EY + 3], o[_EZ + 3]
        lock = [-c.lock_k * (o[_EY] - cy) - c.lock_d * vy, -c.lock_k * (o[_EZ] - cz) - c.lock_d * vz]
        return [fx, *lock] + [-c.rot_k * o[_RX + i] - c.rot_d * o[_RX + 3 + i] for i in range(3)]

    def command_from_motion(self, obs: np.ndarray) -> np.ndarray:
        """The ``[v_cmd]`` commands under which the servo of ``"ee"`` mode reproduces the hand motion in
        ``obs`` (rows of observations at ``dt``): :func:`multiform.envs.compliant.command_from_motion`."""
        obs = np.asarray(obs, dtype=np.float64)
        return command_from_motion(obs[:, _X + 1], self.dt, self.gains.kv)

    # -- named views of the last observation (as dm_control's cartpole has physics.pole_angle_cosine())
    def pendulum_angle(self) -> float:
        """θ, 0 upright, wrapped to (-π, π] [rad]."""
        return self._obs_list[_THETA]

    def pendulum_angular_velocity(self) -> float:
        """ω [rad/s]."""
        return self._obs_list[_OMEGA]

    def flange_offset(self) -> tuple[float, float, float]:
        """The flange's position relative to the workspace centre, world x, y, z [m]."""
        o, c = self._obs_list, self.workspace_centre
        return o[_X], o[_EY] - c[1], o[_EZ] - c[2]

    def flange_tilt_squared(self) -> float:
        """Squared angle of the flange's orientation away from its home orientation [rad²]."""
        o = self._obs_list
        return o[_RX] * o[_RX] + o[_RY] * o[_RY] + o[_RZ] * o[_RZ]

    @property
    def last_torques(self) -> np.ndarray:
        """The joint torques applied in the last step (zero after a reset), after the actuator limits."""
        return self._ctrl.copy()

    def _disturb(self, t: float) -> None:
        tau = 0.0
        for start, end, torque in self._pulses:
            if start > t:
                break
            if t < end:
                tau += torque
        self._applied = tau
        self._xfrc[4] = tau

    def _observe(self) -> np.ndarray:
        xm = self._pxmat
        theta = math.atan2(xm[2], xm[8])
        if theta == -math.pi:
            theta = math.pi
        mujoco.mj_objectVelocity(self.model, self.data, _OBJ_SITE, self._site, self._vel6, 0)
        mujoco.mju_mat2Quat(self._quat, self._smat)
        mujoco.mju_quat2Vel(self._rv, self._quat, 1.0)
        px, py, pz = self._spos.tolist()
        wx, wy, wz, vx, vy, vz = self._vel6.tolist()
        o = [theta, float(self._pcvel[1]), px - self.workspace_centre[0], vx, px, py, pz, vx, vy, vz,
             *self._rv.tolist(), wx, wy, wz, *self._qpos6.tolist(), *self._qvel6.tolist()]
        self._obs_list = o
        return np.array(o)
