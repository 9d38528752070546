"""Views of recorded episodes in a skill's own variables, and the training sets cut from them.

A demonstration stores raw observations and, per sample, the transition the mentor was executing.
Everything the learners need is read off that through the net: the value of every condition
variable at every sample (derived variables, ``time``, ``dwell_<place>``, ``fires_<t>``), the
samples of each law from successful segments, the mentor's switching states, and the states seen
while each place held the token.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

from ..demos.episode import Episode
from ..petri.net import APN


def token_place(apn: APN, transition: str) -> str | None:
    """The place the token sits in while ``transition``'s maneuver runs (its first output place)."""
    if transition not in apn.transition_ids:
        return None
    outs = list(apn.transition(transition).outputs)
    return outs[0] if outs else None


def value_matrix(apn: APN, ep: Episode, names: Sequence[str]) -> np.ndarray:
    """The values of ``names`` (state, derived and clock variables) at every sample of ``ep``.

    Clocks follow the mentor's tags: a run of one tag counts as one firing of that transition at its
    first sample, so ``dwell_<place>`` is the time since the run that put the token there began.
    """
    n = ep.num_samples
    cols: dict[str, np.ndarray] = {}
    obs_index = {k: i for i, k in enumerate(ep.observation_names)}
    for v in apn.variables:
        if v in obs_index:
            cols[v] = ep.obs[:, obs_index[v]]
    t = np.arange(n) * ep.dt
    cols["time"] = t
    wanted = set(names) | {v for g in apn.derived.values() for v in g.variables}
    wanted_clock = sorted(x for x in wanted if x.startswith(("dwell_", "fires_")))
    if wanted_clock:
        segs = ep.segments()
        for x in wanted_clock:
            col = np.zeros(n)
            if x.startswith("dwell_"):
                place = x[len("dwell_"):]
                for s, e, tag in segs:
                    if token_place(apn, tag) == place:
                        col[s:e] = t[s:e] - t[s]
            else:
                tid = x[len("fires_"):]
                count = 0
                for s, e, tag in segs:
                    if tag == tid:
                        count += 1
                    col[s:e] = count
            cols[x] = col
    for name, g in apn.derived.items():
        cols[name] = g.evaluate_arrays({v: cols[v] for v in g.variables if v in cols})
    missing = [x for x in names if x not in cols]
    if missing:
        raise KeyError(f"episode has no value for {', '.join(missing)}")
    return np.stack([cols[x] for x in names], axis=1) if names else np.zeros((n, 0))


MIRROR_SUFFIX = "~mirror"


def mirror_episode(apn: APN, ep: Episode) -> Episode:
    """``ep`` seen in the skill's declared mirror (``apn.mirror``): the named observations and commands
    change sign; tags, labels and timing stay. Raises ``ValueError`` if the skill declares none."""
    if not apn.mirror:
        raise ValueError(f"skill {apn.name!r} declares no mirror symmetry")
    obs_sign = np.array([apn.mirror.get(v, 1) for v in ep.observation_names], dtype=float)
    act_sign = np.array([apn.mirror.get(c, 1) for c in ep.command_names], dtype=float)
    return replace(ep, obs=ep.obs * obs_sign, actions=ep.actions * act_sign if ep.actions.size else ep.actions)


def is_mirror(source: str) -> bool:
    """Whether a segment source names a mirror image (``demo_3~mirror``)."""
    return source.endswith(MIRROR_SUFFIX)


def base_source(source: str) -> str:
    """The episode a (possibly mirrored) segment source comes from: ``demo_3~mirror`` → ``demo_3``."""
    return source[: -len(MIRROR_SUFFIX)] if is_mirror(source) else source


def is_demonstration(source: str) -> bool:
    """Whether a segment or label source names one of the mentor's demonstrations (``demo_3``, or
    its mirror image ``demo_3~mirror``), not a practice trial."""
    return base_source(source).startswith("demo_")


def success_mask(ep: Episode) -> np.ndarray:
    """Per sample: True inside a segment the mentor labelled success."""
    mask = np.zeros(ep.num_samples, dtype=bool)
    for lab in ep.labels:
        if lab.success:
            mask[lab.start:lab.end] = True
    return mask


@dataclass
class LawData:
    """A law's training samples: inputs ``X``, the mentor's commands ``Y``, and the episode index."""

    X: np.ndarray
    Y: np.ndarray
    episode: np.ndarray


def law_data(apn: APN, episodes: Sequence[Episode], law: str, success_only: bool = True,
             lag: float | None = None, masks: Sequence[np.ndarray | None] | None = None) -> LawData:
    """The samples in which the mentor executed a transition run by ``law``.

    With ``success_only`` (the paper: "the robot only learns from the successful demonstration"),
    only samples inside segments the mentor labelled success are kept. ``lag`` [s] (default: the
    law's, from the skill file) pairs each state with the command the mentor gave that long after it
    (both inside the kept samples): a person's command answers what they saw a reaction time earlier.
    ``masks`` (one per episode, None: all) keeps only the samples they mark (several mentors' data
    weighed by thinning, :mod:`.fusion`).
    """
    spec = apn.laws[law]
    lag = spec.lag if lag is None else lag
    tids = {t.id for t in apn.transitions if t.law == law}
    out_idx = None
    xs, ys, eps = [], [], []
    for k, ep in enumerate(episodes):
        if out_idx is None:
            out_idx = [ep.command_names.index(c) for c in spec.outputs]
        keep = np.isin(ep.transitions, list(tids))
        if success_only:
            keep &= success_mask(ep)
        if masks is not None and masks[k] is not None:
            keep &= masks[k]
        shift = int(round(lag / ep.dt))
        if shift:
            keep[len(keep) - shift:] = False
            keep[:len(keep) - shift] &= keep[shift:]
        if not keep.any():
            continue
        X = value_matrix(apn, ep, spec.inputs)[keep]
        xs.append(X)
        ys.append(ep.actions[np.flatnonzero(keep) + shift][:, out_idx])
        eps.append(np.full(len(X), k))
    if not xs:
        return LawData(np.zeros((0, len(spec.inputs))), np.zeros((0, len(spec.outputs))), np.zeros(0, int))
    return LawData(np.concatenate(xs), np.concatenate(ys), np.concatenate(eps))


