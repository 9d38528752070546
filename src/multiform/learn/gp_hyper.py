"""A GP law's hyperparameters: maximum marginal likelihood of a shared squared-exponential kernel.

One kernel serves every output (:class:`~multiform.learn.gp.GPLaw`), so the likelihood is summed
over the outputs. L-BFGS-B runs on our own analytic gradient (scikit-learn's builds an n×n×(d+2)
gradient tensor and took 20–27 s at n = 2,000 here), on a random subset of ``n_hyper`` points: each
evaluation costs O(n³) while the optimum barely moves beyond ~1,000 points. Restarts run on a
300-point probe subset and only the best is refined on the ``n_hyper`` subset.

Everything here works on standardised inputs and outputs; ``theta = [log l (d or 1), log σf, log σn]``.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from scipy.linalg import lapack
from scipy.optimize import minimize

from .sparse_gp import se_kernel

_PROBE = 300
_LOG_2PI = float(np.log(2.0 * np.pi))
# log-space bounds (standardised inputs and outputs)
_BOUNDS_LENGTH = (np.log(1e-2), np.log(1e3))
_BOUNDS_SF = (np.log(1e-2), np.log(1e2))
_BOUNDS_NOISE = (np.log(1e-3), np.log(1e1))


def neg_log_marginal_likelihood(theta: np.ndarray, X: np.ndarray, Y: np.ndarray, ard: bool
                                ) -> tuple[float, np.ndarray]:
    """Negative log marginal likelihood of a shared SE kernel over all columns of ``Y`` and its
    gradient in ``theta = [log l (d or 1), log σf, log σn]``.

    ``X`` (n, d) and ``Y`` (n, p) are standardised. With ``W = ααᵀ − p K⁻¹`` and ``G = W ∘ K_f``,
    the gradient of the log likelihood is ``½ tr(W ∂K)``: ``Σ_i g_i z_id² − z_dᵀ G z_d`` for
    ``log l_d`` (``g = G 1``, ``z = x / l``), ``Σ G`` for ``log σf`` and ``σn² tr W`` for ``log σn``.
    """
    n, d = X.shape
    p = Y.shape[1]
    ell = np.exp(theta[:-2])
    sf2 = float(np.exp(2.0 * theta[-2]))
    sn2 = float(np.exp(2.0 * theta[-1]))
    Z = X / ell
    Kf = se_kernel(Z, Z, sf2)
    K = Kf.copy()
    K.flat[::n + 1] += sn2
    L, info = lapack.dpotrf(K, lower=1, clean=1, overwrite_a=1)
    if info != 0:
        return 1e25, np.zeros_like(theta)
    alpha, _ = lapack.dpotrs(L, Y, lower=1)
    nlml = 0.5 * float(np.sum(Y * alpha)) + p * float(np.sum(np.log(np.diag(L)))) + 0.5 * n * p * _LOG_2PI
    Kinv, info = lapack.dpotri(L, lower=1, overwrite_c=1)
    if info != 0:
        return 1e25, np.zeros_like(theta)
    Kinv = np.tril(Kinv)
    Kinv += np.tril(Kinv, -1).T
    W = alpha @ alpha.T
    W -= p * Kinv
    trW = float(np.trace(W))
    G = W
    G *= Kf
    g = G.sum(axis=1)
    grad_ell = g @ (Z * Z) - np.einsum("ij,ij->j", Z, G @ Z)
    if not ard:
        grad_ell = np.array([grad_ell.sum()])
    grad = np.concatenate([grad_ell, [float(g.sum()), sn2 * trW]])
    return nlml, -grad


def optimise_hyperparameters(Xs: np.ndarray, Ys: np.ndarray, rng: np.random.Generator, ard: bool,
                             n_hyper: int, n_restarts: int, max_iter: int) -> tuple[np.ndarray, float]:
    """Maximise the log marginal likelihood on a random subset of ``n_hyper`` points; returns
    ``(theta, log marginal likelihood)``.

    Restarts are cheap: every start (the default one and ``n_restarts`` random ones) is optimised
    on a probe subset of 300 points, and only the best optimum is refined on the ``n_hyper`` subset
    (one evaluation costs ≈ 0.1 s at 1,000 points, ≈ 4 ms at 300).
    """
    n, d = Xs.shape
    idx = rng.permutation(n)[:n_hyper]
    Xs, Ys = Xs[idx], Ys[idx]
    n_ell = d if ard else 1
    bounds = [_BOUNDS_LENGTH] * n_ell + [_BOUNDS_SF, _BOUNDS_NOISE]
    starts = [np.concatenate([np.zeros(n_ell), [0.0, np.log(0.1)]])]
    for _ in range(n_restarts):
        starts.append(np.concatenate([rng.uniform(np.log(0.2), np.log(5.0), n_ell),
                                      [rng.uniform(np.log(0.5), np.log(2.0)),
                                       rng.uniform(np.log(0.01), np.log(0.5))]]))

    def run(x0: np.ndarray, X: np.ndarray, Y: np.ndarray) -> Any:
        return minimize(neg_log_marginal_likelihood, x0, args=(X, Y, ard), jac=True,
                        method="L-BFGS-B", bounds=bounds, options={"maxiter": max_iter})

    if len(starts) > 1 and len(Xs) > _PROBE:
        probes = [run(x0, Xs[:_PROBE], Ys[:_PROBE]) for x0 in starts]
        starts = [min(probes, key=lambda r: r.fun).x]
    best = min((run(x0, Xs, Ys) for x0 in starts), key=lambda r: r.fun)
    return np.asarray(best.x), -float(best.fun)
