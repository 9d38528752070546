"""The squared-exponential kernel in a scaled space, and a sparse (FITC or DTC) GP posterior.

All functions work on *scaled* inputs ``z = (x - mean) / (scale * length_scale)``, where the kernel
is one exponential of a squared distance: ``k(z, z') = sf2 * exp(-|z - z'|² / 2)`` (paper eq. 1 with
ARD length scales folded into the scaling), and on standardised outputs.

The sparse posterior summarises n training points by m inducing inputs ``Zm`` (k-means centres in
the scaled space). With ``Q_ab = K_am K_mm⁻¹ K_mb`` and ``Λ`` diagonal (Quiñonero-Candela &
Rasmussen 2005)::

    FITC: Λ = diag(K_nn − Q_nn) + σ²I          DTC: Λ = σ²I
    Σ = (K_mm + K_mn Λ⁻¹ K_nm)⁻¹
    mean(x) = k_m(x) · β,            β = Σ K_mn Λ⁻¹ y                      O(m) per state
    var(x)  = sf2 − k_m(x)ᵀ M k_m(x), M = K_mm⁻¹ − Σ                       O(m²) per state

Built in O(n m²) time and O(m · chunk) memory (the n points are streamed in chunks).
"""

from __future__ import annotations

import warnings

import numpy as np
from scipy.linalg import cho_solve, solve_triangular

SPARSE_METHODS = ("fitc", "dtc")
_CHUNK = 4096
_KMEANS_SAMPLE = 10_000


def se_kernel(A: np.ndarray, B: np.ndarray, sf2: float) -> np.ndarray:
    """``sf2 · exp(−|a − b|² / 2)`` for every row pair of scaled inputs ``A`` (a, d) and ``B`` (b, d)."""
    D = np.einsum("ij,ij->i", A, A)[:, None] + np.einsum("ij,ij->i", B, B)[None, :]
    D -= 2.0 * (A @ B.T)
    np.maximum(D, 0.0, out=D)
    D *= -0.5
    np.exp(D, out=D)
    D *= sf2
    return D


def cholesky_jitter(K: np.ndarray, base: float) -> tuple[np.ndarray, float]:
    """Lower Cholesky factor of ``K + j·I``, raising ``j`` from 0 (then ``base``) ×10 until it works.

    Returns ``(L, j)``. ``K`` is not modified.
    """
    jitter = 0.0
    for _ in range(8):
        try:
            A = K if jitter == 0.0 else K + jitter * np.eye(K.shape[0])
            return np.linalg.cholesky(A), jitter
        except np.linalg.LinAlgError:
            jitter = base if jitter == 0.0 else jitter * 10.0
    raise np.linalg.LinAlgError(f"kernel matrix not positive definite even with jitter {jitter:g}")


def select_inducing(Z: np.ndarray, m: int, seed: int) -> np.ndarray:
    """``m`` inducing inputs: k-means centres of the scaled training inputs (on a random subsample of
    at most 10,000 points, which keeps this under a second for n = 50,000)."""
    n = Z.shape[0]
    if m >= n:
        return Z.copy()
    from sklearn.cluster import KMeans
    from sklearn.exceptions import ConvergenceWarning

    rng = np.random.default_rng(seed)
    sample = Z if n <= _KMEANS_SAMPLE else Z[rng.choice(n, _KMEANS_SAMPLE, replace=False)]
    with warnings.catch_warnings():     # fewer distinct points than centres: handled just below
        warnings.filterwarnings("ignore", message="Number of distinct clusters", category=ConvergenceWarning)
        km = KMeans(n_clusters=m, n_init=1, max_iter=100, random_state=seed).fit(sample)
    centres = km.cluster_centers_
    uniq = np.unique(np.round(centres, 12), axis=0)
    if uniq.shape[0] < m:        # duplicated data: fall back to distinct training points
        idx = rng.choice(n, m, replace=False)
        centres = Z[idx]
    return np.ascontiguousarray(centres, dtype=np.float64)


def sparse_posterior(Z: np.ndarray, Y: np.ndarray, Zm: np.ndarray, sf2: float, noise_var: float,
                     method: str = "fitc") -> tuple[np.ndarray, np.ndarray]:
    """``(β, M)`` of the sparse posterior (module docstring) for scaled inputs ``Z`` (n, d),
    standardised outputs ``Y`` (n, p) and inducing inputs ``Zm`` (m, d)."""
    if method not in SPARSE_METHODS:
        raise ValueError(f"unknown sparse method {method!r}; known: {', '.join(SPARSE_METHODS)}")
    m = Zm.shape[0]
    Kmm = se_kernel(Zm, Zm, sf2)
    Lm, _ = cholesky_jitter(Kmm, 1e-8 * sf2)
    B = np.eye(m)
    c = np.zeros((m, Y.shape[1]))
    for s in range(0, Z.shape[0], _CHUNK):
        Kmc = se_kernel(Zm, Z[s:s + _CHUNK], sf2)
        V = solve_triangular(Lm, Kmc, lower=True, overwrite_b=True, check_finite=False)
        if method == "fitc":
            lam = np.maximum(sf2 - np.einsum("ij,ij->j", V, V), 0.0) + noise_var
        else:
            lam = np.full(V.shape[1], noise_var)
        Vs = V / np.sqrt(lam)
        B += Vs @ Vs.T
        c += V @ (Y[s:s + _CHUNK] / lam[:, None])
    Lb = np.linalg.cholesky(B)
    beta = solve_triangular(Lm.T, cho_solve((Lb, True), c), lower=False, check_finite=False)
    Lm_inv = solve_triangular(Lm, np.eye(m), lower=True, check_finite=False)
    T = np.eye(m) - cho_solve((Lb, True), np.eye(m))
    M = Lm_inv.T @ T @ Lm_inv
    M = 0.5 * (M + M.T)
    return np.ascontiguousarray(beta), np.ascontiguousarray(M)
