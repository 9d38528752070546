"""Several mentors of unequal skill: how far to trust each, estimated from the data alone.

With one mentor nothing here runs: every demonstration and label is trusted as given (the method as
the paper has it). With several (episodes whose ``mentor`` differ), training estimates two kinds of
trust and uses them; ``docs/how-it-learns.md`` ("Several mentors") says why this way.

* **Labels, per place** — Dawid & Skene's latent-class model (1979), by crowd-kit's
  ``DawidSkene``: every labelled stay in a judged place is an item; its annotators are the mentor
  who labelled it and the *outcome*, the net's own reading of what the mentor's tags show happened
  next (the token went on by a transition of the place that does not lead to failure, or the
  demonstration ended there in success). The outcome view is shared by every mentor's items, so
  each mentor's confusion matrix (sensitivity, specificity) is measured against the same yardstick
  and the careful mentors pin down how good that yardstick is. A stay's fused verdict is its
  posterior; judges learn from fused verdicts, not from last-writer-wins.
* **Maneuvers, per transition** — for each mentor and transition, ``success``: the posterior mean
  of a Beta(1, 1) over how often the mentor's segments of it succeeded (fused verdicts), and
  ``precision``: how closely the mentor's commands follow the law all mentors show together (its
  noise about the precision-weighted consensus of the nearest states of the other demonstrations,
  re-estimated as an EM of a regression whose noise differs by demonstrator: ILEED's
  per-demonstrator expertise, Beliaev et al. 2022, and the reliability behind Argall et al.'s
  demonstration weights), relative to the steadiest mentor. The weight is their product,
  relative to the best mentor of the transition (1.0). Laws keep each sample of a mentor's
  segments of a transition with that probability (thinning weighs a mentor's data as a GP weighs
  density), learned switch conditions learn from the switches of mentors weighted at least
  :data:`TRUSTED` in the transition switched into, and regions and laws take only stays the fused
  verdicts call successful.
* **Practice** — each graded trial is evidence about the mentors whose maneuvers the robot
  reproduced: a segment's states are matched to their nearest demonstrated states of that
  transition, and each mentor's share of the match adds the robot's grade of the stay to its
  ``success`` counts. A mentor's grade of a trial joins the Dawid–Skene items with the trial's
  outcome beside it, so a mentor whose grades disagree with what the trial showed loses trust.

Everything is kept in ``MODEL/mentors.json`` with its evidence and a history of how it moved.
"""

from __future__ import annotations

import warnings
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from ..demos.episode import Episode, SegmentLabel, mentors_of
from ..errors import InvalidInput
from ..io import read_json, write_json
from ..petri.net import APN
from .views import place_episode, success_mask, value_matrix

OUTCOME = "outcome"               # the Dawid–Skene annotator that reads what happened next
KIND, VERSION = "mentors", 1
FILE = "mentors.json"
TRUSTED = 0.5                     # switch conditions learn from mentors weighted at least this in the transition
NEIGHBOURS = 10                   # k of the precision's nearest-neighbour consensus
PER_MENTOR = 3000                 # samples per mentor and transition the precision is measured on
Key = tuple[str, int, int]


@dataclass
class Item:
    """One labelled stay for Dawid–Skene: ``labels`` by annotator (mentor), the net's ``outcome``."""

    key: Key
    place: str
    labels: dict[str, bool]
    outcome: bool


def outcome_view(apn: APN, ep: Episode, end: int, place: str) -> bool:
    """The net's reading of how a stay in ``place`` ending at sample ``end`` went: the next tag is a
    transition out of ``place`` that does not lead to failure, or the episode ended there in success."""
    if end >= ep.num_samples:
        return ep.outcome == "success"
    tag = str(ep.transitions[end])
    if tag not in apn.transition_ids:
        return False
    return place in apn.transition(tag).preset and not apn.leads_to_failure(tag)


