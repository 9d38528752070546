"""The one-state path: float32 kernel exponentials against float64 and the formulas of eqs. 5/6.

Error bound under test: where ``GPLaw`` takes the float32 path (its probe-measured deviation
``fast_exp_error_`` ≤ ``FAST_EXP_PROBE_TOL``), the mean agrees with the float64 path and with a
direct numpy eq. 5 within ``FAST_EXP_TOL`` (1e-3) × ``y_scale_`` at any state; otherwise the path
is float64 and agrees to 1e-9. Variances are always float64 and match the dense formulas.
"""

from __future__ import annotations

import numpy as np
import pytest
from sklearn.base import clone

from multiform.learn.gp import FAST_EXP_PROBE_TOL, FAST_EXP_TOL, GPLaw
from multiform.learn.sparse_gp import se_kernel


def raw_points(g: GPLaw) -> tuple[np.ndarray, np.ndarray]:
    Z, W = (g.Z_, g.alpha_) if g.mode_ == "exact" else (g.inducing_, g.beta_)
    return Z * g.length_scale_ * g.x_scale_ + g.x_mean_, W


def eq5(g: GPLaw, Xq: np.ndarray) -> np.ndarray:
    """Eq. 5 from raw inputs in float64: σf² exp(−½ Σ_d ((x_d − x_id) / l_d)²) weights, no augmented gemv."""
    P, W = raw_points(g)
    ell = g.x_scale_ * g.length_scale_
    K = g.sigma_f_ ** 2 * np.exp(-0.5 * (((Xq[:, None, :] - P[None]) / ell) ** 2).sum(-1))
    B = g.linear_coef_
    return (K @ W + ((Xq - g.x_mean_) / g.x_scale_) @ B[:-1] + B[-1]) * g.y_scale_ + g.y_mean_


def states(X: np.ndarray, rng: np.random.Generator, k: int = 400) -> np.ndarray:
    """Near the data, 0.5–10 standard deviations away, and absurdly far."""
    sd = X.std(0)
    near = X[rng.choice(len(X), k)] + 0.05 * sd * rng.normal(size=(k, X.shape[1]))
    far = X[rng.choice(len(X), k)] + sd * rng.uniform(0.5, 10, (k, 1)) * rng.normal(size=(k, X.shape[1]))
    return np.vstack([near, far, 1e3 * sd * rng.normal(size=(20, X.shape[1]))])


def smooth_law() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A benchmark-like law: 5 inputs, 2 outputs, noise 5 %."""
    rng = np.random.default_rng(0)
    X = np.column_stack([rng.uniform(-np.pi, np.pi, 1200), rng.uniform(-4, 4, 1200), rng.uniform(-0.5, 0.5, 1200),
                         rng.uniform(-1.5, 1.5, 1200), rng.uniform(-1, 1, 1200)])
    Y = np.column_stack([2 * np.sin(X[:, 0]) * np.cos(0.5 * X[:, 1]) - 0.8 * X[:, 2],
                         np.tanh(1.5 * X[:, 0] + 0.5 * X[:, 1]) + 0.2 * X[:, 2] * X[:, 3]])
    Y += 0.05 * Y.std(0) * rng.normal(size=Y.shape)
    theta = np.log([0.6, 1.5, 2.0, 3.0, 3.0, 1.5, 0.06])
    return X, Y, theta


def balance_law() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A balancing feedback: θ within a few hundredths of a radian of upright, off-centre cart
    positions, linear mean; standardised θ length scale 0.3 → the −½|z|² terms reach ~10³."""
    rng = np.random.default_rng(1)
    n = 1000
    X = np.column_stack([rng.normal(0.0, 0.03, n), rng.normal(0, 0.3, n), 5.0 + rng.normal(0, 0.05, n),
                         rng.normal(0, 0.2, n)])
    y = -30 * X[:, 0] - 4 * X[:, 1] + 2 * (X[:, 2] - 5) + 0.5 * X[:, 3] + 3 * np.sin(40 * X[:, 0])
    y += 0.05 * rng.normal(size=n)
    theta = np.log([0.3, 1.0, 0.05, 2.0, 1.0, 0.1])
    return X, y, theta


def test_numpy_float32_exp_is_within_four_ulp():
    """The assumption behind the float32 path's error bound (:mod:`multiform.learn.gp_predict`): numpy's
    float32 exp (SIMD where available) is within four ulp."""
    a = np.linspace(-87.0, 5.0, 400_001).astype(np.float32)
    e32 = np.exp(a).astype(np.float64)
    e64 = np.exp(a.astype(np.float64))
    ulp = np.spacing(e64.astype(np.float32)).astype(np.float64)
    assert np.max(np.abs(e32 - e64) / ulp) <= 4.0


