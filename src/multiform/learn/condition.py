"""Learned firing conditions: an SVM on the states where the mentor switched into a transition.

The paper relearns t1's condition "by regression from the demonstrated switching action": the
positives are the states within a short window after each of the mentor's successful switches
into the transition, the negatives the states of the preceding maneuver far from any switch (where
the mentor chose *not* to switch) — :func:`multiform.learn.views.switch_data` cuts both.

Fitting (scikit-learn, offline): inputs standardised, RBF ``SVC`` with ``class_weight="balanced"``
(a few dozen switch samples against thousands of swing samples); the training set is subsampled to
``max_train`` rows (positives kept first, up to half), then halved until the model has at most
``max_support`` support vectors — with fewer training rows than that cap the cap always holds.

Evaluation (the net, every tick): ``__call__(x) -> bool`` and ``decision(x)`` run through
:class:`~.fast_svm.FastDecision` (one compiled loop per state). ``threshold`` trades false positives (firing where
the mentor would not) against misses: the condition holds where ``decision(x) > threshold``;
:meth:`LearnedCondition.threshold_for` picks one for a target false-positive rate. The net fires it on
entering that region, or with ``at_peak`` at the peak of its decision along each passage through it
(:class:`multiform.petri.firing.NetRunner`; :func:`first_firing` is the same rule on a recorded run):
a switch is a moment, and where the mentor switched anywhere along a spread of moments the region spans
them all, so its edge is the earliest of them, not the typical one. Which rule a fitted condition uses
is read off the demonstrations (:func:`switch_lags`). Files saved without the setting fire on entering,
as they did when they were written.
"""

from __future__ import annotations

import os
import warnings
from collections.abc import Sequence
from typing import Any

import numpy as np
from sklearn.base import BaseEstimator
from sklearn.pipeline import Pipeline
from sklearn.preprocessing import StandardScaler
from sklearn.svm import SVC

from ..errors import InvalidInput, MissingInput
from ..io import load_npz, save_npz
from .fast_svm import FastDecision
from .features import as_str_list, check_names

KIND = "learned_condition"
VERSION = 1


