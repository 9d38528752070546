"""The pictures and videos of a run folder: nets per version, motion plots of chosen trials,
practice progress, success rates, MP4s.

They are made from plain data (the run's metrics, its settings, its model directory) and the task
the caller names. A run folder is data: redrawing one (:func:`rebuild`) runs the task the user
names (on the command line, or a bundled or installed task's plain name), never a module or file
that ``metrics.json`` names, and refuses a configuration out of the ranges the command line allows.
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from dataclasses import MISSING, dataclass
from pathlib import Path
from typing import Any

from ..runtime.perturb import TrialSpec, run_spec
from ..errors import InvalidInput, Problem
from ..io import read_json
from ..model import SkillModel
from ..stats import evaluation_split
from ..petri.diagram import changed_elements, draw
from ..task import Task
from .page import word
from .plots import motion_plot, practice_plot, rates_plot

MAX_EVAL_TRIALS = 1_000_000
MAX_SEED = 2**31 - 1
_NAME = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_.-]{0,99}")      # a scenario's name: a folder of the run


@dataclass(frozen=True)
class RunSettings:
    """What the pictures of a run need of its configuration: which evaluation trials it ran
    (``eval_trials``, ``seed``, ``push_fraction``), whether the learned inverse model drove the
    joints and whether to render videos."""

    eval_trials: int
    seed: int
    push_fraction: float
    inverse_model: bool = True
    videos: bool = True

    @classmethod
    def from_config(cls, config: Any, file: str) -> RunSettings:
        """The settings in ``metrics.json``'s ``config``, each checked against the range the command
        line allows (a number from a file bounds the work a redraw does)."""
        if not isinstance(config, Mapping):
            raise InvalidInput("must be an object", file=file, element="config")
        ranges = {"eval_trials": (1, MAX_EVAL_TRIALS), "seed": (0, MAX_SEED), "push_fraction": (0.0, 1.0)}
        values, problems = {}, []
        for key, field in cls.__dataclass_fields__.items():
            v = values[key] = config.get(key, field.default)
            if v is MISSING:
                problems.append(Problem(file, f"config.{key}", "missing"))
                continue
            if key not in ranges:
                ok, want = isinstance(v, bool), "true or false"
            else:
                low, high = ranges[key]
                whole = isinstance(low, int)
                ok = (not isinstance(v, bool) and isinstance(v, int if whole else (int, float)) and low <= v <= high)
                want = f"a {'whole ' if whole else ''}number in {low}..{high}"
            if not ok:
                problems.append(Problem(file, f"config.{key}", f"must be {want}, got {str(v)[:40]!r}"))
        if problems:
            raise InvalidInput(problems)
        return cls(**values)


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


def _trial(model: SkillModel, task: Task, inverse_model: bool, seed: int, push: dict[str, Any] | None,
           qpos_every: int, observer: Any = None):
    """Rerun evaluation trial ``seed``; returns the trace and the push's time (None without one)."""
    env = model.make_env(render_mode="rgb_array")
    try:
        ex = model.executor(env, use_inverse_model=inverse_model)
        kw = {"observer": observer} if observer is not None else {}
        trace, hand = run_spec(ex, TrialSpec(seed, task.trial_options(seed), push), qpos_every=qpos_every, **kw)
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


