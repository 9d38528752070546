"""GPLaw: agreement with scikit-learn and the exact formulas, sparse accuracy, persistence."""

from __future__ import annotations

import json
import zipfile

import numpy as np
import pytest
from scipy.optimize import approx_fprime
from sklearn.base import clone
from sklearn.gaussian_process import GaussianProcessRegressor
from sklearn.gaussian_process.kernels import RBF, WhiteKernel
from sklearn.gaussian_process.kernels import ConstantKernel as C

from multiform.errors import InvalidInput
from multiform.io import save_npz
from multiform.learn.compiled import gp_mean_one
from multiform.learn.gp import FAST_EXP_TOL, KIND, VERSION, GPLaw, neg_log_marginal_likelihood
from multiform.learn.gp_hyper import optimise_hyperparameters

THETA5 = np.array([np.log(1.2), np.log(0.8), np.log(2.0), np.log(1.5), np.log(3.0), np.log(1.3), np.log(0.05)])


def law(X: np.ndarray) -> np.ndarray:
    a = np.sin(X[:, 0]) * np.cos(0.5 * X[:, 1]) + 0.3 * X[:, 2] * X[:, 3] - 0.2 * X[:, 4]
    b = np.tanh(X[:, 0] + 0.5 * X[:, 3]) + 0.1 * X[:, 1] ** 2
    return np.column_stack([a, b])


def data(n: int, seed: int = 0, noise: float = 0.02) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    X = rng.uniform(-2, 2, (n, 5))
    return X, law(X) + noise * rng.normal(size=(n, 2))


def standardised(g: GPLaw, X: np.ndarray, Y: np.ndarray | None = None):
    Xs = (X - g.x_mean_) / g.x_scale_
    return Xs if Y is None else (Xs, (Y - g.y_mean_) / g.y_scale_)


# -- the marginal likelihood -------------------------------------------------------------------------
@pytest.mark.parametrize("ard", [True, False])
def test_lml_gradient_matches_finite_differences(ard):
    X, Y = data(120)
    Xs, Ys = (X - X.mean(0)) / X.std(0), (Y - Y.mean(0)) / Y.std(0)
    theta = THETA5 if ard else np.array([0.3, 0.1, np.log(0.1)])
    _, grad = neg_log_marginal_likelihood(theta, Xs, Ys, ard)
    num = approx_fprime(theta, lambda t: neg_log_marginal_likelihood(t, Xs, Ys, ard)[0], 1e-6)
    np.testing.assert_allclose(grad, num, rtol=1e-4, atol=1e-3)


def test_lml_equals_sklearn_log_marginal_likelihood():
    X, Y = data(150)
    y = Y[:, 0]
    Xs, ys = (X - X.mean(0)) / X.std(0), (y - y.mean()) / y.std()
    gpr = GaussianProcessRegressor(C(1.0) * RBF(np.ones(5)) + WhiteKernel(0.01), alpha=0.0, optimizer=None)
    gpr.fit(Xs, ys)
    ell, sf, sn = np.exp(THETA5[:5]), np.exp(THETA5[5]), np.exp(THETA5[6])
    sk_theta = np.log(np.concatenate([[sf ** 2], ell, [sn ** 2]]))
    ours, _ = neg_log_marginal_likelihood(THETA5, Xs, ys[:, None], True)
    assert -ours == pytest.approx(gpr.log_marginal_likelihood(sk_theta), rel=1e-9)