class LearnedCondition(BaseEstimator):
    """A boolean condition over ``input_names`` learned from positive and negative states.

    After :meth:`fit`: ``decision_`` (FastDecision), ``estimator_`` (the scikit-learn pipeline it was
    compiled from; not saved), ``n_support_``, ``n_train_``, ``fit_rounds_`` ((training rows, support
    vectors) per attempt at the cap), ``train_rates_``.
    """

    def __init__(self, input_names: Sequence[str] = (), C: float = 10.0, gamma: float | str = "scale",
                 threshold: float = 0.0, max_support: int = 500, max_train: int = 4000,
                 class_weight: Any = "balanced", random_state: int = 0, at_peak: bool = False):
        self.input_names = input_names
        self.C = C
        self.gamma = gamma
        self.threshold = threshold
        self.max_support = max_support
        self.max_train = max_train
        self.class_weight = class_weight
        self.random_state = random_state
        self.at_peak = at_peak

    # -- fitting ------------------------------------------------------------------------------------
    def fit(self, X: np.ndarray, y: np.ndarray) -> LearnedCondition:
        """``y`` True where the condition should hold (the mentor switched)."""
        X = np.asarray(X, dtype=np.float64)
        y = np.asarray(y).astype(bool)
        if X.ndim != 2 or len(X) != len(y):
            raise ValueError(f"X must be (n, d) with one label per row; got X {X.shape}, y {y.shape}")
        if self.input_names and X.shape[1] != len(self.input_names):
            raise ValueError(f"X has {X.shape[1]} columns for {len(self.input_names)} input names")
        if not np.all(np.isfinite(X)):
            raise ValueError("X has non-finite values")
        if y.all() or not y.any():
            raise ValueError("need states where the condition holds and states where it does not")
        if self.max_support < 2:
            raise ValueError("max_support must be at least 2")
        rng = np.random.default_rng(self.random_state)
        pos, neg = np.flatnonzero(y), np.flatnonzero(~y)
        size = min(len(y), self.max_train)
        self.fit_rounds_: list[tuple[int, int]] = []
        while True:
            idx = _balanced_subsample(pos, neg, size, rng)
            model = self._fit_one(X[idx], y[idx])
            n_sv = int(model[-1].support_vectors_.shape[0])
            self.fit_rounds_.append((len(idx), n_sv))
            if n_sv <= self.max_support:
                break
            size = max(2, min(len(idx) - 1, int(len(idx) * 0.9 * self.max_support / n_sv)))
        self.n_train_ = len(idx)
        self.n_support_ = n_sv
        self.n_features_in_ = X.shape[1]
        self.estimator_ = model
        self.decision_ = FastDecision.from_sklearn(model)
        self.train_rates_ = self.rates(X[idx], y[idx])    # on the rows it was fitted on (all rows can be 10⁵⁺)
        return self

    def fit_switches(self, positives: np.ndarray, negatives: np.ndarray) -> LearnedCondition:
        """Fit from switch states (hold) and non-switch states (do not hold), e.g. a ``SwitchData``."""
        P, N = np.atleast_2d(positives), np.atleast_2d(negatives)
        return self.fit(np.concatenate([P, N]), np.r_[np.ones(len(P), bool), np.zeros(len(N), bool)])

    def _fit_one(self, X: np.ndarray, y: np.ndarray) -> Pipeline:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            return Pipeline([("scale", StandardScaler()),
                             ("svm", SVC(kernel="rbf", C=self.C, gamma=self.gamma,
                                         class_weight=self.class_weight))]).fit(X, y)

    # -- evaluation ---------------------------------------------------------------------------------
    def __call__(self, x: np.ndarray) -> bool:
        """Whether the condition holds at one state (1-D float array in ``input_names`` order)."""
        return self.decision_.decision_one(x) > self.threshold

    def decision(self, X: np.ndarray) -> np.ndarray | float:
        """The SVM's decision value(s); a 1-D ``x`` gives a float."""
        return self.decision_.decision(X)

    def holds(self, X: np.ndarray) -> np.ndarray:
        """Vectorised :meth:`__call__` over rows."""
        return np.asarray(self.decision_.decision(np.atleast_2d(X))) > self.threshold

    def rates(self, X: np.ndarray, y: np.ndarray) -> dict[str, float]:
        """``hit``: fraction of positives where it holds; ``false_positive``: fraction of negatives."""
        h, y = self.holds(X), np.asarray(y).astype(bool)
        return {"hit": float(h[y].mean()) if y.any() else float("nan"),
                "false_positive": float(h[~y].mean()) if (~y).any() else float("nan")}

    def threshold_for(self, negatives: np.ndarray, max_false_positive: float) -> float:
        """The smallest threshold at which at most ``max_false_positive`` of ``negatives`` hold."""
        d = np.sort(np.asarray(self.decision_.decision(np.atleast_2d(negatives))))[::-1]
        k = int(np.floor(max_false_positive * len(d)))
        return float(d[k]) if k < len(d) else float(d[-1])

    # -- persistence --------------------------------------------------------------------------------
    def save(self, path: str | os.PathLike) -> None:
        arrays, dmeta = self.decision_.to_arrays()
        meta = {"input_names": list(self.input_names), "threshold": self.threshold, "C": self.C,
                "gamma": self.gamma, "max_support": self.max_support, "max_train": self.max_train,
                "random_state": self.random_state, "at_peak": self.at_peak, "n_train": self.n_train_,
                "fit_rounds": self.fit_rounds_, "train_rates": self.train_rates_, "decision": dmeta}
        save_npz(path, arrays, meta, KIND, VERSION)

    @classmethod
    def load(cls, path: str | os.PathLike, input_names: Sequence[str] | None = None) -> LearnedCondition:
        """Read a saved condition; ``input_names`` (what the net will feed it) must match."""
        f = str(path)
        arrays, meta = load_npz(path, KIND, VERSION)
        names = as_str_list(meta.get("input_names"), f, "input_names")
        if input_names is not None:
            check_names(input_names, names, f, "input_names")
        if not isinstance(meta.get("decision"), dict):
            raise InvalidInput("decision function metadata missing", file=f, element="decision")
        dec = FastDecision.from_arrays(arrays, meta["decision"], file=f)
        if dec.n_features != len(names):
            raise InvalidInput(f"decision function reads {dec.n_features} inputs, names list {len(names)}",
                               file=f, element="support_vectors")
        try:
            c = cls(input_names=tuple(names), C=float(meta["C"]), gamma=meta["gamma"],
                    threshold=float(meta["threshold"]), max_support=int(meta["max_support"]),
                    max_train=int(meta["max_train"]), random_state=int(meta["random_state"]),
                    at_peak=bool(meta.get("at_peak", False)))
            c.n_train_ = int(meta["n_train"])
            c.fit_rounds_ = [tuple(int(v) for v in r) for r in meta["fit_rounds"]]
            c.train_rates_ = {k: float(v) for k, v in meta["train_rates"].items()}
        except (KeyError, TypeError, ValueError, AttributeError) as exc:
            raise InvalidInput(f"condition settings incomplete ({type(exc).__name__}: {exc})", file=f,
                               element="meta") from None
        if not np.isfinite(c.threshold):
            raise InvalidInput("threshold is not finite", file=f, element="threshold")
        c.decision_, c.n_support_, c.n_features_in_ = dec, dec.n_support, dec.n_features
        return c


