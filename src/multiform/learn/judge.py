"""Judges: per place, an SVM that learned the mentor's unstated success criteria from labelled segments.

A judge turns a segment (the samples while one maneuver ran with the token in its place) into the
features of :mod:`.features` over the place's ``judge`` variables and scores them with a
:class:`~.kernel_pool.KernelPoolClassifier`: a calibrated P(success) in [0, 1]; a verdict is
``score >= 0.5``. Besides kernel and hyperparameters, the cross-validation also chooses which
statistics to use (``feature_sets``: end state only, end state + extrema, all) — with a few dozen
labels, 22 features of which two matter defeat every kernel, and the mentor's criteria are usually
about where a sub-procedure ended and how far it strayed.

Revision without loss: a judge keeps its training set (features, verdicts and the segment each came
from). :meth:`Judge.revise` adds new labels — a new label on a segment it already knows replaces that
row, as a mentor's later word supersedes — and refits, re-running the kernel search on all of them.
:meth:`Judge.fit_records` fits straight from the :class:`~.labels.LabelStore`.

Whole-trial score (:func:`grade_episode`): each judged place's score is the score of its *last*
segment in the trial (a failed swing-up followed by a successful repeat has passed "swung up"), and
the trial's score is the **minimum** over the judged places — a trial is as good as its weakest
sub-procedure — with a place the trial never reached scoring 0. ``combine="product"`` is offered too.
A stay shorter than every demonstration segment its judge was taught (:attr:`Judge.shortest_taught_`)
is not graded when its place has a longer stay in the trial: it is the token passing through (a way
back and the way in firing within a few ticks), not a sub-procedure, and a judge shown a few
milliseconds of it scores what it never saw. A place whose every stay is that short is graded as it
is (the robot may simply be quicker than the mentor there).
"""

from __future__ import annotations

import os
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from sklearn.base import BaseEstimator

from ..errors import InvalidInput
from ..io import load_npz, save_npz
from .features import STATS, EpisodeLike, Segment, as_str_list, check_names, feature_matrix, feature_names, \
    segment_from_episode
from .kernel_pool import KernelPoolClassifier
from .labels import LabelRecord
from .views import base_source, is_demonstration, is_mirror

KIND = "judge"
VERSION = 1
_PREFIX = "svm_"
PASS = 0.5                 # a score at least this is a success

Key = tuple[str, int, int]
FEATURE_SETS: dict[str, tuple[str, ...]] = {"end": ("end",), "extrema": ("end", "min", "max", "absmax"), "all": STATS}


def subset_columns(variables: Sequence[str], stats: Sequence[str]) -> list[int]:
    """Columns of :func:`feature_names` holding ``stats`` of every variable, plus ``duration``."""
    names = feature_names(variables)
    return [i for i, n in enumerate(names) if n == "duration" or n.rsplit(".", 1)[-1] in stats]


def _key(seg: Segment) -> Key:
    return (seg.source, int(seg.start), int(seg.end))


