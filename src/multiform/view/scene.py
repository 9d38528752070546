"""The MuJoCo scene as rerun 3-D primitives: one entity per body that carries visible geoms, its
geoms logged once in the body's frame, the body's pose logged over time.

Poses are read from the simulator for viewing only, as the video's poses are; the robot never sees them.
"""

from __future__ import annotations

from collections.abc import Sequence

import mujoco
import numpy as np
import rerun as rr

ROOT = "scene"


def _name(model: mujoco.MjModel, kind: mujoco.mjtObj, i: int, prefix: str) -> str:
    return mujoco.mj_id2name(model, kind, i) or f"{prefix}{i}"


def _xyzw(wxyz: np.ndarray) -> np.ndarray:
    return np.concatenate([wxyz[..., 1:], wxyz[..., :1]], axis=-1)


def _shape(model: mujoco.MjModel, g: int):
    """The rerun archetype of geom ``g`` in its own frame, or None for a type it does not draw."""
    kind, size = int(model.geom_type[g]), model.geom_size[g]
    colour = (np.clip(model.geom_rgba[g], 0, 1) * 255).astype(np.uint8)
    if kind == mujoco.mjtGeom.mjGEOM_BOX:
        return rr.Boxes3D(half_sizes=[size], colors=[colour], fill_mode="solid")
    if kind == mujoco.mjtGeom.mjGEOM_SPHERE:
        return rr.Ellipsoids3D(half_sizes=[[size[0]] * 3], colors=[colour], fill_mode="solid")
    if kind == mujoco.mjtGeom.mjGEOM_ELLIPSOID:
        return rr.Ellipsoids3D(half_sizes=[size], colors=[colour], fill_mode="solid")
    if kind == mujoco.mjtGeom.mjGEOM_CAPSULE:        # rerun's capsule starts at its origin and runs along +z
        return rr.Capsules3D(lengths=[2 * size[1]], radii=[size[0]], translations=[[0, 0, -size[1]]], colors=[colour])
    if kind == mujoco.mjtGeom.mjGEOM_CYLINDER:
        return rr.Cylinders3D(lengths=[2 * size[1]], radii=[size[0]], centers=[[0, 0, 0]], colors=[colour],
                              fill_mode="solid")
    return None


def scene_bodies(model: mujoco.MjModel) -> list[int]:
    """The bodies that carry at least one visible geom the view can draw (the world body excluded)."""
    out = []
    for b in range(1, model.nbody):
        geoms = np.flatnonzero(model.geom_bodyid == b)
        if any(model.geom_rgba[g][3] > 0 and _shape(model, g) is not None for g in geoms):
            out.append(b)
    return out


def body_paths(model: mujoco.MjModel, bodies: Sequence[int]) -> list[str]:
    return [f"{ROOT}/{_name(model, mujoco.mjtObj.mjOBJ_BODY, b, 'body')}" for b in bodies]


def log_geometry(rec: rr.RecordingStream, model: mujoco.MjModel, bodies: Sequence[int]) -> None:
    """Every visible geom of ``bodies``, static, under its body's entity; the floor as a flat box."""
    rec.log(ROOT, rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
    for b, path in zip(bodies, body_paths(model, bodies)):
        for g in np.flatnonzero(model.geom_bodyid == b):
            shape = _shape(model, g)
            if shape is None or model.geom_rgba[g][3] <= 0:
                continue
            gp = f"{path}/{_name(model, mujoco.mjtObj.mjOBJ_GEOM, int(g), 'geom')}"
            rec.log(gp, rr.Transform3D(translation=model.geom_pos[g], quaternion=_xyzw(model.geom_quat[g])), static=True)
            rec.log(gp, shape, static=True)
    for g in np.flatnonzero((model.geom_bodyid == 0) & (model.geom_type == mujoco.mjtGeom.mjGEOM_PLANE)):
        rec.log(f"{ROOT}/floor", rr.Boxes3D(half_sizes=[[1.0, 1.0, 0.001]], centers=[model.geom_pos[g]],
                                           colors=[[200, 200, 200, 255]], fill_mode="solid"), static=True)


def log_poses(rec: rr.RecordingStream, model: mujoco.MjModel, bodies: Sequence[int], ticks: np.ndarray, dt: float,
              xpos: np.ndarray, xquat: np.ndarray) -> None:
    """The poses of ``bodies`` at ``ticks`` (``xpos`` (F, B, 3), ``xquat`` (F, B, 4) wxyz) as columns."""
    if not len(ticks):
        return
    times = [rr.TimeColumn("tick", sequence=ticks), rr.TimeColumn("sim_time", duration=ticks * dt)]
    for j, path in enumerate(body_paths(model, bodies)):
        rec.send_columns(path, indexes=times,
                         columns=rr.Transform3D.columns(translation=xpos[:, j], quaternion=_xyzw(xquat[:, j])))
