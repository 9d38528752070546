"""A binary SVM classifier that picks its kernel from a pool by stratified cross-validation.

The paper's judges: "a pool of different learning kernels … from which the learning agent selects
to achieve the best clustering result". Every kernel of the pool (RBF, polynomial, linear, sigmoid)
is tried with a small grid over C and its own parameters (``DEFAULT_GRIDS``: 12 + 6 + 4 + 6
candidates), on standardised features, with the same stratified folds — and, if ``subsets`` name
column subsets of the features, on each of them. Each kernel's best cross-validated score is kept
in ``cv_scores_``; the best (subset, kernel, parameters) overall is refitted on all samples. Ties go
to the steadier candidate (smaller std over folds), then the smaller subset, then the pool's order. Scoring is balanced accuracy by default
(mentor labels are rarely balanced), and ``class_weight="balanced"`` for the same reason.

Scores in [0, 1] come from Platt scaling (own code, the Lin–Lin–Weng 2007 algorithm with
prior-smoothed targets) fitted on the *cross-validated* decision values of the chosen candidate —
what libsvm's ``probability=True`` does internally, but deterministic and with the folds we chose.
``predict`` is ``score >= 0.5``, so a verdict and its score never disagree.

Small label sets are normal here (a few demonstrations), so the degenerate cases are handled:

* one class only — no SVM; the score is Laplace's rule of succession, (n + 1) / (n + 2) for the
  seen class (``best_kernel_ == "constant"``);
* a class with a single sample — no cross-validation is possible; the default candidate (RBF,
  C = 1, γ = 1 / n_features) is fitted on all samples and Platt-scaled on its in-sample decision
  values (``calibration_ == "in-sample"``, ``cv_scores_`` all NaN);
* fewer samples of a class than folds — the number of folds drops to that count (at least 2).
"""

from __future__ import annotations

import warnings
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from sklearn.base import BaseEstimator, ClassifierMixin
from sklearn.metrics import accuracy_score, balanced_accuracy_score
from sklearn.model_selection import ParameterGrid, StratifiedGroupKFold, StratifiedKFold
from sklearn.preprocessing import StandardScaler
from sklearn.svm import SVC

from ..errors import InvalidInput
from .fast_svm import FastDecision

# gamma entries are multiples of 1 / n_features (scikit-learn's "scale" on standardised features)
DEFAULT_GRIDS: dict[str, dict[str, list[Any]]] = {
    "rbf": {"C": [0.1, 1.0, 10.0, 100.0], "gamma": [0.1, 1.0, 10.0]},
    "poly": {"C": [0.1, 1.0, 10.0], "degree": [2, 3], "gamma": [1.0], "coef0": [1.0]},
    "linear": {"C": [0.01, 0.1, 1.0, 10.0]},
    "sigmoid": {"C": [0.1, 1.0, 10.0], "gamma": [0.1, 1.0], "coef0": [-1.0]},
}
DEFAULT_CANDIDATE = ("rbf", {"C": 1.0, "gamma": 1.0})
SCORERS = {"balanced_accuracy": balanced_accuracy_score, "accuracy": accuracy_score}


def platt_fit(f: np.ndarray, y: np.ndarray, max_iter: int = 100) -> tuple[float, float]:
    """Fit P(y=1|f) = 1 / (1 + exp(A f + B)) by Newton's method with backtracking.

    Lin, Lin & Weng (2007), "A note on Platt's probabilistic outputs for support vector machines":
    targets (N+ + 1)/(N+ + 2) and 1/(N- + 2) keep A finite on separable data.
    """
    f = np.asarray(f, dtype=np.float64)
    y = np.asarray(y, dtype=bool)
    n_pos, n_neg = int(y.sum()), int((~y).sum())
    t = np.where(y, (n_pos + 1.0) / (n_pos + 2.0), 1.0 / (n_neg + 2.0))
    A, B = 0.0, float(np.log((n_neg + 1.0) / (n_pos + 1.0)))
    sigma, eps = 1e-12, 1e-5

    def objective(a: float, b: float) -> float:
        z = a * f + b
        return float(np.sum(np.where(z >= 0, t * z + np.log1p(np.exp(-z)), (t - 1) * z + np.log1p(np.exp(z)))))

    fval = objective(A, B)
    for _ in range(max_iter):
        z = A * f + B
        p = np.where(z >= 0, np.exp(-z) / (1 + np.exp(-z)), 1 / (1 + np.exp(z)))
        q = 1 - p
        d2 = p * q
        h11 = sigma + float(np.sum(f * f * d2))
        h22 = sigma + float(np.sum(d2))
        h21 = float(np.sum(f * d2))
        d1 = t - p
        g1, g2 = float(np.sum(f * d1)), float(np.sum(d1))
        if abs(g1) < eps and abs(g2) < eps:
            break
        det = h11 * h22 - h21 * h21
        dA = -(h22 * g1 - h21 * g2) / det
        dB = -(-h21 * g1 + h11 * g2) / det
        gd = g1 * dA + g2 * dB
        step = 1.0
        while step >= 1e-10:
            nA, nB = A + step * dA, B + step * dB
            nf = objective(nA, nB)
            if nf < fval + 1e-4 * step * gd:
                A, B, fval = nA, nB, nf
                break
            step /= 2
        else:
            break
    return float(A), float(B)


