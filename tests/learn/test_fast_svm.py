"""The numpy decision function equals scikit-learn's, and its files fail loudly and safely."""

import numpy as np
import pytest
from sklearn.pipeline import make_pipeline
from sklearn.preprocessing import StandardScaler
from sklearn.svm import SVC, OneClassSVM

from multiform.errors import InvalidInput
from multiform.io import save_npz
from multiform.learn.fast_svm import KIND, VERSION, FastDecision


@pytest.fixture(scope="module")
def data():
    rng = np.random.default_rng(7)
    X = rng.normal(size=(400, 4)) * [1.0, 3.0, 0.1, 10.0] + [0.0, 1.0, -0.2, 5.0]
    y = (X[:, 0] ** 2 + 0.3 * X[:, 1] - 2 * X[:, 2] > 1.0) ^ (rng.random(400) < 0.05)
    Xq = rng.normal(size=(300, 4)) * [1.5, 4.0, 0.2, 12.0] + [0.0, 1.0, -0.2, 5.0]
    return X, y, Xq


@pytest.mark.parametrize("kernel,params", [
    ("rbf", {"C": 3.0, "gamma": "scale"}),
    ("rbf", {"C": 0.5, "gamma": 2.0}),
    ("poly", {"C": 1.0, "degree": 3, "coef0": 1.0, "gamma": 0.3}),
    ("poly", {"C": 1.0, "degree": 2, "coef0": 0.0, "gamma": "auto"}),
    ("linear", {"C": 0.3}),
    ("sigmoid", {"C": 1.0, "gamma": 0.1, "coef0": -1.0}),
])
def test_svc_decision_equals_sklearn(data, kernel, params):
    X, y, Xq = data
    pipe = make_pipeline(StandardScaler(), SVC(kernel=kernel, **params)).fit(X, y)
    fast = FastDecision.from_sklearn(pipe)
    ref = pipe.decision_function(Xq)
    np.testing.assert_allclose(fast.decision(Xq), ref, rtol=0, atol=1e-8)
    one = np.array([fast.decision_one(x.copy()) for x in Xq])
    np.testing.assert_allclose(one, ref, rtol=0, atol=1e-8)
    assert np.array_equal(fast.decision(Xq) > 0, pipe.predict(Xq))


def test_unscaled_svc_and_one_class(data):
    X, y, Xq = data
    svc = SVC(kernel="rbf", C=2.0, gamma=0.05).fit(X, y)
    np.testing.assert_allclose(FastDecision.from_sklearn(svc).decision(Xq), svc.decision_function(Xq), atol=1e-8)
    oc = make_pipeline(StandardScaler(), OneClassSVM(nu=0.1, gamma=0.5)).fit(X)
    fast = FastDecision.from_sklearn(oc)
    np.testing.assert_allclose(fast.decision(Xq), oc.decision_function(Xq), atol=1e-8)
    assert fast.decision(Xq[0]) == pytest.approx(oc.decision_function(Xq[:1])[0], abs=1e-8)


def test_refuses_what_it_cannot_compile(data):
    X, y, _ = data
    multi = SVC().fit(X, (X[:, 0] > 0).astype(int) + (X[:, 1] > 1))
    with pytest.raises(ValueError, match="binary"):
        FastDecision.from_sklearn(multi)
    with pytest.raises(ValueError, match="precomputed"):
        FastDecision.from_sklearn(SVC(kernel="precomputed").fit(X @ X.T, y))
    fast = FastDecision.from_sklearn(SVC().fit(X, y))
    with pytest.raises(ValueError, match="expected"):
        fast.decision(np.zeros((3, 5)))


def test_save_load_round_trip(tmp_path, data):
    X, y, Xq = data
    pipe = make_pipeline(StandardScaler(), SVC(kernel="poly", degree=3, coef0=0.5)).fit(X, y)
    fast = FastDecision.from_sklearn(pipe)
    path = tmp_path / "f.npz"
    fast.save(path)
    back = FastDecision.load(path)
    assert back.kernel == "poly" and back.degree == 3 and back.n_support == fast.n_support
    np.testing.assert_array_equal(back.decision(Xq), fast.decision(Xq))


def test_corrupt_and_mismatched_files(tmp_path, data):
    X, y, _ = data
    fast = FastDecision.from_sklearn(make_pipeline(StandardScaler(), SVC()).fit(X, y))
    path = tmp_path / "f.npz"
    fast.save(path)
    good = path.read_bytes()

    path.write_bytes(good[: len(good) // 2])                  # truncated
    with pytest.raises(InvalidInput, match="f.npz"):
        FastDecision.load(path)
    assert path.read_bytes() == good[: len(good) // 2]         # reading never touches the file

    arrays, meta = fast.to_arrays()
    bad = tmp_path / "bad.npz"
    save_npz(bad, {**arrays, "dual_coef": arrays["dual_coef"][:-1]}, meta, KIND, VERSION)
    with pytest.raises(InvalidInput, match="dual_coef") as e:
        FastDecision.load(bad)
    assert "bad.npz" in str(e.value)
    save_npz(bad, arrays, {**meta, "kernel": "laplacian"}, KIND, VERSION)
    with pytest.raises(InvalidInput, match="kernel"):
        FastDecision.load(bad)
    save_npz(bad, arrays, meta, "judge", VERSION)
    with pytest.raises(InvalidInput, match="expected a 'fast_svm'"):
        FastDecision.load(bad)
    save_npz(bad, arrays, meta, KIND, VERSION + 1)
    with pytest.raises(InvalidInput, match="version"):
        FastDecision.load(bad)
    nan = dict(arrays, support_vectors=np.full_like(arrays["support_vectors"], np.nan))
    save_npz(bad, nan, meta, KIND, VERSION)
    with pytest.raises(InvalidInput, match="non-finite"):
        FastDecision.load(bad)
