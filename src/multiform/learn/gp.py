"""A transition's control law: Gaussian process regression with a fast one-state prediction path.

The paper learns each maneuver's law y = f(x) by GP regression with the squared-exponential kernel
``k(xi, xj) = σf² exp(−‖xi − xj‖² / 2l²)`` (eq. 1); the predictive mean is ``k*ᵀ K⁻¹ y`` (eq. 5) and
the variance ``k(x*, x*) − k*ᵀ K⁻¹ k*`` (eq. 6), with ``K`` the kernel matrix plus the noise σn²I.

:class:`GPLaw` is a scikit-learn estimator:

* inputs and outputs are standardised; ARD length scales (one per input) by default;
* **one kernel shared by all outputs** (one σf, one set of length scales, one noise level in
  standardised output units). One Cholesky factor and one kernel vector per state serve every
  output, so a law's cost at 1 kHz does not grow with the number of command components; the outputs
  of one maneuver are functions of the same state with similar smoothness. If outputs differ
  strongly in smoothness, fit one ``GPLaw`` per output;
* hyperparameters maximise the log marginal likelihood (summed over the outputs) with L-BFGS-B on
  our own analytic gradient (scikit-learn's builds an n×n×(d+2) gradient tensor and took 20–27 s
  at n = 2,000 here), on a random subset of ``n_hyper`` points: each evaluation costs O(n³) while
  the optimum barely moves beyond ~1,000 points. Restarts (``n_restarts`` random starts besides
  the default one) run on a 300-point probe subset; the best is refined on the ``n_hyper`` subset
  (:mod:`.gp_hyper`);
* the posterior is then solved on the full set (:mod:`.gp_posterior`). Up to ``sparse_threshold`` points it is exact
  (``α = K⁻¹y`` and the Cholesky factor); above, a sparse FITC posterior on ``n_inducing`` k-means
  centres replaces it (:mod:`multiform.learn.sparse_gp`). FITC rather than DTC: its diagonal
  correction ``Λ = diag(K − Q) + σ²`` treats training points the inducing set represents poorly as
  noisier instead of over-trusting the low-rank kernel there; prediction formula and cost are the
  same. DTC is available (``sparse_method="dtc"``). Both use the hyperparameters of the exact GP.
* Exact variance costs O(n²) per state (a triangular solve with the Cholesky factor). Measured
  here, one core, mean + variance: ≈ 20 µs at n = 250, ≈ 40 µs at n = 500, ≈ 120 µs at n = 1,000,
  ≈ 0.4–0.8 ms at n = 2,000 (``benchmarks/bench_gp.py``), against ≈ 15 µs for the variance of a
  FITC form on 300 points. So above ``exact_var_max_n`` points (default 500) the variance of an
  exact GP is computed through a FITC companion on ``n_inducing`` points, in :meth:`predict_one_var`
  and :meth:`predict` alike, so the two always agree; the mean stays exact.
  ``sparse_threshold=None, exact_var_max_n=None`` keeps everything exact at any n.
* ``sparse_threshold`` defaults to 3,000: the exact mean costs ≈ 5 ns per training point (one
  ``exp`` each; numpy's float64 ``exp`` is scalar on AVX2 machines), so 3,000 points stay near
  15 µs. Time series recorded at 1 kHz are very redundant; subsampling them before fitting keeps a
  law exact.

* ``mean="linear"`` adds an explicit linear mean (Rasmussen & Williams §2.7, with the linear
  coefficients fitted by ridge regression first and the GP on the residual): far from the data the
  law then falls back to the linear fit instead of to a constant. A balancing law fitted on mostly
  near-upright states otherwise returns about zero command at a 0.3 rad catch — the short length
  scale the near-upright data selects (≈ 0.07 rad) leaves no support out there.

Variances are those of the latent law f(x) (eq. 6), in output units, without the observation noise
(``noise_`` × ``y_scale_`` is that noise's standard deviation).

The one-state mean (:meth:`predict_one`) is one compiled call (:mod:`multiform.learn.compiled`:
numpy spends more on its per-call overhead than on the arithmetic of 300 points), numpy above
``COMPILED_MEAN_MAX_POINTS`` points, where its vectorised ``exp`` wins: the input is
mapped into the scaled space where the kernel is one ``exp`` of a squared distance expanded as
``z·u − ½|z|² − ½|u|²``; no validation. The exponents are float64
(the ``−½|z|²`` terms reach 10³–10⁴ for short length scales, too large for float32); with
``fast_exp`` the mean then takes their ``exp`` in float32 and sums in float64. Each kernel value is
off by at most ``(|a| + 8)·2⁻²⁴`` relatively, but a low-noise posterior's weights cancel (|α| up to
10⁴–10⁶ for FITC on 50,000 points), so at ``_prepare`` the law measures the float32 mean's deviation
at 1,250 probe states around its points and keeps float64 unless it is ≤ ``FAST_EXP_PROBE_TOL``
(2e-4 of ``y_scale_``); tests hold the admitted path to ``FAST_EXP_TOL`` (1e-3) at any state.
The variance's kernel vector is always float64 (:meth:`predict_one_var`).

The class itself is the estimator and its prediction paths; the hyperparameter search
(:mod:`.gp_hyper`), the posterior (:mod:`.gp_posterior`) and the file format (:mod:`.gp_store`)
are modules of their own.
"""

