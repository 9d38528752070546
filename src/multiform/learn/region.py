"""Place regions: where in state space each place's token has been, and whether a new state belongs.

Model: per place, a Gaussian mixture (full covariances, 1..``max_components`` chosen by BIC) of the
states seen while its token was there, in one standardisation shared by all places so densities
are comparable. Why a mixture rather than a OneClassSVM or one Gaussian: a place's states are not
one blob (the swing-up's states trace a spiral out from hanging to upright), a mixture follows that;
and its log-density keeps falling quadratically away from the data, so "which place is this
disturbed state closest to" still has an answer just outside every seen region, where an RBF
one-class SVM's decision flattens to the same constant for all places. It is also cheap to
evaluate at the control rate (about 1 µs for all places at once, one compiled loop).

Calibration: each place's mixture is fitted on half its samples and calibrated on the other half.
With ℓ the log-density, τ its ``1 - coverage`` quantile and m its median on the held-out half::

    score(x) = 1 / (1 + exp(-ln 9 · (ℓ(x) - τ) / (m - τ)))

so a score of 0.5 is the region's boundary (``coverage`` of the place's own unseen states score
≥ 0.5), a typical state of the place scores 0.9, and a state far from it tends to 0. A state
belongs to the best-scoring place if that score is ≥ 0.5 (its logit ≥ 0); otherwise no place
relates to it.
"""

from __future__ import annotations

import os
import warnings
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from scipy.special import logsumexp
from sklearn.base import BaseEstimator
from sklearn.mixture import GaussianMixture
from threadpoolctl import threadpool_limits

from ..errors import InvalidInput
from ..io import load_npz, save_npz
from .compiled import mixture_logits_one
from .features import as_str_list, check_names

KIND = "place_regions"
COND_KIND = "region_condition"
VERSION = 1
LN9 = float(np.log(9.0))


class _PlaceDensity:
    """One place's mixture in standardised coordinates, with its calibration, as plain arrays."""

    def __init__(self, weights: np.ndarray, means: np.ndarray, prec_chol: np.ndarray, tau: float, median: float):
        self.weights = np.asarray(weights, dtype=np.float64)
        self.means = np.asarray(means, dtype=np.float64)
        self.prec_chol = np.asarray(prec_chol, dtype=np.float64)
        self.tau, self.median = float(tau), float(median)
        self._k, self._d = self.means.shape
        self.slope = LN9 / max(self.median - self.tau, 1e-9)

    def log_density(self, U: np.ndarray) -> np.ndarray:
        """ℓ for rows of standardised ``U`` (n, d) (used while calibrating)."""
        Y = np.einsum("nkd,kde->nke", U[:, None, :] - self.means[None], self.prec_chol) if len(U) else \
            np.zeros((0, self._k, self._d))
        logdet = np.log(np.abs(np.einsum("kii->ki", self.prec_chol))).sum(1)
        const = np.log(self.weights) + logdet - 0.5 * self._d * np.log(2 * np.pi)
        return logsumexp(const - 0.5 * np.einsum("nke,nke->nk", Y, Y), axis=1)

    def to_arrays(self, prefix: str) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
        return ({f"{prefix}weights": self.weights, f"{prefix}means": self.means, f"{prefix}prec_chol": self.prec_chol},
                {"tau": self.tau, "median": self.median, "components": int(self._k)})

    @classmethod
    def from_arrays(cls, arrays: Mapping[str, np.ndarray], meta: Mapping[str, Any], d: int, file: str,
                    prefix: str) -> _PlaceDensity:
        for k in ("weights", "means", "prec_chol"):
            if prefix + k not in arrays:
                raise InvalidInput("array is missing", file=file, element=prefix + k)
            a = arrays[prefix + k]
            if a.dtype.kind != "f" or not np.all(np.isfinite(a)):
                raise InvalidInput("must hold finite floats", file=file, element=prefix + k)
        w, mu, pc = arrays[prefix + "weights"], arrays[prefix + "means"], arrays[prefix + "prec_chol"]
        k = w.shape[0] if w.ndim == 1 else -1
        if k < 1 or np.any(w <= 0):
            raise InvalidInput(f"has shape {w.shape} or non-positive weights", file=file, element=prefix + "weights")
        if mu.shape != (k, d):
            raise InvalidInput(f"has shape {mu.shape}, expected ({k}, {d})", file=file, element=prefix + "means")
        if pc.shape != (k, d, d) or np.any(np.einsum("kii->ki", pc) == 0):
            raise InvalidInput(f"has shape {pc.shape} or a singular factor, expected ({k}, {d}, {d})", file=file,
                               element=prefix + "prec_chol")
        try:
            tau, med = float(meta["tau"]), float(meta["median"])
        except (KeyError, TypeError, ValueError):
            raise InvalidInput("calibration (tau, median) missing", file=file, element=prefix + "meta") from None
        if not (np.isfinite(tau) and np.isfinite(med)):
            raise InvalidInput("calibration is not finite", file=file, element=prefix + "meta")
        return cls(w, mu, pc, tau, med)