def platt_score(f: np.ndarray | float, A: float, B: float) -> np.ndarray | float:
    """1 / (1 + exp(A f + B)), computed without overflow."""
    z = np.clip(A * np.asarray(f, dtype=np.float64) + B, -700, 700)
    out = 1.0 / (1.0 + np.exp(z))
    return float(out) if np.ndim(out) == 0 else out


def _svc(kernel: str, params: Mapping[str, Any], n_features: int, class_weight: Any) -> SVC:
    p = dict(params)
    if "gamma" in p:
        p["gamma"] = float(p["gamma"]) / max(n_features, 1)
    return SVC(kernel=kernel, class_weight=class_weight, **p)


class KernelPoolClassifier(ClassifierMixin, BaseEstimator):
    """Binary SVM whose kernel, hyperparameters and feature subset are chosen by stratified CV.

    ``y`` is boolean (True = success). ``subsets`` optionally names column subsets of ``X`` to try
    (e.g. a judge's "end state only" and "all statistics"); None tries all columns only.
    ``cv_repeats`` repeats the cross-validation on reshuffled folds (a steadier choice on few labels,
    at that many times the cost); ``fit(X, y, groups)`` keeps rows of one group in one fold.
    After :meth:`fit`: ``best_kernel_``, ``best_params_`` (gamma as the multiple of 1 / n_features),
    ``best_subset_`` and ``columns_`` (the columns used), ``best_score_``, ``cv_scores_`` (per kernel:
    best mean score over its grid and the subsets, its std over folds, its params and subset, number
    of candidates), ``subset_scores_`` (best score per subset), ``n_splits_``, ``platt_`` (A, B),
    ``calibration_`` and ``decision_`` (the refitted model as a :class:`FastDecision`, reading
    ``columns_``).
    """

    def __init__(self, kernels: Sequence[str] = ("rbf", "poly", "linear", "sigmoid"),
                 grids: Mapping[str, Mapping[str, Sequence[Any]]] | None = None, cv: int = 5,
                 scoring: str = "balanced_accuracy", class_weight: Any = "balanced",
                 subsets: Mapping[str, Sequence[int]] | None = None, cv_repeats: int = 1, random_state: int = 0):
        self.kernels = kernels
        self.grids = grids
        self.cv = cv
        self.cv_repeats = cv_repeats
        self.scoring = scoring
        self.class_weight = class_weight
        self.subsets = subsets
        self.random_state = random_state

    # -- fitting ------------------------------------------------------------------------------------
    def fit(self, X: np.ndarray, y: np.ndarray, groups: Sequence[Any] | None = None) -> KernelPoolClassifier:
        """Search the pool by cross-validation and refit the best on all rows. Rows sharing a group
        (e.g. a segment and its mirror image) always fall in the same fold."""
        X = np.asarray(X, dtype=np.float64)
        y = np.asarray(y).astype(bool)
        subsets = self._check_fit(X, y)
        self.classes_ = np.array([False, True])
        self.n_features_in_ = X.shape[1]
        self.n_samples_ = len(y)
        self.class_counts_ = {"failure": int((~y).sum()), "success": int(y.sum())}
        self.cv_scores_: dict[str, dict[str, Any]] = {}
        self.subset_scores_: dict[str, float] = {}
        self.decision_: FastDecision | None = None
        self.platt_ = (0.0, 0.0)
        self.constant_ = None
        self.constant_score_ = float("nan")
        min_count = min(self.class_counts_.values())
        nan_scores = {k: {"score": float("nan"), "std": float("nan"), "params": {}, "subset": "", "candidates": 0}
                      for k in self.kernels}

        if min_count == 0:
            return self._fit_constant(y, nan_scores)

        if min_count < 2:
            kernel, params = DEFAULT_CANDIDATE
            subset = max(subsets, key=lambda k: len(subsets[k]))
            self.best_kernel_, self.best_params_, self.best_score_ = kernel, dict(params), float("nan")
            self.best_subset_, self.columns_ = subset, subsets[subset]
            self.n_splits_ = 0
            self.calibration_ = "in-sample"
            self.cv_scores_ = nan_scores
            self.decision_ = self._fit_one(kernel, params, X[:, self.columns_], y)
            f = np.asarray(self.decision_.decision(X[:, self.columns_]))
        else:
            f = self._search(X, y, min_count, subsets, groups)
            self.decision_ = self._fit_one(self.best_kernel_, self.best_params_, X[:, self.columns_], y)
            self.calibration_ = "cross-validated"
            inside = np.asarray(self.decision_.decision(X[:, self.columns_]))
            if SCORERS[self.scoring](y, inside > 0) < self.best_score_ - 0.1:
                # The refit on all samples disagrees with its folds (its decision values live on
                # another scale); calibrating on the folds' values would misplace the 0.5 threshold.
                f = inside
                self.calibration_ = "in-sample (the refit disagreed with the folds)"
        self.platt_ = platt_fit(f, y)
        return self

    def _check_fit(self, X: np.ndarray, y: np.ndarray) -> dict[str, list[int]]:
        """Raise ``ValueError`` on bad data or parameters; returns the column subsets to search."""
        if X.ndim != 2 or len(X) != len(y):
            raise ValueError(f"X must be (n, d) with one label per row; got X {X.shape}, y {y.shape}")
        if len(X) == 0:
            raise ValueError("no samples to fit")
        if not np.all(np.isfinite(X)):
            raise ValueError("X has non-finite values")
        if self.scoring not in SCORERS:
            raise ValueError(f"unknown scoring {self.scoring!r}; known: {', '.join(SCORERS)}")
        unknown = [k for k in self.kernels if k not in DEFAULT_GRIDS]
        if unknown:
            raise ValueError(f"unknown kernel(s) {unknown}; known: {', '.join(DEFAULT_GRIDS)}")
        subsets = {k: [int(c) for c in v] for k, v in (self.subsets or {"all": range(X.shape[1])}).items()}
        for name, cols in subsets.items():
            if not cols or min(cols) < 0 or max(cols) >= X.shape[1]:
                raise ValueError(f"subset {name!r} names columns outside 0..{X.shape[1] - 1}")
        return subsets

    def _fit_constant(self, y: np.ndarray, nan_scores: dict[str, dict[str, Any]]) -> KernelPoolClassifier:
        """One class only: the judge answers it always, with Laplace's rule for its probability."""
        seen = bool(y[0])
        self.constant_ = seen
        self.best_kernel_, self.best_params_, self.best_score_ = "constant", {}, float("nan")
        self.best_subset_, self.columns_ = "", []
        self.n_splits_ = 0
        self.calibration_ = "laplace"
        self.cv_scores_ = nan_scores
        p = (len(y) + 1.0) / (len(y) + 2.0)
        self.constant_score_ = p if seen else 1.0 - p
        return self

    def _fit_one(self, kernel: str, params: Mapping[str, Any], X: np.ndarray, y: np.ndarray) -> FastDecision:
        scaler = StandardScaler().fit(X)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            svc = _svc(kernel, params, X.shape[1], self.class_weight).fit(scaler.transform(X), y)
        return FastDecision.from_sklearn(svc, scaler)

    def _search(self, X: np.ndarray, y: np.ndarray, min_count: int, subsets: Mapping[str, list[int]],
                groups: Sequence[Any] | None = None) -> np.ndarray:
        """Every (subset, kernel, params) on the same folds; sets the best_* attributes and returns
        the winner's out-of-fold decision values (for Platt scaling)."""
        self.n_splits_ = int(max(2, min(self.cv, min_count)))
        repeats = max(1, int(self.cv_repeats))
        if groups is None:
            folds = [f for r in range(repeats) for f in StratifiedKFold(
                self.n_splits_, shuffle=True, random_state=self.random_state + r).split(X, y)]
        else:
            if len(groups) != len(y):
                raise ValueError(f"{len(groups)} groups for {len(y)} rows")
            codes = np.unique(np.asarray([str(g) for g in groups]), return_inverse=True)[1]
            self.n_splits_ = int(max(2, min(self.n_splits_, len(np.unique(codes[~y])), len(np.unique(codes[y])))))
            folds = [f for r in range(repeats) for f in StratifiedGroupKFold(
                self.n_splits_, shuffle=True, random_state=self.random_state + r).split(X, y, codes)]
        scorer = SCORERS[self.scoring]
        grids = {**DEFAULT_GRIDS, **(self.grids or {})}
        cands = {k: list(ParameterGrid(dict(grids[k]))) for k in self.kernels}
        best_by_kernel: dict[str, tuple[tuple[float, ...], dict[str, Any], str, np.ndarray, float]] = {}
        for sname, cols in subsets.items():
            scaled = []
            for tr, te in folds:
                sc = StandardScaler().fit(X[tr][:, cols])
                scaled.append((sc.transform(X[tr][:, cols]), y[tr], sc.transform(X[te][:, cols]), te))
            sbest = -np.inf
            for rank, kernel in enumerate(self.kernels):
                for params in cands[kernel]:
                    scores, oof = [], np.zeros(len(y))
                    for Xtr, ytr, Xte, te in scaled:
                        try:
                            with warnings.catch_warnings():
                                warnings.simplefilter("ignore")
                                m = _svc(kernel, params, len(cols), self.class_weight).fit(Xtr, ytr)
                        except ValueError:
                            scores.append(0.0)
                            continue
                        f = FastDecision.from_sklearn(m).decision(Xte)
                        oof[te] += f / repeats
                        scores.append(scorer(y[te], f > 0))
                    mean, std = float(np.mean(scores)), float(np.std(scores))
                    sbest = max(sbest, mean)
                    # ties: steadier, fewer features, then larger C (with every multiplier at its
                    # bound a tiny-C refit can put libsvm's intercept outside the data)
                    key = (mean, -std, -len(cols), float(params.get("C", 1.0)), -rank)
                    if kernel not in best_by_kernel or key > best_by_kernel[kernel][0]:
                        best_by_kernel[kernel] = (key, dict(params), sname, oof, std)
            self.subset_scores_[sname] = sbest
        for kernel in self.kernels:
            key, params, sname, _, std = best_by_kernel[kernel]
            self.cv_scores_[kernel] = {"score": key[0], "std": std, "params": params, "subset": sname,
                                       "candidates": len(cands[kernel]) * len(subsets)}
        winner = max(self.kernels, key=lambda k: best_by_kernel[k][0])
        key, params, sname, oof, _ = best_by_kernel[winner]
        self.best_kernel_, self.best_params_, self.best_score_ = winner, params, key[0]
        self.best_subset_, self.columns_ = sname, list(subsets[sname])
        return oof

    # -- prediction ---------------------------------------------------------------------------------
    def decision_function(self, X: np.ndarray) -> np.ndarray:
        """The SVM's decision values (positive = success); for a constant model ±1."""
        X = self._check(X)
        if self.decision_ is None:
            return np.full(len(X), 1.0 if self.constant_ else -1.0)
        return np.asarray(self.decision_.decision(X[:, self.columns_]))

    def score_samples(self, X: np.ndarray) -> np.ndarray:
        """Calibrated P(success) per row, in [0, 1]."""
        X = self._check(X)
        if self.decision_ is None:
            return np.full(len(X), self.constant_score_)
        return np.asarray(platt_score(self.decision_.decision(X[:, self.columns_]), *self.platt_)).reshape(-1)

    def predict_proba(self, X: np.ndarray) -> np.ndarray:
        p = self.score_samples(X)
        return np.stack([1.0 - p, p], axis=1)

    def predict(self, X: np.ndarray) -> np.ndarray:
        return self.score_samples(X) >= 0.5

    def _check(self, X: np.ndarray) -> np.ndarray:
        if not hasattr(self, "classes_"):
            raise RuntimeError("fit the classifier first")
        X = np.asarray(X, dtype=np.float64)
        if X.ndim == 1:
            X = X[None, :]
        if X.shape[1] != self.n_features_in_:
            raise ValueError(f"expected {self.n_features_in_} features, got {X.shape[1]}")
        return X

    def summary(self) -> str:
        """One line per kernel: CV score, params and feature subset, the chosen one marked."""
        lines = [f"{self.n_samples_} samples ({self.class_counts_['success']} success, "
                 f"{self.class_counts_['failure']} failure), {self.n_splits_}-fold CV, {self.scoring}"]
        if len(self.subset_scores_) > 1:
            lines.append("  feature subsets: " + ", ".join(f"{k} {v:.3f}" for k, v in self.subset_scores_.items()))
        for k, r in self.cv_scores_.items():
            mark = "*" if k == self.best_kernel_ else " "
            lines.append(f" {mark} {k:8s} {r['score']:.3f} ± {r['std']:.3f}  {r['params']}"
                         + (f" on {r['subset']}" if r.get("subset") else ""))
        if self.calibration_ != "cross-validated":
            lines.append(f"   chosen: {self.best_kernel_} {self.best_params_} (calibration: {self.calibration_})")
        return "\n".join(lines)

    # -- persistence --------------------------------------------------------------------------------
    def to_arrays(self, prefix: str = "") -> tuple[dict[str, np.ndarray], dict[str, Any]]:
        meta = {"best_kernel": self.best_kernel_, "best_params": self.best_params_,
                "best_score": _json_float(self.best_score_), "best_subset": self.best_subset_,
                "columns": list(self.columns_), "subset_scores": {k: _json_float(v) for k, v in self.subset_scores_.items()},
                "n_splits": self.n_splits_,
                "cv_scores": {k: {**v, "score": _json_float(v["score"]), "std": _json_float(v["std"])}
                              for k, v in self.cv_scores_.items()},
                "platt": list(self.platt_), "calibration": self.calibration_, "n_features": self.n_features_in_,
                "n_samples": self.n_samples_, "class_counts": self.class_counts_,
                "constant": self.constant_, "constant_score": _json_float(self.constant_score_),
                "scoring": self.scoring, "kernels": list(self.kernels)}
        arrays: dict[str, np.ndarray] = {}
        if self.decision_ is not None:
            arrays, meta["decision"] = self.decision_.to_arrays(prefix)
        return arrays, meta

    @classmethod
    def from_arrays(cls, arrays: Mapping[str, np.ndarray], meta: Mapping[str, Any], file: str = "",
                    prefix: str = "") -> KernelPoolClassifier:
        try:
            m = cls(kernels=tuple(meta["kernels"]), scoring=str(meta["scoring"]))
            m.classes_ = np.array([False, True])
            m.n_features_in_ = int(meta["n_features"])
            m.n_samples_ = int(meta["n_samples"])
            m.class_counts_ = {k: int(v) for k, v in meta["class_counts"].items()}
            m.best_kernel_ = str(meta["best_kernel"])
            m.best_params_ = dict(meta["best_params"])
            m.best_score_ = _from_json_float(meta["best_score"])
            m.best_subset_ = str(meta["best_subset"])
            m.columns_ = [int(c) for c in meta["columns"]]
            m.subset_scores_ = {str(k): _from_json_float(v) for k, v in meta["subset_scores"].items()}
            m.n_splits_ = int(meta["n_splits"])
            m.cv_scores_ = {k: {**v, "score": _from_json_float(v["score"]), "std": _from_json_float(v["std"])}
                            for k, v in meta["cv_scores"].items()}
            A, B = (float(v) for v in meta["platt"])
            m.platt_ = (A, B)
            m.calibration_ = str(meta["calibration"])
            m.constant_ = meta["constant"] if meta["constant"] is None else bool(meta["constant"])
            m.constant_score_ = _from_json_float(meta["constant_score"])
        except (KeyError, TypeError, ValueError, AttributeError) as exc:
            raise InvalidInput(f"classifier metadata incomplete or malformed ({type(exc).__name__}: {exc})",
                               file=file, element=f"{prefix}meta") from None
        if not (np.isfinite(A) and np.isfinite(B)):
            raise InvalidInput("Platt parameters are not finite", file=file, element=f"{prefix}meta.platt")
        if m.constant_ is None:
            if "decision" not in meta:
                raise InvalidInput("decision function is missing", file=file, element=f"{prefix}meta")
            if any(c < 0 or c >= m.n_features_in_ for c in m.columns_) or not m.columns_:
                raise InvalidInput(f"columns {m.columns_} outside the {m.n_features_in_} features", file=file,
                                   element=f"{prefix}meta.columns")
            m.decision_ = FastDecision.from_arrays(arrays, meta["decision"], file=file, prefix=prefix)
            if m.decision_.n_features != len(m.columns_):
                raise InvalidInput(f"decision function reads {m.decision_.n_features} features, metadata names "
                                   f"{len(m.columns_)} columns", file=file, element=f"{prefix}support_vectors")
        else:
            m.decision_ = None
        return m


def _json_float(v: float) -> float | None:
    return None if v is None or not np.isfinite(v) else float(v)


def _from_json_float(v: Any) -> float:
    return float("nan") if v is None else float(v)
