"""Ways back held off once taken: practice trials that find out how far out of its place a law still
recovers after the robot came back.

A way back (a transition that leaves a place for another once the state has left the place's
region, :class:`~multiform.learn.region.RegionCondition` with ``rather_than``) fires below a leave
floor: the lowest logit the mentor's successful stays there reached. From a few demonstrations that
region is narrow, and the floor stops a law that would have recovered. From 5 demonstrations (job
seed 2) 26 of 36 pushed failures went: a push, the way back, the swing-up, a fast catch, and 140 ms
later the way back again, at a state the balance law holds; the swing-up threw the pendulum away.
Nothing the robot did tells it so: the way back always fired first.

So on some practice trials the robot takes each way back once and then holds it off down to a deep
probe floor (the first firing saves the trial from the push as usual: held off from the start, the
way back only showed that no law recovers from a push; below the probe floor lie the catches no law
holds, logits of -100 and less, and a way back still saves some of those trials), and sees for
itself what the law does with the catch that follows. Each
stay in the way back's place after its first firing gives the lowest logit at which the way back
would have fired again (its other part, "into" the place it leads to or "outside" every region,
holding) and whether the stay went on as the skill was written. :func:`choose_floor` weighs those
stays against the way back's own success rate in the trials where it fired again, and lowers the
floor only where letting the law go on wins more stays than the way back would have.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..learn.region import RegionCondition
from ..learn.training import went_on
from ..petri.net import APN
from ..runtime.trace import Trace


@dataclass(frozen=True)
class WayBack:
    """A transition whose learned condition leaves ``place`` below ``floor`` (a calibrated logit)."""

    transition: str
    condition: str          # the learned condition's name
    place: str
    floor: float


def ways_back(apn: APN, conditions: Mapping[str, Any]) -> list[WayBack]:
    """The net's ways back: transitions whose learned condition is a region condition that leaves
    a place (``rather_than``)."""
    out = []
    for t in apn.transitions:
        c = conditions.get(t.condition.model) if t.condition.is_learned else None
        if isinstance(c, RegionCondition) and c.rather_than is not None and c.rather_than in t.inputs:
            out.append(WayBack(t.id, t.condition.model, c.rather_than, c.leave_below))
    return out


class Once:
    """A way back's condition as written until its transition has fired in the trial, and with its
    floor at ``below`` after (it reads the transition's firing count, ``fires_<id>``, beside the state)."""

    def __init__(self, condition: RegionCondition, transition: str, below: float):
        self.condition = condition
        self.after = condition.with_floor(min(below, condition.leave_below))
        self.input_names = (*condition.input_names, f"fires_{transition}")

    def __call__(self, x: np.ndarray) -> bool:
        return (self.condition if x[-1] < 1.0 else self.after)(x[:-1])


def held_off(conditions: Mapping[str, Any], ways: Sequence[WayBack], below: float) -> dict[str, Any]:
    """``conditions`` with every way back held off down to ``below`` once it has fired (:class:`Once`)."""
    out = dict(conditions)
    for w in ways:
        out[w.condition] = Once(conditions[w.condition], w.transition, below)
    return out


def probe_stays(apn0: APN, trace: Trace, way: WayBack, condition: RegionCondition) -> list[list[float | bool]]:
    """Per stay of ``trace`` in the way back's place after the way back first fired: [the lowest logit
    of the place at which the way back's other part held (None if it never did), whether the stay
    went on as ``apn0``, the mentor's net, was written]. A stay that fell below the probe floor was
    ended there by the way back: its lowest logit is below every floor a stay that went on supports."""
    first = next((f.tick for f in trace.firings if f.transition == way.transition), None)
    if first is None:
        return []
    regions = condition.regions
    V = np.column_stack([trace.value(n) for n in regions.input_names]).astype(np.float64)
    j = regions.place_index(way.place)
    on = went_on(apn0, trace)
    out: list[list[float | bool]] = []
    for s, e in trace.stays(way.place):
        if s <= first:
            continue
        Z = regions.logits(V[s:e])
        if condition.mode == "into":
            other = Z[:, regions.place_index(condition.into)] >= 0.0
        else:
            other = (np.delete(Z, j, axis=1) < 0.0).all(axis=1)
        m = float(Z[other, j].min()) if other.any() else None
        out.append([None if m is None else round(m, 4), bool(on(way.place, e))])
    return out


def choose_floor(stays: Sequence[Sequence[Any]], floor: float, way_rate: float, min_gain: float = 1.0
                 ) -> tuple[float, float] | None:
    """The floor below ``floor`` that the held-off stays favour, and its gain; None if none gains
    ``min_gain`` stays.

    A stay whose lowest logit m lies in [f, floor) is one the way back would have ended and a floor
    f lets go on: it gains 1 if it went on and loses ``way_rate`` (the chance the way back, firing
    again, would have saved the trial) either way. Candidates are the m of stays that went on; ties
    keep the higher floor.
    """
    below = [(float(m), bool(h)) for m, h in stays if m is not None and m < floor]
    best, gain = None, 0.0
    for f in sorted({m for m, h in below if h}, reverse=True):
        g = sum(h - way_rate for m, h in below if m >= f)
        if g > gain + 1e-9:
            best, gain = f, g
    return None if best is None or gain < min_gain else (best, gain)