class PlaceRegions(BaseEstimator):
    """Per-place state-space regions over ``input_names``; see the module docstring.

    After :meth:`fit`: ``places_``, ``mean_`` / ``scale_`` (shared standardisation),
    ``components_`` (mixture size per place), ``n_samples_`` per place.
    """

    def __init__(self, input_names: Sequence[str] = (), max_components: int = 6, coverage: float = 0.98,
                 reg_covar: float = 1e-3, max_samples: int = 4000, random_state: int = 0):
        self.input_names = input_names
        self.max_components = max_components
        self.coverage = coverage
        self.reg_covar = reg_covar
        self.max_samples = max_samples
        self.random_state = random_state

    def fit(self, samples: Mapping[str, np.ndarray]) -> PlaceRegions:
        """``samples``: place → (n, d) states seen while its token was there (e.g. ``views.place_samples``)."""
        if not samples:
            raise ValueError("no places to model")
        if not 0 < self.coverage < 1:
            raise ValueError("coverage must be in (0, 1)")
        rng = np.random.default_rng(self.random_state)
        data = {}
        for p, X in samples.items():
            X = np.asarray(X, dtype=np.float64)
            if X.ndim != 2 or (self.input_names and X.shape[1] != len(self.input_names)):
                raise ValueError(f"place {p}: expected (n, {len(self.input_names) or 'd'}) states, got {X.shape}")
            if not np.all(np.isfinite(X)):
                raise ValueError(f"place {p}: non-finite states")
            if len(X) < 10:
                raise ValueError(f"place {p}: {len(X)} states are too few for a region (need 10)")
            if len(X) > self.max_samples:
                X = X[rng.choice(len(X), self.max_samples, replace=False)]
            data[p] = X
        allX = np.concatenate(list(data.values()))
        self.mean_ = allX.mean(0)
        self.scale_ = allX.std(0)
        self.scale_[self.scale_ == 0] = 1.0
        self.places_ = tuple(data)
        self.densities_: dict[str, _PlaceDensity] = {}
        self.components_, self.n_samples_ = {}, {}
        for p, X in data.items():
            U = (X - self.mean_) / self.scale_
            perm = rng.permutation(len(U))
            half = len(U) // 2
            fit_u, cal_u = U[perm[:half]], U[perm[half:]]
            gm = self._mixture(fit_u)
            ell = _PlaceDensity(gm.weights_, gm.means_, gm.precisions_cholesky_, 0.0, 1.0).log_density(cal_u)
            dens = _PlaceDensity(gm.weights_, gm.means_, gm.precisions_cholesky_,
                                 float(np.quantile(ell, 1 - self.coverage)), float(np.median(ell)))
            self.densities_[p] = dens
            self.components_[p] = int(gm.n_components)
            self.n_samples_[p] = len(X)
        self._prepare()
        return self

    def _mixture(self, U: np.ndarray) -> GaussianMixture:
        """The BIC-best mixture of 1..max_components. One BLAS/OpenMP thread: on these small
        problems k-means' thread pool costs 20x more than it saves on a shared 2-core machine."""
        best, best_bic = None, np.inf
        for k in range(1, max(1, min(self.max_components, len(U) // 10)) + 1):
            with warnings.catch_warnings(), threadpool_limits(1):
                warnings.simplefilter("ignore")
                gm = GaussianMixture(k, covariance_type="full", reg_covar=self.reg_covar,
                                     random_state=self.random_state).fit(U)
            bic = gm.bic(U)
            if bic < best_bic:
                best, best_bic = gm, bic
        assert best is not None
        return best

    def _prepare(self) -> None:
        """Stack every place's mixture into one affine map from the raw state, so scoring all places
        is one pass: y = x W - c; a = const - (y*y) S; ℓ_p = logsumexp over p's components;
        z_p = (ℓ_p - τ_p) · slope_p, the calibrated logit (score = σ(z))."""
        self.n_features_in_ = d = len(self.mean_)
        inv = 1.0 / self.scale_
        Ws, cs, consts, groups = [], [], [], []
        for i, p in enumerate(self.places_):
            dn = self.densities_[p]
            k = dn._k
            W = dn.prec_chol.transpose(1, 0, 2).reshape(d, k * d)          # u @ W = [u P_1, ..., u P_k]
            c = np.einsum("kd,kde->ke", dn.means, dn.prec_chol).reshape(-1)
            Ws.append(inv[:, None] * W / np.sqrt(2.0))                      # folds standardisation and 1/2
            cs.append(((self.mean_ * inv) @ W + c) / np.sqrt(2.0))
            logdet = np.log(np.abs(np.einsum("kii->ki", dn.prec_chol))).sum(1)
            consts.append(np.log(dn.weights) + logdet - 0.5 * d * np.log(2 * np.pi))
            groups += [i] * k
        self._W = np.ascontiguousarray(np.concatenate(Ws, axis=1))
        self._c = np.concatenate(cs)
        self._const = np.concatenate(consts)
        K = len(self._const)
        self._S = np.kron(np.eye(K), np.ones((d, 1)))                         # (K d, K) sums each block
        self._component_place = np.array(groups, dtype=np.int64)
        self._groups = [np.flatnonzero(self._component_place == i) for i in range(len(self.places_))]
        self._tau = np.array([self.densities_[p].tau for p in self.places_])
        self._slope = np.array([self.densities_[p].slope for p in self.places_])
        self._memo_key: bytes | None = None
        self._memo = np.empty(0)
        self._amax = float(self._const.max())
        self._tau_shifted = self._tau - self._amax
        self._index = {p: i for i, p in enumerate(self.places_)}

    def place_index(self, place: str) -> int:
        """The column of ``place`` in :meth:`logits` and :meth:`logits_one` (``places_`` order)."""
        return self._index[place]

    def logits_one(self, x: np.ndarray) -> np.ndarray:
        """z per place (``places_`` order) for one raw state; the control-rate path.

        The result of the last state is memoised (conditions sharing these regions, see
        :func:`share_regions`, ask about the same state in the same tick); the returned array is
        shared, do not modify it."""
        key = x.tobytes()
        if key == self._memo_key:
            return self._memo
        s = mixture_logits_one(x, self._W, self._c, self._const, self._component_place, self._amax,
                               self._tau_shifted, self._slope)
        self._memo_key, self._memo = key, s
        return s

    def logits(self, X: np.ndarray) -> np.ndarray:
        """z for rows of raw states ``X``: shape (n, n_places)."""
        X = np.atleast_2d(np.asarray(X, dtype=np.float64))
        if X.shape[1] != self.n_features_in_:
            raise ValueError(f"expected {self.n_features_in_} state entries, got {X.shape[1]}")
        Y = X @ self._W - self._c
        A = self._const - (Y * Y) @ self._S
        ell = np.stack([logsumexp(A[:, g], axis=1) for g in self._groups], axis=1)
        return (ell - self._tau) * self._slope

    # -- scoring ------------------------------------------------------------------------------------
    def scores(self, X: np.ndarray) -> dict[str, np.ndarray]:
        """Score in [0, 1] of every place for every row of ``X`` (n, d) — a diagnosis ``RegionScorer``."""
        S = _sigmoid(self.logits(X))
        return {p: S[:, i] for i, p in enumerate(self.places_)}

    def score_one(self, x: np.ndarray, place: str) -> float:
        """One place's score for one state."""
        return float(_sigmoid(self.logits_one(np.asarray(x, dtype=np.float64))[self.place_index(place)]))

    def best(self, X: np.ndarray) -> list[str | None]:
        """Per row, the best-matching place, or None when no place's score reaches 0.5."""
        Z = self.logits(X)
        k = Z.argmax(1)
        return [self.places_[i] if Z[r, i] >= 0.0 else None for r, i in enumerate(k)]

    def belongs(self, X: np.ndarray, place: str) -> np.ndarray:
        """Per row: ``place`` scores at least 0.5."""
        return self.logits(X)[:, self.place_index(place)] >= 0.0

    def coverage_on(self, samples: Mapping[str, np.ndarray]) -> dict[str, float]:
        """Fraction of each place's given states that score ≥ 0.5 for that place."""
        return {p: float(self.belongs(X, p).mean()) for p, X in samples.items() if p in self.densities_}

    # -- conditions the repair operators add --------------------------------------------------------
    def condition(self, into: str, rather_than: str | None = None, leave_below: float = 0.0) -> RegionCondition:
        """True when the state belongs to ``into`` (score ≥ 0.5) and, if given, has left
        ``rather_than`` (logit below ``leave_below`` ≤ 0, i.e. score below σ(leave_below)) — the
        paper's t7: back from "balanced" to "swung up"."""
        places = [into] + ([rather_than] if rather_than else [])
        for p in places:
            if p not in self.densities_:
                raise KeyError(f"no region for place {p!r} (have: {', '.join(self.places_)})")
        return RegionCondition(self._subset(places), "into", into, rather_than, leave_below)

    def outside_condition(self, leaving: str | None = None, leave_below: float = 0.0) -> RegionCondition:
        """True when the state belongs to no place's region; with ``leaving``, that place counts as
        left only below ``leave_below`` (≤ 0), as in :meth:`condition`."""
        if leaving is not None and leaving not in self.densities_:
            raise KeyError(f"no region for place {leaving!r} (have: {', '.join(self.places_)})")
        return RegionCondition(self._subset(list(self.places_)), "outside", rather_than=leaving,
                               leave_below=leave_below)

    def _subset(self, places: Sequence[str]) -> PlaceRegions:
        r = PlaceRegions(**self.get_params())
        r.mean_, r.scale_, r.places_ = self.mean_, self.scale_, tuple(places)
        r.densities_ = {p: self.densities_[p] for p in places}
        r.components_ = {p: self.components_[p] for p in places}
        r.n_samples_ = {p: self.n_samples_[p] for p in places}
        r._prepare()
        return r

    # -- persistence --------------------------------------------------------------------------------
    def to_arrays(self) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
        arrays: dict[str, np.ndarray] = {"mean": self.mean_, "scale": self.scale_}
        dmeta = {}
        for i, p in enumerate(self.places_):
            a, m = self.densities_[p].to_arrays(f"p{i}_")
            arrays.update(a)
            dmeta[p] = {**m, "samples": self.n_samples_[p]}
        meta = {"input_names": list(self.input_names), "places": list(self.places_), "densities": dmeta,
                "coverage": self.coverage, "max_components": self.max_components, "reg_covar": self.reg_covar,
                "max_samples": self.max_samples, "random_state": self.random_state}
        return arrays, meta

    @classmethod
    def from_arrays(cls, arrays: Mapping[str, np.ndarray], meta: Mapping[str, Any], file: str = "",
                    input_names: Sequence[str] | None = None) -> PlaceRegions:
        names = as_str_list(meta.get("input_names"), file, "input_names")
        if input_names is not None:
            check_names(input_names, names, file, "input_names")
        places = as_str_list(meta.get("places"), file, "places")
        if not places:
            raise InvalidInput("no places", file=file, element="places")
        d = len(names)
        for k in ("mean", "scale"):
            a = arrays.get(k)
            if a is None or a.shape != (d,) or a.dtype.kind != "f" or not np.all(np.isfinite(a)):
                raise InvalidInput(f"must be {d} finite floats (one per input name)", file=file, element=k)
        if np.any(arrays["scale"] <= 0):
            raise InvalidInput("must be positive", file=file, element="scale")
        dens_meta = meta.get("densities")
        if not isinstance(dens_meta, dict) or set(dens_meta) != set(places):
            raise InvalidInput("must describe every place", file=file, element="densities")
        try:
            r = cls(input_names=tuple(names), max_components=int(meta["max_components"]),
                    coverage=float(meta["coverage"]), reg_covar=float(meta["reg_covar"]),
                    max_samples=int(meta["max_samples"]), random_state=int(meta["random_state"]))
        except (KeyError, TypeError, ValueError) as exc:
            raise InvalidInput(f"settings incomplete ({exc})", file=file, element="meta") from None
        r.mean_, r.scale_, r.places_ = arrays["mean"].astype(np.float64), arrays["scale"].astype(np.float64), tuple(places)
        r.densities_, r.components_, r.n_samples_ = {}, {}, {}
        for i, p in enumerate(places):
            r.densities_[p] = _PlaceDensity.from_arrays(arrays, dens_meta[p], d, file, f"p{i}_")
            r.components_[p] = r.densities_[p]._k
            r.n_samples_[p] = int(dens_meta[p].get("samples", 0))
        r._prepare()
        return r

    def save(self, path: str | os.PathLike) -> None:
        arrays, meta = self.to_arrays()
        save_npz(path, arrays, meta, KIND, VERSION)

    @classmethod
    def load(cls, path: str | os.PathLike, input_names: Sequence[str] | None = None) -> PlaceRegions:
        arrays, meta = load_npz(path, KIND, VERSION)
        return cls.from_arrays(arrays, meta, str(path), input_names)


class RegionCondition:
    """A learned condition built from place regions (what :class:`~multiform.petri.firing.NetRunner`
    calls with one state in ``input_names`` order).

    ``mode="into"``: holds when the state belongs to ``into`` and, if ``rather_than`` is given, has
    left that place: its calibrated logit is below ``leave_below`` (0 = the region's boundary; the
    repair loop passes the lowest logit the mentor's own successful stays there ever reached, so
    that "left" means further out than any state the mentor still succeeded from). Leaving is required, not merely scoring
    higher: the first states of a stay (a balance catch just begun) can score higher for the place
    the token came from, and a way back that fired there would undo every entry at once;
    ``mode="outside"``: holds when no place's score reaches the threshold (and ``rather_than``, the
    place being left, is below ``leave_below``: a catch transient just outside every region is not
    "lost"). Decided
    on the calibrated logits z (score = σ(z), so score ≥ 0.5 ⇔ z ≥ 0) — no exponentials saturate.
    """

    def __init__(self, regions: PlaceRegions, mode: str, into: str | None = None, rather_than: str | None = None,
                 leave_below: float = 0.0):
        if mode not in ("into", "outside"):
            raise ValueError(f"mode must be 'into' or 'outside', got {mode!r}")
        if mode == "into" and into is None:
            raise ValueError("an 'into' condition needs its place")
        if not leave_below <= 0.0:
            raise ValueError(f"leave_below must be ≤ 0 (inside a region the logit is ≥ 0), got {leave_below}")
        self.regions, self.mode, self.into, self.rather_than = regions, mode, into, rather_than
        self.leave_below = float(leave_below)
        self.input_names = tuple(regions.input_names)
        self._i = regions.place_index(into) if into else -1
        self._j = regions.place_index(rather_than) if rather_than else -1
        # "outside": every place below 0, the place being left below its own (lower) bound
        self._outside_bound = np.zeros(len(regions.places_))
        if self._j >= 0:
            self._outside_bound[self._j] = self.leave_below
        self._outside_list = self._outside_bound.tolist()

    def __call__(self, x: np.ndarray) -> bool:
        z = self.regions.logits_one(x)
        if self.mode == "outside":       # plain floats: numpy's .all() dispatch costs more here
            return all(v < b for v, b in zip(z.tolist(), self._outside_list))
        return bool(z[self._i] >= 0.0 and (self._j < 0 or z[self._j] < self.leave_below))

    def with_floor(self, leave_below: float) -> RegionCondition:
        """The same condition leaving its place below ``leave_below`` instead."""
        return RegionCondition(self.regions, self.mode, self.into, self.rather_than, leave_below)

    def holds(self, X: np.ndarray) -> np.ndarray:
        """Vectorised :meth:`__call__` over rows."""
        Z = self.regions.logits(X)
        if self.mode == "outside":
            return (Z < self._outside_bound).all(axis=1)
        ok = Z[:, self._i] >= 0.0
        return ok & (Z[:, self._j] < self.leave_below) if self._j >= 0 else ok

    def save(self, path: str | os.PathLike) -> None:
        arrays, meta = self.regions.to_arrays()
        meta = {**meta, "mode": self.mode, "into": self.into, "rather_than": self.rather_than,
                "leave_below": self.leave_below}
        save_npz(path, arrays, meta, COND_KIND, VERSION)

    @classmethod
    def load(cls, path: str | os.PathLike, input_names: Sequence[str] | None = None) -> RegionCondition:
        f = str(path)
        arrays, meta = load_npz(path, COND_KIND, VERSION)
        leave = meta.get("leave_below", 0.0)
        if isinstance(leave, bool) or not isinstance(leave, (int, float)) or not -float("inf") < leave <= 0:
            raise InvalidInput(f"must be a finite number ≤ 0, got {leave!r}", file=f, element="leave_below")
        regions = PlaceRegions.from_arrays(arrays, meta, f, input_names)
        mode, into, away = meta.get("mode"), meta.get("into"), meta.get("rather_than")
        if mode not in ("into", "outside"):
            raise InvalidInput(f"unknown mode {mode!r}", file=f, element="mode")
        for el, p in (("into", into), ("rather_than", away)):
            if p is not None and p not in regions.places_:
                raise InvalidInput(f"names place {p!r}, which has no region here", file=f, element=el)
        if mode == "into" and into is None:
            raise InvalidInput("an 'into' condition needs its place", file=f, element="into")
        return cls(regions, mode, into, away, float(leave))


def _same_regions(a: PlaceRegions, b: PlaceRegions) -> bool:
    arrays_a, meta_a = a.to_arrays()
    arrays_b, meta_b = b.to_arrays()
    return meta_a == meta_b and arrays_a.keys() == arrays_b.keys() and \
        all(np.array_equal(arrays_a[k], arrays_b[k]) for k in arrays_a)


def share_regions(conditions: Mapping[str, Any]) -> None:
    """Let region conditions built on identical regions (a way back and an "outside" condition
    from the same place, say) share one :class:`PlaceRegions`, so that the state of a tick is
    scored once for all of them (:meth:`PlaceRegions.logits_one` memoises the last state)."""
    kept: list[PlaceRegions] = []
    for cond in conditions.values():
        if not isinstance(cond, RegionCondition):
            continue
        same = next((r for r in kept if _same_regions(r, cond.regions)), None)
        if same is None:
            kept.append(cond.regions)
        else:
            cond.regions = same


def _sigmoid(z: np.ndarray) -> np.ndarray:
    return 1.0 / (1.0 + np.exp(-np.clip(z, -700, 700)))