def stay_items(apn: APN, ep: Episode, source: str, places: Iterable[str], labels: Sequence[SegmentLabel] | None = None
               ) -> list[Item]:
    """The labelled stays of ``ep`` in ``places`` as items (labels: the episode's own, else ``labels``
    given per stay, e.g. a mentor's grades of a trial)."""
    places = set(places)
    stays = place_episode(apn, ep).labels if labels is None else list(labels)
    return [Item((source, int(lab.start), int(lab.end)), str(lab.transition), {lab.labeller: bool(lab.success)},
                 outcome_view(apn, ep, int(lab.end), str(lab.transition)))
            for lab in stays if lab.transition in places]


def dawid_skene(items: Sequence[Item]) -> tuple[dict[Key, float], dict[str, dict[str, dict[str, Any]]]]:
    """Per place, crowd-kit's Dawid–Skene over ``items``: the posterior P(success) of every item, and
    per annotator its sensitivity, specificity, agreement with the fused verdicts and item count."""
    try:
        import pandas as pd
        from crowdkit.aggregation import DawidSkene
    except ImportError:
        raise InvalidInput("learning from several mentors weighs their labels with crowd-kit's Dawid-Skene: "
                           "pip install 'multiform[mentors]'", element="mentors") from None
    post: dict[Key, float] = {}
    trust: dict[str, dict[str, dict[str, Any]]] = {}
    for place in sorted({it.place for it in items}):
        mine = [it for it in items if it.place == place]
        tasks = {it.key: f"{it.key[0]}:{it.key[1]}:{it.key[2]}" for it in mine}
        rows = [(tasks[it.key], w, int(v)) for it in mine for w, v in [*it.labels.items(), (OUTCOME, it.outcome)]]
        df = pd.DataFrame(rows, columns=["task", "worker", "label"])
        if df["label"].nunique() == 1:                       # everyone says the same: nothing to weigh
            p = {t: float(df["label"].iloc[0]) for t in tasks.values()}
            errors = None
        else:
            with warnings.catch_warnings():        # crowd-kit 1.4's pandas calls that pandas 3 deprecates
                warnings.simplefilter("ignore", DeprecationWarning)
                warnings.simplefilter("ignore", FutureWarning)
                warnings.filterwarnings("ignore", category=Warning, module="crowdkit")
                ds = DawidSkene(n_iter=200, tol=1e-7).fit(df)
            p = {str(t): float(v) for t, v in ds.probas_[1].items()}
            errors = ds.errors_
        for it in mine:
            post[it.key] = p[tasks[it.key]]
        trust[place] = {}
        for w, g in df.groupby("worker", sort=True):
            truth = np.array([p[t] >= 0.5 for t in g["task"]])
            said = g["label"].to_numpy().astype(bool)
            trust[place][str(w)] = {
                "items": int(len(g)), "agreement": round(float(np.mean(truth == said)), 4),
                "sensitivity": _rate(errors, w, 1), "specificity": _rate(errors, w, 0)}
    return post, trust


def _rate(errors: Any, worker: Any, label: int) -> float | None:
    """P(annotator says ``label`` | the truth is ``label``) from crowd-kit's error matrices."""
    if errors is None or label not in errors.columns:
        return None
    try:
        return round(float(errors.loc[(worker, label), label]), 4)
    except KeyError:
        return 0.0