# -- exact posterior -----------------------------------------------------------------------------------
def test_mean_matches_sklearn_and_variance_matches_exact_formula():
    X, Y = data(200)
    g = GPLaw(sparse_threshold=None, exact_var_max_n=None, theta=THETA5).fit(X, Y)
    Xs, Ys = standardised(g, X, Y)
    sk = GaussianProcessRegressor(C(g.sigma_f_ ** 2, "fixed") * RBF(g.length_scale_, "fixed"),
                                  alpha=g.noise_ ** 2, optimizer=None).fit(Xs, Ys)
    Xq = np.random.default_rng(5).uniform(-2.5, 2.5, (60, 5))
    mean, std = g.predict(Xq, return_std=True)
    sk_mean = sk.predict(standardised(g, Xq)) * g.y_scale_ + g.y_mean_
    np.testing.assert_allclose(mean, sk_mean, rtol=1e-9, atol=1e-9 * np.abs(sk_mean).max())

    # eq. 6 by hand: k(x*,x*) − k*ᵀ (K + σn² I)⁻¹ k*, in standardised units, times y_scale²
    Z, Zq = Xs / g.length_scale_, standardised(g, Xq) / g.length_scale_
    k = lambda A, B: g.sigma_f_ ** 2 * np.exp(-0.5 * ((A[:, None, :] - B[None, :, :]) ** 2).sum(-1))  # noqa: E731
    K = k(Z, Z) + g.noise_ ** 2 * np.eye(len(Z))
    Kq = k(Zq, Z)
    var = g.sigma_f_ ** 2 - np.einsum("ij,ji->i", Kq, np.linalg.solve(K, Kq.T))
    np.testing.assert_allclose(std ** 2, var[:, None] * g.y_scale_ ** 2, rtol=1e-7, atol=1e-12)


def test_fitted_law_has_small_heldout_error_and_sensible_hyperparameters():
    X, Y = data(400, noise=0.05)
    g = GPLaw(n_hyper=400, input_names=list("abcde"), output_names=["u", "v"]).fit(X, Y)
    Xt = np.random.default_rng(9).uniform(-1.8, 1.8, (500, 5))
    assert g.summary().get("heldout_nrmse") is None
    err = g.heldout_error(Xt, law(Xt))
    assert g.summary().get("heldout_nrmse") is None           # measuring changes nothing
    assert np.array_equal(g.record_heldout_error(Xt, law(Xt)), err)
    assert np.all(err < 0.1), err
    s = g.summary()
    assert s["n"] == 400 and s["mode"] == "exact" and s["outputs"] == ["u", "v"]
    assert list(s["length_scale"]) == list("abcde")
    assert s["heldout_nrmse"] == pytest.approx(list(err))
    # noise 0.05 on outputs of std ≈ 0.6–0.9: the learned standardised noise is of that order
    assert 0.02 < g.noise_ < 0.2
    # x4 enters linearly with a small slope: its length scale is the longest
    assert max(s["length_scale"], key=s["length_scale"].get) == "e"


def test_single_output_shapes_follow_sklearn():
    X, Y = data(100)
    g = GPLaw(n_hyper=100).fit(X, Y[:, 0])
    mean, std = g.predict(X[:7], return_std=True)
    assert mean.shape == (7,) and std.shape == (7,)
    assert g.predict_one(X[0]).shape == (1,)
    assert g.score(X, Y[:, 0]) > 0.99


def test_multi_output_predicts_each_output():
    rng = np.random.default_rng(3)
    X = rng.uniform(-2, 2, (300, 4))
    Y = np.column_stack([np.sin(X[:, 0]), 10.0 * X[:, 1] * X[:, 2], -3.0 + 0.01 * np.cos(X[:, 3])])
    g = GPLaw(n_hyper=300).fit(X, Y, )
    Xt = rng.uniform(-1.8, 1.8, (200, 4))
    Yt = np.column_stack([np.sin(Xt[:, 0]), 10.0 * Xt[:, 1] * Xt[:, 2], -3.0 + 0.01 * np.cos(Xt[:, 3])])
    pred, std = g.predict(Xt, return_std=True)
    assert pred.shape == (200, 3) and std.shape == (200, 3)
    nrmse = np.sqrt(((pred - Yt) ** 2).mean(0)) / Yt.std(0)
    assert np.all(nrmse < 0.15), nrmse
    # one shared kernel: standard deviations differ across outputs only by the output scale
    np.testing.assert_allclose(std / g.y_scale_, np.repeat(std[:, :1] / g.y_scale_[0], 3, axis=1), rtol=1e-12)


