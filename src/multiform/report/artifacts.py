"""The pictures and videos of a run folder: nets per version, motion plots of chosen trials,
practice progress, success rates, MP4s."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

from ..adapt.perturb import PushInPlace
from ..io import read_json
from ..model import SkillModel
from ..petri.diagram import changed_elements, draw
from .plots import motion_plot, practice_plot, rates_plot

if TYPE_CHECKING:
    from ..job import Job


def draw_versions(model: SkillModel, folder: Path, scenario_of: dict[int, str]) -> list[dict[str, str]]:
    """One SVG per net version, what that version changed in colour."""
    nets = model.history.versions()
    revs = model.history.revisions()
    out = []
    for v, apn in enumerate(nets):
        changed = changed_elements(nets[v - 1], apn) if v else set()
        if v == 0:
            caption = "version 0: the mentor's definition, as written"
        else:
            r = revs[v - 1]
            caption = f"version {v}: {r.operator} {r.target}" + (f" (scenario {scenario_of[v]})" if v in scenario_of else "")
        path = folder / f"net_v{v}.svg"
        draw(apn, path, changed=changed, title=caption)
        out.append({"file": str(path.relative_to(folder.parent)), "caption": caption})
    return out


def _trial(model: SkillModel, job: Job, seed: int, push: dict[str, Any] | None, qpos_every: int):
    env = model.make_env(render_mode="rgb_array")
    try:
        ex = model.executor(env, use_inverse_model=job.cfg.inverse_model)
        trace = ex.run(seed=seed, options=job.task.trial_options(seed),
                       perturb=PushInPlace(**push) if push else None, qpos_every=qpos_every)
    finally:
        env.close()
    return trace


def write_video(model: SkillModel, trace, path: Path, fps: int) -> None:
    """The trial as an MP4, rendered without shadows (they more than double a frame's cost on this
    CPU renderer, and the report's two videos were most of its time)."""
    from .video import render_qpos, write_mp4
    env = model.make_env(render_mode="rgb_array", shadows=False)
    try:
        env.reset(seed=trace.seed, options=trace.options)
        frames = render_qpos(env.unwrapped, trace.qpos)
    finally:
        env.close()
    write_mp4(frames, path, fps=fps)


def write_artifacts(job: Job, model: SkillModel, main: dict[str, Any]) -> None:
    """Fill the run folder and ``job.metrics['artifacts']``."""
    out = job.out
    art: dict[str, Any] = {"plots": {}, "videos": {}}
    scenario_of = {r["version"]: r["scenario"] for r in job.metrics.get("revisions", []) if r.get("version")}
    art["nets"] = draw_versions(model, out / "nets", scenario_of)
    for name, s in job.metrics.get("scenarios", {}).items():
        state = read_json(Path(s["state"]))
        revs = [r for r in state["revisions"] if r.get("operator") != "none"]
        p = practice_plot(state["trials"], revs, out / "plots" / f"practice_{name}.png", title=s["title"])
        s["plot"] = str(p.relative_to(out))
    rows = [{"name": r["name"], **{k: r[k] for k in ("rate", "low", "high")}} for r in job.metrics.get("ablation", [])]
    if rows:
        art["plots"]["evaluation"] = str(rates_plot(rows, out / "plots" / "evaluation.png",
                                                    "success over the evaluation trials").relative_to(out))
    detail = main.get("trials_detail", [])
    fps = 30
    qpos_every = int(round(1.0 / (fps * 1e-3)))
    added = {r["target"] for r in job.metrics.get("revisions", []) if r["operator"] == "add_transition"}
    picks = {
        "success_trial": next((d for d in detail if d["success"] and not d["pushed"]), None),
        "recovery_trial": next((d for d in detail if d["success"] and d["pushed"] and set(d["fired"]) & added), None),
    }
    specs = {s.seed: s for s in job.task.evaluation_specs(job.cfg.eval_trials, job.cfg.seed, job.cfg.push_fraction)}
    titles = {"success_trial": "a successful trial of the learned skill",
              "recovery_trial": "pushed while balancing: the added transition backs up to swing-up, then balances again"}
    for key, d in picks.items():
        if d is None:
            continue
        spec = specs[d["seed"]]
        trace = _trial(model, job, spec.seed, spec.push, qpos_every if job.cfg.videos else 0)
        plot = motion_plot(trace, job.task.PLOT_VARIABLES, out / "plots" / f"{key}.png",
                           title=f"{titles[key]} (seed {trace.seed}, {trace.outcome})")
        art["plots"][key] = str(plot.relative_to(out))
        if job.cfg.videos and trace.qpos is not None:
            path = out / "videos" / f"{key}.mp4"
            write_video(model, trace, path, fps)
            art["videos"][key] = {"file": str(path.relative_to(out)), "caption": titles[key]}
    job.metrics["artifacts"] = art
