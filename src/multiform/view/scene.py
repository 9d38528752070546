"""The MuJoCo scene as rerun 3-D primitives: one entity per body that carries visible geoms, its
geoms logged once in the body's frame, the body's pose logged over time; a visible tendon (the
ball-in-a-cup's string) as a line through its path points, logged over time.

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


def scene_tendons(model: mujoco.MjModel) -> list[int]:
    """The tendons drawn with a width and a visible colour (a string, a rope)."""
    return [t for t in range(model.ntendon) if model.tendon_width[t] > 0 and model.tendon_rgba[t][3] > 0]


def tendon_paths(data: mujoco.MjData, tendons: Sequence[int]) -> list[np.ndarray]:
    """The world points each of ``tendons`` runs through now, (k, 3) each (after ``mj_forward``)."""
    points = data.wrap_xpos.reshape(-1, 3)
    return [points[a:a + n].copy() for a, n in ((int(data.ten_wrapadr[t]), int(data.ten_wrapnum[t])) for t in tendons)]


def log_tendons(rec: rr.RecordingStream, model: mujoco.MjModel, tendons: Sequence[int], ticks: Sequence[int],
                dt: float, paths: Sequence[Sequence[np.ndarray]]) -> None:
    """``tendons`` as line strips at ``ticks`` (``paths[i][j]``: tendon j's points at tick i)."""
    entities = [f"{ROOT}/{_name(model, mujoco.mjtObj.mjOBJ_TENDON, t, 'tendon')}" for t in tendons]
    colours = [(np.clip(model.tendon_rgba[t], 0, 1) * 255).astype(np.uint8) for t in tendons]
    radii = [float(model.tendon_width[t]) for t in tendons]
    for tick, row in zip(ticks, paths):
        rec.set_time("tick", sequence=int(tick))
        rec.set_time("sim_time", duration=int(tick) * dt)
        for path, pts, colour, radius in zip(entities, row, colours, radii):
            rec.log(path, rr.LineStrips3D([pts], colors=[colour], radii=[radius]))
