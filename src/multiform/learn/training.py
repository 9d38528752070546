"""Fitting a skill's learned parts from the demonstrations: laws, judges, place regions.

* **Laws** (demonstration): one :class:`~.gp.GPLaw` per law of the skill, on the samples in which
  the mentor executed a transition run by that law, from segments the mentor labelled success only.
  Held-out error is measured on whole held-out demonstrations (samples within a demo are
  correlated, so a random split of samples would flatter the law).
* **Judges** (evaluation): one :class:`~.judge.Judge` per place with ``judge`` variables, on the
  mentor's segment labels (through the label store, so later labels revise them).
* **Regions**: the states seen while each place held the mentor's token, in the union of the
  judged variables (the variables the mentor's places are defined by).
"""

from __future__ import annotations

import warnings

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..demos.episode import Episode
from ..errors import InvalidInput
from ..petri.net import APN
from .features import Segment
from .fusion import Fusion
from .gp import GPLaw
from .judge import Judge
from .labels import LabelRecord, LabelStore, records_from_episode
from .region import PlaceRegions
from .condition import LearnedCondition, switch_lags, switch_windows, window_hits
from .views import (MIRROR_SUFFIX, LawData, base_source, is_demonstration, is_mirror, law_data, mirror_episode,
                    place_episode, place_samples, switch_data, value_matrix)

Progress = Callable[[str], None]


def demo_source(i: int) -> str:
    """The label-store id of demonstration ``i`` (the dataset's ``demo_<i>``)."""
    return f"demo_{i}"