from __future__ import annotations

import os
import time
from collections.abc import Sequence
from typing import Any

import numpy as np
from scipy.linalg import blas, lapack
from sklearn.base import BaseEstimator, RegressorMixin
from sklearn.utils.validation import check_is_fitted, check_X_y

from ..io import load_npz, save_npz
from .compiled import gp_mean_one
from .gp_hyper import neg_log_marginal_likelihood, optimise_hyperparameters  # noqa: F401  (also read from here)
from .gp_posterior import FITTED_ARRAYS, posterior_modes, solve_posterior
from .gp_store import KIND, VERSION, law_from_arrays, law_to_arrays  # noqa: F401  (also read from here)
from .sparse_gp import SPARSE_METHODS, se_kernel

MEANS = ("constant", "linear")
_BATCH = 1024
_mul, _sub, _exp, _dot = np.multiply, np.subtract, np.exp, np.dot
# Bound on the relative error of one kernel value on the float32 exponential path: the exponent
# a is rounded to float32 (|a|·2⁻²⁴) and a float32 exp (libm's expf, numpy's SIMD loop) is within
# 4 ulp (8·2⁻²⁴) when the result is a normal float; below exp(−87) the absolute error is < 2⁻¹²⁶ (flush to zero or
# subnormal), negligible against any law's output. Relative error of k ≤ (|a| + FAST_EXP_ULP)·2⁻²⁴.
FAST_EXP_EPS = 2.0 ** -24
# Up to this many points (inducing or training) the one-state mean is one compiled loop; above it
# numpy's vectorised float32 exp outruns the compiled scalar one (here: 300 points 3.4 against
# 6.0 µs, 1,000 about even, 2,000 10-17 against 8-14 µs).
COMPILED_MEAN_MAX_POINTS = 1000
FAST_EXP_ULP = 8.0
FAST_EXP_TOL = 1e-3
FAST_EXP_PROBE_TOL = 2e-4