class Judge(BaseEstimator):
    """The judge of one place: segment features over ``variables`` + a kernel-pool SVM.

    After fitting: ``pool_`` (the classifier; ``pool_.best_kernel_``, ``pool_.cv_scores_``),
    ``feature_names_``, ``X_`` / ``y_`` / ``keys_`` (the training set and the segment of every row).
    ``feature_sets`` maps a name to the statistics (of :data:`~.features.STATS`) it keeps; None
    uses :data:`FEATURE_SETS`.
    """

    def __init__(self, place: str = "", variables: Sequence[str] = (),
                 kernels: Sequence[str] = ("rbf", "poly", "linear", "sigmoid"),
                 grids: Mapping[str, Mapping[str, Sequence[Any]]] | None = None, cv: int = 5,
                 scoring: str = "balanced_accuracy", feature_sets: Mapping[str, Sequence[str]] | None = None,
                 cv_repeats: int = 1, random_state: int = 0):
        self.place = place
        self.variables = variables
        self.kernels = kernels
        self.grids = grids
        self.cv = cv
        self.cv_repeats = cv_repeats
        self.scoring = scoring
        self.feature_sets = feature_sets
        self.random_state = random_state

    # -- fitting ------------------------------------------------------------------------------------
    def fit(self, segments: Sequence[Segment], y: Sequence[bool]) -> Judge:
        """Learn from labelled segments (``y[i]`` True = the mentor called segment i a success)."""
        if len(segments) != len(y):
            raise ValueError(f"{len(segments)} segments but {len(y)} labels")
        if not self.variables:
            raise ValueError("a judge needs the variables it looks at")
        X = feature_matrix(segments, self.variables)
        keys = [_key(s) for s in segments]
        return self._fit_rows(X, np.asarray(y, dtype=bool), keys)

    def _fit_rows(self, X: np.ndarray, y: np.ndarray, keys: list[Key]) -> Judge:
        bad = [f"{k[0]}[{k[1]}:{k[2]}]" for k, row in zip(keys, X) if not np.all(np.isfinite(row))]
        if bad:
            raise InvalidInput(f"segment(s) with non-finite values cannot train the judge of {self.place}: "
                               f"{', '.join(bad[:5])}{' …' if len(bad) > 5 else ''}", element=f"judge {self.place}")
        self.feature_names_ = feature_names(self.variables)
        self.X_, self.y_, self.keys_ = X, y, list(keys)
        sets = self.feature_sets if self.feature_sets is not None else FEATURE_SETS
        unknown = sorted({s for stats in sets.values() for s in stats} - set(STATS))
        if unknown:
            raise ValueError(f"unknown statistic(s) {unknown}; known: {', '.join(STATS)}")
        subsets = {name: subset_columns(self.variables, stats) for name, stats in sets.items()}
        groups = None
        if any(is_mirror(k[0]) for k in keys):                       # a mirror image stays with its segment
            groups = [(base_source(k[0]), k[1], k[2]) for k in keys]
        self.pool_ = KernelPoolClassifier(kernels=self.kernels, grids=self.grids, cv=self.cv,
                                          cv_repeats=self.cv_repeats, scoring=self.scoring, subsets=subsets,
                                          random_state=self.random_state).fit(X, y, groups)
        return self

    def revise(self, segments: Sequence[Segment], y: Sequence[bool]) -> Judge:
        """Add new labels to the training set and refit. A row whose segment (source, start, end)
        is labelled again takes the new verdict; every other earlier row stays."""
        if not hasattr(self, "X_"):
            return self.fit(segments, y)
        if len(segments) != len(y):
            raise ValueError(f"{len(segments)} segments but {len(y)} labels")
        X, yy, keys = self.X_.copy(), self.y_.copy(), list(self.keys_)
        index = {k: i for i, k in enumerate(keys) if k != ("", 0, 0)}
        new_X = feature_matrix(segments, self.variables)
        add_X, add_y, add_k = [], [], []
        for seg, row, lab in zip(segments, new_X, y):
            k = _key(seg)
            i = index.get(k)
            if i is None:
                add_X.append(row)
                add_y.append(bool(lab))
                add_k.append(k)
                if k != ("", 0, 0):
                    index[k] = len(keys) + len(add_k) - 1
            elif i < len(keys):
                X[i], yy[i] = row, bool(lab)
            else:
                add_X[i - len(keys)], add_y[i - len(keys)] = row, bool(lab)
        if add_X:
            X = np.concatenate([X, np.stack(add_X)])
            yy = np.concatenate([yy, np.asarray(add_y, dtype=bool)])
            keys += add_k
        return self._fit_rows(X, yy, keys)

    def fit_records(self, records: Sequence[LabelRecord],
                    episodes: Mapping[str, EpisodeLike] | Callable[[str], EpisodeLike]) -> Judge:
        """Fit from label records (``LabelStore.effective(place=...)``) and the episodes they name."""
        segs, y = labelled_segments(records, episodes, self.variables)
        return self.fit(segs, y)

    # -- grading ------------------------------------------------------------------------------------
    def grade(self, segment: Segment) -> float:
        """P(success) of one segment, in [0, 1]."""
        return float(self.grade_many([segment])[0])

    def grade_many(self, segments: Sequence[Segment]) -> np.ndarray:
        """Scores of several segments; one with non-finite values (a diverged trial) scores 0."""
        self._check_fitted()
        X = feature_matrix(segments, self.variables)
        ok = np.all(np.isfinite(X), axis=1)
        out = np.zeros(len(X))
        if ok.any():
            out[ok] = self.pool_.score_samples(X[ok])
        return out

    def predict(self, segments: Sequence[Segment]) -> np.ndarray:
        """Verdicts: True where the score is at least 0.5."""
        return self.grade_many(segments) >= PASS

    @property
    def shortest_taught_(self) -> float:
        """The shortest segment (s) of the mentor's demonstrations among the judge's training rows
        (0 if it has none): the briefest stay it knows a verdict for."""
        self._check_fitted()
        col = self.feature_names_.index("duration")
        d = [row[col] for row, k in zip(self.X_, self.keys_) if is_demonstration(k[0])]
        return float(min(d)) if d else 0.0

    def _check_fitted(self) -> None:
        if not hasattr(self, "pool_"):
            raise RuntimeError(f"judge {self.place!r} is not fitted")

    @property
    def best_kernel_(self) -> str:
        return self.pool_.best_kernel_

    @property
    def cv_scores_(self) -> dict[str, dict[str, Any]]:
        return self.pool_.cv_scores_

    def summary(self) -> str:
        self._check_fitted()
        return f"judge {self.place} over {list(self.variables)}: kernel {self.best_kernel_}\n{self.pool_.summary()}"

    # -- persistence --------------------------------------------------------------------------------
    def save(self, path: str | os.PathLike) -> None:
        """Write ``path`` (.npz with JSON metadata), atomically."""
        self._check_fitted()
        arrays, pool_meta = self.pool_.to_arrays(_PREFIX)
        arrays = {**arrays, "train_X": self.X_, "train_y": self.y_.astype(np.uint8)}
        meta = {"place": self.place, "variables": list(self.variables), "feature_names": self.feature_names_,
                "kernels": list(self.kernels), "cv": self.cv, "cv_repeats": self.cv_repeats,
                "scoring": self.scoring,
                "feature_sets": {k: list(v) for k, v in (self.feature_sets or FEATURE_SETS).items()},
                "random_state": self.random_state, "train_keys": [list(k) for k in self.keys_], "pool": pool_meta}
        save_npz(path, arrays, meta, KIND, VERSION)

    @classmethod
    def load(cls, path: str | os.PathLike, variables: Sequence[str] | None = None,
             place: str | None = None) -> Judge:
        """Read a saved judge; ``variables`` / ``place`` (from the skill) must match what it was trained on."""
        f = str(path)
        arrays, meta = load_npz(path, KIND, VERSION, required={"train_X": (None, None), "train_y": (None,)})
        saved_vars = as_str_list(meta.get("variables"), f, "variables")
        names = as_str_list(meta.get("feature_names"), f, "feature_names")
        check_names(feature_names(saved_vars), names, f, "feature_names")
        if variables is not None:
            check_names(variables, saved_vars, f, "variables")
        if place is not None and meta.get("place") != place:
            raise InvalidInput(f"judge of place {meta.get('place')!r}, expected {place!r}", file=f, element="place")
        X, y = arrays["train_X"], arrays["train_y"]
        if X.shape != (len(y), len(names)):
            raise InvalidInput(f"has shape {X.shape}, expected ({len(y)}, {len(names)})", file=f, element="train_X")
        keys = meta.get("train_keys")
        if not isinstance(keys, list) or len(keys) != len(y) or not all(
                isinstance(k, list) and len(k) == 3 and isinstance(k[0], str) for k in keys):
            raise InvalidInput(f"must list one [source, start, end] per training row ({len(y)})", file=f,
                               element="train_keys")
        if not isinstance(meta.get("pool"), dict):
            raise InvalidInput("classifier metadata missing", file=f, element="pool")
        pool = KernelPoolClassifier.from_arrays(arrays, meta["pool"], file=f, prefix=_PREFIX)
        if pool.n_features_in_ != len(names):
            raise InvalidInput(f"classifier reads {pool.n_features_in_} features, the judge has {len(names)}",
                               file=f, element="pool")
        try:
            j = cls(place=str(meta.get("place", "")), variables=tuple(saved_vars), kernels=tuple(meta["kernels"]),
                    cv=int(meta["cv"]), cv_repeats=int(meta.get("cv_repeats", 1)), scoring=str(meta["scoring"]),
                    random_state=int(meta["random_state"]),
                    feature_sets={str(k): tuple(v) for k, v in meta["feature_sets"].items()})
        except (KeyError, TypeError, ValueError, AttributeError) as exc:
            raise InvalidInput(f"judge settings incomplete ({exc})", file=f, element="meta") from None
        j.feature_names_ = names
        j.X_, j.y_ = X.astype(np.float64), y.astype(bool)
        j.keys_ = [(str(a), int(b), int(c)) for a, b, c in keys]
        j.pool_ = pool
        return j


