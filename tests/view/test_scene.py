"""The scene in the view is the simulator's: a geom placed by its body's logged pose and its own
logged offset lands where MuJoCo has it."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

pytest.importorskip("rerun")

from multiform.envs.arm_pendulum import ArmPendulumEnv  # noqa: E402
from multiform.envs.ball_in_cup import BallInCupEnv  # noqa: E402
from multiform.envs.nunchaku import NunchakuEnv  # noqa: E402
from multiform.view import scene  # noqa: E402
from multiform.view.stream import Recording, read_recording  # noqa: E402


def _rot(xyzw):
    q = np.array([xyzw[3], *xyzw[:3]], float)
    m = np.zeros(9)
    mujoco.mju_quat2Mat(m, q)
    return m.reshape(3, 3)


@pytest.mark.parametrize("make", [ArmPendulumEnv, NunchakuEnv, BallInCupEnv])
def test_logged_poses_put_every_geom_where_mujoco_has_it(make, tmp_path):
    env = make()
    env.reset(seed=1)
    m, d = env.unwrapped.model, env.unwrapped.data
    rng = np.random.default_rng(0)
    for j in range(m.njnt):                      # move every hinge and slide: a pose no model file holds
        if m.jnt_type[j] in (mujoco.mjtJoint.mjJNT_HINGE, mujoco.mjtJoint.mjJNT_SLIDE):
            d.qpos[m.jnt_qposadr[j]] += rng.normal(0, 0.3)
    mujoco.mj_forward(m, d)
    bodies = scene.scene_bodies(m)
    out = Recording(tmp_path / "scene.rrd")
    scene.log_geometry(out.rec, m, bodies)
    scene.log_poses(out.rec, m, bodies, np.array([0]), 0.001, d.xpos[bodies][None], d.xquat[bodies][None])
    out.close()
    rec = read_recording(tmp_path / "scene.rrd")
    checked = 0
    for b, path in zip(bodies, scene.body_paths(m, bodies)):
        ent = rec["/" + path]
        row = next(i for i, t in enumerate(ent.get("tick", [])) if t == 0)
        bt, bq = np.array(ent["Transform3D:translation"][row][0]), _rot(ent["Transform3D:quaternion"][row][0])
        for g in np.flatnonzero(m.geom_bodyid == b):
            key = f"/{path}/{mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_GEOM, int(g)) or f'geom{g}'}"
            if key not in rec:
                continue
            offset = next(i for i, v in enumerate(rec[key]["Transform3D:translation"]) if v is not None)
            gt = np.array(rec[key]["Transform3D:translation"][offset][0])
            assert np.allclose(bt + bq @ gt, d.geom_xpos[g], atol=1e-5), key
            gq = _rot(rec[key]["Transform3D:quaternion"][offset][0])
            assert np.allclose(bq @ gq, d.geom_xmat[g].reshape(3, 3), atol=1e-5), key
            checked += 1
    assert checked >= 5
    env.close()


def test_the_string_is_drawn_from_the_cup_to_the_ball(tmp_path):
    """The ball-in-a-cup's string (a tendon, no body of its own) is in the view: a line from its
    anchor under the cup to the ball's centre, at each logged tick; the ball is a body like any other."""
    env = BallInCupEnv()
    base = env
    env.reset(seed=2, options={"phi0": 0.6, "omega0": 0.0})
    m, d = base.model, base.data
    tendons = scene.scene_tendons(m)
    assert [mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_TENDON, t) for t in tendons] == ["toy/string"]
    assert "scene/toy/ball" in scene.body_paths(m, scene.scene_bodies(m))
    ticks, paths, balls = [], [], []
    for k in range(300):
        env.step(np.zeros(2))
        if k % 100 == 0:
            ticks.append(k)
            paths.append(scene.tendon_paths(d, tendons))
            balls.append(d.xpos[m.body("toy/ball").id].copy())
    out = Recording(tmp_path / "string.rrd")
    scene.log_tendons(out.rec, m, tendons, ticks, 0.001, paths)
    out.close()
    ent = read_recording(tmp_path / "string.rrd")["/scene/toy/string"]
    strips = [v for v in ent["LineStrips3D:strips"] if v is not None]
    assert len(strips) == len(ticks)
    for strip, ball in zip(strips, balls):
        pts = np.array(strip[0])
        assert pts.shape == (2, 3)
        assert np.allclose(pts[1], ball, atol=1e-9)
        assert abs(np.linalg.norm(pts[1] - pts[0]) - env.params["length"]) < 2e-3     # taut
    env.close()