# -- the one-state path and the sparse forms ---------------------------------------------------------------
def _laws(X, Y):
    return {
        "exact": GPLaw(sparse_threshold=None, exact_var_max_n=None, theta=THETA5).fit(X, Y),
        "exact_mean_sparse_var": GPLaw(exact_var_max_n=100, n_inducing=150, theta=THETA5).fit(X, Y),
        "fitc": GPLaw(sparse_threshold=100, n_inducing=150, theta=THETA5).fit(X, Y),
        "dtc": GPLaw(sparse_threshold=100, n_inducing=150, sparse_method="dtc", theta=THETA5).fit(X, Y),
        "exact_linear": GPLaw(sparse_threshold=None, mean="linear", theta=THETA5).fit(X, Y),
        "fitc_linear": GPLaw(sparse_threshold=100, n_inducing=150, mean="linear", theta=THETA5).fit(X, Y),
        "fitc_subset_noise": GPLaw(sparse_threshold=100, n_inducing=150, n_hyper=100, subset_noise=True,
                                   theta=THETA5).fit(X, Y),
    }


def test_linear_mean_extrapolates_where_a_constant_mean_reverts():
    """A balancing law seen mostly near upright: u = -k·θ with noise, θ within ±0.05; asked at
    θ = 0.3 the constant-mean GP falls back towards the data mean, the linear-mean GP follows -k·θ."""
    rng = np.random.default_rng(3)
    X = rng.normal(0.0, 0.02, (600, 2))
    y = -8.0 * X[:, 0] - 1.0 * X[:, 1] + rng.normal(0, 0.02, 600)
    far = np.array([[0.3, 0.0], [-0.3, 0.1]])
    truth = -8.0 * far[:, 0] - 1.0 * far[:, 1]
    theta = np.log([1.0, 1.0, 1.0, 0.1])        # one standardised length scale: θ = 0.3 is 15 of them out
    const = GPLaw(theta=theta).fit(X, y)
    lin = GPLaw(mean="linear", theta=theta).fit(X, y)
    np.testing.assert_allclose(lin.predict(far), truth, rtol=0.05)
    np.testing.assert_allclose(const.predict(far), y.mean(), atol=1e-6)
    near = rng.normal(0.0, 0.02, (200, 2))
    np.testing.assert_allclose(lin.predict(near), -8.0 * near[:, 0] - near[:, 1], atol=0.05)
    with pytest.raises(ValueError, match="mean"):
        GPLaw(mean="quadratic").fit(X, y)


@pytest.mark.parametrize("mean", ["constant", "linear"])
def test_affine_plan_adds_a_linear_map_of_other_features(mean):
    """One compiled call gives a GP's mean plus ``f·W + b`` (the inverse model's residual GP and
    linear part), whether the GP's own mean is constant or linear."""
    X, Y = data(300)
    g = GPLaw(mean=mean, theta=THETA5).fit(X, Y)
    rng = np.random.default_rng(4)
    W, b = rng.normal(size=(7, 2)), rng.normal(size=2)
    plan, with_x = g.affine_plan(W, b)
    assert with_x == (mean == "linear")
    for x in rng.uniform(-2.5, 2.5, (20, 5)):
        f = rng.normal(size=7)
        got = gp_mean_one(x, np.r_[x, f] if with_x else f, *plan)
        np.testing.assert_allclose(got, g.predict_one(x) + f @ W + b, rtol=1e-12, atol=1e-12)


def test_modes_follow_thresholds():
    X, Y = data(400)
    laws = _laws(X, Y)
    assert (laws["exact"].mode_, laws["exact"].var_mode_) == ("exact", "exact")
    assert (laws["exact_mean_sparse_var"].mode_, laws["exact_mean_sparse_var"].var_mode_) == ("exact", "sparse")
    assert (laws["fitc"].mode_, laws["fitc"].var_mode_) == ("sparse", "sparse")
    assert laws["fitc"].inducing_.shape == (150, 5) and laws["exact"].chol_ is not None
    assert laws["exact_mean_sparse_var"].chol_ is None


