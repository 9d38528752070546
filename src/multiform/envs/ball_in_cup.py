"""``multiform/BallInCup-v0``: the 6-axis arm holds a cup with a ball on a string and catches the ball.

The model is the arm of :mod:`multiform.envs.arm` (AUBO i5 kinematics, the pendulum taken off) with
the toy of ``assets/ball_in_cup.xml`` on its flange: a cup opening upwards, 0.06 m along the tool
axis, and a 30 g ball (radius 2 cm) that hangs from a string anchored under the cup's bottom and
moves in the world x-z plane (the swing plane), as dm_control's planar ball-in-cup does. The string
is a tendon with an upper length limit: taut it pulls, slack it does nothing, so the ball swings,
flies and falls like the real toy. One step is one 1 ms physics step (implicit-fast integrator).

Why two commands, the hand's velocity along x and z: the skill lives in the swing plane — a
person pumps the ball by moving the cup to and fro, pulls it up, and moves the cup under the
falling ball — so the hand needs exactly the two in-plane translations; the orientation is held
(a tilted cup would only spill the ball). Velocity, not position or torque, because it is what a
person's hand motion is and what a kinesthetic demonstration gives back (the hand's measured
velocity), and the arm's servo makes it good on the real robot's joint limits.

Actions (``action_mode``):

* ``"ee"`` (default): ``[vx, vz]``, the desired flange velocity in the swing plane [m/s], clipped to
  ±2. The reference controller (:func:`multiform.envs.osc.planar_task_acceleration` then computed
  torque, :func:`multiform.envs.osc.torques_for`) tracks it: a 30 rad/s velocity servo per axis
  with soft walls at |x| = 0.45 m and z from -0.15 to +0.25 m about the centre, the acceleration
  capped at 40 m/s², and holds of y and of the orientation.
* ``"kinesthetic"``: ``[fx, fz]``, a person's force on the flange [N], clipped to ±150; the arm is
  in its compliant hand-guiding mode (:mod:`multiform.envs.compliant`): gravity and friction
  compensated, light damping along x and z, virtual walls at the same stroke, y and the orientation
  locked. :meth:`BallInCupEnv.command_from_motion` recovers from the recorded observations the
  ``[vx, vz]`` commands under which the servo of ``"ee"`` mode reproduces the guided motion.
* ``"torque"``: six joint torques [N m], clipped to ±150 (joints 1-3) and ±30 (joints 4-6).

Observations (``observation_names``, float64; the robot's encoders with forward kinematics, and the
ball as a camera tracking it in the swing plane gives it):

==================  ===========================================================================
ball_x, ball_z      the ball's centre relative to the string's anchor under the cup, world x and
                    z [m]; hanging at rest it is (0, -length); in the cup 0.04 < ball_z < 0.10
ball_vx, ball_vz    its velocity relative to the anchor [m/s]
hand_x, hand_z      the flange's offset from the workspace centre (0, -0.55, 0.3) m along x, z [m]
hand_vx, hand_vz    its velocity [m/s]
ee_x, ee_y, ee_z    flange position in the world [m]
ee_vx, ee_vy, ee_vz flange linear velocity [m/s]
ee_rx, ee_ry, ee_rz flange orientation error from the home orientation, a rotation vector [rad]
ee_wx, ee_wy, ee_wz flange angular velocity [rad/s]
q1..q6, qd1..qd6    joint positions [rad] and velocities [rad/s]
==================  ===========================================================================

``command_names`` is ``("vx", "vz")``.

Reset options (all optional):

* ``length`` [m, default 0.35] the string, ``mass`` [kg, default 0.03] the ball;
  ``randomize`` (bool, default False) scales those not given by U(0.9, 1.1).
* ``phi0`` [rad], ``omega0`` [rad/s]: the ball on the taut string at angle ``phi0`` from hanging
  (positive towards +x), turning at ``omega0``; default ``U(-0.1, 0.1)`` and ``U(-0.3, 0.3)``.
  Or ``ball`` = ``[x, z]`` and ``ball_v`` = ``[vx, vz]`` relative to the anchor, anywhere the string
  reaches and no wall is (a ball placed in the cup, for instance).
* ``x0``, ``z0`` [m, default 0]: the hand's start (|x0| ≤ 0.45, -0.15 ≤ z0 ≤ 0.25), the arm at rest in
  the posture that puts the flange there with the home orientation.

The episode's toy is in ``env.params`` (a mentor must not read it; a person does not know it).

Termination: a non-finite or exploding simulation ends the episode with ``terminated=True`` and
``info["diverged"] = True``; the flange far beyond the servo's walls (|x| > 0.6 m, z more than 0.35 m
below or 0.4 m above the centre, y more than 0.25 m off, or tilted more than 1 rad) ends it with
``info["out_of_workspace"] = True``. ``gymnasium.make`` adds a 20 s time limit (20,000 steps;
``max_episode_steps=`` changes it).

``frame_skip`` (default 1): physics steps per env step, the action held over them, as in
:mod:`multiform.envs.arm_pendulum` (``dt`` is ``0.001 * frame_skip``, ``render_fps`` ``1000 /
frame_skip``, the reward the sum over the skipped steps); multiform's own runs use 1.

Reward and success (for Gymnasium tooling; multiform grades trials with the skill's judges): the
reward is ``dt`` for every step that ends with the ball resting in the cup (centre within 0.04 m of
the cup's axis, between the anchor and the rim, moving less than 0.5 m/s relative to the cup), so
a return is the time caught in seconds; ``info["is_success"]`` is True once it has rested there for
1 s without a break. ``info["scene"]`` has the string's true slack (``slack``, m) and whether the
ball rests in the cup (``in_cup``), for people and tests; the robot never reads it.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from importlib import resources
from typing import Any

import gymnasium as gym
import mujoco
import numpy as np

from .arm_model import FLANGE_SITE, arm_posture, arm_spec, mount
from .compliant import DEFAULT_COMPLIANCE, Compliance, apply_hand_force, command_from_motion, compliant_torques, wall_force
from .osc import TORQUE_LIMITS, PlanarGains, Workspace, planar_task_acceleration, torques_for
from .rendering import FramedEnv, check_frame_skip

OBSERVATION_NAMES: tuple[str, ...] = (
    "ball_x", "ball_z", "ball_vx", "ball_vz", "hand_x", "hand_z", "hand_vx", "hand_vz",
    "ee_x", "ee_y", "ee_z", "ee_vx", "ee_vy", "ee_vz", "ee_rx", "ee_ry", "ee_rz", "ee_wx", "ee_wy", "ee_wz",
    "q1", "q2", "q3", "q4", "q5", "q6", "qd1", "qd2", "qd3", "qd4", "qd5", "qd6")
COMMAND_NAMES = ("vx", "vz")
NOMINAL = {"length": 0.35, "mass": 0.03}
MOUNT = 0.06                # the cup's frame this far along the tool axis from the flange [m]
TOY = "toy/"                # the prefix of the toy's names in the mounted model
BALL_RADIUS = 0.017
CUP_HALF_WIDTH = 0.04       # ball centre within this of the cup's axis (the walls' inner faces are 0.047-0.05 m off)
CUP_RIM = 0.10              # ball centre below this height above the anchor (the rim is at 0.11 m)
CUP_FLOOR = 0.015           # and above this one (resting on the bottom it is at 0.035 m)
REST_SPEED = 0.5            # m/s relative to the cup: resting
SUCCESS_HOLD = 1.0          # s resting in the cup: is_success
TERMINATE_X, TERMINATE_Y, TERMINATE_Z = 0.6, 0.25, (-0.35, 0.4)
TERMINATE_TILT = 1.0
GAINS = PlanarGains()
FORCE_MAX = DEFAULT_COMPLIANCE.force_max
_OPTIONS = ("length", "mass", "randomize", "phi0", "omega0", "ball", "ball_v", "x0", "z0")
_OBJ_SITE, _OBJ_BODY = int(mujoco.mjtObj.mjOBJ_SITE), int(mujoco.mjtObj.mjOBJ_BODY)
_I = {n: i for i, n in enumerate(OBSERVATION_NAMES)}
_BX, _BZ, _BVX, _BVZ = _I["ball_x"], _I["ball_z"], _I["ball_vx"], _I["ball_vz"]
_HX, _HZ, _HVX, _HVZ = _I["hand_x"], _I["hand_z"], _I["hand_vx"], _I["hand_vz"]
_EY, _VY, _R0, _W0 = _I["ee_y"], _I["ee_vy"], _I["ee_rx"], _I["ee_wx"]


def model_path() -> str:
    """Path of the toy's MJCF (mounted on the arm by :func:`load_model`)."""
    return str(resources.files("multiform") / "envs" / "assets" / "ball_in_cup.xml")


