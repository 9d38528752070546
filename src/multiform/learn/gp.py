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

The class itself is the estimator; its prediction paths (:mod:`.gp_predict`), the hyperparameter
search (:mod:`.gp_hyper`), the posterior (:mod:`.gp_posterior`) and the file format
(:mod:`.gp_store`) are modules of their own.
"""

from __future__ import annotations

import os
import time
from collections.abc import Sequence
from typing import Any

import numpy as np
from joblib import Parallel, delayed
from sklearn.base import BaseEstimator, RegressorMixin
from sklearn.utils.validation import check_is_fitted, check_X_y
from threadpoolctl import threadpool_limits

from ..io import load_npz, save_npz
from .gp_hyper import neg_log_marginal_likelihood, optimise_hyperparameters  # noqa: F401  (also read from here)
from .gp_posterior import FITTED_ARRAYS, posterior_modes, solve_posterior
from .gp_predict import FAST_EXP_PROBE_TOL, FAST_EXP_TOL, GPPrediction  # noqa: F401  (also read from here)
from .gp_store import KIND, VERSION, law_from_arrays, law_to_arrays  # noqa: F401  (also read from here)
from .sparse_gp import SPARSE_METHODS

MEANS = ("constant", "linear")


class GPLaw(GPPrediction, BaseEstimator, RegressorMixin):
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
    n_jobs: processes that optimise the ``hyper_subsets`` subsets side by side (joblib; None: one,
        unless a :func:`joblib.parallel_config` context says more, as in scikit-learn). Each
        optimisation runs with ``n_threads`` threads wherever it runs, so the law is the same bit for
        bit with any ``n_jobs`` (``benchmarks/bench_gp.py``: 1.5× faster on 2 cores at n = 5,000).
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
                 hyper_subsets: int = 1, n_jobs: int | None = None):
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
        self.n_jobs = n_jobs

    # -- fitting ------------------------------------------------------------------------------
    def fit(self, X: np.ndarray, y: np.ndarray) -> GPLaw:
        """Train the hyperparameters (unless the constructor fixed ``theta``) and solve the posterior
        on all of ``X`` (n, d), ``y`` (n,) or (n, p)."""
        t0 = time.perf_counter()
        X, y = check_X_y(X, y, multi_output=True, y_numeric=True, dtype=np.float64)
        self._check_params(X.shape[1], 1 if y.ndim == 1 else y.shape[1])
        with threadpool_limits(limits=self.n_threads):
            Xs, Ys = self._standardise(X, y)
        tasks = self._hyper_tasks(Xs, Ys)
        fits = Parallel(n_jobs=self.n_jobs if len(tasks) > 1 else 1)(tasks) if tasks else []
        with threadpool_limits(limits=self.n_threads):
            return self._finish(X, Xs, Ys, fits, t0)

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

    def _hyper_tasks(self, Xs: np.ndarray, Ys: np.ndarray) -> list[Any]:
        """The joblib tasks that optimise the hyperparameters, one per subset (none with ``theta``)."""
        if self.theta is not None:
            return []
        return [delayed(_optimise)(self.n_threads, Xs, Ys,
                                   np.random.default_rng(self.random_state if k == 0 else [self.random_state, k]),
                                   self.ard, self.n_hyper, self.n_restarts, self.max_iter)
                for k in range(self.hyper_subsets)]

    def _finish(self, X: np.ndarray, Xs: np.ndarray, Ys: np.ndarray, fits: list[tuple[np.ndarray, float]],
                t0: float) -> GPLaw:
        """The hyperparameters (the median of the subsets' ``fits``, or the fixed ``theta``), then the
        posterior."""
        n, d = X.shape
        if self.theta is None:
            theta = np.median([t for t, _ in fits], axis=0)
            lml = float(np.median([v for _, v in fits]))
        else:
            theta = np.asarray(self.theta, dtype=np.float64).reshape(-1)
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

    @property
    def theta_(self) -> np.ndarray:
        """The fitted hyperparameters as ``theta`` takes them (``[log l…, log σf, log σn]``, standardised
        units): ``set_params(theta=law.theta_)`` fits another posterior with this law's kernel."""
        check_is_fitted(self, "mode_")
        ell = self.length_scale_ if self.ard else self.length_scale_[:1]
        return np.log(np.concatenate([ell, [self.sigma_f_, self.noise_]]))

    def posterior_noise(self) -> float:
        """The noise standard deviation (standardised units) the posterior is solved with: ``noise_``, or
        with ``subset_noise`` ``noise_ · √(n / n_hyper)``.

        Why: samples of time series recorded at 1 kHz are far from independent. The likelihood is
        maximised on ``n_hyper`` points spread over the demonstrations (≈ 0.1 s apart); a posterior on
        all n samples with the same noise trusts each demonstration's idiosyncrasies n / n_hyper times
        over, and a sparse posterior then swings with its inducing points (a pendulum swing-up from 10
        demonstrations, n = 98,020: held-out NRMSE 0.32 with 300 inducing points, 0.51–0.53 with 1,000
        or 2,000; with the scaled noise 0.32–0.33 for all three; docs/measurements-log.md).
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


def _optimise(n_threads: int | None, *args: Any) -> tuple[np.ndarray, float]:
    """:func:`~.gp_hyper.optimise_hyperparameters` with ``n_threads`` BLAS threads, in whichever process
    joblib runs it: a worker's thread count is then the parent's, and so is every rounding."""
    with threadpool_limits(limits=n_threads):     # None: as they are
        return optimise_hyperparameters(*args)


def _safe_scale(s: np.ndarray) -> np.ndarray:
    s = np.asarray(s, dtype=np.float64).copy()
    s[~(s > 1e-12)] = 1.0
    return s
