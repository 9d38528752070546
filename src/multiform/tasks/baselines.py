"""Baselines for the ablation table, built from a trained model on the same demonstrations."""

from __future__ import annotations

import shutil
from pathlib import Path

import yaml

from ..learn.gp import GPLaw
from ..learn.views import value_matrix
from ..model import SkillModel
from ..petri.net import is_clock
from ..petri.skillfile import skill_to_data


def same_laws_model(model: SkillModel, folder: Path, skill: str) -> SkillModel:
    """Another definition (``skill``) with this model's laws, judges, regions and inverse model."""
    m = model.manifest
    other = SkillModel.create(folder, skill, m["demos"], m["env"], m.get("env_kwargs", {}))
    other.adopt(model, ("law", "judge", "regions", "inverse_model"))
    if (model.path / "labels.jsonl").exists():
        shutil.copyfile(model.path / "labels.jsonl", other.path / "labels.jsonl")
    return other


def demo_only_model(model: SkillModel, folder: Path, hold_condition: str, hold_time: float, seed: int = 0,
                    max_train: int = 20000) -> SkillModel:
    """Single-form learning from demonstration: one GP law on *all* demonstration samples (every phase,
    failed segments included), and no skill net. The net of this model is only the evaluation harness:
    it starts the law and ends the trial once ``hold_condition`` has held for ``hold_time`` seconds."""
    import numpy as np

    apn = model.history.version(0)
    inputs: list[str] = []
    for law in apn.laws.values():
        inputs += [v for v in law.inputs if v not in inputs and not is_clock(v)]
    data = skill_to_data(apn)
    skill = {k: data[k] for k in ("variables", "derived", "commands", "safety", "control_rate", "max_duration")
             if k in data}
    skill.update({
        "skill": f"{apn.name}_demonstration_only",
        "description": "Baseline: one GP law learned from all demonstration data, no skill net. The net below is "
                       "only the evaluation harness that ends a trial once the task is done.",
        "env": apn.env,
        "laws": {"all": {"inputs": inputs}},
        "places": {"start": {"label": "start"}, "out": {"label": "not yet done"}, "held": {"label": "holding"},
                   "done": {"label": "task done", "final": "success"}},
        "initial_marking": {"start": 1},
        "transitions": {
            "go": {"in": ["start"], "out": ["out"], "law": "all", "condition": "true"},
            "enter": {"in": ["out"], "out": ["held"], "condition": hold_condition},
            "leave": {"in": ["held"], "out": ["out"], "condition": f"not ({hold_condition})"},
            "finish": {"in": ["held"], "out": ["done"], "condition": f"dwell > {hold_time}"},
        },
    })
    folder.mkdir(parents=True, exist_ok=True)
    skill_path = folder / "definition.yaml"
    skill_path.write_text(yaml.safe_dump(skill, sort_keys=False))
    m = model.manifest
    base = SkillModel.create(folder / "model", skill_path, m["demos"], m["env"], m.get("env_kwargs", {}))
    law_file = base.path / "laws" / "all.npz"
    if not law_file.exists():
        net = base.apn
        xs, ys = [], []
        for ep in model.episodes:
            keep = np.array([bool(t) and t in apn.transition_ids and apn.transition(t).law is not None
                             for t in ep.transitions])
            if keep.any():
                xs.append(value_matrix(net, ep, inputs)[keep])
                ys.append(ep.actions[keep])
        X, Y = np.concatenate(xs), np.concatenate(ys)
        rng = np.random.default_rng(seed)
        if len(X) > max_train:
            idx = rng.choice(len(X), max_train, replace=False)
            X, Y = X[idx], Y[idx]
        law = GPLaw(random_state=seed, input_names=tuple(inputs), output_names=tuple(net.commands),
                    n_restarts=1, sparse_threshold=3000).fit(X, Y)
        base.save_law("all", law)
    base.adopt(model, ("inverse_model",))
    return base
