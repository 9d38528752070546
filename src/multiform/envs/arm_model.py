"""The bundled arm-pendulum MJCF model (``assets/arm_pendulum.xml``): the env and the reference
controller each load their own copy.

The 6-axis arm (AUBO i5 kinematics) is written once, in that file (its bodies, joints, actuators,
scene and cameras, and the home posture). Another tool is mounted on its flange by
:func:`arm_spec` (the same file as a :class:`mujoco.MjSpec` with the pendulum taken off) and
:func:`mount`; :func:`arm_posture` finds the joint positions that put a site at a point with the
home orientation."""

from __future__ import annotations

from importlib import resources

import mujoco
import numpy as np

HOME = "home"                 # the keyframe of the home posture
FLANGE_BODY = "wrist3"        # the body a tool is fixed to
FLANGE_SITE = "flange"
TOOL_FRAME_QUAT = (0.0, 0.0, 0.0, 1.0)  # a frame in the flange body that is world-aligned at home


def model_path() -> str:
    """Path of the bundled MJCF model."""
    return str(resources.files("multiform") / "envs" / "assets" / "arm_pendulum.xml")


def load_model() -> mujoco.MjModel:
    """A fresh copy of the arm-pendulum model. MuJoCo's automatic reset on bad values is off: a
    non-finite state stays visible (and ends the step as ``non_finite``) instead of silently
    teleporting the arm home."""
    m = mujoco.MjModel.from_xml_path(model_path())
    m.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_AUTORESET)
    return m


def arm_spec() -> tuple[mujoco.MjSpec, np.ndarray]:
    """The arm alone as a spec (the pendulum and the home keyframe removed) and its six home joint
    positions."""
    spec = mujoco.MjSpec.from_file(model_path())
    home = np.asarray(list(spec.key(HOME).qpos), dtype=np.float64)[:6]
    spec.delete(spec.body("pendulum"))
    spec.delete(spec.key(HOME))
    return spec, home


def mount(spec: mujoco.MjSpec, tool: mujoco.MjSpec, offset: float, prefix: str) -> mujoco.MjSpec:
    """Fix every body of ``tool``'s worldbody (with its tendons, materials and defaults) to the
    flange, ``offset`` m along the tool axis, in a frame that is world-aligned in the home posture
    (as the pendulum's hinge is). The tool's names get ``prefix``."""
    frame = spec.body(FLANGE_BODY).add_frame(pos=[0.0, offset, 0.0], quat=list(TOOL_FRAME_QUAT))
    spec.attach(tool, frame=frame, prefix=prefix)
    return spec


def arm_posture(model: mujoco.MjModel, data: mujoco.MjData, site: int, home_qpos: np.ndarray,
                target: np.ndarray) -> np.ndarray:
    """Joint positions (the whole ``qpos``, the arm's six changed) that put ``site`` at ``target``
    with the home orientation: damped least squares on the site's Jacobian, from home. ``data`` is
    used as scratch."""
    m, d = model, data
    d.qpos[:] = home_qpos
    mujoco.mj_kinematics(m, d)
    jp, jr = np.zeros((3, m.nv)), np.zeros((3, m.nv))
    quat, rq, dq, err = np.zeros(4), np.zeros(4), np.zeros(4), np.zeros(6)
    mujoco.mju_mat2Quat(rq, d.site_xmat[site])
    for _ in range(100):
        mujoco.mj_kinematics(m, d)
        mujoco.mj_comPos(m, d)
        err[:3] = target - d.site_xpos[site]
        mujoco.mju_mat2Quat(quat, d.site_xmat[site])
        mujoco.mju_negQuat(dq, quat)
        mujoco.mju_mulQuat(dq, rq, dq)
        mujoco.mju_quat2Vel(err[3:], dq, 1.0)
        if np.abs(err).max() < 1e-7:
            break
        mujoco.mj_jacSite(m, d, jp, jr, site)
        J = np.vstack([jp, jr])[:, :6]
        d.qpos[:6] += J.T @ np.linalg.solve(J @ J.T + 1e-8 * np.eye(6), err)
    else:
        raise RuntimeError(f"no arm posture puts the flange at {np.round(target, 4).tolist()} m")
    return d.qpos.copy()