def test_predict_one_equals_batch_of_one_in_every_mode():
    X, Y = data(400)
    Xq = np.random.default_rng(1).uniform(-2.5, 2.5, (25, 5))
    for name, g in _laws(X, Y).items():
        mean, std = g.predict(Xq, return_std=True)
        ref = clone(g).set_params(fast_exp=False).fit(X, Y)
        fast_tol = FAST_EXP_TOL * float(g.y_scale_.min()) if g.fast_exp_ else 1e-12
        for i, x in enumerate(Xq):
            m1 = g.predict_one(x)
            m2, v2 = g.predict_one_var(x)
            np.testing.assert_allclose(ref.predict_one(x), mean[i], rtol=1e-10, atol=1e-12, err_msg=name)
            np.testing.assert_allclose(m1, mean[i], rtol=1e-10, atol=fast_tol, err_msg=name)
            np.testing.assert_allclose(m2, mean[i], rtol=1e-10, atol=fast_tol, err_msg=name)
            np.testing.assert_allclose(np.sqrt(v2), std[i], rtol=1e-7, atol=1e-9, err_msg=name)


def test_sparse_approximates_exact_on_a_smooth_function():
    """5-D inputs spread uniformly (the hard case for inducing points: real demonstrations lie on
    trajectories); same hyperparameters for all, so differences come from the approximation."""
    X, Y = data(1500, seed=2)
    Xq = np.random.default_rng(4).uniform(-1.8, 1.8, (400, 5))
    m_ex, s_ex = GPLaw(sparse_threshold=None, exact_var_max_n=None, theta=THETA5).fit(X, Y).predict(Xq, True)
    scale = Y.std(0)
    rms = {}
    for method in ("fitc", "dtc"):
        for m in (150, 300):
            g = GPLaw(sparse_threshold=1000, n_inducing=m, sparse_method=method, theta=THETA5).fit(X, Y)
            mean, std = g.predict(Xq, return_std=True)
            rms[method, m] = np.sqrt(((mean - m_ex) ** 2).mean(0)) / scale
            if m == 300:
                assert np.all(rms[method, m] < 0.05), (method, rms[method, m])
                assert np.max(np.abs(mean - m_ex) / scale) < 0.25, method
                # std within 0.2 of the prior std σf·y_scale everywhere, 0.05 on average
                dev = np.abs(std - s_ex) / (g.sigma_f_ * g.y_scale_)
                assert dev.max() < 0.2 and dev.mean() < 0.05, (method, dev.max(), dev.mean())
        assert np.all(rms[method, 300] < rms[method, 150])
    # an exact mean with the FITC variance companion: the mean is the exact one
    g = GPLaw(exact_var_max_n=1000, n_inducing=300, theta=THETA5).fit(X, Y)
    mean, std = g.predict(Xq, return_std=True)
    np.testing.assert_allclose(mean, m_ex, rtol=1e-10, atol=1e-12)
    assert (np.abs(std - s_ex) / (g.sigma_f_ * g.y_scale_)).mean() < 0.05


def test_subset_noise_solves_the_posterior_with_the_noise_scaled_to_the_subset_density():
    """400 points, hyperparameters for a 100-point subset: the posterior is the one with the noise
    variance ×4 (σn ×2), as a law with that noise fixed computes it; the fitted noise stays reported."""
    X, Y = data(400)
    Xq = np.random.default_rng(5).uniform(-2.5, 2.5, (30, 5))
    theta2 = THETA5.copy()
    theta2[-1] += np.log(2.0)
    for kw in ({"sparse_threshold": None, "exact_var_max_n": None}, {"sparse_threshold": 100, "n_inducing": 80}):
        g = GPLaw(theta=THETA5, n_hyper=100, subset_noise=True, **kw).fit(X, Y)
        ref = GPLaw(theta=theta2, **kw).fit(X, Y)
        assert g.noise_ == pytest.approx(np.exp(THETA5[-1])) and g.posterior_noise() == pytest.approx(2 * g.noise_)
        for a, b in zip(g.predict(Xq, return_std=True), ref.predict(Xq, return_std=True)):
            np.testing.assert_allclose(a, b, rtol=1e-9, atol=1e-12)
        plain = GPLaw(theta=THETA5, n_hyper=100, **kw).fit(X, Y)
        assert np.abs(plain.predict(Xq) - g.predict(Xq)).max() > 1e-3


