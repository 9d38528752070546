"""The prediction paths of a fitted GP law (:class:`~.gp.GPLaw`): one state at the control rate,
with or without the variance, and batches.

Written here rather than taken from scikit-learn: at 1 kHz a law's mean must cost a few
microseconds (scikit-learn's ``predict`` spends ~110 µs validating its input; FACTS.md), so each
point set is stored augmented and one gemv, or one compiled loop, gives every kernel exponent.

Bound on the relative error of one kernel value on the float32 exponential path: the exponent
a is rounded to float32 (|a|·2⁻²⁴) and a float32 exp (libm's expf, numpy's SIMD loop) is within
4 ulp (8·2⁻²⁴) when the result is a normal float; below exp(−87) the absolute error is < 2⁻¹²⁶
(flush to zero or subnormal), negligible against any law's output. Relative error of k ≤
(|a| + 8)·2⁻²⁴.
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import blas, lapack
from sklearn.utils.validation import check_is_fitted

from .compiled import gp_mean_one
from .sparse_gp import se_kernel

_BATCH = 1024
_mul, _sub, _exp, _dot = np.multiply, np.subtract, np.exp, np.dot
# Up to this many points (inducing or training) the one-state mean is one compiled loop; above it
# numpy's vectorised float32 exp outruns the compiled scalar one (here: 300 points 3.4 against
# 6.0 µs, 1,000 about even, 2,000 10-17 against 8-14 µs).
COMPILED_MEAN_MAX_POINTS = 1000
FAST_EXP_TOL = 1e-3             # the admitted float32 path stays this close (× y_scale_) at any state
FAST_EXP_PROBE_TOL = 2e-4       # admitted if at most this far (× y_scale_) at the probe states


class GPPrediction:
    """The prediction paths of a fitted :class:`~.gp.GPLaw` (its fitted attributes set); built by
    :meth:`_prepare` after a fit or a load."""

    def _prepare(self) -> None:
        """Derived arrays and buffers of the prediction path, built from the stored fitted arrays.

        Each point set (training inputs or inducing inputs) is stored augmented as ``[z, c, 1]`` with
        ``c = log σf² − ½|z|²``, and the state as ``[u, 1, −½|u|²]``, so one gemv gives the exponent
        ``log k = log σf² − ½|z − u|²`` of every point.
        """
        d = self.n_features_in_
        w = 1.0 / (self.x_scale_ * self.length_scale_)
        self._w = w
        self._b = self.x_mean_ * w
        self._sf2 = self.sigma_f_ ** 2
        self._var_scale = self.y_scale_ ** 2
        self._ua = np.zeros(d + 2)
        self._ua[d] = 1.0
        self._uh = self._ua[:d]
        self._d1 = d + 1
        if self.mode_ == "exact":
            self._Zm = np.ascontiguousarray(self.Z_)
            self._Zaug = _augment(self._Zm, self._sf2)
            self._A = np.ascontiguousarray(self.alpha_ * self.y_scale_)
            self._buf = np.empty(self._Zm.shape[0])
        if self.inducing_ is not None:
            self._sZ = np.ascontiguousarray(self.inducing_)
            self._sZaug = _augment(self._sZ, self._sf2)
            self._sB = np.ascontiguousarray(self.beta_ * self.y_scale_)
            self._sM = np.asfortranarray(self.sparse_M_)      # dsymv reads its lower triangle only
            self._sbuf = np.empty(self._sZ.shape[0])
        self._sparse_mean = self.mode_ == "sparse"
        self._exact_var = self.var_mode_ == "exact"
        self._mZaug, self._mW = (self._sZaug, self._sB) if self._sparse_mean else (self._Zaug, self._A)
        self._compiled_mean = self._mZaug.shape[0] <= COMPILED_MEAN_MAX_POINTS
        self._mbuf = self._sbuf if self._sparse_mean else self._buf
        # The mean function in raw units: y_mean for a constant mean, x·W + b for a linear one.
        B = self.linear_coef_
        self._linear = bool(np.any(B[:-1]))
        self._lw = np.ascontiguousarray(B[:-1] / self.x_scale_[:, None] * self.y_scale_)
        self._lb = np.ascontiguousarray(np.atleast_1d((B[-1] - (self.x_mean_ / self.x_scale_) @ B[:-1])
                                                      * self.y_scale_ + self.y_mean_), dtype=np.float64)
        self._no_affine, self._no_lw = np.empty(0), np.zeros((0, self._mW.shape[1]))
        self._mean_lw = self._lw if self._linear else self._no_lw
        self.fast_exp_error_ = self._fast_exp_error() if getattr(self, "fast_exp", True) else None
        self.fast_exp_ = self.fast_exp_error_ is not None and self.fast_exp_error_ <= FAST_EXP_PROBE_TOL

    def _fast_exp_error(self) -> float:
        """Largest deviation of the float32-exponential mean from the float64 one, relative to
        ``y_scale_``, measured at probe states: up to 250 points of the set and the same moved by
        0.25, 0.5, 1 and 2 length scales in random directions. Partial support is where the large
        weights of a low-noise posterior cancel; far from the data every kernel value, and with it
        the error, vanishes. Measured through the one-state path in use (compiled or numpy)."""
        Z = self._sZ if self.mode_ == "sparse" else self._Zm
        rng = np.random.default_rng(0)
        base = Z[rng.permutation(len(Z))[:250]]
        probes = [base]
        for r in (0.25, 0.5, 1.0, 2.0):
            step = rng.normal(size=base.shape)
            probes.append(base + r * step / np.linalg.norm(step, axis=1, keepdims=True))
        P = np.concatenate(probes)
        if self._compiled_mean:
            err = np.zeros(self._mW.shape[1])
            for x in (P + self._b) / self._w:                     # back to raw states
                args = (x, self._no_affine, self._w, self._b, self._mZaug, self._mW, self._lb, self._no_lw)
                np.maximum(err, np.abs(gp_mean_one(*args, True) - gp_mean_one(*args, False)), out=err)
            return float(np.max(err / self.y_scale_))
        D = np.einsum("ij,ij->i", P, P)[:, None] + np.einsum("ij,ij->i", Z, Z)[None, :] - 2.0 * (P @ Z.T)
        a = np.log(self._sf2) - 0.5 * np.maximum(D, 0.0)
        k32 = np.exp(a, dtype=np.float32, casting="same_kind").astype(np.float64)
        return float(np.max(np.abs((k32 - np.exp(a)) @ self._mW) / self.y_scale_))

    def _load_state(self, x: np.ndarray) -> np.ndarray:
        uh = self._uh
        _mul(x, self._w, uh)                 # positional out: ≈ 0.3 µs less per call than out=
        _sub(uh, self._b, uh)
        self._ua[self._d1] = -0.5 * uh.dot(uh)
        return self._ua

    def predict_one(self, x: np.ndarray) -> np.ndarray:
        """Predictive mean (eq. 5) of every output for one state ``x`` (1-D float64 array of
        ``n_features_in_``); returns a new float64 array of ``n_outputs_``.

        The control-rate path, no validation: one compiled call
        (:func:`multiform.learn.compiled.gp_mean_one`) up to ``COMPILED_MEAN_MAX_POINTS`` points,
        numpy on preallocated buffers above (shared: not thread-safe). With ``fast_exp`` the kernel
        exponentials are float32 (module docstring: relative error of the mean ≲ 1e-6 of the output
        scale); everything else is float64.
        """
        if self._compiled_mean:
            return gp_mean_one(x, x if self._linear else self._no_affine, self._w, self._b, self._mZaug, self._mW,
                               self._lb, self._mean_lw, self.fast_exp_)
        ua = self._load_state(x)
        buf = self._mbuf
        _dot(self._mZaug, ua, buf)
        if self.fast_exp_:
            _exp(buf, buf, dtype=np.float32, casting="same_kind")
        else:
            _exp(buf, buf)
        r = buf.dot(self._mW)
        r += self._lb
        if self._linear:
            r += x.dot(self._lw)
        return r

    def affine_plan(self, W: np.ndarray, b: np.ndarray) -> tuple[tuple, bool]:
        """This GP's mean plus an affine map ``f·W + b`` of other features ``f``, as one compiled
        call: returns ``(plan, with_x)``, to be called ``gp_mean_one(x, xf, *plan)`` with ``xf`` =
        ``[x, f]`` if ``with_x`` (the GP's own mean is linear in ``x``) else ``f``. For a GP on the
        residual of a linear fit (:class:`~multiform.learn.inverse.InverseDynamicsModel`)."""
        W = np.asarray(W, dtype=np.float64)
        lw = np.vstack([self._lw, W]) if self._linear else W
        plan = (self._w, self._b, self._mZaug, self._mW, self._lb + b, np.ascontiguousarray(lw), self.fast_exp_)
        return plan, self._linear

    def predict_one_var(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Predictive mean and variance (eqs. 5, 6) of every output for one state ``x``;
        returns ``(mean, var)``, each of ``n_outputs_``. Same contract as :meth:`predict_one`.

        The kernel vector that enters the variance is always float64: the quadratic form cancels
        terms of the size of ``K⁻¹`` (up to ~1e11 for a short-length-scale law), which would
        amplify a float32 exponential's relative error ~1e-7 far past the variance itself. An
        exact mean (``n`` points) beside a sparse variance (``m`` points) keeps the fast mean.
        """
        ua = self._load_state(x)
        if self._exact_var:
            buf = self._buf
            _dot(self._Zaug, ua, buf)
            _exp(buf, buf)
            mean = buf.dot(self._A)
            mean += self._lb
            if self._linear:
                mean += x.dot(self._lw)
            v = blas.dtrsv(self.chol_, buf, lower=1)
            var = self._sf2 - v.dot(v)
            return mean, (var if var > 0.0 else 0.0) * self._var_scale
        sbuf = self._sbuf
        _dot(self._sZaug, ua, sbuf)
        _exp(sbuf, sbuf)
        if self._sparse_mean:
            mean = sbuf.dot(self._sB)
            mean += self._lb
            if self._linear:
                mean += x.dot(self._lw)
        else:
            mean = self.predict_one(x)
        var = self._sf2 - sbuf.dot(blas.dsymv(1.0, self._sM, sbuf, lower=1))
        return mean, (var if var > 0.0 else 0.0) * self._var_scale

    # -- batches --------------------------------------------------------------------------------
    def predict(self, X: np.ndarray, return_std: bool = False) -> np.ndarray | tuple[np.ndarray, np.ndarray]:
        """Predictive mean (and standard deviation of the latent law) for every row of ``X``.

        Shapes follow the training targets: (n,) for 1-D ``y``, (n, p) otherwise.
        """
        check_is_fitted(self, "mode_")
        X = np.asarray(X, dtype=np.float64)
        if X.ndim != 2 or X.shape[1] != self.n_features_in_:
            raise ValueError(f"X must have shape (n, {self.n_features_in_}), got {X.shape}")
        n, p = X.shape[0], self.n_outputs_
        mean = np.empty((n, p))
        std = np.empty((n, p)) if return_std else None
        for s in range(0, n, _BATCH):
            U = X[s:s + _BATCH] * self._w - self._b
            Ks = se_kernel(U, self._sZ, self._sf2) if self.inducing_ is not None else None
            Ke = se_kernel(U, self._Zm, self._sf2) if self.mode_ == "exact" else None
            mean[s:s + _BATCH] = (Ks @ self._sB if self._sparse_mean else Ke @ self._A) + \
                X[s:s + _BATCH] @ self._lw + self._lb
            if return_std:
                if self._exact_var:
                    V = lapack.dtrtrs(self.chol_, Ke.T, lower=1)[0]
                    var = self._sf2 - np.einsum("ij,ij->j", V, V)
                else:
                    var = self._sf2 - np.einsum("ij,ij->i", Ks @ self._sM, Ks)
                np.maximum(var, 0.0, out=var)
                std[s:s + _BATCH] = np.sqrt(var[:, None] * self._var_scale)
        if self.y_1d_:
            mean = mean[:, 0]
            std = std[:, 0] if return_std else None
        return (mean, std) if return_std else mean



def _augment(Z: np.ndarray, sf2: float) -> np.ndarray:
    """``[z, log σf² − ½|z|², 1]`` per row, column-major: the gemv then runs as d + 2 contiguous
    axpys (half the time of the row-major layout for n = 2,000)."""
    c = np.log(sf2) - 0.5 * np.einsum("ij,ij->i", Z, Z)
    return np.asfortranarray(np.column_stack([Z, c, np.ones(Z.shape[0])]))
