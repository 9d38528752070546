"""The auxiliary inverse model: learned from the arm's own babbling, it tracks end-effector commands
about as well as the reference operational-space controller; its 1 kHz path agrees with the batch
path; its file round-trips and bad files are refused."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import multiform.envs  # noqa: F401
from multiform.envs.osc import ReferenceController, task_acceleration
from multiform.errors import InvalidInput
from multiform.io import load_npz, save_npz
from multiform.learn.inverse import KIND, VERSION, InverseDynamicsModel
from multiform.tasks.arm_babbling import joint_babbling, rows, tracking_error


@pytest.fixture(scope="module")
def babbled():
    env = gym.make("multiform/ArmPendulum-v0", action_mode="torque")
    rng = np.random.default_rng(4)
    O, U = joint_babbling(env, 12.0, rng)
    data = rows(env, O, U)
    model = InverseDynamicsModel(n_inducing=100, n_hyper=300, random_state=0).fit(*data)
    yield env, model, data
    env.close()


def test_one_state_path_matches_the_batch_path(babbled):
    env, model, (O, A, T) = babbled
    rng = np.random.default_rng(0)
    for i in rng.choice(len(O), 20, replace=False):
        cmd = np.array([rng.uniform(-1.5, 1.5)])
        a = task_acceleration(O[i], float(cmd[0]))
        np.testing.assert_allclose(model.torques(O[i], cmd), model.predict(O[i], a)[0], rtol=1e-9, atol=1e-9)


def test_learned_from_babbling_it_tracks_like_the_reference(babbled):
    env, model, _ = babbled
    ref = tracking_error(env, ReferenceController(), 4.0, seed=21)
    got = tracking_error(env, model, 4.0, seed=21)
    assert got["velocity_rms"] <= 2.0 * ref["velocity_rms"], (got, ref)


def test_round_trip_and_refusals(babbled, tmp_path):
    env, model, (O, A, T) = babbled
    p = tmp_path / "inv.npz"
    model.save(p)
    back = InverseDynamicsModel.load(p)
    np.testing.assert_array_equal(back.predict(O[:50], A[:50]), model.predict(O[:50], A[:50]))
    arrays, meta = load_npz(p, KIND, VERSION)
    bad = tmp_path / "bad.npz"
    save_npz(bad, {**arrays, "coef": arrays["coef"][:-1]}, meta, KIND, VERSION)
    with pytest.raises(InvalidInput, match="coef"):
        InverseDynamicsModel.load(bad)
    save_npz(bad, {**arrays, "gp/alpha": np.zeros(3)} if "gp/alpha" in arrays else
             {k: v for k, v in arrays.items() if k != "gp/beta"}, meta, KIND, VERSION)
    with pytest.raises(InvalidInput, match="gp/"):
        InverseDynamicsModel.load(bad)
    save_npz(bad, arrays, {**meta, "servo": "os.system"}, KIND, VERSION)
    with pytest.raises(InvalidInput, match="servo"):
        InverseDynamicsModel.load(bad)
    assert p.read_bytes() == p.read_bytes() and InverseDynamicsModel.load(p).n_train_ == model.n_train_


def test_a_saved_model_loads_in_a_fresh_interpreter_that_imported_no_env(babbled, tmp_path):
    """``multiform evaluate MODEL`` loads the inverse model before any env is made: the arm's servo
    must be known from the registry, not from an import of the envs package."""
    import subprocess
    import sys
    env, model, (O, A, T) = babbled
    p = tmp_path / "inv.npz"
    model.save(p)
    code = ("import sys; from multiform.learn.inverse import InverseDynamicsModel; "
            f"m = InverseDynamicsModel.load({str(p)!r}); "
            "assert 'multiform.envs.arm_pendulum' not in sys.modules; print(m.n_train_)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert int(out.stdout) == model.n_train_
