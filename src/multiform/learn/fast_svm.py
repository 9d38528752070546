"""An SVM's decision function as plain arrays, fast enough for the 1 kHz control path.

A fitted scikit-learn ``SVC`` (binary) or ``OneClassSVM`` — optionally behind a ``StandardScaler``
— is compiled to its support vectors, dual coefficients, intercept and kernel parameters::

    f(x) = sum_i a_i K(sv_i, (x - mean) / scale) + b

with K one of ``rbf`` exp(-g|u-v|²), ``poly`` (g u·v + c0)^deg, ``linear`` u·v and ``sigmoid``
tanh(g u·v + c0), exactly as libsvm defines them. For a binary SVC, f > 0 means ``classes_[1]``;
for a OneClassSVM, f > 0 means inside. Why our own code: scikit-learn's ``decision_function`` costs
≈ 120 µs per single sample (input validation); the single-sample path here is one compiled loop
(:mod:`.compiled`, about 1.5 µs for 87 support vectors, ``benchmarks/bench_condition.py``), rows go
through numpy; and a saved model is arrays + JSON, never a pickle.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from typing import Any

import numpy as np

from ..errors import InvalidInput
from ..io import load_npz, save_npz
from .compiled import KERNEL_CODES, svm_decision_one

KERNELS = ("rbf", "poly", "linear", "sigmoid")
KIND = "fast_svm"
VERSION = 1
_CHUNK = 2048


class FastDecision:
    """The decision function of a fitted kernel SVM; see the module docstring for the formula.

    ``decision(X)`` is vectorised over rows; ``decision_one(x)`` is the single-sample path of the
    control loop (preallocated buffers, no validation: ``x`` must be a 1-D float array of length
    ``n_features``).
    """

    def __init__(self, support_vectors: np.ndarray, dual_coef: np.ndarray, intercept: float,
                 kernel: str = "rbf", gamma: float = 1.0, coef0: float = 0.0, degree: int = 3,
                 mean: np.ndarray | None = None, scale: np.ndarray | None = None):
        sv = np.ascontiguousarray(support_vectors, dtype=np.float64)
        if sv.ndim != 2:
            raise ValueError(f"support_vectors must be 2-D, got shape {sv.shape}")
        coef = np.ascontiguousarray(dual_coef, dtype=np.float64).reshape(-1)
        if coef.shape[0] != sv.shape[0]:
            raise ValueError(f"{coef.shape[0]} dual coefficients for {sv.shape[0]} support vectors")
        if kernel not in KERNELS:
            raise ValueError(f"unknown kernel {kernel!r}; known: {', '.join(KERNELS)}")
        d = sv.shape[1]
        self.support_vectors = sv
        self.dual_coef = coef
        self.intercept = float(intercept)
        self.kernel = kernel
        self.gamma = float(gamma)
        self.coef0 = float(coef0)
        self.degree = int(degree)
        self.mean = np.zeros(d) if mean is None else np.ascontiguousarray(mean, dtype=np.float64).reshape(-1)
        self.scale = np.ones(d) if scale is None else np.ascontiguousarray(scale, dtype=np.float64).reshape(-1)
        if self.mean.shape != (d,) or self.scale.shape != (d,):
            raise ValueError(f"mean/scale must have {d} entries")
        if np.any(self.scale == 0):
            raise ValueError("scale has a zero entry")
        self._prepare()

    # -- construction ---------------------------------------------------------------------------
    @classmethod
    def from_sklearn(cls, estimator: Any, scaler: Any = None) -> FastDecision:
        """Compile a fitted ``SVC`` (two classes), ``NuSVC``, ``OneClassSVM`` or a ``Pipeline`` of
        an optional ``StandardScaler`` followed by one of those."""
        steps = getattr(estimator, "steps", None)
        if steps is not None:
            models = [s for _, s in steps if s is not None and s != "passthrough"]
            if len(models) == 2 and scaler is None:
                scaler, estimator = models
            elif len(models) == 1:
                estimator = models[0]
            else:
                raise ValueError("a pipeline must be [StandardScaler,] SVM")
        if not hasattr(estimator, "dual_coef_"):
            raise ValueError(f"{type(estimator).__name__} is not a fitted kernel SVM")
        if estimator.dual_coef_.shape[0] != 1:
            raise ValueError("only binary SVC or OneClassSVM can be compiled (one row of dual coefficients)")
        kernel = estimator.kernel
        if kernel not in KERNELS:
            raise ValueError(f"kernel {kernel!r} cannot be compiled; known: {', '.join(KERNELS)}")
        mean = scale = None
        if scaler is not None:
            n = estimator.support_vectors_.shape[1]
            mean = getattr(scaler, "mean_", None)
            scale = getattr(scaler, "scale_", None)
            mean = np.zeros(n) if mean is None else mean
            scale = np.ones(n) if scale is None else scale
        return cls(estimator.support_vectors_, estimator.dual_coef_[0], float(estimator.intercept_[0]),
                   kernel=kernel, gamma=float(getattr(estimator, "_gamma", 1.0)),
                   coef0=float(estimator.coef0), degree=int(estimator.degree), mean=mean, scale=scale)

    def _prepare(self) -> None:
        sv = self.support_vectors
        self._inv_scale = 1.0 / self.scale
        self._sv_sq = np.einsum("ij,ij->i", sv, sv)
        self._w = self.dual_coef @ sv              # linear kernel collapses to one weight vector
        self._kernel_code = KERNEL_CODES[self.kernel]

    # -- evaluation -----------------------------------------------------------------------------
    @property
    def n_features(self) -> int:
        return int(self.support_vectors.shape[1])

    @property
    def n_support(self) -> int:
        return int(self.support_vectors.shape[0])

    def decision_one(self, x: np.ndarray) -> float:
        """f(x) for one sample (1-D float64 array); the control-rate path (compiled, see
        :mod:`multiform.learn.compiled`)."""
        return svm_decision_one(x, self.mean, self._inv_scale, self.support_vectors, self.dual_coef, self._w,
                                self.intercept, self._kernel_code, self.gamma, self.coef0, self.degree)

    def decision(self, X: np.ndarray) -> np.ndarray | float:
        """f for every row of ``X`` (n, d); a 1-D ``x`` gives a float."""
        X = np.asarray(X, dtype=np.float64)
        if X.ndim == 1:
            if X.shape[0] != self.n_features:
                raise ValueError(f"expected {self.n_features} features, got {X.shape[0]}")
            return self.decision_one(X)
        if X.ndim != 2 or X.shape[1] != self.n_features:
            raise ValueError(f"expected shape (n, {self.n_features}), got {X.shape}")
        out = np.empty(X.shape[0])
        for s in range(0, X.shape[0], _CHUNK):
            out[s:s + _CHUNK] = self._decision_rows(X[s:s + _CHUNK])
        return out

    def _decision_rows(self, X: np.ndarray) -> np.ndarray:
        U = (X - self.mean) * self._inv_scale
        if self.kernel == "linear":
            return U @ self._w + self.intercept
        G = U @ self.support_vectors.T
        if self.kernel == "rbf":
            d2 = np.einsum("ij,ij->i", U, U)[:, None] + self._sv_sq[None, :] - 2.0 * G
            np.maximum(d2, 0.0, out=d2)
            K = np.exp(-self.gamma * d2)
        elif self.kernel == "poly":
            K = (self.gamma * G + self.coef0) ** self.degree
        else:
            K = np.tanh(self.gamma * G + self.coef0)
        return K @ self.dual_coef + self.intercept

    # -- persistence ----------------------------------------------------------------------------
    def to_arrays(self, prefix: str = "") -> tuple[dict[str, np.ndarray], dict[str, Any]]:
        """Arrays and JSON metadata that :meth:`from_arrays` reads back (``prefix`` namespaces the
        keys so several decision functions share one file)."""
        arrays = {f"{prefix}support_vectors": self.support_vectors, f"{prefix}dual_coef": self.dual_coef,
                  f"{prefix}mean": self.mean, f"{prefix}scale": self.scale}
        meta = {"kernel": self.kernel, "gamma": self.gamma, "coef0": self.coef0, "degree": self.degree,
                "intercept": self.intercept, "n_support": self.n_support, "n_features": self.n_features}
        return arrays, meta

    @classmethod
    def from_arrays(cls, arrays: Mapping[str, np.ndarray], meta: Mapping[str, Any], file: str = "",
                    prefix: str = "") -> FastDecision:
        """Rebuild from :meth:`to_arrays` output, raising :class:`InvalidInput` on any inconsistency."""
        def bad(element: str, msg: str) -> InvalidInput:
            return InvalidInput(msg, file=file, element=element)

        keys = ["support_vectors", "dual_coef", "mean", "scale"]
        for k in keys:
            if prefix + k not in arrays:
                raise bad(prefix + k, "array is missing")
        sv, coef, mean, scale = (np.asarray(arrays[prefix + k]) for k in keys)
        for name, a in zip(keys, (sv, coef, mean, scale)):
            if a.dtype.kind not in "fiu":
                raise bad(prefix + name, f"has dtype {a.dtype}, expected numbers")
            if not np.all(np.isfinite(a)):
                raise bad(prefix + name, "has non-finite values")
        if sv.ndim != 2:
            raise bad(prefix + "support_vectors", f"has shape {sv.shape}, expected (n, d)")
        n, d = sv.shape
        if coef.shape != (n,):
            raise bad(prefix + "dual_coef", f"has shape {coef.shape}, expected ({n},) for {n} support vectors")
        for name, a in (("mean", mean), ("scale", scale)):
            if a.shape != (d,):
                raise bad(prefix + name, f"has shape {a.shape}, expected ({d},)")
        if np.any(scale == 0):
            raise bad(prefix + "scale", "has a zero entry")
        kernel = meta.get("kernel")
        if kernel not in KERNELS:
            raise bad(f"{prefix}kernel", f"unknown kernel {kernel!r}")
        try:
            params = {k: float(meta[k]) for k in ("gamma", "coef0", "intercept")}
            degree = int(meta["degree"])
        except (KeyError, TypeError, ValueError) as exc:
            raise bad(f"{prefix}meta", f"kernel parameters missing or not numbers ({exc})") from None
        if not all(np.isfinite(v) for v in params.values()):
            raise bad(f"{prefix}meta", "kernel parameters are not finite")
        return cls(sv, coef, params["intercept"], kernel=kernel, gamma=params["gamma"], coef0=params["coef0"],
                   degree=degree, mean=mean, scale=scale)

    def save(self, path: str | os.PathLike) -> None:
        arrays, meta = self.to_arrays()
        save_npz(path, arrays, meta, KIND, VERSION)

    @classmethod
    def load(cls, path: str | os.PathLike) -> FastDecision:
        arrays, meta = load_npz(path, KIND, VERSION)
        return cls.from_arrays(arrays, meta, file=str(path))
