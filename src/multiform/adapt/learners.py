"""What repair and learning from practice fit from a model's demonstrations: switch conditions,
region conditions, the leave floors, the mentor's evidence, and judges revised by new labels.
Each fit is saved into the model directory (``conditions/``, ``judges/``) and named."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from ..demos.episode import Episode
from ..errors import InvalidInput
from ..learn.judge import Judge
from ..learn.labels import now
from ..learn.region import PlaceRegions
from ..learn.training import demo_source, fused_records, judged_places, label_balance, record_segments
from ..learn.views import is_mirror, switch_data
from ..model import SkillModel
from ..petri.net import APN
from ..runtime.trace import Trace


class ModelLearners:
    """The :class:`~multiform.adapt.repair.Learners` of a model: fit from its demonstrations and
    regions, save into ``conditions/``, return the name."""

    def __init__(self, model: SkillModel, seed: int = 0):
        self.model = model
        self.seed = seed
        self._floors: dict[str, float] | None = None
        self._mentor: dict[tuple, Any] = {}

    def fresh_law(self, law: str) -> str:
        """An unused name for a new fit of ``law`` (``<law>_r1``, ``<law>_r2``, ...)."""
        used = {p.stem for p in (self.model.path / "laws").glob("*.npz")}
        k = 1
        while f"{law}_r{k}" in used:
            k += 1
        return f"{law}_r{k}"

    def _fresh(self, stem: str) -> str:
        used = {p.stem for p in (self.model.path / "conditions").glob("*.npz")}
        name, k = stem, 1
        while name in used:
            k += 1
            name = f"{stem}_{k}"
        return name

    def switch_variables(self, apn: APN, transition: str) -> tuple[str, ...]:
        from ..learn.training import switch_variables
        return switch_variables(apn, transition)

    def switch_episodes(self, transition: str) -> list[Episode]:
        """The demonstrations whose switches into ``transition`` a condition learns from: all of one
        mentor's; of several, those of the mentors trusted in it (:meth:`~multiform.learn.fusion.Fusion.switch_episodes`)."""
        fusion = self.model.fusion()
        eps = self.model.episodes
        return eps if fusion is None else fusion.switch_episodes(eps, transition)

    def has_switches(self, apn: APN, transition: str) -> bool:
        names = self.switch_variables(apn, transition)
        d = switch_data(apn, self.switch_episodes(transition), transition, names)
        return len(d.switch_states) >= 3 and len(d.negatives) >= 10

    def mentor(self, apn: APN) -> Any:
        """What the demonstrations say about ``apn`` (:func:`~multiform.adapt.mentor.mentor_evidence`),
        with the fitted laws it runs; computed once per net structure, conditions and laws; None if the
        model has no demonstrations."""
        from .mentor import mentor_evidence
        key = (tuple((t.id, tuple(t.inputs), tuple(t.outputs), str(t.condition), t.law) for t in apn.transitions),
               tuple((k, v.fit_name) for k, v in sorted(apn.laws.items())))
        if key not in self._mentor:
            try:
                self._mentor[key] = mentor_evidence(apn, self.model.episodes)
                self._mentor[key].laws = self.model.laws(apn)     # to judge which law explains a maneuver
            except InvalidInput:
                self._mentor[key] = None
        return self._mentor[key]

    def fit_switch(self, apn: APN, transition: str, prefer: str = "cv") -> tuple[Any, dict[str, Any]]:
        """The condition :meth:`switch_condition` would save, and its evidence, unsaved."""
        from ..learn.training import fit_switch_condition
        names = self.switch_variables(apn, transition)
        eps = self.switch_episodes(transition)
        cond, info = fit_switch_condition(apn, eps, transition, names, seed=self.seed, prefer=prefer)
        if len(eps) < len(self.model.episodes):
            info["mentors"] = sorted({ep.mentor for ep in eps})
        return cond, info

    def save_switch(self, transition: str, cond: Any, info: dict[str, Any]) -> tuple[str, dict[str, Any]]:
        """Save a condition of :meth:`fit_switch` under a fresh name; returns it with its evidence."""
        name = self._fresh(f"{transition}_switch")
        self.model.save_condition(name, cond)
        return name, {"model": name, **info}

    def switch_condition(self, apn: APN, transition: str, prefer: str = "cv") -> tuple[str, dict[str, Any]]:
        """A condition for ``transition`` learned from the mentor's switches into it (``prefer``: which
        setting, :func:`~multiform.learn.training.fit_switch_condition`), saved under a fresh name."""
        return self.save_switch(transition, *self.fit_switch(apn, transition, prefer))

    def _regions(self) -> PlaceRegions:
        r = self.model.regions()
        if r is None:
            raise InvalidInput("the model has no place regions (train first)", file=str(self.model.path))
        return r

    def leave_floors(self) -> dict[str, float]:
        """Per place with a region, the calibrated logit below which the state has left it: the lowest
        the mentor's successful stays there reached (:func:`~multiform.learn.training.region_floor`).
        Diagnosis, ways back and the "outside" condition all use this one meaning of "left", in
        this one unit."""
        if self._floors is None:
            from ..learn.training import region_floor
            regions = self._regions()
            apn0 = self.model.history.version(0)
            self._floors = {p: region_floor(apn0, self.model.episodes, regions, p) for p in regions.places_}
        return dict(self._floors)

    def include_own_stays(self, traces: Sequence[Trace]) -> dict[str, float]:
        """Lower each place's floor to the lowest logit of the robot's own stays there that went on
        as the skill was written (:func:`~multiform.learn.training.own_stay_floors`). Returns the
        floors."""
        from ..learn.training import own_stay_floors
        own = own_stay_floors(self.model.history.version(0), traces, self._regions())
        self._floors = {p: min(z, own[p]) for p, z in self.leave_floors().items()}
        return dict(self._floors)

    def region_condition(self, apn: APN, into: str, away_from: str) -> tuple[str, dict[str, Any]]:
        regions = self._regions()
        other = away_from if away_from in regions.places_ else None
        floor = self.leave_floors()[other] if other else 0.0
        cond = regions.condition(into, other, leave_below=floor)
        name = self._fresh(f"in_{into}")
        self.model.save_condition(name, cond)
        return name, {"model": name, "variables": list(cond.input_names), "into": into, "rather_than": other,
                      "leave_below_logit": round(floor, 3)}

    def with_floor(self, condition: str, floor: float) -> tuple[str, dict[str, Any]]:
        """A copy of the region condition ``condition`` that leaves its place below ``floor`` instead,
        saved under a fresh name."""
        from ..learn.region import RegionCondition
        c = self.model.conditions().get(condition)
        if not isinstance(c, RegionCondition):
            raise InvalidInput(f"{condition!r} is not a region condition", file=str(self.model.path))
        new = c.with_floor(floor)
        name = self._fresh(f"in_{c.into}" if c.mode == "into" else f"outside_{c.rather_than}")
        self.model.save_condition(name, new)
        return name, {"model": name, "variables": list(new.input_names), "into": c.into, "rather_than": c.rather_than,
                      "leave_below_logit": round(floor, 3)}

    def outside_condition(self, apn: APN, place: str, states: Sequence[Sequence[float]]) -> tuple[str, dict[str, Any]]:
        regions = self._regions()
        leaving = place if place in regions.places_ else None
        floor = self.leave_floors()[leaving] if leaving else 0.0
        cond = regions.outside_condition(leaving, leave_below=floor)
        name = self._fresh(f"outside_{place}")
        self.model.save_condition(name, cond)
        return name, {"model": name, "variables": list(regions.input_names), "examples": len(states),
                      "leaving": leaving, "leave_below_logit": round(floor, 3)}


