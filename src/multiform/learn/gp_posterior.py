"""A GP law's posterior on its whole training set, once the hyperparameters are known.

Up to ``sparse_threshold`` points it is exact (``α = K⁻¹y`` and the Cholesky factor for the
variance); above, a sparse posterior on ``n_inducing`` k-means centres replaces it
(:mod:`multiform.learn.sparse_gp`). Above ``exact_var_max_n`` points an exact mean keeps a sparse
companion for its variance (an exact variance costs O(n²) per state). Inputs are in the scaled space
of :mod:`~multiform.learn.sparse_gp`, outputs standardised.
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import lapack

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
                    n_inducing: int, sparse_method: str, seed: int) -> dict[str, np.ndarray | None]:
    """The posterior's arrays (keys of :data:`FITTED_ARRAYS`) for scaled inputs ``Z`` (n, d) and
    standardised outputs ``Ys`` (n, p)."""
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
        out["inducing"] = select_inducing(Z, min(n_inducing, n), seed)
        out["beta"], out["sparse_M"] = sparse_posterior(Z, Ys, out["inducing"], sf2, sn2, sparse_method)
    return out
