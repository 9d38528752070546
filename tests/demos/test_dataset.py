import hashlib
import json

import h5py
import numpy as np
import pytest

from multiform.demos.dataset import labels_array, read_dataset, write_dataset
from multiform.demos.episode import Episode, SegmentLabel
from multiform.errors import InvalidInput

NAMES = ("theta", "omega", "x", "xdot")


def _episode(seed: int, n: int = 300, outcome: str = "success") -> Episode:
    rng = np.random.default_rng(seed)
    tags = np.array(["t0"] * (n // 3) + ["t1"] * (n - n // 3))
    labels = [SegmentLabel(0, n // 3, "t0", True), SegmentLabel(n // 3, n, "t1", outcome == "success")]
    return Episode(obs=rng.normal(size=(n, 4)), actions=rng.normal(size=(n, 1)), transitions=tags,
                   observation_names=NAMES, command_names=("v_cmd",), dt=1e-3, seed=seed,
                   reset_options={"length": 0.4}, labels=labels, outcome=outcome)


@pytest.fixture
def demo_file(tmp_path):
    eps = [_episode(0), _episode(1, outcome="failure"), _episode(2, n=500)]
    return write_dataset(tmp_path / "demos.h5", eps, "pendulum", "multiform/ArmPendulum-v0", {"action_mode": "ee"}), eps


def _digest(path):
    return hashlib.sha256(path.read_bytes()).hexdigest()


def test_round_trip(demo_file):
    path, eps = demo_file
    ds = read_dataset(path)
    assert len(ds) == 3 and ds.skill == "pendulum" and ds.env_kwargs == {"action_mode": "ee"}
    assert ds.meta["obs_dtype"] == "float32"
    for a, b in zip(eps, ds):
        # observations are stored as float32 (to the bit), commands exactly
        assert np.array_equal(a.obs.astype(np.float32), b.obs) and np.array_equal(a.actions, b.actions)
        assert list(a.transitions) == list(b.transitions)
        assert a.labels == b.labels and a.outcome == b.outcome and a.reset_options == b.reset_options
    s = ds.summary()
    assert s["demos"] == 3 and s["success"] == 2 and s["samples_per_transition"]["t0"] == 100 + 100 + 166


def test_robomimic_layout(demo_file):
    path, eps = demo_file
    with h5py.File(path) as f:
        assert f["data"].attrs["format_version"] == 3
        env_args = json.loads(f["data"].attrs["env_args"])
        assert env_args["type"] == 2       # robomimic's EnvType.GYM_TYPE
        # the actions are what the env in env_args takes: normalised by the env's own limit, 1.5 m/s
        assert env_args["env_kwargs"] == {"action_mode": "ee", "normalize_actions": True}
        assert list(f["data"].attrs["action_low"]) == [-1.5] and list(f["data"].attrs["action_high"]) == [1.5]
        np.testing.assert_array_equal(f["data/demo_0/actions"][()], np.clip(2 * (eps[0].actions + 1.5) / 3 - 1, -1, 1))
        np.testing.assert_array_equal(f["data/demo_0/commands"][()], eps[0].actions)
        assert f["data/demo_0"].attrs["num_samples"] == 300
        assert f["data/demo_0/obs/theta"].shape == (300, 1)
        assert f["data/demo_0/obs/theta"].compression == "gzip"
        theta = eps[0].column("theta").astype(np.float32)
        assert np.array_equal(f["data/demo_0/next_obs/theta"][:-1, 0], theta[1:])
        assert f["data/demo_0/next_obs/theta"][-1, 0] == theta[-1]
        actions = f["data/demo_0/actions"][()]
        assert actions.shape == (300, 1) and np.abs(actions).max() <= 1.0
        assert f["data/demo_0/dones"][-1] == 1
        assert list(f["data/demo_0/rewards"][-2:]) == [0.0, 1.0] and f["data/demo_1/rewards"][-1] == 0.0
        names = json.loads(f["data"].attrs["transition_names"])
        assert f["data/demo_0/transition"].dtype == np.uint8 and names == ["t0", "t1"]
        assert [x.decode() for x in f["mask/success"][()]] == ["demo_0", "demo_2"]
        assert [x.decode() for x in f["mask/failure"][()]] == ["demo_1"]
        assert [x.decode() for x in f["mask/train"][()]] == ["demo_0", "demo_1", "demo_2"]   # int(0.3) valid
        assert len(f["mask/valid"][()]) == 0


def test_truncated_file_refused_and_untouched(demo_file):
    path, _ = demo_file
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])
    before = _digest(path)
    with pytest.raises(InvalidInput) as info:
        read_dataset(path)
    assert str(path) in str(info.value)
    assert _digest(path) == before


def test_corrupt_bytes_refused(tmp_path):
    path = tmp_path / "junk.h5"
    path.write_bytes(b"\x89HDF\r\n" + bytes(range(256)) * 10)
    with pytest.raises(InvalidInput, match="not a readable HDF5 file"):
        read_dataset(path)


def test_wrong_version_names_group(demo_file):
    path, _ = demo_file
    with h5py.File(path, "r+") as f:
        f["data"].attrs["format_version"] = 7
    before = _digest(path)
    with pytest.raises(InvalidInput, match=r"data: format version 7"):
        read_dataset(path)
    assert _digest(path) == before


@pytest.mark.parametrize("mutate, fragment", [
    (lambda f: f["data/demo_1/obs/omega"].__setitem__(5, np.nan), "data/demo_1/obs/omega: non-finite value at sample 5"),
    (lambda f: f["data/demo_2/obs"].__delitem__("xdot"), "data/demo_2/obs/xdot: missing dataset"),
    (lambda f: (f["data/demo_0"].__delitem__("actions"),
                f["data/demo_0"].create_dataset("actions", data=np.zeros((300, 2)))), "data/demo_0/actions: shape (300, 2)"),
    (lambda f: f["data/demo_0"].attrs.__setitem__("num_samples", 299), "data/demo_0/obs/theta: shape (300, 1), expected (299, 1)"),
    (lambda f: (f["data/demo_1"].__delitem__("labels"),
                f["data/demo_1"].create_dataset("labels", data=np.zeros(3))), "data/demo_1/labels: expected fields"),
])
def test_bad_field_names_demo_and_field(demo_file, mutate, fragment):
    path, _ = demo_file
    with h5py.File(path, "r+") as f:
        mutate(f)
    before = _digest(path)
    with pytest.raises(InvalidInput) as info:
        read_dataset(path)
    assert fragment in str(info.value)
    assert _digest(path) == before


def test_failed_write_leaves_old_file(demo_file):
    path, eps = demo_file
    before = _digest(path)
    bad = _episode(9)
    bad.observation_names = ("a", "b", "c", "d")
    with pytest.raises(InvalidInput):
        write_dataset(path, [eps[0], bad], "pendulum", "x")
    assert _digest(path) == before
    assert [p.name for p in path.parent.iterdir()] == ["demos.h5"]


def _write_version_1(path, eps):
    """A file as multiform wrote it before format 2: uncompressed, 1-D obs, tags as strings."""
    with h5py.File(path, "w") as f:
        data = f.create_group("data")
        data.attrs.update(format_version=1, skill="pendulum", dt=1e-3,
                          env_args=json.dumps({"env_name": "multiform/ArmPendulum-v0", "env_kwargs": {}}),
                          observation_names=json.dumps(list(NAMES)), command_names='["v_cmd"]')
        for i, ep in enumerate(eps):
            g = data.create_group(f"demo_{i}")
            g.attrs.update(num_samples=ep.num_samples, seed=ep.seed, outcome=ep.outcome, reset_options="{}")
            for k, key in enumerate(NAMES):
                g.create_dataset(f"obs/{key}", data=ep.obs[:, k])
            g.create_dataset("actions", data=ep.actions)
            g.create_dataset("dones", data=np.eye(1, ep.num_samples, ep.num_samples - 1, dtype=np.uint8)[0])
            g.create_dataset("transition", data=ep.transitions.astype("S64"))
            g.create_dataset("labels", data=labels_array(ep.labels))


def test_version_1_files_still_read(tmp_path):
    eps = [_episode(0), _episode(1, outcome="failure")]
    _write_version_1(tmp_path / "old.h5", eps)
    ds = read_dataset(tmp_path / "old.h5")
    assert ds.meta["format_version"] == 1 and ds.meta["obs_dtype"] == "float64"
    for a, b in zip(eps, ds):
        assert np.array_equal(a.obs, b.obs) and np.array_equal(a.actions, b.actions)
        assert list(a.transitions) == list(b.transitions) and a.labels == b.labels


def _as_version_2(path):
    """Rewrite a file of an env without normalize_actions as format 2 wrote it: the actions divided
    by a power of two per command (``action_scale``)."""
    with h5py.File(path, "r+") as f:
        d = f["data"]
        assert "action_high" not in d.attrs
        peak = max(np.abs(d[k]["actions"][()]).max() for k in d if k.startswith("demo_"))
        scale = 2.0 ** np.ceil(np.log2(peak))
        d.attrs["format_version"] = 2
        d.attrs["action_scale"] = [scale]
        for k in [k for k in d if k.startswith("demo_")]:
            a = d[k]["actions"][()] / scale
            del d[k]["actions"]
            d[k].create_dataset("actions", data=a)
    return path


def test_version_2_files_still_load_with_their_commands_exact(tmp_path):
    eps = [_episode(0), _episode(1, outcome="failure")]
    for ep in eps:
        ep.actions = ep.actions * 3.7
    path = _as_version_2(write_dataset(tmp_path / "v2.h5", eps, "pendulum", "x", {"action_mode": "ee"}))
    ds = read_dataset(path)
    assert ds.meta["format_version"] == 2 and ds.env_kwargs == {"action_mode": "ee"}
    for a, b in zip(eps, ds.episodes, strict=True):
        assert np.array_equal(a.actions, b.actions)


def test_compact_storage_is_exact_and_small(tmp_path):
    """Commands of an env without normalize_actions are stored as they are, bit for bit; identical
    observation columns are stored once; the tags cost a byte a sample."""
    rng = np.random.default_rng(3)
    ep = _episode(0, n=4000)
    ep.actions = rng.normal(scale=37.3, size=(4000, 1))
    ep.obs[:, 3] = ep.obs[:, 2]
    path = write_dataset(tmp_path / "d.h5", [ep], "pendulum", "x")
    back = read_dataset(path).episodes[0]
    assert np.array_equal(back.actions, ep.actions) and np.array_equal(back.obs, ep.obs.astype(np.float32))
    with h5py.File(path) as f:
        assert "action_high" not in f["data"].attrs and "commands" not in f["data/demo_0"]
        assert np.array_equal(f["data/demo_0/actions"][()], ep.actions)
        assert f["data/demo_0/obs/x"].id == f["data/demo_0/obs/xdot"].id          # one dataset, two names
        assert f["data/demo_0/transition"].id.get_storage_size() < 4000


@pytest.mark.parametrize("mutate, fragment", [
    (lambda f: f["data"].attrs.__setitem__("action_scale", [3.0]), "action_scale must be 1 positive powers of two"),
    (lambda f: f["data"].attrs.__setitem__("transition_names", '["t0"]'), "code 1 has no name"),
    (lambda f: f["data"].attrs.__delitem__("transition_names"), "missing attribute 'transition_names'"),
])
def test_bad_version_2_tables_refused(tmp_path, mutate, fragment):
    path = _as_version_2(write_dataset(tmp_path / "v2.h5", [_episode(0), _episode(1)], "pendulum", "x"))
    with h5py.File(path, "r+") as f:
        mutate(f)
    with pytest.raises(InvalidInput, match=fragment):
        read_dataset(path)


def test_float64_observations_on_request_half_as_compact(tmp_path):
    ep = _episode(0, n=20000)
    exact = write_dataset(tmp_path / "d64.h5", [ep], "pendulum", "x", obs_dtype="float64")
    back = read_dataset(exact)
    assert back.meta["obs_dtype"] == "float64" and back.episodes[0].obs.dtype == np.float64
    np.testing.assert_array_equal(back.episodes[0].obs, ep.obs)
    assert np.array_equal(back.episodes[0].actions, ep.actions)
    small = write_dataset(tmp_path / "d32.h5", [ep], "pendulum", "x")
    assert small.stat().st_size < 0.65 * exact.stat().st_size         # the commands stay float64
    with pytest.raises(InvalidInput, match="obs_dtype must be float64 or float32"):
        write_dataset(tmp_path / "e.h5", [ep], "pendulum", "x", obs_dtype="float16")


@pytest.mark.parametrize("mutate, fragment", [
    (lambda f: f["data"].attrs.__setitem__("action_high", [-1.5]), "action_low/action_high must be 1 finite limits"),
    (lambda f: f["data"].attrs.__delitem__("action_low"), "missing attribute 'action_low'"),
    (lambda f: f["data/demo_1"].__delitem__("commands"), "data/demo_1/commands: missing dataset"),
    (lambda f: f["data/demo_0/commands"].__setitem__((5, 0), np.nan), "data/demo_0/commands: must hold finite"),
])
def test_bad_version_3_tables_refused(demo_file, mutate, fragment):
    path, _ = demo_file
    with h5py.File(path, "r+") as f:
        mutate(f)
    with pytest.raises(InvalidInput, match=fragment):
        read_dataset(path)