def test_hyper_subsets_take_the_median_of_the_subsets_optima(tmp_path):
    """Hyperparameters over 3 subsets of 100 points: each log hyperparameter is the median of the optima
    found on those subsets (the first the single-subset fit's own), computed here one by one."""
    X, Y = data(400)
    g1 = GPLaw(n_hyper=100, n_restarts=0, sparse_threshold=None).fit(X, Y)
    g3 = GPLaw(n_hyper=100, n_restarts=0, sparse_threshold=None, hyper_subsets=3).fit(X, Y)
    Xs, Ys = standardised(g3, X, Y)
    thetas = [optimise_hyperparameters(Xs, Ys, np.random.default_rng(s), True, 100, 0, 200)[0]
              for s in (0, [0, 1], [0, 2])]
    assert not np.allclose(thetas[0], thetas[1], rtol=1e-3)           # the subsets disagree
    np.testing.assert_allclose(np.log(g1.length_scale_), thetas[0][:-2], rtol=1e-10)
    med = np.median(thetas, axis=0)
    np.testing.assert_allclose(np.log(g3.length_scale_), med[:-2], rtol=1e-10)
    np.testing.assert_allclose(np.log([g3.sigma_f_, g3.noise_]), med[-2:], rtol=1e-10)
    g3.save(tmp_path / "law.npz")
    h = GPLaw.load(tmp_path / "law.npz")
    assert h.get_params() == g3.get_params() and h.hyper_subsets == 3
    np.testing.assert_array_equal(h.predict(X[:20]), g3.predict(X[:20]))
    with pytest.raises(ValueError, match="hyper_subsets"):
        GPLaw(hyper_subsets=0).fit(X, Y)


def test_hyper_subsets_fitted_side_by_side_give_the_same_law_bit_for_bit(tmp_path):
    """n_jobs (or a joblib parallel_config around the fit, as a job sets) only moves the subsets'
    optimisations into worker processes: every fitted number is the sequential fit's, and the saved
    file does not say where it ran."""
    from joblib import parallel_config
    X, Y = data(400)
    kw = dict(n_hyper=100, n_restarts=1, sparse_threshold=None, hyper_subsets=3)
    seq = GPLaw(**kw).fit(X, Y)
    side = GPLaw(**kw, n_jobs=2).fit(X, Y)
    with parallel_config(n_jobs=2):
        ctx = GPLaw(**kw).fit(X, Y)
    for g in (side, ctx):
        for attr in ("length_scale_", "sigma_f_", "noise_", "log_marginal_likelihood_", "alpha_"):
            np.testing.assert_array_equal(getattr(g, attr), getattr(seq, attr))
    side.save(tmp_path / "side.npz")
    seq.save(tmp_path / "seq.npz")
    assert GPLaw.load(tmp_path / "side.npz").get_params() == seq.get_params()
    # a law's hyperparameters given to another (as fit_law's held-out probe takes them): the same kernel
    again = GPLaw(**kw).set_params(theta=seq.theta_).fit(X, Y)
    for attr in ("length_scale_", "sigma_f_", "noise_", "alpha_"):
        np.testing.assert_allclose(getattr(again, attr), getattr(seq, attr), rtol=1e-6)
    assert again.log_marginal_likelihood_ is None


def test_sparse_variance_grows_away_from_the_data():
    X, Y = data(600)
    g = GPLaw(sparse_threshold=100, n_inducing=100, theta=THETA5).fit(X, Y)
    _, v_in = g.predict_one_var(np.zeros(5))
    _, v_out = g.predict_one_var(np.full(5, 8.0))
    assert np.all(v_out > 10 * v_in)
    np.testing.assert_allclose(v_out, g.sigma_f_ ** 2 * g.y_scale_ ** 2, rtol=1e-6)


def test_estimator_contract():
    g = GPLaw(n_inducing=50, input_names=["a", "b"])
    assert clone(g).get_params() == g.get_params()
    assert not hasattr(g, "mode_")
    with pytest.raises(ValueError, match="input_names has 2 names"):
        g.fit(*data(30))
    with pytest.raises(ValueError, match="theta must have 7"):
        GPLaw(theta=np.zeros(3)).fit(*data(30))


