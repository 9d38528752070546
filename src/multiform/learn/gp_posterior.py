"""A GP law's posterior on its whole training set, once the hyperparameters are known.

Up to ``sparse_threshold`` points it is exact (``α = K⁻¹y`` and the Cholesky factor for the
variance); above, a sparse posterior on ``n_inducing`` k-means centres replaces it
(:mod:`multiform.learn.sparse_gp`). Above ``exact_var_max_n`` points an exact mean keeps a sparse
companion for its variance (an exact variance costs O(n²) per state). Inputs are in the scaled space
of :mod:`~multiform.learn.sparse_gp`, outputs standardised.
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import block_diag, lapack

from .sparse_gp import cholesky_jitter, se_kernel, select_inducing, sparse_posterior

MODES = ("exact", "sparse")
# the arrays a posterior consists of (absent ones are None): file key -> GPLaw attribute
FITTED_ARRAYS = {"Z": "Z_", "alpha": "alpha_", "chol": "chol_", "inducing": "inducing_",
                 "beta": "beta_", "sparse_M": "sparse_M_"}


def posterior_modes(n: int, sparse_threshold: int | None, exact_var_max_n: int | None) -> tuple[str, str]:
    """``(mode, var_mode)`` of the mean and the variance for ``n`` training points."""
    mode = "sparse" if sparse_threshold is not None and n > sparse_threshold else "exact"
    exact_var = exact_var_max_n is None or n <= exact_var_max_n
    return mode, "exact" if mode == "exact" and exact_var else "sparse"


def solve_posterior(Z: np.ndarray, Ys: np.ndarray, sf2: float, sn2: float, mode: str, var_mode: str,
                    n_inducing: int, sparse_method: str, seed: int, n_draws: int = 1,
                    focus: float = 0.0) -> dict[str, np.ndarray | None]:
    """The posterior's arrays (keys of :data:`FITTED_ARRAYS`) for scaled inputs ``Z`` (n, d) and
    standardised outputs ``Ys`` (n, p).

    With ``n_draws`` > 1 the sparse posterior is the mean of that many sparse posteriors on
    independent draws of ``n_inducing`` inducing inputs (:func:`bagged_sparse_posterior`); with
    ``focus`` > 0 that fraction of each draw's inducing inputs goes where a first sparse posterior
    explains the data worst (:func:`focused_inducing`)."""
    n = Z.shape[0]
    out: dict[str, np.ndarray | None] = dict.fromkeys(FITTED_ARRAYS)
    if mode == "exact":
        K = se_kernel(Z, Z, sf2)
        K.flat[::n + 1] += sn2
        L, _ = cholesky_jitter(K, 1e-10 * sf2)
        del K
        out["Z"] = Z
        out["alpha"] = lapack.dpotrs(L, Ys, lower=1)[0]
        if var_mode == "exact":
            out["chol"] = np.asfortranarray(L)
    if var_mode == "sparse":
        out["inducing"], out["beta"], out["sparse_M"] = bagged_sparse_posterior(
            Z, Ys, sf2, sn2, min(n_inducing, n), sparse_method, seed, n_draws, focus)
    return out


def draw_seed(seed: int, k: int) -> int:
    """The k-means seed of inducing draw ``k`` (draw 0 is the single-draw posterior's)."""
    return seed + 7919 * k


def bagged_sparse_posterior(Z: np.ndarray, Ys: np.ndarray, sf2: float, sn2: float, m: int, method: str,
                            seed: int, n_draws: int, focus: float = 0.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(inducing, β, M)`` of the mean of ``n_draws`` sparse posteriors, each on its own k-means draw
    of ``m`` inducing inputs (:func:`draw_seed`).

    Why: which inducing inputs one draw places decides what a sparse posterior says in regions the
    data visits rarely, and with it the closed loop (a pendulum swing-up from 10 demonstrations
    failed 19, 3 and 26 of 60 pushed trials with 300, 1000 and 2000 points). The draws share the
    kernel, so their mean is again one sparse form on the union of the inducing sets: the mean's
    weights are the members' ``β / K`` stacked, its ``M`` the members' ``M / K`` on the block diagonal
    (the variance is the members' mean variance). Prediction costs as one posterior on ``K·m``
    points.
    """
    if n_draws < 1:
        raise ValueError(f"n_draws must be ≥ 1, got {n_draws}")
    parts = []
    for k in range(n_draws):
        Zm = (focused_inducing(Z, Ys, sf2, sn2, m, method, draw_seed(seed, k), focus) if focus > 0
              else select_inducing(Z, m, draw_seed(seed, k)))
        parts.append((Zm, *sparse_posterior(Z, Ys, Zm, sf2, sn2, method)))
    if n_draws == 1:
        return parts[0]
    inducing = np.concatenate([p[0] for p in parts])
    beta = np.concatenate([p[1] for p in parts]) / n_draws
    M = block_diag(*[p[2] for p in parts]) / n_draws
    return np.ascontiguousarray(inducing), np.ascontiguousarray(beta), np.ascontiguousarray(M)


FOCUS_QUANTILE = 0.95


def focused_inducing(Z: np.ndarray, Ys: np.ndarray, sf2: float, sn2: float, m: int, method: str, seed: int,
                     focus: float) -> np.ndarray:
    """``m`` inducing inputs: ``round(focus·m)`` k-means centres of the samples a first sparse
    posterior (on ``m`` k-means centres of all samples) explains worst, the ``1 − FOCUS_QUANTILE``
    of largest residual in any output, and ``m`` minus those k-means centres of all samples.

    Why: k-means centres follow the density of the data, so a behaviour the demonstrations show
    rarely (a mentor braking a pendulum that spins over the top: 4 % of the swing-up samples) gets
    few centres, and FITC treats what the centres cannot represent as noise.
    """
    if not 0.0 <= focus < 1.0:
        raise ValueError(f"focus must be in [0, 1), got {focus}")
    first = select_inducing(Z, m, seed)
    r = int(round(focus * m))
    if r == 0:
        return first
    beta, _ = sparse_posterior(Z, Ys, first, sf2, sn2, method)
    res = np.empty(Z.shape[0])
    for s in range(0, Z.shape[0], 4096):
        res[s:s + 4096] = np.abs(Ys[s:s + 4096] - se_kernel(Z[s:s + 4096], first, sf2) @ beta).max(axis=1)
    hard = np.flatnonzero(res >= np.quantile(res, FOCUS_QUANTILE))
    return np.concatenate([select_inducing(Z, m - r, seed), select_inducing(Z[hard], min(r, len(hard)), seed)])