def load_model() -> tuple[mujoco.MjModel, np.ndarray]:
    """A fresh model of the arm holding the toy, and its home ``qpos`` (arm at home, the ball hanging
    at the nominal length). Contacts are on (only the ball and the cup collide, so the parent filter
    is off); MuJoCo's automatic
    reset on bad values is off, so a non-finite state ends the step visibly."""
    spec, home6 = arm_spec()
    spec.modelname = "arm_ball_in_cup"
    spec.option.disableflags &= ~int(mujoco.mjtDisableBit.mjDSBL_CONTACT)
    spec.option.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_AUTORESET)
    # the ball hangs from the flange's body like the cup (on its own joints): without this, MuJoCo's
    # parent filter (by welded body) would drop every ball-cup contact
    spec.option.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_FILTERPARENT)
    mount(spec, mujoco.MjSpec.from_file(model_path()), MOUNT, TOY)
    spec.worldbody.add_camera(name="swing", pos=[0.0, -1.9, 0.35], xyaxes=[1, 0, 0, 0, 0, 1], fovy=45)
    m = spec.compile()
    home = np.zeros(m.nq)
    home[:6] = home6
    home[m.joint(TOY + "ball_z").qposadr[0]] = -NOMINAL["length"]
    return m, home


class BallInCupEnv(FramedEnv, gym.Env):
    """The arm catching a ball on a string in a cup (see the module docstring).

    ``action_mode`` is ``"ee"``, ``"kinesthetic"`` or ``"torque"``; ``gains`` the velocity servo's
    (:class:`multiform.envs.osc.PlanarGains`), ``compliance`` the hand-guiding mode's;
    ``width``/``height``/``camera`` the ``rgb_array`` frames (cameras ``"swing"``, ``"front"``,
    ``"side"``); ``shadows`` False renders without them; ``frame_skip`` physics steps per env step.
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": 1000}
    observation_names = OBSERVATION_NAMES
    command_names = COMMAND_NAMES
    guided_velocity_names = ("hand_vx", "hand_vz")     # the hand velocities the commands are, for a guiding hand
    action_modes = ("ee", "kinesthetic", "torque")

    def __init__(self, render_mode: str | None = None, action_mode: str = "ee", gains: PlanarGains | None = None,
                 compliance: Compliance | None = None, width: int = 480, height: int = 360, camera: str = "swing",
                 shadows: bool = True, frame_skip: int = 1):
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode must be one of {self.metadata['render_modes']} or None")
        self.frame_skip = check_frame_skip(frame_skip)
        if action_mode not in self.action_modes:
            raise ValueError(f"action_mode must be one of {self.action_modes}, not {action_mode!r}")
        self.render_mode = render_mode
        self.action_mode = action_mode
        self.gains = gains if gains is not None else GAINS
        self.compliance = compliance if compliance is not None else DEFAULT_COMPLIANCE
        self.width, self.height, self.camera, self.shadows = int(width), int(height), camera, bool(shadows)
        self.model, self.home_qpos = load_model()
        self.data = mujoco.MjData(self.model)
        m, d = self.model, self.data
        self._h = float(m.opt.timestep)                   # one physics step
        self.dt = self._h * self.frame_skip                # one env step
        self.metadata = {**type(self).metadata, "render_fps": int(round(1.0 / self.dt))}
        self.workspace_centre = tuple(self.gains.centre)
        self.torque_limits = TORQUE_LIMITS
        if action_mode == "ee":
            v = self.gains.v_max
            self.action_space = gym.spaces.Box(-v, v, (2,), dtype=np.float64)
        elif action_mode == "kinesthetic":
            f = self.compliance.force_max
            self.action_space = gym.spaces.Box(-f, f, (2,), dtype=np.float64)
        else:
            self.action_space = gym.spaces.Box(-TORQUE_LIMITS, TORQUE_LIMITS, dtype=np.float64)
        self.observation_space = gym.spaces.Box(-np.inf, np.inf, (len(OBSERVATION_NAMES),), dtype=np.float64)
        self._site = m.site(FLANGE_SITE).id
        self._anchor = m.site(TOY + "anchor").id
        self._ball = m.body(TOY + "ball").id
        self._bq = (int(m.joint(TOY + "ball_x").qposadr[0]), int(m.joint(TOY + "ball_z").qposadr[0]))
        self._bv = (int(m.joint(TOY + "ball_x").dofadr[0]), int(m.joint(TOY + "ball_z").dofadr[0]))
        self._string = m.tendon(TOY + "string").id
        self._ball_geom = m.geom(TOY + "ball").id
        self._work = Workspace(m, d, FLANGE_SITE)
        self._vel6 = np.zeros(6)
        self._a6 = np.zeros(6)
        self._ten_length = d.ten_length[self._string:self._string + 1]
        if self._bv[1] != self._bv[0] + 1:
            raise RuntimeError("the ball's slide joints must be adjacent degrees of freedom")
        self._bqvel = d.qvel[self._bv[0]:self._bv[0] + 2]
        self._quat = np.zeros(4)
        self._rv = np.zeros(3)
        self._spos, self._smat = d.site_xpos[self._site], d.site_xmat[self._site]
        self._apos, self._bpos = d.site_xpos[self._anchor], d.xpos[self._ball]
        self._qpos6, self._qvel6 = d.qpos[:6], d.qvel[:6]
        self._ctrl = d.ctrl
        self._obs_list: list[float] = [0.0] * len(OBSERVATION_NAMES)
        self._hold_steps = int(math.ceil(SUCCESS_HOLD / self._h - 1e-9))
        self._resting = 0
        self.params: dict[str, float] = dict(NOMINAL)
        self._renderer: mujoco.Renderer | None = None

    # ------------------------------------------------------------------ reset
    def reset(self, *, seed: int | None = None, options: Mapping[str, Any] | None = None):
        super().reset(seed=seed)
        options = self._reset_options(options, _OPTIONS)
        rng = self.np_random
        randomize = bool(options.get("randomize", False))
        p = {k: float(options[k]) if options.get(k) is not None
             else NOMINAL[k] * (float(rng.uniform(0.9, 1.1)) if randomize else 1.0) for k in ("length", "mass")}
        if not (0.15 <= p["length"] <= 0.8 and 0.001 <= p["mass"] <= 1.0):
            raise ValueError(f"toy out of range: {p}; allowed: length in [0.15, 0.8] m, mass in [0.001, 1] kg")
        ball, ball_v = self._ball_start(options, p["length"], rng)
        x0, z0 = (float(options.get(k) or 0.0) for k in ("x0", "z0"))
        g = self.gains
        if not (math.isfinite(x0) and math.isfinite(z0) and abs(x0) <= g.x_limit and g.z_low <= z0 <= g.z_high):
            raise ValueError(f"x0, z0 must be within ±{g.x_limit} m and [{g.z_low}, {g.z_high}] m, got {x0!r}, {z0!r}")
        self.params = p
        m, d = self.model, self.data
        m.body_mass[self._ball] = p["mass"]
        m.body_inertia[self._ball] = 0.4 * p["mass"] * BALL_RADIUS ** 2
        m.tendon_range[self._string] = (0.0, p["length"])
        mujoco.mj_setConst(m, d)
        mujoco.mj_resetData(m, d)
        if x0 == 0.0 and z0 == 0.0:
            d.qpos[:] = self.home_qpos
        else:
            target = np.array(self.workspace_centre) + (x0, 0.0, z0)
            d.qpos[:] = arm_posture(m, d, self._site, self.home_qpos, target)
        d.qpos[self._bq[0]], d.qpos[self._bq[1]] = ball
        d.qvel[self._bv[0]], d.qvel[self._bv[1]] = ball_v
        mujoco.mj_forward(m, d)
        self._resting = 0
        obs = self._observe()
        return obs, self._info(False, False)

    def _ball_start(self, options: Mapping[str, Any], length: float, rng: np.random.Generator
                    ) -> tuple[tuple[float, float], tuple[float, float]]:
        if options.get("ball") is not None or options.get("ball_v") is not None:
            if options.get("phi0") is not None or options.get("omega0") is not None:
                raise ValueError("give the ball's start as phi0/omega0 or as ball/ball_v, not both")
            try:
                bx, bz = (float(v) for v in options.get("ball") or (0.0, -length))
                vx, vz = (float(v) for v in options.get("ball_v") or (0.0, 0.0))
            except (TypeError, ValueError):
                raise ValueError(f"ball and ball_v must be [x, z] pairs of numbers, got {options.get('ball')!r}, "
                                 f"{options.get('ball_v')!r}") from None
            if not all(math.isfinite(v) for v in (bx, bz, vx, vz)) or math.hypot(bx, bz) > length + 1e-9:
                raise ValueError(f"ball must be finite and within the string's reach ({length:.3f} m) of the "
                                 f"anchor, got {[bx, bz]}")
            if self._in_wall(bx, bz):
                raise ValueError(f"ball {[bx, bz]} would start inside the cup's wall")
            return (bx, bz), (vx, vz)
        phi = options.get("phi0")
        phi = float(phi) if phi is not None else float(rng.uniform(-0.1, 0.1))
        om = options.get("omega0")
        om = float(om) if om is not None else float(rng.uniform(-0.3, 0.3))
        if not (math.isfinite(phi) and math.isfinite(om) and abs(om) <= 100.0):
            raise ValueError(f"phi0 and omega0 must be finite (|omega0| <= 100 rad/s), got {phi!r}, {om!r}")
        s, c = math.sin(phi), math.cos(phi)
        ball = (length * s, -length * c)
        if self._in_wall(*ball):
            raise ValueError(f"phi0 = {phi} puts the ball inside the cup's wall")
        return ball, (length * om * c, length * om * s)

    def _in_wall(self, bx: float, bz: float) -> bool:
        """Whether a ball centred at (bx, bz) (cup frame at home) overlaps one of the cup's capsules."""
        m = self.model
        for g in range(m.ngeom):
            if g == self._ball_geom or m.geom_bodyid[g] != m.body(TOY + "cup").id or not m.geom_contype[g]:
                continue
            half, r = m.geom_size[g, 1], m.geom_size[g, 0]
            c = m.geom_pos[g]
            axis = m.geom_quat[g]
            mat = np.zeros(9)
            mujoco.mju_quat2Mat(mat, axis)
            u = mat.reshape(3, 3)[:, 2]
            rel = np.array([bx, 0.0, bz]) - c
            t = min(max(float(rel @ u), -half), half)
            if np.linalg.norm(rel - t * u) < r + BALL_RADIUS:
                return True
        return False

    # ------------------------------------------------------------------- step
    def _physics_step(self, action):
        m, d = self.model, self.data
        o = self._obs_list
        mode = self.action_mode
        if mode == "ee":
            a6 = planar_task_acceleration(o[_HX], o[_HZ], o[_HVX], o[_HVZ], o[_EY], o[_VY], o[_R0:_R0 + 3],
                                          o[_W0:_W0 + 3], float(action[0]), float(action[1]), self.gains)
            self._a6[:] = a6
            tau = torques_for(self._a6, m, d, self.torque_limits, self._work)
        elif mode == "kinesthetic":
            tau = compliant_torques(m, d, self._work, self._impedance(o), self.torque_limits)
            f = self.compliance.force_max
            fx, fz = float(action[0]), float(action[1])
            if fx - fx == 0.0 and fz - fz == 0.0:
                apply_hand_force(m, d, self._site, np.array([min(max(fx, -f), f), 0.0, min(max(fz, -f), f)]))
        else:
            tau = np.minimum(np.maximum(np.asarray(action, dtype=np.float64), -TORQUE_LIMITS), TORQUE_LIMITS)
        total = float(tau.sum())
        if total - total != 0.0:                  # NaN or ±inf: nothing non-finite goes into MuJoCo
            return np.zeros(len(OBSERVATION_NAMES)), 0.0, True, False, self._info(True, False, non_finite=True)
        self._ctrl[:] = tau
        mujoco.mj_step2(m, d)
        mujoco.mj_step1(m, d)
        obs = self._observe()
        o = self._obs_list
        total = sum(o)
        if total - total != 0.0 or abs(o[_BVX]) + abs(o[_BVZ]) > 1e3:
            self._resting = 0
            return (np.zeros(len(OBSERVATION_NAMES)), 0.0, True, False,
                    self._info(True, False, non_finite=total - total != 0.0))
        out = self._out_of_workspace(o)
        resting = self.ball_resting_in_cup()
        self._resting = self._resting + 1 if resting else 0
        return obs, self._h if resting else 0.0, out, False, self._info(False, out, resting=resting)

    def _impedance(self, o: Sequence[float]) -> list[float]:
        """The compliant mode's wrench at the flange: light damping and walls along x and z, y and
        the orientation locked."""
        c, g = self.compliance, self.gains
        fx = -c.damping * o[_HVX] + wall_force(o[_HX], o[_HVX], -g.x_limit, g.x_limit, c)
        fz = -c.damping * o[_HVZ] + wall_force(o[_HZ], o[_HVZ], g.z_low, g.z_high, c)
        fy = -c.lock_k * (o[_EY] - self.workspace_centre[1]) - c.lock_d * o[_VY]
        return [fx, fy, fz] + [-c.rot_k * o[_R0 + i] - c.rot_d * o[_W0 + i] for i in range(3)]

    def _out_of_workspace(self, o: Sequence[float]) -> bool:
        rx, ry, rz = o[_R0], o[_R0 + 1], o[_R0 + 2]
        return (abs(o[_HX]) > TERMINATE_X or abs(o[_EY] - self.workspace_centre[1]) > TERMINATE_Y
                or not TERMINATE_Z[0] <= o[_HZ] <= TERMINATE_Z[1] or rx * rx + ry * ry + rz * rz > TERMINATE_TILT ** 2)

    def _info(self, diverged: bool, out: bool, non_finite: bool = False, resting: bool | None = None
              ) -> dict[str, Any]:
        slack = self.params["length"] - self._ten_length[0]
        info: dict[str, Any] = {"diverged": diverged, "out_of_workspace": out,
                                "is_success": (not diverged) and self._resting >= self._hold_steps,
                                "scene": {"slack": slack if slack > 0.0 else 0.0,
                                          "in_cup": self.ball_resting_in_cup() if resting is None else resting}}
        if diverged:
            info["non_finite"] = non_finite
        return info

    # -- named views of the state
    def ball_resting_in_cup(self) -> bool:
        """The ball's centre inside the cup (within 0.04 m of its axis, between anchor and rim) and
        moving less than 0.5 m/s relative to it."""
        o = self._obs_list
        return (abs(o[_BX]) < CUP_HALF_WIDTH and CUP_FLOOR < o[_BZ] < CUP_RIM
                and o[_BVX] * o[_BVX] + o[_BVZ] * o[_BVZ] < REST_SPEED * REST_SPEED)

    def string_slack(self) -> float:
        """How much shorter than the string the anchor-ball distance is [m] (0 when taut)."""
        return max(0.0, float(self.params["length"] - self._ten_length[0]))

    def command_from_motion(self, obs: np.ndarray) -> np.ndarray:
        """The ``[vx, vz]`` commands under which the servo of ``"ee"`` mode reproduces the hand motion
        in ``obs`` (rows of observations at ``dt``): :func:`multiform.envs.compliant.command_from_motion`."""
        obs = np.asarray(obs, dtype=np.float64)
        return command_from_motion(obs[:, [_HVX, _HVZ]], self.dt, self.gains.kv)

    def _observe(self) -> np.ndarray:
        m, d = self.model, self.data
        mujoco.mj_objectVelocity(m, d, _OBJ_SITE, self._site, self._vel6, 0)
        mujoco.mju_mat2Quat(self._quat, self._smat)
        mujoco.mju_quat2Vel(self._rv, self._quat, 1.0)
        px, py, pz = self._spos.tolist()
        ax, ay, az = self._apos.tolist()
        bx, by, bz = self._bpos.tolist()
        wx, wy, wz, vx, vy, vz = self._vel6.tolist()
        # the ball relative to the anchor: its slides turned into the world (the cup's frame is the
        # flange's), plus the cup's turning carrying it round the anchor
        r00, r01, r02, r10, r11, r12, r20, r21, r22 = self._smat.tolist()
        qx, qz = self._bqvel[0], self._bqvel[1]
        dx, dy, dz = bx - ax, by - ay, bz - az
        rvx = r00 * qx + r02 * qz + wy * dz - wz * dy
        rvz = r20 * qx + r22 * qz + wx * dy - wy * dx
        cx, cz = self.workspace_centre[0], self.workspace_centre[2]
        o = [dx, dz, rvx, rvz, px - cx, pz - cz, vx, vz,
             px, py, pz, vx, vy, vz, *self._rv.tolist(), wx, wy, wz, *self._qpos6.tolist(), *self._qvel6.tolist()]
        self._obs_list = o
        return np.array(o)