def _balanced_subsample(pos: np.ndarray, neg: np.ndarray, size: int, rng: np.random.Generator) -> np.ndarray:
    """``size`` indices: positives first (up to half), negatives fill the rest, both drawn at random."""
    n_pos = min(len(pos), max(1, size // 2), size - 1)
    n_neg = min(len(neg), size - n_pos)
    n_pos = min(len(pos), size - n_neg)
    return np.sort(np.concatenate([rng.choice(pos, n_pos, replace=False), rng.choice(neg, n_neg, replace=False)]))


def load_condition(path: str | os.PathLike, input_names: Sequence[str] | None = None) -> Any:
    """Load any learned condition model by the kind in its header: a :class:`LearnedCondition`
    or a :class:`~.region.RegionCondition`."""
    from .region import RegionCondition

    f = str(path)
    try:
        with np.load(path, allow_pickle=False) as npz:
            header = str(npz["__format__"]) if "__format__" in npz.files else ""
    except FileNotFoundError:
        raise MissingInput("file not found", file=f) from None
    except Exception as exc:
        raise InvalidInput(f"not a valid .npz file ({type(exc).__name__}: {exc})", file=f) from None
    if '"kind": "region_condition"' in header:
        return RegionCondition.load(path, input_names)
    return LearnedCondition.load(path, input_names)


def switch_windows(apn: Any, episodes: Sequence[Any], transition: str, names: Sequence[str], before: float = 0.0,
                   after: float = 0.1, near: tuple[str, float] | None = None) -> list[tuple[int, int, np.ndarray]]:
    """The states around each of the mentor's successful switches into ``transition``.

    One entry per switch (the first sample ``s`` of a segment of ``transition`` the mentor labelled
    success): ``(episode index, s, states)`` with the values of ``names`` at the samples from
    ``before`` s before ``s`` to ``after`` s after it (both ends included). ``near = (v, r)``
    keeps only the samples with ``|v| <= r`` (``v`` one of ``names``); a switch left with no
    sample is still listed, with an empty array, so callers can count it.
    """
    from .views import success_mask, value_matrix

    out: list[tuple[int, int, np.ndarray]] = []
    if not episodes:
        return out
    col = list(names).index(near[0]) if near is not None else -1
    for k, ep in enumerate(episodes):
        ok = success_mask(ep)
        starts = [s for s, _, tag in ep.segments() if tag == transition and ok[s]]
        if not starts:
            continue
        V = value_matrix(apn, ep, names)
        b, a = int(round(before / ep.dt)), int(round(after / ep.dt))
        for s in starts:
            W = V[max(0, s - b):min(len(V), s + a + 1)]
            if near is not None:
                W = W[np.abs(W[:, col]) <= near[1]]
            out.append((k, s, W))
    return out


def window_hits(cond: Any, windows: Sequence[tuple[int, int, np.ndarray]]) -> np.ndarray:
    """Per window of :func:`switch_windows`: whether ``cond`` holds at some state of it (False if empty)."""
    return np.array([bool(len(W)) and bool(cond.holds(W).any()) for _, _, W in windows], dtype=bool)


def first_firing(decision: np.ndarray, threshold: float, at_peak: bool) -> int:
    """Where a learned condition first fires along consecutive ticks' decision values (-1: nowhere).

    On entering: the first value above ``threshold``. ``at_peak``: the first value no higher than the
    one before it, which was above ``threshold`` (the net's rule, one tick after the peak).
    """
    d = np.asarray(decision, dtype=np.float64)
    if at_peak:
        k = np.flatnonzero((d[:-1] > threshold) & (d[1:] <= d[:-1])) + 1
    else:
        k = np.flatnonzero(d > threshold)
    return int(k[0]) if len(k) else -1


def switch_lags(cond: Any, apn: Any, episodes: Sequence[Any], transition: str, names: Sequence[str],
                at_peak: bool) -> np.ndarray:
    """How long after each of the mentor's decisions to switch into ``transition`` the condition would
    have fired by the given rule, run along the mentor's own trajectory from the start of the stay
    the switch ended to the end of the maneuver it began (s; negative: before it; NaN: not there).

    The mentor decided on what it saw its reaction time before the recorded switch: the ``lag`` its
    maneuver's law is learned across (the robot, reacting at once, should switch where it decided).
    """
    from .views import stays, success_mask, value_matrix

    t = apn.transition(transition)
    inputs = set(t.inputs)
    reaction = apn.laws[t.law].lag if t.law in apn.laws else 0.0
    out: list[float] = []
    for ep in episodes:
        ok = success_mask(ep)
        segs = [(s, e) for s, e, tag in ep.segments() if tag == transition and ok[s]]
        if not segs:
            continue
        d = np.asarray(cond.decision(value_matrix(apn, ep, names)), dtype=np.float64)
        begun = {e: s for s, e, p in stays(apn, ep.transitions) if p in inputs}
        for s, e in segs:
            a = begun.get(s, s)
            k = first_firing(d[a:e], cond.threshold, at_peak)
            out.append((a + k - s) * ep.dt + reaction if k >= 0 else np.nan)
    return np.array(out)
