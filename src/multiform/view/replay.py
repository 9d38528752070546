"""Replay a recorded demonstration or a saved trial trace into the view (an ``.rrd`` file, a live
viewer) or to an MP4 with the same overlays as the report's videos.

A demonstration is replayed on its env from its seed, reset options (start state, pushes) and
recorded commands; the replayed states must equal the recorded ones (the simulator is
deterministic), or the replay stops with an error saying where they part. A trial trace is shown as
recorded; its scene needs poses, kept in the trace (``qpos_every``) or rebuilt by running the trial
again from its seed with the skill model that ran it (``model``), checked against the trace.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import gymnasium as gym
import mujoco
import numpy as np

from ..demos.dataset import read_dataset
from ..demos.episode import Episode
from ..errors import InvalidInput
from ..model import make_env
from ..report.video import draw_lines, render_qpos, replay, write_mp4
from ..runtime.trace import Trace
from . import scene
from .stream import Recording, log_event, log_marking, log_net, log_series

TOLERANCE = 1e-9          # replayed vs recorded states: MuJoCo is deterministic on one machine


@dataclass
class Replayed:
    """What a replay shows: per tick the states, commands, the transition being executed, the marked
    places; poses every ``every`` ticks; the pushes ``(start, end)`` in seconds."""

    name: str
    dt: float
    state_names: tuple[str, ...]
    states: np.ndarray
    command_names: tuple[str, ...]
    commands: np.ndarray
    tags: np.ndarray
    places: list[str]
    every: int
    qpos: list[np.ndarray]
    env: gym.Env | None
    pushes: list[tuple[float, float]]
    firings: list[tuple[int, str]]
    marking: np.ndarray | None = None
    place_ids: tuple[str, ...] = ()
    apn: Any = None
    max_error: float = 0.0
    outcome: str = ""


def _pulses(options: dict[str, Any]) -> list[tuple[float, float]]:
    return [(float(p["time"]), float(p["time"]) + float(p["duration"])) for p in options.get("disturbances") or []]


def _tag_changes(tags: np.ndarray) -> list[tuple[int, str]]:
    return [(int(k), str(tags[k])) for k in range(len(tags)) if tags[k] and (k == 0 or tags[k] != tags[k - 1])]


def replay_demo(path: str | os.PathLike, index: int = 0, every: int = 33) -> Replayed:
    """Replay demonstration ``index`` of the file at ``path`` on its env; raises
    :class:`InvalidInput` when the index does not exist or the replay departs from the recording."""
    import multiform.envs  # noqa: F401  (registers the envs)
    from ..petri.skillfile import load_skill
    ds = read_dataset(path)
    if not 0 <= index < len(ds.episodes):
        raise InvalidInput(f"has {len(ds.episodes)} demonstration(s); there is no demo {index}", file=str(path),
                           element="--demo")
    ep: Episode = ds.episodes[index]
    if ds.meta.get("teaching"):
        raise InvalidInput(f"holds {ds.meta['teaching']} demonstrations: the mentor guided the arm, and its "
                           "forces are never recorded, so a demonstration does not replay from its recorded commands "
                           "(the commands recovered from the arm's motion drive its servo, not the person's arm)",
                           file=str(path), element=f"demo_{index}")
    env = make_env(ds.env_name, ds.env_kwargs, str(path), render_mode="rgb_array", shadows=False)
    obs, snaps = replay(env, ep, qpos_every=every)
    n = min(len(obs), ep.num_samples)
    # the replayed states rounded as the file stores them (float32 by default) match it to the last bit
    stored = np.asarray(obs[:n], dtype=ds.meta.get("obs_dtype", "float64")).astype(np.float64)
    diff = np.abs(stored - ep.obs[:n])
    err = float(diff.max()) if n else 0.0
    if n != ep.num_samples or not err <= TOLERANCE:
        bad = int(np.argmax(np.any(diff > TOLERANCE, axis=1))) if n else 0
        env.close()
        raise InvalidInput(f"demo {index} does not replay as recorded: the states part at sample {bad} of "
                           f"{ep.num_samples} (largest difference {err:.3g})", file=str(path), element=f"demo_{index}")
    try:
        apn = load_skill(ds.skill)
    except Exception:                 # a demo file of a skill this installation does not have
        apn = None
    tags = np.asarray(ep.transitions).astype(str)
    places = []
    for t in tags:
        tr = apn.transition(t) if apn is not None and t in apn.transition_ids else None
        places.append(", ".join(tr.outputs) if tr is not None else "")
    return Replayed(name=f"{Path(path).name} demo {index}", dt=ep.dt, state_names=tuple(ep.observation_names),
                    states=ep.obs, command_names=tuple(ep.command_names), commands=ep.actions, tags=tags, places=places,
                    every=every, qpos=snaps, env=env, pushes=_pulses(dict(ep.reset_options)),
                    firings=_tag_changes(tags), max_error=err, outcome=ep.outcome)


def replay_trace(path: str | os.PathLike, model_dir: str | os.PathLike | None = None, every: int = 33) -> Replayed:
    """A saved trial trace; with ``model_dir`` its scene is rebuilt by running the trial again (the
    net version it ran, its seed and options) and checked to give the same states."""
    trace = Trace.load(path)
    env, snaps, apn, err = None, [], None, 0.0
    if trace.qpos is not None and model_dir is None:
        raise InvalidInput("keeps poses but names no env; give --model, the skill model that ran it", file=str(path))
    if model_dir is not None:
        from ..model import SkillModel
        model = SkillModel(model_dir)
        apn = model.history.version(trace.net_version)
        env = model.make_env(render_mode="rgb_array", shadows=False)
        if trace.qpos is not None:
            snaps, every = list(trace.qpos), trace.qpos_every
        else:
            again = model.executor(env, apn).run(seed=trace.seed, options=trace.options, qpos_every=every)
            n = min(again.num_ticks, trace.num_ticks)
            err = float(np.max(np.abs(again.obs[:n] - trace.obs[:n]))) if n else 0.0
            if again.num_ticks != trace.num_ticks or err > TOLERANCE or again.fired() != trace.fired():
                env.close()
                raise InvalidInput(f"running trial seed {trace.seed} again with net version {trace.net_version} "
                                   f"does not give the recorded trial (largest state difference {err:.3g}; a push "
                                   f"during the trial is not stored in its trace); replay it without --model to see "
                                   f"its series, marking and firings without the scene", file=str(path))
            snaps = list(again.qpos)
    tags = trace.tags()
    places = [", ".join(p for p, k in zip(trace.place_ids, row) if k > 0) for row in trace.marking]
    return Replayed(name=f"{Path(path).name}", dt=trace.dt, state_names=tuple(trace.value_names), states=trace.values,
                    command_names=tuple(trace.command_names), commands=trace.commands, tags=tags, places=places,
                    every=every, qpos=snaps, env=env, pushes=[], firings=[(f.tick, f.transition) for f in trace.firings],
                    marking=trace.marking, place_ids=tuple(trace.place_ids), apn=apn, max_error=err,
                    outcome=trace.outcome)


def to_recording(r: Replayed, path: str | os.PathLike, live: str | None = None) -> Path:
    """The replay as a rerun recording (the entities of :mod:`multiform.view.stream`)."""
    out = Recording(path, f"replay of {r.name}", live)
    rec = out.rec
    try:
        ticks = np.arange(len(r.states))
        log_series(rec, "state", r.state_names, ticks, r.dt, np.asarray(r.states, np.float64))
        log_series(rec, "command", r.command_names, ticks, r.dt, np.asarray(r.commands, np.float64))
        if r.marking is not None:          # a trial: the net's marking and firings
            if r.apn is not None:
                log_net(rec, r.apn)
            log_marking(rec, r.apn, 0, r.dt, r.marking[0], None, r.place_ids)
            for k, t in r.firings:
                log_marking(rec, r.apn, k, r.dt, r.marking[k], t, r.place_ids)
        else:                               # a demonstration: what the mentor said it was doing
            for k, t in r.firings:
                log_event(rec, k, r.dt, f"the mentor: {t}")
        for a, b in r.pushes:
            log_event(rec, int(round(a / r.dt)), r.dt, "push", "WARN")
            log_event(rec, int(round(b / r.dt)), r.dt, "push ends")
        if r.env is not None and r.qpos:
            base = r.env.unwrapped
            m, d = base.model, base.data
            bodies, tendons = scene.scene_bodies(m), scene.scene_tendons(m)
            scene.log_geometry(rec, m, bodies)
            xpos, xquat, strings = [], [], []
            for q in r.qpos:
                d.qpos[:] = q
                mujoco.mj_forward(m, d)
                xpos.append(d.xpos[bodies].copy())
                xquat.append(d.xquat[bodies].copy())
                strings.append(scene.tendon_paths(d, tendons))
            ticks = np.arange(len(r.qpos)) * r.every
            scene.log_poses(rec, m, bodies, ticks, r.dt, np.array(xpos), np.array(xquat))
            if tendons:
                scene.log_tendons(rec, m, tendons, ticks, r.dt, strings)
        if r.outcome:
            log_event(rec, len(r.states) - 1, r.dt, f"outcome: {r.outcome}")
    except BaseException:
        out.abandon()
        raise
    return out.close()


def labels(r: Replayed, i: int) -> list[str]:
    """The overlay of frame ``i``: time, place, transition, and the push while it acts (+0.5 s)."""
    k = min(i * r.every, len(r.states) - 1)
    t = k * r.dt
    lines = [f"t = {t:6.2f} s", f"place: {r.places[k] or '-'}", f"transition: {r.tags[k] or '-'}"]
    if any(a <= t < b + 0.5 for a, b in r.pushes):
        lines.append("PUSH")
    return lines


def to_video(r: Replayed, path: str | os.PathLike) -> Path:
    """The replay as an MP4 (one frame per ``every`` ticks) with the overlay on every frame."""
    if r.env is None or not r.qpos:
        raise InvalidInput("has no poses to render: give --model, the skill model that ran the trial",
                           element="--video")
    frames = (draw_lines(f, labels(r, i)) for i, f in enumerate(render_qpos(r.env.unwrapped, r.qpos)))
    return write_mp4(frames, path, fps=1.0 / (r.every * r.dt))