def write_artifacts(out: Path, task: Task, model: SkillModel, metrics: dict[str, Any], main: dict[str, Any],
                    settings: RunSettings, view_trials: tuple[str, ...] = (), view_live: str | None = None) -> None:
    """Fill the run folder ``out`` and ``metrics['artifacts']``; ``main`` holds the evaluation's
    ``trials_detail`` (the picked trials are rerun from their seeds with ``task``). The picked trials
    named in ``view_trials`` are also saved as rerun recordings (``view/<name>.rrd``) and sent to
    the viewer ``view_live`` (see :func:`multiform.view.stream.viewer_url`)."""
    out = Path(out)
    art: dict[str, Any] = {"plots": {}, "videos": {}}
    titles = {k: s.get("title", k) for k, s in metrics.get("scenarios", {}).items()}
    scenario_of = {r["version"]: titles.get(r["scenario"], r["scenario"]) for r in metrics.get("revisions", [])
                   if r.get("version")}
    art["nets"] = draw_versions(model, out / "nets", scenario_of)
    for name, s in metrics.get("scenarios", {}).items():
        state = read_json(out / "practice" / name / "state.json")
        revs = [r for r in state["revisions"] if r.get("operator") != "none"]
        p = practice_plot(state["trials"], revs, out / "plots" / f"practice_{name}.png", title=s["title"])
        s["plot"] = str(p.relative_to(out))
    rows = [{k: r[k] for k in ("name", "rate", "low", "high", "successes", "trials")} for r in metrics.get("ablation", [])]
    if rows:
        art["plots"]["evaluation"] = str(rates_plot(rows, out / "plots" / "evaluation.png",
                                                    "success over the evaluation trials").relative_to(out))
    detail = main.get("trials_detail", [])
    fps = 30
    qpos_every = int(round(1.0 / (fps * 1e-3)))
    added = {r["target"] for r in metrics.get("revisions", []) if r["operator"] == "add_transition"}
    picks = {
        "success_trial": next((d for d in detail if d["success"] and not d["pushed"]), None),
        "recovery_trial": next((d for d in detail if d["success"] and d["pushed"] and set(d["fired"]) & added), None),
    }
    specs = {s.seed: s for s in task.evaluation_specs(settings.eval_trials, settings.seed, settings.push_fraction)}
    words = getattr(task, "REPORT", {})
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
        trace, push_time = _trial(model, task, settings.inverse_model, spec.seed, spec.push,
                                  qpos_every if settings.videos else 0, observer)
        events = [(push_time, "push")] if push_time is not None else []
        plot = motion_plot(trace, task.PLOT_VARIABLES, out / "plots" / f"{key}.png",
                           title=f"{caption} (seed {trace.seed}, {trace.outcome})", events=events)
        art["plots"][key] = {"file": str(plot.relative_to(out)), "caption": caption, "figure": figure,
                             "fired": trace.fired(), "seed": trace.seed, "push_time": push_time}
        if observer is not None:
            judges = model.judges()
            if judges:
                observer.grade(model.grade(trace, f"view_{key}", judges))
            observer.close()
            art.setdefault("views", {})[key] = {"file": str(observer.path.relative_to(out)), "caption": caption}
        if settings.videos and trace.qpos is not None:
            path = out / "videos" / f"{key}.mp4"
            write_video(model, trace, path, fps, push_time)
            art["videos"][key] = {"file": str(path.relative_to(out)), "caption": caption}
    metrics["artifacts"] = art


def rebuild(run_dir: str | Path, task: Task, view: bool = False) -> Path:
    """Redraw a finished run's pictures (rerunning its two picked trials from their seeds with
    ``task``, which the caller names: never one the folder names) and its page, from the run's
    ``metrics.json``; with ``view``, also save those trials' rerun recordings."""
    from ..io import write_json
    from .page import build_report
    run = Path(run_dir)
    file = str(run / "metrics.json")
    metrics = read_json(run / "metrics.json", "run metrics (is this a run folder?)")
    if not isinstance(metrics, dict):
        raise InvalidInput("must be a JSON object", file=file)
    settings = RunSettings.from_config(metrics.get("config", {}), file)
    scenarios = metrics.get("scenarios", {})
    if not isinstance(scenarios, dict):
        raise InvalidInput("must be an object", file=file, element="scenarios")
    for name in scenarios:          # each names a folder of the run: practice/NAME
        if not _NAME.fullmatch(name) or name.startswith("."):
            raise InvalidInput(f"scenario name {name[:40]!r} is not a name (letters, digits, _ . -)", file=file,
                               element="scenarios")
    trials = read_json(run / "evaluation_trials.json", "evaluation trials")
    if not isinstance(trials, dict) or not all(isinstance(v, list) for v in trials.values()):
        raise InvalidInput("must map each variant to its list of trials", file=str(run / "evaluation_trials.json"))
    main = {"trials_detail": next(iter(trials.values()), [])}
    if len(main["trials_detail"]) != settings.eval_trials:
        raise InvalidInput(f"holds {len(main['trials_detail'])} evaluation trials, metrics.json's config.eval_trials "
                           f"says {settings.eval_trials}", file=str(run / "evaluation_trials.json"))
    for k, v in evaluation_split(main["trials_detail"]).items():
        metrics.setdefault(k, v)
    write_artifacts(run, task, SkillModel(run / "model"), metrics, main, settings,
                    view_trials=("success_trial", "recovery_trial") if view else ())
    write_json(run / "metrics.json", metrics)
    return build_report(run, metrics)