class Fusion:
    """Trust in each mentor (module docstring): built by :func:`estimate_fusion`, kept in
    ``mentors.json`` (:meth:`save`, :meth:`load`), updated by practice (:meth:`observe_trial`,
    :meth:`observe_grades`)."""

    def __init__(self, mentors: Sequence[str], items: Sequence[Item], maneuvers: Mapping[str, Mapping[str, Any]],
                 practice: Mapping[str, Mapping[str, Sequence[float]]] | None = None,
                 history: Sequence[Mapping[str, Any]] = (), seed: int = 0):
        self.mentors = list(mentors)
        self.items = list(items)
        self.maneuvers = {t: {m: dict(v) for m, v in d.items()} for t, d in maneuvers.items()}
        self.practice = {t: {m: [float(x) for x in v] for m, v in d.items()} for t, d in (practice or {}).items()}
        self.history = [dict(h) for h in history]
        self.seed = seed
        self._refs: dict[str, tuple[Any, np.ndarray, np.ndarray, np.ndarray]] = {}
        self._update_labels()

    # -- the estimates ------------------------------------------------------------------------------
    def _update_labels(self) -> None:
        self.posterior, self.labels = dawid_skene(self.items) if self.items else ({}, {})

    def verdict(self, key: Key, default: bool) -> bool:
        """The fused verdict on the stay ``key`` (``default`` where there is none)."""
        p = self.posterior.get(tuple(key))        # type: ignore[arg-type]
        return default if p is None else bool(p >= 0.5)

    def success(self, transition: str, mentor: str) -> float | None:
        """Posterior mean of how often ``mentor``'s way of doing ``transition`` succeeds: Beta(1, 1)
        updated by its demonstrated segments (fused verdicts) and the robot's practice of them."""
        d = self.maneuvers.get(transition, {}).get(mentor)
        if d is None:
            return None
        s, f = self.practice.get(transition, {}).get(mentor, (0.0, 0.0))
        ok, n = d["successes"] + s, d["segments"] + s + f
        return (1.0 + ok) / (2.0 + n)

    def weights(self, transition: str) -> dict[str, float]:
        """Each mentor's weight in ``transition``: success x precision, relative to the best (1.0)."""
        q = {}
        for m, d in self.maneuvers.get(transition, {}).items():
            p = self.success(transition, m)
            c = d.get("precision")
            q[m] = (p or 0.0) * (1.0 if c is None else c)
        top = max(q.values(), default=0.0)
        return {m: (v / top if top > 0 else 1.0) for m, v in q.items()}

    def weight(self, mentor: str, transition: str) -> float:
        """``mentor``'s weight in ``transition``; 1.0 for a mentor or transition it knows nothing of."""
        return self.weights(transition).get(mentor, 1.0)

    # -- what the learners take ---------------------------------------------------------------------
    def fused(self, apn: APN, episodes: Sequence[Episode], sources: Sequence[str] | None = None) -> list[Episode]:
        """``episodes`` with each stay the fused verdicts overrule relabelled: every segment label
        inside it takes the fused verdict (sources: ``demo_<i>`` by position unless given)."""
        out = []
        for i, ep in enumerate(episodes):
            src = sources[i] if sources is not None else f"demo_{i}"
            changes = []
            for stay in place_episode(apn, ep).labels:
                v = self.verdict((src, stay.start, stay.end), stay.success)
                if v != stay.success:
                    changes.append((stay.start, stay.end, v))
            if not changes:
                out.append(ep)
                continue
            labels = []
            for lab in ep.labels:
                hit = next((v for s, e, v in changes if s <= lab.start < e), None)
                labels.append(lab if hit is None else replace(lab, success=hit))
            out.append(replace(ep, labels=labels))
        return out

    def sample_masks(self, episodes: Sequence[Episode], seed: int) -> list[np.ndarray | None]:
        """Per episode, the samples a law keeps: each sample of a mentor's segment of a transition with
        that mentor's weight in it (seeded per episode); None where every sample stays."""
        out: list[np.ndarray | None] = []
        for i, ep in enumerate(episodes):
            if ep.mentor not in self.mentors:
                out.append(None)
                continue
            tags, inverse = np.unique(ep.transitions, return_inverse=True)
            w = np.array([self.weight(ep.mentor, str(t)) for t in tags])
            if np.all(w >= 1.0):
                out.append(None)
                continue
            u = np.random.default_rng([seed, 44, i]).random(ep.num_samples)
            out.append(u < w[inverse.reshape(-1)])
        return out

    def switch_episodes(self, episodes: Sequence[Episode], transition: str) -> list[Episode]:
        """The (fused) episodes whose switches into ``transition`` a condition learns from: those of
        mentors weighted at least :data:`TRUSTED` in it."""
        return [ep for ep in episodes if self.weight(ep.mentor, transition) >= TRUSTED]

    # -- practice -----------------------------------------------------------------------------------
    def observe_trial(self, apn: APN, demos: Sequence[Episode], trial: Episode,
                      stay_success: Mapping[tuple[int, int], bool], demo_apn: APN | None = None) -> int:
        """The robot's graded trial (run by ``apn``; its segments by transition, ``stay_success`` by
        stay ``(start, end)``) as evidence on the mentors whose demonstrated states (``demos``, read
        through ``demo_apn``, default ``apn``) it followed; returns the segments counted."""
        counted = 0
        for s, e, t in trial.segments():
            if t not in self.maneuvers:
                continue
            ok = next((v for (a, b), v in stay_success.items() if a <= s < b), None)
            if ok is None:
                continue
            share = self._shares(apn, demo_apn or apn, demos, t, trial, s, e)
            if not share:
                continue
            counts = self.practice.setdefault(t, {})
            for m, f in share.items():
                c = counts.setdefault(m, [0.0, 0.0])
                c[0 if ok else 1] += f
            counted += 1
        return counted

    def _shares(self, apn: APN, demo_apn: APN, demos: Sequence[Episode], t: str, trial: Episode, s: int, e: int
                ) -> dict[str, float]:
        """Which mentors' demonstrated states of ``t`` the trial's segment ``[s, e)`` followed: the
        fraction of its (every 10th) states whose nearest demonstrated state each mentor made."""
        ref = self._reference(demo_apn, demos, t)
        if ref is None:
            return {}
        nn, mu, sd, who = ref
        law = apn.laws[apn.transition(t).law]
        X = value_matrix(apn, trial, law.inputs)[s:e:10]
        if not len(X):
            return {}
        idx = nn.kneighbors((X - mu) / sd, n_neighbors=1, return_distance=False)[:, 0]
        names, counts = np.unique(who[idx], return_counts=True)
        return {str(m): float(c) / len(idx) for m, c in zip(names, counts)}

    def _reference(self, apn: APN, demos: Sequence[Episode], t: str):
        if t not in self._refs:
            from sklearn.neighbors import NearestNeighbors
            law = apn.laws[apn.transition(t).law]
            X, _, who, _ = _transition_states(apn, self.fused(apn, demos), t, law.inputs, self.seed)
            if not len(X):
                self._refs[t] = None        # type: ignore[assignment]
            else:
                mu, sd = X.mean(axis=0), X.std(axis=0) + 1e-12
                self._refs[t] = (NearestNeighbors(n_neighbors=1).fit((X - mu) / sd), mu, sd, who)
        return self._refs[t]

    def observe_grades(self, apn: APN, trial: Episode, source: str, grades: Sequence[SegmentLabel]) -> int:
        """A mentor's grades of a trial's stays join the Dawid–Skene items, each beside what the trial
        showed happened next; the label trust is re-estimated. Returns the items added."""
        items = stay_items(apn, trial, source, {p.id for p in apn.places if p.judge and not p.final}, grades)
        known = {it.key: it for it in self.items}
        for it in items:
            if it.key in known:
                known[it.key].labels.update(it.labels)
            else:
                self.items.append(it)
                known[it.key] = it
        if items:
            self._update_labels()
        return len(items)

    # -- record -------------------------------------------------------------------------------------
    def snapshot(self, when: str, **extra: Any) -> dict[str, Any]:
        """The weights per transition and the label agreement per place now, appended to the history."""
        row = {"when": when, **extra,
               "maneuvers": {t: {m: round(w, 4) for m, w in self.weights(t).items()} for t in sorted(self.maneuvers)},
               "labels": {p: {w: d["agreement"] for w, d in sorted(v.items())} for p, v in sorted(self.labels.items())}}
        self.history.append(row)
        return row

    def table(self) -> dict[str, Any]:
        """The estimates with their evidence, per transition and mentor and per place and annotator."""
        man = {}
        for t in sorted(self.maneuvers):
            w = self.weights(t)
            man[t] = {m: {**d, "success": _r(self.success(t, m)), "weight": _r(w.get(m)),
                          "practice": [round(x, 3) for x in self.practice.get(t, {}).get(m, (0.0, 0.0))]}
                      for m, d in sorted(self.maneuvers[t].items())}
        changed = sum(1 for it in self.items if it.labels and all(v != self.verdict(it.key, v) for v in it.labels.values()))
        return {"mentors": self.mentors, "maneuvers": man, "labels": self.labels, "items": len(self.items),
                "verdicts_overruled": changed}

    def to_json(self) -> dict[str, Any]:
        return {"__format__": {"kind": KIND, "version": VERSION}, "seed": self.seed, "mentors": self.mentors,
                "estimates": self.table(), "maneuvers": self.maneuvers, "practice": self.practice,
                "items": [[*it.key, it.place, it.labels, it.outcome] for it in self.items], "history": self.history}

    def save(self, path: str | Path) -> None:
        write_json(path, self.to_json())

    @classmethod
    def load(cls, path: str | Path) -> Fusion:
        """Read ``mentors.json``; a malformed file is refused naming the file and element."""
        f = str(path)
        d = read_json(path, "mentor trust")
        if not isinstance(d, dict) or d.get("__format__") != {"kind": KIND, "version": VERSION}:
            raise InvalidInput(f"not a multiform {KIND} file of version {VERSION}", file=f, element="__format__")
        try:
            items = [Item((str(s), int(a), int(b)), str(p), {str(k): bool(v) for k, v in lab.items()}, bool(o))
                     for s, a, b, p, lab, o in d["items"]]
            return cls(d["mentors"], items, d["maneuvers"], d.get("practice"), d.get("history", ()), int(d.get("seed", 0)))
        except (KeyError, TypeError, ValueError) as exc:
            raise InvalidInput(f"malformed ({type(exc).__name__}: {exc})", file=f) from None