def labelled_segments(records: Sequence[LabelRecord],
                      episodes: Mapping[str, EpisodeLike] | Callable[[str], EpisodeLike],
                      variables: Sequence[str]) -> tuple[list[Segment], np.ndarray]:
    """The segments label records point at, cut from ``episodes`` (source id → episode), and their
    verdicts. A record naming an unknown source or bounds outside its episode raises InvalidInput."""
    get = episodes.get if isinstance(episodes, Mapping) else episodes
    segs, y = [], []
    for r in records:
        ep = get(r.source)
        if ep is None:
            raise InvalidInput(f"label names unknown episode {r.source!r}", element=f"{r.source}[{r.start}:{r.end}]")
        segs.append(segment_from_episode(ep, r.start, r.end, variables, source=r.source, transition=r.transition))
        y.append(r.success)
    return segs, np.asarray(y, dtype=bool)


@dataclass
class SegmentGrade:
    """A judge's grade of one segment of a trial (``mentor``: the mentor's verdict, if labelled)."""

    source: str
    start: int
    end: int
    transition: str
    place: str
    score: float
    mentor: bool | None = None

    @property
    def success(self) -> bool:
        return self.score >= PASS

    @property
    def disagrees(self) -> bool:
        return self.mentor is not None and self.mentor != self.success