class GPLaw(BaseEstimator, RegressorMixin):
    """GP regression control law (see the module docstring).

    Parameters
    ----------
    ard: one length scale per input (True) or one for all.
    n_hyper: points (a random subset) on which the hyperparameters are trained.
    n_restarts: random restarts of the optimiser beyond the default start.
    max_iter: L-BFGS-B iterations per start.
    sparse_threshold: above this many training points the posterior is sparse (None: never).
    n_inducing: inducing points of the sparse posterior / sparse variance companion.
    sparse_method: "fitc" or "dtc".
    exact_var_max_n: above this many points an exact GP's variance goes through the sparse
        companion (None: always exact).
    input_names, output_names: variable names stored with the law (checked against the data).
    n_threads: BLAS and OpenMP threads while fitting (None: leave as is). 1 by default: on a busy
        2-core machine OpenBLAS with 2 threads made a 1,000-point Cholesky 30× slower than with 1.
    mean: "constant" (the output mean) or "linear" (an explicit linear mean; module docstring).
    random_state: seed for the hyperparameter subset, restarts and k-means.
    fast_exp: the one-state mean (:meth:`predict_one`) takes its kernel exponentials in float32
        (module docstring); False keeps it float64 throughout.
    theta: fixed hyperparameters [log l…, log σf, log σn] in standardised units (one length scale,
        or one per input with ``ard``); None (default): trained by maximum marginal likelihood.
    subset_noise: the posterior on all n points takes the noise variance σn² · n / n_hyper, as if its
        points were as dense as the subset the hyperparameters were fitted on (:meth:`posterior_noise`).
    hyper_subsets: the hyperparameters are the median (per log hyperparameter) of those maximising the
        likelihood on this many random subsets of ``n_hyper`` points (the first one the subset of a
        single fit); the reported log marginal likelihood is the median of theirs. 1: one subset.
        Why: on demonstrations recorded at 1 kHz the likelihood's optimum moves with the subset (a
        pendulum swing-up from 10 demonstrations: length scales of cos θ from 0.09 to 0.47 over
        three subsets of 1,000 points; the median of seven, 0.40–0.52), and the closed loop with it.
    """

    def __init__(self, ard: bool = True, n_hyper: int = 1000, n_restarts: int = 2, max_iter: int = 200,
                 sparse_threshold: int | None = 3000, n_inducing: int = 300, sparse_method: str = "fitc",
                 exact_var_max_n: int | None = 500, input_names: Sequence[str] | None = None,
                 output_names: Sequence[str] | None = None, n_threads: int | None = 1,
                 mean: str = "constant", random_state: int = 0, fast_exp: bool = True,
                 theta: Sequence[float] | np.ndarray | None = None, subset_noise: bool = False,
                 hyper_subsets: int = 1):
        self.ard = ard
        self.n_hyper = n_hyper
        self.n_restarts = n_restarts
        self.max_iter = max_iter
        self.sparse_threshold = sparse_threshold
        self.n_inducing = n_inducing
        self.sparse_method = sparse_method
        self.exact_var_max_n = exact_var_max_n
        self.input_names = input_names
        self.output_names = output_names
        self.n_threads = n_threads
        self.mean = mean
        self.random_state = random_state
        self.fast_exp = fast_exp
        self.theta = theta
        self.subset_noise = subset_noise
        self.hyper_subsets = hyper_subsets

    # -- fitting ------------------------------------------------------------------------------
    def fit(self, X: np.ndarray, y: np.ndarray) -> GPLaw:
        """Train the hyperparameters (unless the constructor fixed ``theta``) and solve the posterior
        on all of ``X`` (n, d), ``y`` (n,) or (n, p)."""
        X, y = check_X_y(X, y, multi_output=True, y_numeric=True, dtype=np.float64)
        self._check_params(X.shape[1], 1 if y.ndim == 1 else y.shape[1])
        if self.n_threads is None:
            return self._fit(X, y, self.theta)
        from threadpoolctl import threadpool_limits
        with threadpool_limits(limits=self.n_threads):
            return self._fit(X, y, self.theta)

    def _check_params(self, d: int, p: int) -> None:
        if self.mean not in MEANS:
            raise ValueError(f"mean must be one of {MEANS}, got {self.mean!r}")
        if self.sparse_method not in SPARSE_METHODS:
            raise ValueError(f"sparse_method must be one of {SPARSE_METHODS}, got {self.sparse_method!r}")
        if self.n_inducing < 1 or self.n_hyper < 2 or self.hyper_subsets < 1:
            raise ValueError("n_inducing and hyper_subsets must be ≥ 1 and n_hyper ≥ 2")
        for what, names, k in (("input_names", self.input_names, d), ("output_names", self.output_names, p)):
            if names is not None and len(names) != k:
                raise ValueError(f"{what} has {len(names)} names but the data has {k} columns")

    def _fit(self, X: np.ndarray, y: np.ndarray, theta: Sequence[float] | np.ndarray | None) -> GPLaw:
        t0 = time.perf_counter()
        Xs, Ys = self._standardise(X, y)
        n, d = X.shape
        if theta is None:
            fits = [optimise_hyperparameters(Xs, Ys, np.random.default_rng(self.random_state if k == 0
                                                                            else [self.random_state, k]),
                                             self.ard, self.n_hyper, self.n_restarts, self.max_iter)
                    for k in range(self.hyper_subsets)]
            theta = np.median([t for t, _ in fits], axis=0)
            lml = float(np.median([v for _, v in fits]))
        else:
            theta = np.asarray(theta, dtype=np.float64).reshape(-1)
            n_ell = d if self.ard else 1
            if theta.shape != (n_ell + 2,):
                raise ValueError(f"theta must have {n_ell + 2} entries (log length scales, log σf, log σn)")
            lml = None
        ell = np.exp(theta[:-2])
        self.length_scale_ = np.broadcast_to(ell, (d,)).astype(np.float64)
        self.sigma_f_ = float(np.exp(theta[-2]))
        self.noise_ = float(np.exp(theta[-1]))
        self.log_marginal_likelihood_ = lml
        self.n_hyper_used_ = min(n, self.n_hyper) if lml is not None else 0
        self.mode_, self.var_mode_ = posterior_modes(n, self.sparse_threshold, self.exact_var_max_n)
        posterior = solve_posterior(Xs / self.length_scale_, Ys, self.sigma_f_ ** 2, self.posterior_noise() ** 2,
                                    self.mode_, self.var_mode_, self.n_inducing, self.sparse_method,
                                    self.random_state)
        for key, attr in FITTED_ARRAYS.items():
            setattr(self, attr, posterior[key])
        self.heldout_nrmse_ = None
        self.fit_seconds_ = time.perf_counter() - t0
        self._prepare()
        return self

    def posterior_noise(self) -> float:
        """The noise standard deviation (standardised units) the posterior is solved with: ``noise_``, or
        with ``subset_noise`` ``noise_ · √(n / n_hyper)``.

        Why: samples of time series recorded at 1 kHz are far from independent. The likelihood is
        maximised on ``n_hyper`` points spread over the demonstrations (≈ 0.1 s apart); a posterior on
        all n samples with the same noise trusts each demonstration's idiosyncrasies n / n_hyper times
        over, and a sparse posterior then swings with its inducing points (a pendulum swing-up from 10
        demonstrations, n = 98,020: held-out NRMSE 0.32 with 300 inducing points, 0.51–0.53 with 1,000
        or 2,000; with the scaled noise 0.32–0.33 for all three; docs/measurements.md).
        """
        scale = self.n_train_ / min(self.n_train_, self.n_hyper) if self.subset_noise else 1.0
        return self.noise_ * float(np.sqrt(max(scale, 1.0)))

    def _standardise(self, X: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Learn the standardisation of inputs and outputs (and with ``mean="linear"`` the linear
        mean); returns the standardised inputs and the standardised outputs the GP is to explain."""
        self.y_1d_ = y.ndim == 1
        Y = y.reshape(len(y), -1)
        n, d = X.shape
        self.n_features_in_ = d
        self.n_outputs_ = Y.shape[1]
        self.n_train_ = n
        self.x_mean_ = X.mean(axis=0)
        self.x_scale_ = _safe_scale(X.std(axis=0))
        self.y_mean_ = Y.mean(axis=0)
        self.y_scale_ = _safe_scale(Y.std(axis=0))
        Xs = (X - self.x_mean_) / self.x_scale_
        Ys = (Y - self.y_mean_) / self.y_scale_
        self.linear_coef_ = np.zeros((d + 1, Y.shape[1]))
        if self.mean == "linear":
            A = np.c_[Xs, np.ones(n)]
            self.linear_coef_ = np.linalg.solve(A.T @ A + 1e-6 * n * np.eye(d + 1), A.T @ Ys)
            Ys = Ys - A @ self.linear_coef_
        return Xs, Ys

    # -- the 1 kHz path -------------------------------------------------------------------------
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
        self._fast = self.fast_exp_error_ is not None and self.fast_exp_error_ <= FAST_EXP_PROBE_TOL

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
                               self._lb, self._mean_lw, self._fast)
        ua = self._load_state(x)
        buf = self._mbuf
        _dot(self._mZaug, ua, buf)
        if self._fast:
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
        plan = (self._w, self._b, self._mZaug, self._mW, self._lb + b, np.ascontiguousarray(lw), self._fast)
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

    # -- evaluation and reporting ------------------------------------------------------------------
    def heldout_error(self, X: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Normalised RMSE per output (RMSE / standard deviation of the held-out targets) on data not
        used for fitting."""
        pred = self.predict(X).reshape(len(X), -1)
        Y = np.asarray(y, dtype=np.float64).reshape(len(X), -1)
        rmse = np.sqrt(np.mean((pred - Y) ** 2, axis=0))
        return rmse / _safe_scale(Y.std(axis=0))

    def record_heldout_error(self, X: np.ndarray, y: np.ndarray) -> np.ndarray:
        """:meth:`heldout_error`, kept in ``heldout_nrmse_`` for :meth:`summary` and saved files."""
        self.heldout_nrmse_ = self.heldout_error(X, y)
        return self.heldout_nrmse_

    def summary(self) -> dict[str, Any]:
        """Compact description: size, mode, hyperparameters (length scales in input units; σf and
        noise in standardised output units), held-out error if computed."""
        check_is_fitted(self, "mode_")
        names = list(self.input_names) if self.input_names is not None else [f"x{i}" for i in range(self.n_features_in_)]
        out = {
            "n": int(self.n_train_),
            "mode": self.mode_,
            "var_mode": self.var_mode_,
            "n_inducing": 0 if self.inducing_ is None else int(self.inducing_.shape[0]),
            "length_scale": {k: float(v) for k, v in zip(names, self.length_scale_ * self.x_scale_)},
            "sigma_f": self.sigma_f_,
            "noise": self.noise_,
            "n_hyper": int(self.n_hyper_used_),
            "log_marginal_likelihood": self.log_marginal_likelihood_,
            "heldout_nrmse": None if self.heldout_nrmse_ is None else [float(v) for v in self.heldout_nrmse_],
        }
        if self.output_names is not None:
            out["outputs"] = list(self.output_names)
        return out

    # -- persistence ------------------------------------------------------------------------------
    def save(self, path: str | os.PathLike) -> None:
        """Write the fitted law as arrays + JSON metadata in one ``.npz`` (atomic, no pickle)."""
        save_npz(path, *self.to_arrays(), KIND, VERSION)

    def to_arrays(self) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
        """The fitted law as named arrays and JSON metadata (what :meth:`save` writes; models that
        embed a GP store these under a prefix of their own; :mod:`.gp_store`)."""
        check_is_fitted(self, "mode_")
        return law_to_arrays(self)

    @classmethod
    def load(cls, path: str | os.PathLike) -> GPLaw:
        """Read a law written by :meth:`save`; any inconsistency raises :class:`InvalidInput`
        naming the file and the array or metadata entry."""
        arrays, meta = load_npz(path, KIND, VERSION)
        return cls.from_arrays(arrays, meta, str(path))

    @classmethod
    def from_arrays(cls, arrays: dict[str, np.ndarray], meta: dict[str, Any], file: str, prefix: str = "") -> GPLaw:
        """Inverse of :meth:`to_arrays`; problems name ``file`` and the entry (under ``prefix``)."""
        law = law_from_arrays(cls, arrays, meta, file, prefix)
        law._prepare()
        return law


def _augment(Z: np.ndarray, sf2: float) -> np.ndarray:
    """``[z, log σf² − ½|z|², 1]`` per row, column-major: the gemv then runs as d + 2 contiguous
    axpys (half the time of the row-major layout for n = 2,000)."""
    c = np.log(sf2) - 0.5 * np.einsum("ij,ij->i", Z, Z)
    return np.asfortranarray(np.column_stack([Z, c, np.ones(Z.shape[0])]))


def _safe_scale(s: np.ndarray) -> np.ndarray:
    s = np.asarray(s, dtype=np.float64).copy()
    s[~(s > 1e-12)] = 1.0
    return s