def split_episodes(n: int, heldout: float, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Indices of training and held-out demonstrations (at least one of each when n >= 2)."""
    rng = np.random.default_rng(seed)
    perm = rng.permutation(n)
    k = int(round(heldout * n))
    k = min(max(k, 1 if n >= 2 and heldout > 0 else 0), n - 1) if n >= 2 else 0
    return np.sort(perm[k:]), np.sort(perm[:k])


@dataclass
class LawSettings:
    """GP settings for the laws (see :class:`~.gp.GPLaw`)."""

    n_hyper: int = 1000
    n_restarts: int = 1
    sparse_threshold: int | None = 3000
    n_inducing: int = 300
    subset_noise: bool = True        # the posterior's noise variance scaled by n / n_hyper (GPLaw.posterior_noise):
                                     # the noise is fitted on points ~0.1 s apart but used on every 1 kHz sample
    hyper_subsets: int = 7           # hyperparameters: the median over this many random subsets (GPLaw): with one
                                     # subset, 10 demos' swing-up laws hung on which 1,000 samples it drew
    max_train: int = 100000          # a random subset above this: 10 demos (80-100k samples a law) are kept whole,
                                     # so the few samples of rare states stay; 40 demos' 330k all kept gave 90.5 %,
                                     # 100k 99.0 % (the three together: docs/measurements-log.md)
    mean: str | None = None          # GP mean function; None: the skill file's choice per law
    own_ratio: float = 1.0           # the robot's own samples at most this many times the mentor's (a random
                                     # subset): on-policy swing-ups from hanging, 5x the mentor's data, drowned
                                     # its recoveries from pushes (10 demos, seed 0: pushed practice trials failed)
    own_novelty: float = 0.0         # an own sample joins only where the mentor-only law's posterior std is at
                                     # least this fraction of its prior std (0: every own sample may join);
                                     # see :func:`novel_samples`
    mirror: bool = True              # also learn from each episode's mirror image (skills that declare one):
                                     # with 10 demos, a swing-up learned from one image drifted to one end
                                     # of the stroke and stalled there (seed 2: 4/40 trials; both: 20/40)


def fit_law(apn: APN, episodes: Sequence[Episode], law: str, success_only: bool = True,
            heldout: float = 0.2, seed: int = 0, settings: LawSettings | None = None,
            own: Sequence[Episode] = (), own_apn: APN | None = None, current: GPLaw | None = None,
            mentor_law: GPLaw | None = None, fusion: Fusion | None = None, own_required: bool = False,
            theta: np.ndarray | None = None) -> tuple[GPLaw | None, dict[str, Any]]:
    """Fit one law; returns the law (fitted on all its data) and a summary with held-out NRMSE: the error
    on whole held-out episodes of the law's hyperparameters with their posterior solved on the others.

    ``own`` are the robot's own practice episodes whose labels mark the segments it graded
    successful (:mod:`multiform.adapt.experience`), read through ``own_apn`` (the net that ran them,
    default ``apn``): their samples join the mentor's, paired at the same tick (the robot's command
    answers the state it read, with no reaction time). Held-out error is measured on whole held-out
    episodes of both kinds; with ``current``, that law's error on the same held-out samples is
    reported beside it (``heldout_nrmse_current``), so a refit shows before and after. With
    ``mentor_law`` (the law fitted on the mentor's data alone) and ``settings.own_novelty`` > 0, only
    the own samples where that law is unsure join (:func:`novel_samples`). With ``fusion`` (several
    mentors, :mod:`.fusion`), each mentor's samples of a transition are kept with its weight there.
    With ``own_required``, own episodes of which no sample joins give no law (None, and the summary
    without the fits): the data is what the current law was fitted on, so a refit would only redraw
    its fitting noise, at the cost of a fit. With ``theta`` (a law's ``theta_``), the hyperparameters
    are that law's and only the posterior is solved on the data.
    """
    s = settings or LawSettings()
    masks = fusion.sample_masks(episodes, seed) if fusion is not None else None
    data, n_mentor, n_offered = _law_samples(apn, episodes, law, success_only, seed, s, own, own_apn, mentor_law,
                                             masks)
    if len(data.X) < 20:
        raise ValueError(f"law {law}: only {len(data.X)} samples from {'successful ' if success_only else ''}"
                         f"segments; record more demonstrations")
    rng = np.random.default_rng(seed)
    spec = apn.laws[law]

    def make() -> GPLaw:
        return GPLaw(n_hyper=s.n_hyper, n_restarts=s.n_restarts, sparse_threshold=s.sparse_threshold,
                     n_inducing=s.n_inducing, subset_noise=s.subset_noise,
                     hyper_subsets=s.hyper_subsets, mean=s.mean or spec.mean, random_state=seed, input_names=tuple(spec.inputs),
                     output_names=tuple(spec.outputs), theta=theta)

    def subset(idx: np.ndarray) -> np.ndarray:
        return idx if len(idx) <= s.max_train else np.sort(rng.choice(idx, s.max_train, replace=False))

    spread = np.maximum(data.Y.std(axis=0), 1e-12)     # of all the law's data: a command that the held-out
                                                        # episodes happen to hold constant (a magnet) divides by ~0

    def nrmse(pred: np.ndarray, Y: np.ndarray) -> float:
        return float((np.sqrt(np.mean((pred - Y) ** 2, axis=0)) / spread).max())

    demos = np.unique(data.episode)
    summary: dict[str, Any] = {"n": int(len(data.X)), "demos": int(np.sum(demos < len(episodes))),
                               "success_only": success_only}
    if masks is not None:
        summary["mentor_samples"] = _per_mentor(data.episode, episodes)
    if own:
        summary.update(n_mentor=int(n_mentor), n_own=int(len(data.X) - n_mentor), n_own_offered=int(n_offered),
                       own_ratio=s.own_ratio, own_novelty=s.own_novelty,
                       own_episodes=int(np.sum(demos >= len(episodes))))
        if own_required and summary["n_own"] == 0:
            return None, summary
    # the law on all its data and, to measure it, a probe on all but the held-out demonstrations with the
    # law's hyperparameters: a posterior, not a second hyperparameter search (which doubled a law's fit)
    te = tr = None
    if len(demos) >= 2 and heldout > 0:
        tr_d, te_d = split_episodes(len(demos), heldout, seed)
        tr = subset(np.flatnonzero(np.isin(data.episode, demos[tr_d])))
        te = np.flatnonzero(np.isin(data.episode, demos[te_d]))
    rows = subset(np.arange(len(data.X)))
    law_model = make().fit(data.X[rows], data.Y[rows])
    if te is not None:
        probe = make().set_params(theta=law_model.theta_).fit(data.X[tr], data.Y[tr])
        summary["heldout_nrmse"] = nrmse(probe.predict(data.X[te]), data.Y[te])
        summary["heldout_samples"] = int(len(te))
        if current is not None:
            summary["heldout_nrmse_current"] = nrmse(current.predict(data.X[te]), data.Y[te])
    info = law_model.summary()
    summary.update(mode=info["mode"], n_fit=info["n"], n_inducing=info["n_inducing"],
                   length_scales={k: round(v, 4) for k, v in info["length_scale"].items()},
                   signal_std=round(float(info["sigma_f"]), 4), noise_std=round(float(info["noise"]), 4))
    return law_model, summary


def _per_mentor(episode_index: np.ndarray, episodes: Sequence[Episode]) -> dict[str, int]:
    """Samples per mentor among a law's data (mirror images counted with their episode)."""
    out: dict[str, int] = {}
    for k, n in zip(*np.unique(episode_index, return_counts=True)):
        if k < len(episodes):
            out[episodes[k].mentor] = out.get(episodes[k].mentor, 0) + int(n)
    return dict(sorted(out.items()))


def _law_samples(apn: APN, episodes: Sequence[Episode], law: str, success_only: bool, seed: int, s: LawSettings,
                 own: Sequence[Episode], own_apn: APN | None, mentor_law: GPLaw | None,
                 masks: Sequence[np.ndarray | None] | None = None) -> tuple[LawData, int, int]:
    """:func:`fit_law`'s samples: the mentor's (and their mirror images), then the robot's own that
    are novel enough, at most ``own_ratio`` times the mentor's. Returns them with the number of the
    mentor's and of the own samples offered; own episodes are numbered after the mentor's."""
    mirror = s.mirror and bool(apn.mirror)

    def both(d: LawData, net: APN, eps: Sequence[Episode], lag: float | None, only: bool,
             keep: Sequence[np.ndarray | None] | None = None) -> LawData:
        """``d`` and, with ``mirror``, the same episodes' mirror images (sharing their episode index,
        so an image is held out with its episode)."""
        if not mirror:
            return d
        m = law_data(net, [mirror_episode(net, ep) for ep in eps], law, success_only=only, lag=lag, masks=keep)
        return LawData(np.concatenate([d.X, m.X]), np.concatenate([d.Y, m.Y]), np.concatenate([d.episode, m.episode]))

    data = both(law_data(apn, episodes, law, success_only=success_only, masks=masks), apn, episodes, None,
                success_only, masks)
    n_mentor, n_offered = len(data.X), 0
    if own:
        net = own_apn or apn
        mine = both(law_data(net, own, law, success_only=True, lag=0.0), net, own, 0.0, True)
        n_offered = len(mine.X)
        if mentor_law is not None and s.own_novelty > 0:
            mine = novel_samples(mine, mentor_law, s.own_novelty)
        cap = int(s.own_ratio * n_mentor)
        if len(mine.X) > cap:
            keep = np.sort(np.random.default_rng([seed, 1]).choice(len(mine.X), cap, replace=False))
            mine = LawData(mine.X[keep], mine.Y[keep], mine.episode[keep])
        data = LawData(np.concatenate([data.X, mine.X]), np.concatenate([data.Y, mine.Y]),
                       np.concatenate([data.episode, mine.episode + len(episodes)]))
    return data, n_mentor, n_offered


def novel_samples(data: LawData, current: GPLaw, min_ratio: float) -> LawData:
    """The samples of ``data`` where ``current`` is still unsure: its posterior standard deviation is
    at least ``min_ratio`` of its prior one (in any output).

    Why: where the mentor's samples already pin the law down, an own sample adds nothing the mentor
    did not show; it only pulls hyperparameters and inducing points toward the robot's on-policy
    states (with 10 demos, many own swing-ups from hanging made recoveries after a push worse). Where
    the law is unsure, the robot's own graded success is the only teacher there is.
    """
    if not len(data.X):
        return data
    _, sd = current.predict(data.X, return_std=True)
    prior = current.sigma_f_ * np.asarray(current.y_scale_, dtype=np.float64)
    ratio = (np.asarray(sd).reshape(len(data.X), -1) / prior).max(axis=1)
    keep = np.flatnonzero(ratio >= min_ratio)
    return LawData(data.X[keep], data.Y[keep], data.episode[keep])


def mentor_records(apn: APN, episodes: Sequence[Episode]) -> list[LabelRecord]:
    """The mentor's labels of the demonstrations as label-store records, one per place stay
    (see :func:`~.views.place_episode`)."""
    out = []
    for i, ep in enumerate(episodes):
        out += records_from_episode(demo_source(i), place_episode(apn, ep).labels, lambda p: p)
    return out


def judged_places(apn: APN) -> dict[str, tuple[str, ...]]:
    """Places that have a judge, with the variables it reads."""
    return {p.id: p.judge for p in apn.places if p.judge and not p.final}


def record_segments(apn: APN, ep: Episode, record: LabelRecord, variables: Sequence[str],
                    cache: dict[str, np.ndarray], mirror: bool = True) -> list[Segment]:
    """The segment ``record`` points at in ``ep``, in ``variables``; with ``mirror`` and a skill that
    declares a mirror symmetry, followed by its mirror image (source ``<source>~mirror``, same label).
    ``cache`` keeps each (mirrored) episode's value matrix by source across calls."""
    out = []
    for src in (record.source, record.source + MIRROR_SUFFIX) if mirror and apn.mirror else (record.source,):
        if src not in cache:
            cache[src] = value_matrix(apn, mirror_episode(apn, ep) if is_mirror(src) else ep, variables)
        out.append(Segment(cache[src][record.start:record.end], tuple(variables), ep.dt, src, record.start,
                           record.end, record.transition))
    return out


def demo_segments(apn: APN, episodes: Sequence[Episode], records: Sequence[LabelRecord], variables: Sequence[str],
                  mirror: bool = False) -> tuple[list[Segment], np.ndarray]:
    """The segments label records point at (demonstrations only), in the skill's variables, with
    their mirror images if ``mirror`` (:func:`record_segments`)."""
    cache: dict[str, np.ndarray] = {}
    segs, y = [], []
    for r in records:
        if not is_demonstration(r.source):
            continue
        cut = record_segments(apn, episodes[int(r.source.split("_")[1])], r, variables, cache, mirror)
        segs += cut
        y += [r.success] * len(cut)
    return segs, np.asarray(y, dtype=bool)


def fused_records(records: Sequence[LabelRecord], fusion: Fusion | None) -> list[LabelRecord]:
    """``records`` with each verdict the fused one where several mentors' trust was estimated
    (:meth:`~.fusion.Fusion.verdict`); as they are otherwise."""
    if fusion is None:
        return list(records)
    from dataclasses import replace
    return [replace(r, success=fusion.verdict(r.key, r.success)) for r in records]


# a judge learns to tell success from failure only from at least this many labels of each verdict
MIN_LABELS_PER_VERDICT = 3


def label_balance(success: Sequence[bool] | np.ndarray) -> dict[str, Any]:
    """Whether a judge's labels (of its own segments, mirror images aside) can teach it to tell
    success from failure: at least :data:`MIN_LABELS_PER_VERDICT` of each verdict. ``uninformative``
    is the note the job prints when not (None when they can: a revised judge's note is replaced)."""
    own = np.asarray(success, dtype=bool)
    fewest = int(min(own.sum(), (~own).sum()))
    if fewest >= MIN_LABELS_PER_VERDICT:
        return {"informative": True, "uninformative": None}
    kind = "failure" if (~own).sum() <= own.sum() else "success"
    return {"informative": False,
            "uninformative": (f"only {fewest} {kind} label(s) among {len(own)} segments: the judge cannot tell success "
                              f"from failure here and grades every stay as "
                              f"{'successful' if kind == 'failure' else 'failed'}; the robot relies on the net's own "
                              f"outcome for this place")}


def fit_judge(apn: APN, episodes: Sequence[Episode], store: LabelStore, place: str, seed: int = 0,
              heldout: float = 0.25, mirror: bool = True, fusion: Fusion | None = None) -> tuple[Judge, dict[str, Any]]:
    """Fit the judge of ``place`` on the store's effective mentor labels (and, if the skill declares a
    mirror symmetry and ``mirror`` is set, on their mirror images too); held-out accuracy on a split by
    demonstration, tested on the held-out demonstrations' own segments (a mirror image follows its
    demonstration into the same side of the split). With ``fusion`` (several mentors) a stay's label
    is the fused verdict of all who labelled it (:func:`fused_records`)."""
    variables = judged_places(apn)[place]
    records = fused_records([r for r in store.effective(place=place) if is_demonstration(r.source)], fusion)
    segs, y = demo_segments(apn, episodes, records, variables, mirror=mirror)
    mirrored = np.array([is_mirror(s.source) for s in segs], dtype=bool)
    summary: dict[str, Any] = {"segments": int((~mirrored).sum()), "success_labels": int(y[~mirrored].sum()),
                               "mirror_images": int(mirrored.sum())}
    if len(y) < 4:
        raise InvalidInput(f"only {summary['segments']} labelled segment(s) of the mentor's demonstrations reach "
                           f"this place ({len(y)} with mirror images); its judge needs at least 4: record more "
                           f"demonstrations", element=f"places.{place}.judge")
    summary.update(label_balance(y[~mirrored]))
    with warnings.catch_warnings():     # expected with few labels (folds with one class): not the user's business
        warnings.simplefilter("ignore", UserWarning)
        _fit_judge_rows(place, variables, segs, y, mirrored, episodes, heldout, seed, summary)
        judge = Judge(place=place, variables=variables, random_state=seed).fit(segs, y)
    summary["kernel"] = judge.best_kernel_
    best = judge.cv_scores_.get(judge.best_kernel_, {})
    summary["cv_score"] = best.get("score") if isinstance(best, dict) else best
    summary["cv_scores"] = {k: (v.get("score") if isinstance(v, dict) else v) for k, v in judge.cv_scores_.items()}
    return judge, summary


def _fit_judge_rows(place: str, variables: Sequence[str], segs: list, y: np.ndarray, mirrored: np.ndarray,
                    episodes: Sequence[Episode], heldout: float, seed: int, summary: dict[str, Any]) -> None:
    """The held-out accuracy of a judge fitted on the other demonstrations (into ``summary``)."""
    if heldout > 0 and len(episodes) >= 4:
        tr_d, te_d = split_episodes(len(episodes), heldout, seed)
        te_src = {demo_source(int(i)) for i in te_d}
        te = np.array([base_source(s.source) in te_src for s in segs])
        if te.any() and (~te).any() and len(set(y[~te])) == 2:
            probe = Judge(place=place, variables=variables, random_state=seed).fit(
                [s for s, t in zip(segs, te) if not t], y[~te])
            test = te & ~mirrored
            pred = probe.predict([s for s, t in zip(segs, test) if t])
            summary["heldout_accuracy"] = float(np.mean(pred == y[test]))
            summary["heldout_segments"] = int(test.sum())


def region_variables(apn: APN) -> tuple[str, ...]:
    """The variables place regions are modelled in: the union of the places' judge variables."""
    out: list[str] = []
    for p in apn.places:
        for v in p.judge:
            if v not in out:
                out.append(v)
    return tuple(out)


def fit_regions(apn: APN, episodes: Sequence[Episode], seed: int = 0) -> tuple[PlaceRegions, dict[str, Any]]:
    """Place regions from the states seen while each place held the mentor's token (successful segments)."""
    names = region_variables(apn)
    samples = place_samples(apn, episodes, names, success_only=True)
    samples = {p: X for p, X in samples.items() if len(X) >= 10}
    regions = PlaceRegions(input_names=names, random_state=seed).fit(samples)
    return regions, {"variables": list(names), "places": {p: int(len(X)) for p, X in samples.items()},
                     "components": {p: int(k) for p, k in regions.components_.items()}}


def region_floor(apn: APN, episodes: Sequence[Episode], regions: PlaceRegions, place: str) -> float:
    """The lowest calibrated logit of ``place``'s region over the mentor's successful stays there
    (≤ 0): a catch begins outside the balanced region, so a state counts as having left the place
    only when it is further out than any state the mentor still succeeded from."""
    from .views import stays, success_mask
    names = list(regions.input_names)
    j = regions.places_.index(place)
    floor = 0.0
    for ep in episodes:
        ok = success_mask(ep)
        V = None
        for s, e, p in stays(apn, ep.transitions):
            if p != place or not ok[s:e].all():
                continue
            V = value_matrix(apn, ep, names) if V is None else V
            floor = min(floor, float(regions.logits(V[s:e])[:, j].min()))
    return floor


def own_stay_floors(apn: APN, traces: Sequence[Any], regions: PlaceRegions) -> dict[str, float]:
    """Per place, the lowest calibrated logit of its region over the robot's own stays there that
    went on as the skill was written: left by a transition of ``apn`` (the mentor's net) into a
    place that is not a failure (0.0 where there is none). ``traces`` are trial traces
    (:class:`~multiform.runtime.trace.Trace`).

    The learned laws do not retrace the mentor's states (the robot's swing-up turns at other
    angles), and a state the robot itself went on from has not left its place: an "outside P1"
    fitted to the mentor's floor alone fired in the middle of ordinary swing-ups (main job,
    seed 0, 56.5 %)."""
    floors = {p: 0.0 for p in regions.places_}
    for tr in traces:
        V = np.column_stack([tr.value(n) for n in regions.input_names]).astype(np.float64)
        on = went_on(apn, tr)
        for j, place in enumerate(regions.places_):
            for s, e in tr.stays(place):
                if on(place, e):
                    floors[place] = min(floors[place], float(regions.logits(V[s:e])[:, j].min()))
    return floors


def went_on(apn: APN, trace: Any) -> Callable[[str, int], bool]:
    """Whether a stay of ``trace`` in a place, ending at tick e, went on as the skill was written:
    the firing that took the token away at e is a transition of ``apn`` (the mentor's net) into a
    place that is not a failure."""
    forward = {t.id for t in apn.transitions if not apn.leads_to_failure(t.id)}
    left = {f.tick: f.transition for f in trace.firings}

    def on(place: str, e: int) -> bool:
        t = left.get(e)
        return t in forward and place not in apn.transition(t).outputs
    return on


SWITCH_GRID = ({"C": 10.0, "gamma": 1.0}, {"C": 10.0, "gamma": 3.0}, {"C": 100.0, "gamma": 1.0},
               {"C": 100.0, "gamma": 3.0}, {"C": 100.0, "gamma": 10.0})
SWITCH_WINDOWS = (0.02, 0.05, 0.1, 0.2)     # s after a switch whose states are positives


def _seconds(lags: np.ndarray) -> float | None:
    """The median of switch lags that fired (s, rounded), None if none did."""
    fired = lags[~np.isnan(lags)]
    return round(float(np.median(fired)), 4) if len(fired) else None


def switch_variables(apn: APN, transition: str) -> tuple[str, ...]:
    """The variables a switch condition reads: the judged variables of the place it leaves, and
    the state variables the mentor's own condition for it reads (the mentor said what matters,
    if not exactly how: a regrasp condition learned without ``grip`` fired before the catch)."""
    t = apn.transition(transition)
    names: list[str] = []
    for p in t.inputs:
        for v in apn.place(p).judge:
            if v not in names:
                names.append(v)
    guard = t.condition.guard
    state = set(apn.variables) | set(apn.derived)
    for v in sorted(guard.variables if guard is not None else ()):
        if v in state and v not in names:
            names.append(v)
    return tuple(names) or tuple(apn.variables)


def switch_condition(apn: APN, episodes: Sequence[Episode], transition: str, names: Sequence[str], data: Any,
                     params: Mapping[str, float], seed: int = 0) -> tuple[LearnedCondition, dict[bool, np.ndarray]]:
    """The switch condition of one setting: an SVM with ``params`` on the switch ``data``
    (:func:`~.views.switch_data` of ``episodes``), and its firing rule; returns it with the switch
    lags of both rules along the demonstrations (:func:`~.condition.switch_lags`, keyed by ``at_peak``).

    Fired on entering its region, the condition meets the earliest of the mentor's switching moments;
    at the peak of its decision, the most typical. Whichever lands nearer the mentor's own decisions to
    switch on the demonstrations is the rule (entering on a tie: the rule conditions always had)."""
    cond = LearnedCondition(input_names=tuple(names), random_state=seed, **params).fit_switches(data.positives,
                                                                                                data.negatives)
    lag = {rule: switch_lags(cond, apn, episodes, transition, names, at_peak=rule) for rule in (False, True)}
    off = {rule: float(np.median(np.where(np.isnan(v), np.inf, np.abs(v)))) if len(v) else np.inf
           for rule, v in lag.items()}
    cond.at_peak = bool(off[True] < off[False])
    return cond, lag


def fit_switch_condition(apn: APN, episodes: Sequence[Episode], transition: str, names: Sequence[str],
                         seed: int = 0, max_false_positive: float = 0.01, folds: int = 3,
                         windows: Sequence[float] = SWITCH_WINDOWS, moment: float = 0.1, prefer: str = "cv"
                         ) -> tuple[LearnedCondition, dict[str, Any]]:
    """Learn when the mentor switches into ``transition`` (the paper's relearned t1 condition).

    An RBF SVM separates the mentor's switching states from the states of the maneuver before, far
    from any switch (:func:`~.views.switch_data`). A person's switch is a moment, not a sample (a
    reaction time of tens of ms), so how long after each switch the states count as positives
    (``windows``, s) is chosen with C and γ by cross-validation over whole demonstrations: the
    highest rate of held-out switches at which the condition holds somewhere in the switch's
    ``moment`` (the first ``moment`` s of the switch), among the settings whose rate of holding on
    held-out non-switch states stays under ``max_false_positive`` (a condition that fires early
    makes the robot switch into a maneuver it cannot finish), else the lowest such rate; ties go to
    the higher hit rate at the switches' first samples (switching as early as the mentor did), then
    the lower false-positive rate, then the shorter window. Whether the net fires it on entering its
    region or at the peak of its decision is chosen on the demonstrations too (:func:`~.condition.switch_lags`).

    ``prefer="smooth"`` takes instead the smoothest region among the settings that hold at as many
    held-out switches as any (the longest window, then the smallest γ, then the smallest C): the
    false-positive rate per sample favours tight regions that the robot's own trajectories, never
    quite the mentor's, pass beside. Neither choice predicts closed-loop success well, so practice
    examines the smooth one on its own trials (:mod:`multiform.adapt.practice.switches`).
    """
    if prefer not in ("cv", "smooth"):
        raise ValueError(f"prefer must be 'cv' or 'smooth', got {prefer!r}")
    n = len(episodes)
    rng = np.random.default_rng(seed)
    order = rng.permutation(n)
    parts = [order[i::folds] for i in range(folds)] if n >= folds else [order]
    moments = switch_windows(apn, episodes, transition, names, before=0.0, after=moment)
    mom_ep = np.array([k for k, _, _ in moments], dtype=int)
    scores = []
    data = {}
    for window in windows:
        d = data[window] = switch_data(apn, episodes, transition, names, window=window)
        for params in SWITCH_GRID:
            hits, exact, fps = [], [], []
            for te in parts:
                pos_tr, neg_tr = ~np.isin(d.pos_episode, te), ~np.isin(d.neg_episode, te)
                sw_te, neg_te = np.isin(d.switch_episode, te), ~neg_tr
                if pos_tr.sum() < 2 or not sw_te.any() or neg_tr.sum() < 10 or not neg_te.any():
                    continue
                c = LearnedCondition(input_names=tuple(names), random_state=seed, **params)
                c.fit_switches(d.positives[pos_tr], d.negatives[neg_tr])
                hits.append(float(window_hits(c, [m for m, e in zip(moments, mom_ep) if e in te]).mean()))
                exact.append(float(c.holds(d.switch_states[sw_te]).mean()))
                fps.append(float(c.holds(d.negatives[neg_te]).mean()))
            if hits:
                scores.append((window, params, float(np.mean(hits)), float(np.mean(exact)), float(np.mean(fps))))
    if not scores:
        raise ValueError(f"too few demonstrated switches into {transition} to learn its condition")
    if prefer == "smooth":
        best = max(s[2] for s in scores)
        window, params, hit, exact, fp = max((s for s in scores if s[2] >= best - 1e-9),
                                             key=lambda s: (s[0], -s[1]["gamma"], -s[1]["C"]))
    else:
        ok = [s for s in scores if s[4] <= max_false_positive]
        window, params, hit, exact, fp = (max(ok, key=lambda s: (s[2], s[3], -s[4], -s[0])) if ok
                                          else min(scores, key=lambda s: s[4]))
    d = data[window]
    cond, lag = switch_condition(apn, episodes, transition, names, d, params, seed)
    info = {"variables": list(names), "params": params, "window": window, "moment": moment,
            "fires": "at its peak" if cond.at_peak else "on entering",
            "median_lag_on_entering": _seconds(lag[False]), "median_lag_at_peak": _seconds(lag[True]),
            "cv_hit_in_moment": round(hit, 4), "cv_hit_at_switches": round(exact, 4),
            "cv_holds_far_from_switches": round(fp, 4), "mentor_switches": int(len(d.switch_states)),
            "positives": int(len(d.positives)), "negatives": int(len(d.negatives)),
            "support_vectors": int(cond.n_support_),
            "cv": [{"window": w, "params": p, "hit_in_moment": round(h, 4), "hit": round(e, 4),
                    "false_positive": round(f, 5)} for w, p, h, e, f in scores]}
    if prefer != "cv":
        info["prefer"] = prefer
    return cond, info
