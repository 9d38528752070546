"""A skill model directory: everything the robot has learned about one skill, pickle-free.

::

    MODEL_DIR/
      skill.yaml             the mentor's definition, copied once and never written again
      skill.history.jsonl    the robot's revisions of it (JSON lines)
      model.json             manifest: skill, env, the demonstrations it learned from, summaries
      laws/<fit>.npz         GP control laws (the mentor-only fit is named for its law; refits from
                             practice get new names, and the net says which fit each law runs)
      experience/            the robot's own graded practice: segments.jsonl (provenance) + traces
      judges/<place>.npz     SVM judges
      conditions/<name>.npz  learned conditions (switch SVMs, region conditions)
      regions.npz            place regions
      inverse_model.npz      the auxiliary inverse model (optional)
      labels.jsonl           every label: the mentor's and later ones

Everything is ``.npz`` + JSON, loaded with ``allow_pickle=False``; a shared model directory can
never run code.
"""

from __future__ import annotations

import datetime as _dt
import os
import shutil
from collections.abc import Mapping, Sequence
from functools import cached_property
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

from .demos.dataset import read_dataset
from .demos.episode import Episode
from .errors import InvalidInput
from .io import read_json, write_json
from .learn.condition import load_condition
from .learn.gp import GPLaw
from .learn.judge import Judge, TrialGrade, grade_episode
from .learn.labels import LabelStore
from .learn.region import PlaceRegions, share_regions
from .learn.views import place_episode, switch_data
from .petri.net import APN
from .petri.revision import History
from .petri.skillfile import load_skill, resolve_skill
from .runtime.executor import Executor
from .runtime.trace import Trace

MANIFEST_VERSION = 1