@dataclass
class TrialGrade:
    """Grades of every judged segment, each judged place (its last segment) and the whole trial."""

    segments: list[SegmentGrade] = field(default_factory=list)
    places: dict[str, float] = field(default_factory=dict)
    score: float = 0.0
    combine: str = "min"

    @property
    def success(self) -> bool:
        return self.score >= PASS

    def disagreements(self) -> list[SegmentGrade]:
        return [g for g in self.segments if g.disagrees]

    def to_json(self) -> dict[str, Any]:
        return {"score": self.score, "success": self.success, "combine": self.combine, "places": self.places,
                "segments": [{"source": g.source, "start": g.start, "end": g.end, "transition": g.transition,
                              "place": g.place, "score": g.score, "success": g.success, "mentor": g.mentor}
                             for g in self.segments]}


def credit_handovers(grade: TrialGrade, forward: Callable[[SegmentGrade], bool], judged: Sequence[str]
                     ) -> TrialGrade:
    """``grade`` where a place whose last graded stay handed the token on to a stay of another place
    that passes, through a way forward (``forward(next_stay)``: the transition that began the next
    stay belongs to the skill as written and does not lead to failure), takes that stay's grade when
    it is higher. A maneuver whose successor succeeded from where it left off did its job: so the
    mentor grades a swing-up whose catch held. A stay passes when its judge passes it or, by the same
    rule, when it handed on to a stay that passes: credit runs back along the chain of handovers
    (ball-in-cup: a pumping and a pull whose ball flew into the cup and stayed). A judge taught by a
    few demonstrations cannot always see that in the segment alone (pendulum, 5 demos, job seed 2:
    the robot's verdict agreed with the physical check on 160 of 200 evaluation trials, 199 with the
    handovers credited). The stays' own grades are kept: they choose the robot's own training data.
    ``judged``: every judged place (one the trial never visited scores 0)."""
    segs = sorted(grade.segments, key=lambda g: g.start)
    credited = [g.score for g in segs]
    for i in range(len(segs) - 2, -1, -1):
        nxt = segs[i + 1]
        if nxt.place != segs[i].place and credited[i + 1] >= PASS and forward(nxt):
            credited[i] = max(credited[i], credited[i + 1])
    places = dict(grade.places)
    for p, i in {g.place: i for i, g in enumerate(segs)}.items():
        places[p] = max(places[p], credited[i])
    scores = [places.get(p, 0.0) for p in judged]
    return TrialGrade(grade.segments, places, _combine(scores, grade.combine) if scores else grade.score,
                      grade.combine)


