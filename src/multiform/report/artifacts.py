"""The pictures and videos of a run folder: nets per version, motion plots of chosen trials,
practice progress, success rates, MP4s."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

from ..adapt.perturb import PushInPlace
from ..io import read_json
from ..model import SkillModel
from ..stats import evaluation_split
from ..petri.diagram import changed_elements, draw
from .page import word
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
            caption = f"version {v}: {word(r.operator)} of {r.target}" + (f", in practice {scenario_of[v]}" if v in scenario_of else "")
        path = folder / f"net_v{v}.svg"
        draw(apn, path, changed=changed, title=caption)
        out.append({"file": str(path.relative_to(folder.parent)), "caption": caption})
    return out


def _trial(model: SkillModel, job: Job, seed: int, push: dict[str, Any] | None, qpos_every: int,
           observer: Any = None):
    """Rerun evaluation trial ``seed``; returns the trace and the push's time (None without one)."""
    env = model.make_env(render_mode="rgb_array")
    hand = PushInPlace(**push) if push else None
    try:
        ex = model.executor(env, use_inverse_model=job.cfg.inverse_model)
        kw = {"observer": observer} if observer is not None else {}
        trace = ex.run(seed=seed, options=job.task.trial_options(seed), perturb=hand, qpos_every=qpos_every, **kw)
    finally:
        env.close()
    return trace, (None if hand is None or hand.tick is None else hand.tick * trace.dt)


def write_video(model: SkillModel, trace, path: Path, fps: int, push_time: float | None = None) -> None:
    """The trial as an MP4 with time, place, active transition and push drawn on every frame,
    rendered without shadows (they more than double a frame's cost on this CPU renderer, and the
    report's two videos were most of its time)."""
    from .video import overlay_frames, render_qpos, write_mp4
    env = model.make_env(render_mode="rgb_array", shadows=False)
    try:
        env.reset(seed=trace.seed, options=trace.options)
        frames = overlay_frames(render_qpos(env.unwrapped, trace.qpos), trace, push_time=push_time)
        write_mp4(frames, path, fps=fps)
    finally:
        env.close()


def write_artifacts(job: Job, model: SkillModel, main: dict[str, Any], view_trials: tuple[str, ...] = (),
                    view_live: str | None = None) -> None:
    """Fill the run folder and ``job.metrics['artifacts']``; the picked trials named in
    ``view_trials`` are also saved as rerun recordings (``view/<name>.rrd``) and sent to the viewer
    ``view_live`` (see :func:`multiform.view.stream.viewer_url`)."""
    out = job.out
    art: dict[str, Any] = {"plots": {}, "videos": {}}
    titles = {k: s.get("title", k) for k, s in job.metrics.get("scenarios", {}).items()}
    scenario_of = {r["version"]: titles.get(r["scenario"], r["scenario"]) for r in job.metrics.get("revisions", [])
                   if r.get("version")}
    art["nets"] = draw_versions(model, out / "nets", scenario_of)
    for name, s in job.metrics.get("scenarios", {}).items():
        state = read_json(out / "practice" / name / "state.json")
        revs = [r for r in state["revisions"] if r.get("operator") != "none"]
        p = practice_plot(state["trials"], revs, out / "plots" / f"practice_{name}.png", title=s["title"])
        s["plot"] = str(p.relative_to(out))
    rows = [{k: r[k] for k in ("name", "rate", "low", "high", "successes", "trials")} for r in job.metrics.get("ablation", [])]
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
    words = getattr(job.task, "REPORT", {})
    figure = words.get("motion_figure")
    for key, d in picks.items():
        if d is None:
            continue
        spec = specs[d["seed"]]
        caption = words.get(key, "a successful trial of the learned skill" if key == "success_trial"
                            else "recovery from a push through a transition the robot added")
        observer = None
        if key in view_trials:
            from ..view.stream import TrialStream
            observer = TrialStream(model.apn, out / "view" / f"{key}.rrd", title=f"{caption} (seed {spec.seed})",
                                   live=view_live)
        trace, push_time = _trial(model, job, spec.seed, spec.push, qpos_every if job.cfg.videos else 0, observer)
        events = [(push_time, "push")] if push_time is not None else []
        plot = motion_plot(trace, job.task.PLOT_VARIABLES, out / "plots" / f"{key}.png",
                           title=f"{caption} (seed {trace.seed}, {trace.outcome})", events=events)
        art["plots"][key] = {"file": str(plot.relative_to(out)), "caption": caption, "figure": figure,
                             "fired": trace.fired(), "seed": trace.seed, "push_time": push_time}
        if observer is not None:
            judges = model.judges()
            if judges:
                observer.grade(model.grade(trace, f"view_{key}", judges))
            observer.close()
            art.setdefault("views", {})[key] = {"file": str(observer.path.relative_to(out)), "caption": caption}
        if job.cfg.videos and trace.qpos is not None:
            path = out / "videos" / f"{key}.mp4"
            write_video(model, trace, path, fps, push_time)
            art["videos"][key] = {"file": str(path.relative_to(out)), "caption": caption}
    job.metrics["artifacts"] = art


def rebuild(run_dir: str | Path, view: bool = False) -> Path:
    """Redraw a finished run's pictures (rerunning its two picked trials from their seeds) and its
    page, from the run's ``metrics.json``; with ``view``, also save those trials' rerun recordings."""
    from ..io import write_json
    from ..job import Job, JobConfig
    from .page import build_report
    run = Path(run_dir)
    metrics = read_json(run / "metrics.json")
    cfg = JobConfig(**{k: v for k, v in metrics.get("config", {}).items() if k in JobConfig.__dataclass_fields__})
    job = Job(metrics.get("task_spec", metrics["task"]), run, cfg, log=lambda s: None, progress=False)
    job.metrics = metrics
    trials = read_json(run / "evaluation_trials.json")
    main = {"trials_detail": next(iter(trials.values()), [])}
    for k, v in evaluation_split(main["trials_detail"]).items():
        metrics.setdefault(k, v)
    write_artifacts(job, SkillModel(run / "model"), main, view_trials=("success_trial", "recovery_trial") if view else ())
    write_json(run / "metrics.json", metrics)
    return build_report(run, metrics)