class SkillModel:
    """Opens (or creates with :meth:`create`) a model directory; pieces load lazily."""

    def __init__(self, path: str | os.PathLike):
        self.path = Path(path)
        if not (self.path / "skill.yaml").exists():
            raise InvalidInput("not a skill model directory (no skill.yaml)", file=str(self.path))
        self.history = History(self.path / "skill.yaml", self.path / "skill.history.jsonl")

    @classmethod
    def create(cls, path: str | os.PathLike, skill: str | os.PathLike, demos: str | os.PathLike | None = None,
               env_id: str | None = None, env_kwargs: Mapping[str, Any] | None = None) -> SkillModel:
        """Start a model directory from a skill file (copied) and, optionally, a demonstration file."""
        path = Path(path)
        src = resolve_skill(skill)
        apn = load_skill(src)                          # validate before writing anything
        path.mkdir(parents=True, exist_ok=True)
        dst = path / "skill.yaml"
        if dst.exists():
            if dst.read_bytes() != src.read_bytes():
                raise InvalidInput("holds a different skill definition; use a new directory", file=str(dst))
        else:
            shutil.copyfile(src, dst)
        manifest = {"format_version": MANIFEST_VERSION, "skill": apn.name,
                    "created": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
                    "env": env_id or apn.env, "env_kwargs": dict(env_kwargs or {}),
                    "demos": str(Path(demos).resolve()) if demos else None, "training": {}}
        old = path / "model.json"
        if old.exists():
            manifest = {**read_json(old), **{k: v for k, v in manifest.items() if v is not None and k != "created"}}
        write_json(old, manifest)
        return cls(path)

    # -- manifest ---------------------------------------------------------------------------------
    @property
    def manifest(self) -> dict[str, Any]:
        m = read_json(self.path / "model.json", "model manifest")
        if m.get("format_version") != MANIFEST_VERSION:
            raise InvalidInput(f"manifest version {m.get('format_version')!r}, expected {MANIFEST_VERSION}",
                               file=str(self.path / "model.json"))
        return m

    def update_manifest(self, **items: Any) -> None:
        """Merge ``items`` into ``model.json`` (nested dicts merged at every level)."""
        def merge(old: dict[str, Any], new: Mapping[str, Any]) -> dict[str, Any]:
            out = dict(old)
            for k, v in new.items():
                out[k] = merge(out[k], v) if isinstance(v, Mapping) and isinstance(out.get(k), dict) else v
            return out
        write_json(self.path / "model.json", merge(self.manifest, items))

    # -- the net ----------------------------------------------------------------------------------
    @property
    def apn(self) -> APN:
        """The latest version of the net (original + revisions)."""
        return self.history.latest()

    @property
    def version(self) -> int:
        return len(self.history.revisions())

    # -- demonstrations ---------------------------------------------------------------------------
    @cached_property
    def episodes(self) -> list[Episode]:
        demos = self.manifest.get("demos")
        if not demos:
            raise InvalidInput("the model has no demonstration file", file=str(self.path / "model.json"))
        return list(read_dataset(demos))

    # -- learned pieces ---------------------------------------------------------------------------
    def save_law(self, name: str, law: GPLaw) -> None:
        law.save(self.path / "laws" / f"{name}.npz")

    def laws(self, apn: APN | None = None) -> dict[str, GPLaw]:
        """The fitted laws ``apn`` (default: the latest net) runs, by law name: each law's current
        fit (``laws/<fit>.npz``; a refit from practice is a new file, the earlier fits stay)."""
        apn = self.apn if apn is None else apn
        out = {}
        for name, spec in apn.laws.items():
            p = self.path / "laws" / f"{spec.fit_name}.npz"
            if p.exists():
                out[name] = GPLaw.load(p)
        return out

    def save_judge(self, place: str, judge: Judge) -> None:
        judge.save(self.path / "judges" / f"{place}.npz")

    def judges(self) -> dict[str, Judge]:
        apn = self.apn
        out = {}
        for p in sorted((self.path / "judges").glob("*.npz")):
            if p.stem in apn.place_ids:
                out[p.stem] = Judge.load(p, variables=apn.place(p.stem).judge or None)
        return out

    def save_condition(self, name: str, model: Any) -> None:
        model.save(self.path / "conditions" / f"{name}.npz")

    def conditions(self) -> dict[str, Any]:
        conds = {p.stem: load_condition(p) for p in sorted((self.path / "conditions").glob("*.npz"))}
        share_regions(conds)
        return conds

    def save_regions(self, regions: PlaceRegions) -> None:
        regions.save(self.path / "regions.npz")

    def regions(self) -> PlaceRegions | None:
        p = self.path / "regions.npz"
        return PlaceRegions.load(p) if p.exists() else None

    @property
    def labels(self) -> LabelStore:
        return LabelStore(self.path / "labels.jsonl")

    def inverse_model(self):
        """The learned inverse model, or None if the model has none (the env then takes commands)."""
        p = self.path / "inverse_model.npz"
        if not p.exists():
            return None
        from .learn.inverse import InverseDynamicsModel
        return InverseDynamicsModel.load(p)

    # -- running ----------------------------------------------------------------------------------
    def make_env(self, **overrides: Any) -> gym.Env:
        """The env the skill runs on (the manifest's id and arguments; ``overrides`` win)."""
        import multiform.envs  # noqa: F401  (registers the envs)
        m = self.manifest
        # Gymnasium's passive checker wraps every step (≈ 10 µs at 1 kHz); our envs pass its full
        # check_env in their tests, so the skill's runs go without it.
        return gym.make(m["env"], disable_env_checker=True, **{**m.get("env_kwargs", {}), **overrides})

    def executor(self, env: gym.Env, apn: APN | None = None, use_inverse_model: bool = True) -> Executor:
        """An executor for ``apn`` (default: the latest net) with this model's laws and conditions."""
        apn = apn or self.apn
        inverse = self.inverse_model() if use_inverse_model else None
        return Executor(apn, env, self.laws(apn), self.conditions(), inverse, net_version=self.version)

    def grade(self, trace: Trace, source: str, judges: Mapping[str, Judge] | None = None,
              apn: APN | None = None) -> TrialGrade:
        """The judges' grades of a trial: every sub-procedure and the whole trial. ``apn`` is the
        net that ran it (default: the latest, read from disk; a caller grading many trials of one
        net passes it)."""
        apn = self.apn if apn is None else apn
        judges = self.judges() if judges is None else judges
        if trace.outcome == "diverged" or not judges:
            return TrialGrade(score=0.0)
        return grade_episode(place_episode(apn, trace.to_episode()), judges, lambda p: p, source=source,
                             labels=self.labels.effective(sources=[source]))


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
        from .learn.training import switch_variables
        return switch_variables(apn, transition)

    def has_switches(self, apn: APN, transition: str) -> bool:
        names = self.switch_variables(apn, transition)
        d = switch_data(apn, self.model.episodes, transition, names)
        return len(d.switch_states) >= 3 and len(d.negatives) >= 10

    def mentor(self, apn: APN) -> Any:
        """What the demonstrations say about ``apn`` (:func:`~multiform.adapt.mentor.mentor_evidence`),
        computed once per net structure and conditions; None if the model has no demonstrations."""
        from .adapt.mentor import mentor_evidence
        key = tuple((t.id, tuple(t.inputs), tuple(t.outputs), str(t.condition)) for t in apn.transitions)
        if key not in self._mentor:
            try:
                self._mentor[key] = mentor_evidence(apn, self.model.episodes)
            except InvalidInput:
                self._mentor[key] = None
        return self._mentor[key]

    def switch_condition(self, apn: APN, transition: str) -> tuple[str, dict[str, Any]]:
        from .learn.training import fit_switch_condition
        names = self.switch_variables(apn, transition)
        cond, info = fit_switch_condition(apn, self.model.episodes, transition, names, seed=self.seed)
        name = self._fresh(f"{transition}_switch")
        self.model.save_condition(name, cond)
        return name, {"model": name, **info}

    def _regions(self) -> PlaceRegions:
        r = self.model.regions()
        if r is None:
            raise InvalidInput("the model has no place regions (train first)", file=str(self.model.path))
        return r

    def leave_floors(self) -> dict[str, float]:
        """Per place with a region, the logit below which the state has left it: the lowest the
        mentor's successful stays there reached (:func:`~multiform.learn.training.region_floor`).
        Diagnosis, ways back and the "outside" condition all use this one meaning of "left"."""
        if self._floors is None:
            from .learn.training import region_floor
            regions = self._regions()
            apn0 = self.model.history.version(0)
            self._floors = {p: region_floor(apn0, self.model.episodes, regions, p) for p in regions.places_}
        return dict(self._floors)

    def include_own_stays(self, traces: Sequence[Trace]) -> dict[str, float]:
        """Lower each place's floor to the lowest logit of the robot's own stays there that went on
        as the skill was written (:func:`~multiform.learn.training.own_stay_floors`). Returns the
        floors."""
        from .learn.training import own_stay_floors
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

    def outside_condition(self, apn: APN, place: str, states: Sequence[Sequence[float]]) -> tuple[str, dict[str, Any]]:
        regions = self._regions()
        leaving = place if place in regions.places_ else None
        floor = self.leave_floors()[leaving] if leaving else 0.0
        cond = regions.outside_condition(leaving, leave_below=floor)
        name = self._fresh(f"outside_{place}")
        self.model.save_condition(name, cond)
        return name, {"model": name, "variables": list(regions.input_names), "examples": len(states),
                      "leaving": leaving, "leave_below_logit": round(floor, 3)}