def _combine(scores: Sequence[float], combine: str) -> float:
    """The trial's score from its places': the lowest, or their product."""
    return float(min(scores)) if combine == "min" else float(np.prod(scores))


def grade_episode(ep: EpisodeLike, judges: Mapping[str, Judge], place_of: Callable[[str], str | None]
                  | Mapping[str, str], source: str = "", labels: Sequence[LabelRecord] = (),
                  combine: str = "min") -> TrialGrade:
    """Grade every segment of ``ep`` whose place has a judge, each judged place, and the whole trial.

    ``ep`` needs ``transitions`` (per-sample tags) as an :class:`~multiform.demos.episode.Episode`
    has; ``place_of`` maps a transition to the place its segment is judged in; ``labels`` (mentor
    records of this ``source``) fill in ``mentor`` so disagreements show.
    """
    if combine not in ("min", "product"):
        raise ValueError(f"combine must be 'min' or 'product', got {combine!r}")
    get = place_of.get if isinstance(place_of, Mapping) else place_of
    tags = np.asarray(getattr(ep, "transitions"))
    mentor = {r.key: r.success for r in labels if r.source == source}
    out = TrialGrade(combine=combine)
    stays = []
    if len(tags):
        cut = np.flatnonzero(tags[1:] != tags[:-1]) + 1
        for s, e in zip(np.concatenate([[0], cut]), np.concatenate([cut, [len(tags)]])):
            t = str(tags[s])
            place = get(t) if t else None
            if place in judges:
                stays.append((int(s), int(e), t, place))
    shortest = {p: j.shortest_taught_ for p, j in judges.items()}
    taught = {p for s, e, _, p in stays if (e - s) * ep.dt >= shortest[p]}
    for s, e, t, place in stays:
        if place in taught and (e - s) * ep.dt < shortest[place]:
            continue                    # passed through; the place has a stay of a length its judge knows
        j = judges[place]
        seg = segment_from_episode(ep, s, e, j.variables, source=source, transition=t)
        out.segments.append(SegmentGrade(source, s, e, t, place, j.grade(seg), mentor.get((source, s, e))))
    for g in out.segments:
        out.places[g.place] = g.score
    scores = [out.places.get(p, 0.0) for p in judges]
    if scores:
        out.score = _combine(scores, combine)
    return out