# -- persistence -------------------------------------------------------------------------------------------
def test_save_load_round_trip_is_exact(tmp_path):
    X, Y = data(400)
    Xq = np.random.default_rng(1).uniform(-2.5, 2.5, (30, 5))
    for name, g in _laws(X, Y).items():
        g.set_params(input_names=list("abcde"), output_names=["u", "v"])
        g.record_heldout_error(Xq, law(Xq))
        path = tmp_path / f"{name}.npz"
        g.save(path)
        h = GPLaw.load(path)
        hp, gp = h.get_params(), g.get_params()
        assert np.array_equal(hp.pop("theta"), gp.pop("theta")) and hp == gp
        assert (h.mode_, h.var_mode_, h.n_train_) == (g.mode_, g.var_mode_, g.n_train_)
        assert h.summary() == g.summary()
        m1, s1 = g.predict(Xq, return_std=True)
        m2, s2 = h.predict(Xq, return_std=True)
        np.testing.assert_array_equal(m1, m2)
        np.testing.assert_array_equal(s1, s2)
        for x in Xq[:5]:
            np.testing.assert_array_equal(g.predict_one(x), h.predict_one(x))
            for a, b in zip(g.predict_one_var(x), h.predict_one_var(x)):
                np.testing.assert_array_equal(a, b)


@pytest.fixture
def saved(tmp_path):
    X, Y = data(200)
    path = tmp_path / "law.npz"
    GPLaw(exact_var_max_n=None, theta=THETA5).fit(X, Y).save(path)
    return path


def _arrays_and_meta(path):
    with np.load(path, allow_pickle=False) as z:
        arrays = {k: z[k] for k in z.files}
    header = json.loads(str(arrays.pop("__format__")))
    return arrays, header["meta"]


def _expect_invalid(path, *fragments):
    before = path.read_bytes()
    with pytest.raises(InvalidInput) as exc:
        GPLaw.load(path)
    msg = str(exc.value)
    assert str(path) in msg
    for f in fragments:
        assert f in msg, msg
    assert path.read_bytes() == before


def test_load_truncated_file(saved):
    data_ = saved.read_bytes()
    saved.write_bytes(data_[: len(data_) // 2])
    _expect_invalid(saved, "not a valid .npz")


def test_load_wrong_version(saved, tmp_path):
    arrays, meta = _arrays_and_meta(saved)
    save_npz(saved, arrays, meta, KIND, VERSION + 1)
    _expect_invalid(saved, f"version {VERSION + 1}", f"reads version {VERSION}")


def test_load_wrong_kind(saved):
    arrays, meta = _arrays_and_meta(saved)
    save_npz(saved, arrays, meta, "fast_svm", VERSION)
    _expect_invalid(saved, "'fast_svm'", "'gp_law'")


def test_load_wrong_shaped_array(saved):
    arrays, meta = _arrays_and_meta(saved)
    arrays["alpha"] = arrays["alpha"][:-1]
    save_npz(saved, arrays, meta, KIND, VERSION)
    _expect_invalid(saved, "alpha", "shape (199, 2)", "expected (200, 2)")


def test_load_missing_array_and_bad_meta(saved):
    arrays, meta = _arrays_and_meta(saved)
    del arrays["chol"]
    save_npz(saved, arrays, meta, KIND, VERSION)
    _expect_invalid(saved, "chol", "missing")
    arrays, meta = _arrays_and_meta(saved)
    meta["mode"] = "magic"
    save_npz(saved, arrays, meta, KIND, VERSION)
    _expect_invalid(saved, "meta.mode", "magic")


def test_load_non_finite_and_non_positive(saved):
    arrays, meta = _arrays_and_meta(saved)
    arrays["Z"][3, 1] = np.nan
    arrays["hyper"][1] = -1.0
    save_npz(saved, arrays, meta, KIND, VERSION)
    _expect_invalid(saved, "Z: has non-finite values")


def test_load_object_array(saved):
    arrays, meta = _arrays_and_meta(saved)
    with zipfile.ZipFile(saved) as z:
        header = np.load(z.open("__format__.npy"), allow_pickle=False)
    bad = dict(arrays, alpha=np.array([{"x": 1}, None], dtype=object))
    with open(saved, "wb") as fh:
        np.savez(fh, __format__=header, **bad)
    _expect_invalid(saved, "Object arrays cannot be loaded")