@pytest.mark.parametrize("which", ["smooth", "balance", "smooth_sparse"])
def test_fast_mean_agrees_with_float64_and_eq5(which):
    X, Y, theta = smooth_law() if which.startswith("smooth") else balance_law()
    kw = {"mean": "linear"} if which == "balance" else {}
    if which == "smooth_sparse":
        kw.update(sparse_threshold=500, n_inducing=200)
    g = GPLaw(exact_var_max_n=None, **kw, theta=theta).fit(X, Y)
    ref = clone(g).set_params(fast_exp=False).fit(X, Y)
    Xq = states(X, np.random.default_rng(7))
    fast = np.array([g.predict_one(x) for x in Xq]).reshape(len(Xq), -1)
    f64 = np.array([ref.predict_one(x) for x in Xq]).reshape(len(Xq), -1)
    direct = eq5(g, Xq)
    y_scale = g.y_scale_
    assert np.max(np.abs(f64 - direct) / y_scale) < 1e-9
    err = np.max(np.abs(fast - direct) / y_scale)
    if g.fast_exp_:
        assert g.fast_exp_error_ <= FAST_EXP_PROBE_TOL
        assert err <= FAST_EXP_TOL, err
        assert err <= 5 * g.fast_exp_error_ + 1e-12, (err, g.fast_exp_error_)
        assert err > 0.0                      # the float32 path is really taken
    else:
        assert err < 1e-9
    # predict_one_var's kernel vector feeds the variance: float64, so its mean is the float64 one
    mv = np.array([g.predict_one_var(x)[0] for x in Xq[:100]]).reshape(100, -1)
    assert np.max(np.abs(mv - direct[:100]) / y_scale) < 1e-9
    if which != "smooth_sparse":
        assert g.fast_exp_, g.fast_exp_error_


def test_large_weights_keep_the_float64_path():
    """A near-noiseless posterior on dense data: α of 10⁴ and more cancel; float32 exponentials would be off by
    far more than the tolerance, so GPLaw measures that and stays float64."""
    rng = np.random.default_rng(3)
    X = rng.uniform(-1, 1, (800, 2))
    y = np.sin(3 * X[:, 0]) + X[:, 1] ** 2
    g = GPLaw(exact_var_max_n=None, theta=np.log([0.8, 0.8, 1.0, 1e-5])).fit(X, y)
    assert np.abs(g.alpha_).max() > 1e4
    assert not g.fast_exp_ and g.fast_exp_error_ > FAST_EXP_PROBE_TOL
    Xq = states(X, rng, 100)
    np.testing.assert_allclose([g.predict_one(x)[0] for x in Xq], eq5(g, Xq)[:, 0], rtol=1e-9, atol=1e-9)


def test_predict_one_returns_a_new_array():
    X, Y, theta = smooth_law()
    g = GPLaw(exact_var_max_n=None, theta=theta).fit(X[:300], Y[:300])
    a = g.predict_one(X[0])
    b = g.predict_one(X[1])
    assert a.dtype == np.float64 and a.shape == (2,) and not np.shares_memory(a, b)
    np.testing.assert_array_equal(a, g.predict_one(X[0]))


def fitc_dense_variance(g: GPLaw, X: np.ndarray, Xq: np.ndarray) -> np.ndarray:
    """FITC latent variance by the textbook dense formulas (own inverses, no stored M):
    σf² − k*ᵀ Kmm⁻¹ k* + k*ᵀ (Kmm + Kmn Λ⁻¹ Knm)⁻¹ k*, Λ = diag(Knn − Qnn) + σn²."""
    sf2, sn2 = g.sigma_f_ ** 2, g.noise_ ** 2
    Z = (X - g.x_mean_) / g.x_scale_ / g.length_scale_
    Zq = (Xq - g.x_mean_) / g.x_scale_ / g.length_scale_
    Zm = g.inducing_
    Kmm = se_kernel(Zm, Zm, sf2)
    Kmn = se_kernel(Zm, Z, sf2)
    Kqm = se_kernel(Zq, Zm, sf2)
    Kmm_inv = np.linalg.inv(Kmm)
    lam = sf2 - np.einsum("ij,ik,kj->j", Kmn, Kmm_inv, Kmn) + sn2
    Sigma = np.linalg.inv(Kmm + (Kmn / lam) @ Kmn.T)
    var = sf2 - np.einsum("ij,jk,ik->i", Kqm, Kmm_inv - Sigma, Kqm)
    return var[:, None] * g.y_scale_ ** 2


@pytest.mark.parametrize("sparse_mean", [True, False])
def test_sparse_variance_matches_dense_fitc_formula(sparse_mean):
    X, Y, theta = smooth_law()
    X, Y = X[:600], Y[:600]
    theta = np.log([1.2, 3.0, 1.0, 3.0, 3.0, 1.0, 0.1])   # long length scales: Kmm well conditioned
    kw = dict(sparse_threshold=300) if sparse_mean else dict(exact_var_max_n=300)
    g = GPLaw(n_inducing=40, **kw, theta=theta).fit(X, Y)
    assert g.var_mode_ == "sparse" and (g.mode_ == "sparse") == sparse_mean
    Xq = states(X, np.random.default_rng(2), 60)
    var = np.array([g.predict_one_var(x)[1] for x in Xq])
    dense = fitc_dense_variance(g, X, Xq)
    prior = g.sigma_f_ ** 2 * g.y_scale_ ** 2
    np.testing.assert_allclose(var, dense, rtol=1e-6, atol=1e-9 * prior.max())
    np.testing.assert_allclose(np.sqrt(var), g.predict(Xq, return_std=True)[1], rtol=1e-7, atol=1e-9)