@dataclass
class SwitchData:
    """States where the mentor switched into a transition (positives) and did not (negatives)."""

    positives: np.ndarray
    negatives: np.ndarray
    pos_episode: np.ndarray
    neg_episode: np.ndarray
    switch_states: np.ndarray        # exactly the first sample of each successful switch
    switch_episode: np.ndarray


def switch_data(apn: APN, episodes: Sequence[Episode], transition: str, names: Sequence[str],
                window: float = 0.02, margin: float = 0.3) -> SwitchData:
    """Where the mentor switched into ``transition`` versus where it did not.

    Positives: the samples within ``window`` seconds after the first sample of each successful
    segment of ``transition`` (a person's switch is a moment, not a sample). Negatives: the samples
    of the maneuvers that ran in the same place before the switch, further than ``margin`` seconds
    from any switch (those are states where the mentor chose *not* to switch).
    """
    pre = apn.transition(transition).preset
    before = {t.id for t in apn.transitions if set(t.outputs) & pre and t.id != transition}
    pos, neg, pe, ne, sw, swe = [], [], [], [], [], []
    w, m = int(round(window / episodes[0].dt)) if episodes else 0, int(round(margin / episodes[0].dt)) if episodes else 0
    for k, ep in enumerate(episodes):
        V = value_matrix(apn, ep, names)
        ok = success_mask(ep)
        starts = [s for s, e, tag in ep.segments() if tag == transition and ok[s]]
        near = np.zeros(ep.num_samples, dtype=bool)
        for s in starts:
            pos.append(V[s:s + w + 1])
            pe.append(np.full(len(V[s:s + w + 1]), k))
            sw.append(V[s])
            swe.append(k)
            near[max(0, s - m):s + m] = True
        cand = np.isin(ep.transitions, list(before)) & ~near
        if cand.any():
            neg.append(V[cand])
            ne.append(np.full(int(cand.sum()), k))
    d = len(names)
    cat = lambda a, shape: np.concatenate(a) if a else np.zeros(shape)  # noqa: E731
    return SwitchData(cat(pos, (0, d)), cat(neg, (0, d)), cat(pe, (0,)).astype(int), cat(ne, (0,)).astype(int),
                      np.array(sw).reshape(-1, d), np.array(swe, dtype=int))


def place_samples(apn: APN, episodes: Sequence[Episode], names: Sequence[str], success_only: bool = True
                  ) -> dict[str, np.ndarray]:
    """Per place, the states seen while the mentor's token was there."""
    out: dict[str, list[np.ndarray]] = {}
    for ep in episodes:
        V = value_matrix(apn, ep, names)
        ok = success_mask(ep) if success_only else np.ones(ep.num_samples, dtype=bool)
        for s, e, tag in ep.segments():
            p = token_place(apn, tag)
            if p is None or apn.place(p).final:
                continue
            rows = V[s:e][ok[s:e]]
            if len(rows):
                out.setdefault(p, []).append(rows)
    return {p: np.concatenate(v) for p, v in out.items()}


def stays(apn: APN, tags: Sequence[str]) -> list[tuple[int, int, str]]:
    """Maximal runs of samples with the token in one place, as ``(start, end, place)``.

    A place's stay spans every maneuver run while the token sat there: a swing-up and its repeats,
    a catch and the balancing after it. Judges grade stays, so the mentor's tagging and the robot's
    firings (which may split the same stay differently) are graded alike.
    """
    if len(tags) == 0:
        return []
    # one lookup per distinct tag, runs found on integer codes: demos have ~10^4 samples and few tags
    uniq, inverse = np.unique(np.asarray(tags, dtype=str), return_inverse=True)
    names: list[str] = []
    code_of_tag = []
    for t in uniq.tolist():
        p = token_place(apn, t) if t else None
        if p is not None and p not in names:
            names.append(p)
        code_of_tag.append(-1 if p is None else names.index(p))
    codes = np.asarray(code_of_tag)[inverse.reshape(-1)]
    bounds = np.concatenate([[0], np.flatnonzero(codes[1:] != codes[:-1]) + 1, [len(codes)]]).tolist()
    return [(s, e, names[c]) for s, e, c in zip(bounds[:-1], bounds[1:], codes[bounds[:-1]].tolist()) if c >= 0]


def place_episode(apn: APN, ep: Episode) -> Episode:
    """``ep`` with per-sample place ids as its tags and one label per stay (success when every
    mentor label inside the stay says success), for the judges."""
    from dataclasses import replace

    from ..demos.episode import SegmentLabel
    tags = np.full(ep.num_samples, "", dtype=object)
    labels = []
    for s, e, p in stays(apn, ep.transitions):
        tags[s:e] = p
        inside = [lab for lab in ep.labels if lab.start < e and lab.end > s]
        if inside:
            labels.append(SegmentLabel(s, e, p, all(lab.success for lab in inside), inside[-1].labeller))
    return replace(ep, transitions=tags.astype(str), labels=labels)