def refit_judges(model: SkillModel, places: Sequence[str], episodes: Mapping[str, Episode], labeller: str = "",
                 seed: int = 0) -> dict[str, dict[str, Any]]:
    """Revise the judges of ``places`` with the store's effective mentor labels whose segments can
    be cut from ``episodes`` or the model's demonstrations; saves them and notes them in the manifest.

    A place without a saved judge gets a new one fitted on those labels. If the skill declares a
    mirror symmetry, every label also teaches its segment's mirror image (as in the first fit).
    """
    apn = model.apn
    judged = judged_places(apn)
    known: dict[str, Episode] = dict(episodes)
    try:
        for i, ep in enumerate(model.episodes):
            known.setdefault(demo_source(i), ep)
    except InvalidInput:
        pass                                    # demonstrations moved away: label sources only
    store = model.labels
    saved = model.judges()
    info: dict[str, dict[str, Any]] = {}
    for place in places:
        variables = judged[place]
        cache: dict[str, np.ndarray] = {}
        segs, y, unknown, used = [], [], 0, 0
        for r in fused_records(store.effective(place=place), model.fusion()):
            ep = known.get(r.source)
            if ep is None or r.end > ep.num_samples:
                unknown += 1
                continue
            cut = record_segments(apn, ep, r, variables, cache)
            segs += cut
            y += [r.success] * len(cut)
            used += 1
        old = saved.get(place)
        judge = old.revise(segs, y) if old is not None else \
            Judge(place=place, variables=variables, random_state=seed).fit(segs, y)
        model.save_judge(place, judge)
        best = judge.cv_scores_.get(judge.best_kernel_, {})
        real = np.array([not is_mirror(k[0]) for k in judge.keys_], dtype=bool)
        info[place] = {"segments": int(real.sum()), "success_labels": int(judge.y_[real].sum()),
                       "mirror_images": int((~real).sum()), **label_balance(judge.y_[real]),
                       "kernel": judge.best_kernel_, "cv_score": best.get("score") if isinstance(best, dict) else best,
                       "cv_scores": {k: (v.get("score") if isinstance(v, dict) else v)
                                     for k, v in judge.cv_scores_.items()},
                       "revised": now(), "revised_by": labeller, "labels_used": used,
                       "labels_not_found": unknown}
    judges_info = dict(model.manifest.get("training", {}).get("judges", {}))
    judges_info.update(info)
    model.update_manifest(training={"judges": judges_info})
    return info
