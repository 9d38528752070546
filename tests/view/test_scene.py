"""The scene in the view is the simulator's: a geom placed by its body's logged pose and its own
logged offset lands where MuJoCo has it."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

pytest.importorskip("rerun")

from multiform.envs.arm_pendulum import ArmPendulumEnv  # noqa: E402
from multiform.envs.nunchaku import NunchakuEnv  # noqa: E402
from multiform.view import scene  # noqa: E402
from multiform.view.stream import Recording, read_recording  # noqa: E402


def _rot(xyzw):
    q = np.array([xyzw[3], *xyzw[:3]], float)
    m = np.zeros(9)
    mujoco.mju_quat2Mat(m, q)
    return m.reshape(3, 3)


@pytest.mark.parametrize("make", [ArmPendulumEnv, NunchakuEnv])
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