def _r(x: float | None) -> float | None:
    return None if x is None else round(float(x), 4)


def _transition_states(apn: APN, episodes: Sequence[Episode], t: str, names: Sequence[str], seed: int,
                       outputs: Sequence[str] = (), lag: float = 0.0
                       ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The states (in ``names``) of the successful segments of ``t`` in ``episodes``, at most
    :data:`PER_MENTOR` per mentor (a seeded subset), the commands ``outputs`` ``lag`` s later, each
    sample's mentor and episode index."""
    by: dict[str, list[tuple[np.ndarray, np.ndarray, np.ndarray]]] = {}
    for k, ep in enumerate(episodes):
        keep = (ep.transitions == t) & success_mask(ep)
        shift = int(round(lag / ep.dt))
        if shift:
            keep[len(keep) - shift:] = False
        if not keep.any():
            continue
        idx = np.flatnonzero(keep)
        X = value_matrix(apn, ep, names)[idx]
        Y = ep.actions[idx + shift][:, [ep.command_names.index(c) for c in outputs]]
        by.setdefault(ep.mentor, []).append((X, Y, np.full(len(idx), k)))
    xs, ys, who, eps = [], [], [], []
    rng = np.random.default_rng([seed, 45])
    for m in sorted(by):
        X, Y, E = (np.concatenate([part[j] for part in by[m]]) for j in range(3))
        if len(X) > PER_MENTOR:
            pick = np.sort(rng.choice(len(X), PER_MENTOR, replace=False))
            X, Y, E = X[pick], Y[pick], E[pick]
        xs.append(X)
        ys.append(Y)
        eps.append(E)
        who.append(np.full(len(X), m, dtype=object))
    if not xs:
        return np.zeros((0, len(names))), np.zeros((0, len(outputs))), np.zeros(0, dtype=object), np.zeros(0, int)
    return np.concatenate(xs), np.concatenate(ys), np.concatenate(who), np.concatenate(eps)


def precision(apn: APN, episodes: Sequence[Episode], t: str, seed: int = 0, rounds: int = 5
              ) -> dict[str, dict[str, Any]]:
    """How closely each mentor's commands in its successful segments of ``t`` follow the law all the
    mentors show together: every command against the precision-weighted mean command of the
    :data:`NEIGHBOURS` nearest states (standardised law inputs) of the *other* demonstrations, in
    standardised commands, over the states that lie as near such neighbours as most do (three
    quarters); each mentor's mean squared difference is its noise, and the neighbours are weighted
    by the inverse noise of their mentor, re-estimated ``rounds`` times (the EM of a regression
    whose noise differs by demonstrator, as ILEED's). ``precision`` is the smallest noise over the
    mentor's own (1.0: the steadiest hand)."""
    from sklearn.neighbors import NearestNeighbors
    law = apn.laws[apn.transition(t).law]
    X, Y, who, eps = _transition_states(apn, episodes, t, law.inputs, seed, law.outputs, law.lag)
    names = sorted(set(who.tolist()))
    blank = {m: {"samples": int(np.sum(who == m)), "mse": None, "precision": None} for m in names}
    if len(names) < 2:
        return blank
    mu, sd = X.mean(axis=0), X.std(axis=0) + 1e-12
    Z, V = (X - mu) / sd, Y / (Y.std(axis=0) + 1e-12)
    dist = np.zeros(len(Z))
    nbr = np.zeros((len(Z), NEIGHBOURS), dtype=int)
    for e in np.unique(eps):
        q, ref = eps == e, np.flatnonzero(eps != e)
        if len(ref) < NEIGHBOURS:
            return blank
        d, idx = NearestNeighbors(n_neighbors=NEIGHBOURS).fit(Z[ref]).kneighbors(Z[q])
        dist[q], nbr[q] = d[:, 0], ref[idx]
    near = dist <= np.quantile(dist, 0.75)
    code = np.array([names.index(m) for m in who])
    noise = np.ones(len(names))
    for _ in range(rounds):
        w = (1.0 / noise)[code[nbr]]                                   # (n, k) neighbour weights
        pred = (w[:, :, None] * V[nbr]).sum(axis=1) / w.sum(axis=1)[:, None]
        r2 = ((V - pred) ** 2).sum(axis=1)
        noise = np.array([r2[near & (code == j)].mean() if (near & (code == j)).sum() >= 10 else np.nan
                          for j in range(len(names))])
        if np.all(np.isnan(noise)):
            return blank
        noise = np.where(np.isnan(noise), np.nanmax(noise), np.maximum(noise, 1e-12))
    best = float(noise.min())
    counted = {m: (near & (code == j)).sum() >= 10 for j, m in enumerate(names)}
    return {m: {"samples": int(np.sum(who == m)), "mse": _r(noise[j]) if counted[m] else None,
                "precision": _r(best / noise[j]) if counted[m] else None}
            for j, m in enumerate(names)}


def estimate_fusion(apn: APN, episodes: Sequence[Episode], seed: int = 0) -> Fusion | None:
    """Trust in each mentor of ``episodes`` (module docstring); None with fewer than two mentors: one
    mentor's data is used as given."""
    mentors = mentors_of(episodes)
    if len(mentors) < 2:
        return None
    judged = {p.id for p in apn.places if p.judge and not p.final}
    items = [it for i, ep in enumerate(episodes) for it in stay_items(apn, ep, f"demo_{i}", judged)]
    fusion = Fusion(mentors, items, {}, seed=seed)
    fused = fusion.fused(apn, episodes)
    maneuvers: dict[str, dict[str, Any]] = {}
    for t in apn.transitions:
        if t.law is None or t.law not in apn.laws:
            continue
        counts: dict[str, list[int]] = {m: [0, 0] for m in mentors}
        for ep in fused:
            for lab in ep.labels:
                if lab.transition == t.id:
                    counts[ep.mentor][0] += 1
                    counts[ep.mentor][1] += int(lab.success)
        prec = precision(apn, fused, t.id, seed)
        maneuvers[t.id] = {m: {"segments": n, "successes": k, **prec.get(m, {"samples": 0, "mse": None,
                                                                         "precision": None})}
                           for m, (n, k) in counts.items() if n}
    fusion.maneuvers = maneuvers
    fusion.snapshot("training")
    return fusion
