"""Single-state kernels of the 1 kHz path, compiled with numba.

Why compiled: a learned condition is evaluated every tick on one state of two to four variables
against a few dozen support vectors or mixture components. The arithmetic is a microsecond; done
as numpy calls on arrays that small it costs 8-15 µs, nearly all of it the per-call overhead of a
handful of ufuncs (``benchmarks/bench_condition.py``). One compiled loop does the same arithmetic
with one call. Where the work is large enough that numpy's vectorised ``exp`` and BLAS win (the GP
laws' 300-point means), the laws stay numpy.

Functions are compiled on first use and cached beside this file (``cache=True``), so a worker
process loads them instead of compiling again.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

RBF, POLY, LINEAR, SIGMOID = 0, 1, 2, 3
KERNEL_CODES = {"rbf": RBF, "poly": POLY, "linear": LINEAR, "sigmoid": SIGMOID}


@njit(cache=True, nogil=True)
def svm_decision_one(x: np.ndarray, mean: np.ndarray, inv_scale: np.ndarray, sv: np.ndarray,
                     dual_coef: np.ndarray, w: np.ndarray, intercept: float, kernel: int, gamma: float,
                     coef0: float, degree: int) -> float:
    """libsvm's ``sum_i a_i K(sv_i, u) + b`` at ``u = (x - mean) * inv_scale``; ``w`` is
    ``dual_coef @ sv`` (the linear kernel's one weight vector)."""
    d = x.shape[0]
    u = np.empty(d)
    for i in range(d):
        u[i] = (x[i] - mean[i]) * inv_scale[i]
    if kernel == LINEAR:
        s = 0.0
        for i in range(d):
            s += w[i] * u[i]
        return s + intercept
    s = 0.0
    for j in range(sv.shape[0]):
        if kernel == RBF:
            d2 = 0.0
            for i in range(d):
                e = u[i] - sv[j, i]
                d2 += e * e
            k = math.exp(-gamma * d2)
        else:
            dot = 0.0
            for i in range(d):
                dot += sv[j, i] * u[i]
            k = (gamma * dot + coef0) ** degree if kernel == POLY else math.tanh(gamma * dot + coef0)
        s += dual_coef[j] * k
    return s + intercept


@njit(cache=True, nogil=True)
def mixture_logits_one(x: np.ndarray, W: np.ndarray, c: np.ndarray, const: np.ndarray, groups: np.ndarray,
                       amax: float, tau_shifted: np.ndarray, slope: np.ndarray) -> np.ndarray:
    """Calibrated logits of the places' Gaussian mixtures at one raw state (see
    :meth:`multiform.learn.region.PlaceRegions._prepare` for the stacked map ``W, c, const``):
    component k's log density is ``const_k - |x W_k - c_k|²``, place p sums its components'
    ``exp(· - amax)`` (no overflow: every term ≤ 0; a place whose components all underflow gets
    ℓ ≈ amax − 690, far outside it, as it should be), then ``z_p = (log(sum + 1e-300) - tau'_p) · slope_p``."""
    d = x.shape[0]
    K = const.shape[0]
    s = np.zeros(tau_shifted.shape[0])
    for k in range(K):
        acc = 0.0
        for e in range(d):
            col = k * d + e
            y = -c[col]
            for i in range(d):
                y += x[i] * W[i, col]
            acc += y * y
        s[groups[k]] += math.exp(const[k] - acc - amax)
    for p in range(s.shape[0]):
        s[p] = (math.log(s[p] + 1e-300) - tau_shifted[p]) * slope[p]
    return s


@njit(cache=True, nogil=True)
def gp_mean_one(x: np.ndarray, xl: np.ndarray, w: np.ndarray, b: np.ndarray, Zaug: np.ndarray, W: np.ndarray,
                lb: np.ndarray, lw: np.ndarray, fast: bool) -> np.ndarray:
    """A GP's predictive mean at one raw state plus an affine map (see
    :meth:`multiform.learn.gp.GPLaw.predict_one`): ``u = x·w − b``, exponents
    ``Zaug · [u, 1, −½|u|²]`` (``Zaug`` column-major: each of its d + 2 columns is one pass over
    contiguous memory), kernel values their ``exp`` (float32 with ``fast``), then
    ``k·W + lb + xl·lw``. ``xl`` is the affine map's input: ``x`` for a linear mean, empty for a
    constant one, or other features of the same state."""
    d = x.shape[0]
    m, q = W.shape
    h = 0.0
    buf = np.empty(m)
    for j in range(m):
        buf[j] = Zaug[j, d]
    for i in range(d):
        ui = x[i] * w[i] - b[i]
        h += ui * ui
        for j in range(m):
            buf[j] += Zaug[j, i] * ui
    h *= -0.5
    r = lb.copy()
    for j in range(m):
        a = buf[j] + Zaug[j, d + 1] * h
        k = np.float64(math.exp(np.float32(a))) if fast else math.exp(a)
        for o in range(q):
            r[o] += k * W[j, o]
    for i in range(xl.shape[0]):
        xi = xl[i]
        for o in range(q):
            r[o] += xi * lw[i, o]
    return r
