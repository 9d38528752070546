"""Plots of a run: motion variables with the transitions marked (the paper's Fig. 7), practice
progress with the revisions marked, and success rates with their intervals."""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import matplotlib.ticker  # noqa: E402
import numpy as np  # noqa: E402

from ..io import atomic_path  # noqa: E402
from ..runtime.trace import Trace  # noqa: E402
from .page import word  # noqa: E402

PLACE_COLOURS = ["#e8f1fa", "#fdf0e2", "#e6f5ea", "#f3e8f7", "#fbe9e9", "#eef3e1", "#f5f5dc"]


def _save(fig: plt.Figure, path: str | os.PathLike) -> Path:
    path = Path(path)
    with atomic_path(path, suffix=path.suffix) as tmp:
        fig.savefig(tmp, format=path.suffix.lstrip(".") or "png", dpi=110, bbox_inches="tight")
    plt.close(fig)
    return path


def motion_figure(trace: Trace, variables: Sequence[tuple[str, str]], title: str = "",
                  commands: bool = True, events: Sequence[tuple[float, str]] = ()) -> plt.Figure:
    """The figure of :func:`motion_plot`: every firing labelled above the top panel (labels that would
    overlap go up a row), ``events`` ``(time, text)`` such as a push drawn as dashed lines."""
    t = trace.time
    n = len(variables) + (1 if commands else 0)
    fig, axes = plt.subplots(n, 1, figsize=(9, 1.6 * n + 0.6), sharex=True)
    axes = np.atleast_1d(axes)
    spans = token_spans(trace)
    colour = {p: PLACE_COLOURS[i % len(PLACE_COLOURS)] for i, p in enumerate(trace.place_ids)}
    for ax, (name, label) in zip(axes, variables):
        ax.plot(t, trace.value(name), lw=1.0, color="#1f4e79")
        ax.set_ylabel(label, fontsize=9)
    if commands:
        ax = axes[-1]
        for j, c in enumerate(trace.command_names):
            ax.plot(t, trace.commands[:, j], lw=0.9, label=f"{c} (applied)")
            ax.plot(t, trace.raw_commands[:, j], lw=0.6, ls="--", alpha=0.7, label=f"{c} (law)")
        ax.set_ylabel("command", fontsize=9)
        ax.legend(fontsize=7, loc="upper right", ncol=2)
    for ax in axes:
        for p, a, b in spans:
            ax.axvspan(t[a], t[min(b, len(t) - 1)], color=colour[p], alpha=0.8, lw=0, zorder=0)
        for f in trace.firings:
            ax.axvline(f.time, color="#c0392b", lw=0.6, alpha=0.6)
        for when, _ in events:
            ax.axvline(when, color="#7b3294", lw=1.0, ls="--")
        ax.grid(alpha=0.3, lw=0.4)
        ax.tick_params(labelsize=8)
    handles = [matplotlib.patches.Patch(color=colour[p], label=p) for p, _, _ in
               {s[0]: s for s in spans}.values()]
    axes[-1].set_xlabel("time [s]")
    fig.legend(handles=handles, loc="lower center", ncol=max(1, len(handles)), fontsize=8, title="token in",
               title_fontsize=8, bbox_to_anchor=(0.5, -0.02))
    fig.suptitle(title or f"trial seed {trace.seed}: {trace.outcome}", fontsize=10)
    fig.tight_layout(rect=(0, 0.04, 1, 0.98))
    _label_firings(fig, axes[0], trace, events)
    fig.tight_layout(rect=(0, 0.04, 1, 0.98))
    return fig


def _label_firings(fig: plt.Figure, top: plt.Axes, trace: Trace, events: Sequence[tuple[float, str]]) -> None:
    """One label per firing (gid ``firing``) and per event (gid ``event``) above ``top``, each in the
    lowest row where it overlaps no earlier label, so none hides another."""
    renderer = fig.canvas.get_renderer()
    rows: list[list[Any]] = []
    labels = [(f.time, f.transition, "#c0392b", "firing") for f in trace.firings]
    labels += [(when, text, "#7b3294", "event") for when, text in events]
    for when, text, colour, gid in sorted(labels, key=lambda x: x[0]):
        for r in range(len(rows) + 1):
            if r == len(rows):
                rows.append([])
            art = top.annotate(text, (when, 1.0), xycoords=("data", "axes fraction"), xytext=(1, 2 + 9 * r),
                               textcoords="offset points", fontsize=7, color=colour, ha="left", va="bottom",
                               gid=gid, annotation_clip=False)
            box = art.get_window_extent(renderer).expanded(1.05, 1.0)
            if not any(box.overlaps(b) for b in rows[r]):
                rows[r].append(box)
                break
            art.remove()


def token_spans(trace: Trace) -> list[tuple[str, int, int]]:
    """``(place, first tick, end tick)`` of each stay of the token (the first marked place per tick)."""
    marked = trace.marking > 0
    spans: list[tuple[str, int, int]] = []
    current, start = None, 0
    for k in range(trace.num_ticks):
        where = np.flatnonzero(marked[k])
        p = trace.place_ids[where[0]] if len(where) else None
        if p != current:
            if current is not None:
                spans.append((current, start, k))
            current, start = p, k
    if current is not None:
        spans.append((current, start, trace.num_ticks))
    return spans


def motion_plot(trace: Trace, variables: Sequence[tuple[str, str]], path: str | os.PathLike,
                title: str = "", commands: bool = True, events: Sequence[tuple[float, str]] = ()) -> Path:
    """One panel per variable ``(name, axis label)``; firings as labelled vertical lines, places as
    shading, ``events`` (e.g. the push) as dashed lines (the paper's Figs. 7 and 11)."""
    return _save(motion_figure(trace, variables, title, commands, events), path)


def revision_lines(trials: Sequence[dict[str, Any]], revisions: Sequence[dict[str, Any]]) -> list[tuple[float, dict]]:
    """Where each revision goes on the practice axis: half a trial before the first trial that ran
    its version (or after the last trial when none ran it)."""
    out = []
    for r in revisions:
        v = r.get("version")
        first = next((t["trial"] for t in trials if v is not None and t.get("net_version", 0) >= v), None)
        if first is None:
            if r.get("after_trial") is None:
                continue
            first = r["after_trial"] + 1
        out.append((first - 0.5, r))
    return out


def _revisions_label(rs: Sequence[dict[str, Any]]) -> str:
    """One label for revisions on one line, short enough to stay inside the axes: "v6–v10: law
    refitted ×5" when they share an operator (the page's table names each), each in turn otherwise."""
    ops = {r["operator"] for r in rs}
    if len(rs) > 1 and len(ops) == 1:
        return f"v{rs[0].get('version')}–v{rs[-1].get('version')}: {word(rs[0]['operator'])} ×{len(rs)}"
    return "; ".join(f"v{r.get('version')}: {word(r['operator'])} of {r['target']}" for r in rs)


def practice_figure(trials: Sequence[dict[str, Any]], revisions: Sequence[dict[str, Any]],
                    title: str = "practice") -> plt.Figure:
    """The figure of :func:`practice_plot`."""
    fig, ax = plt.subplots(figsize=(9, 2.8))
    idx = np.array([tr.get("trial", i) for i, tr in enumerate(trials)], dtype=float)
    ok = np.array([tr["success"] for tr in trials], dtype=float)
    score = np.array([np.nan if tr.get("judge_score") is None else tr["judge_score"] for tr in trials], dtype=float)
    explored = np.array([bool(tr.get("explored")) for tr in trials], dtype=bool)
    colours = ["#1b9e77" if s else "#c0392b" for s in ok]
    ax.scatter(idx[~explored], ok[~explored], c=[c for c, e in zip(colours, explored) if not e], s=18, zorder=3,
               label="outcome", gid="outcome")
    if explored.any():
        ax.scatter(idx[explored], ok[explored], facecolors="none", edgecolors=[c for c, e in zip(colours, explored) if e],
                   s=18, zorder=3, label="outcome, exploring trial", gid="outcome")
    ax.plot(idx, score, color="#7570b3", lw=1, marker=".", ms=4, label="judges' score")
    plain = ~explored
    if plain.sum() >= 2:            # the skill as it is: the exploring trials try variations of it
        w = min(10 if explored.any() else 5, int(plain.sum()))
        ax.plot(idx[plain], np.convolve(ok[plain], np.ones(w) / w, mode="full")[: int(plain.sum())], color="#555",
                lw=1, ls=":", label=f"success rate (last {w}{' plain' if explored.any() else ''})")
    at: dict[float, list[dict[str, Any]]] = {}
    for x, r in revision_lines(trials, revisions):
        ax.axvline(x, color="#d95f02", lw=1.2, gid=f"revision v{r.get('version')}")
        at.setdefault(x, []).append(r)
    for x, rs in at.items():         # revisions made together (a round of refits) share one label
        ax.annotate(_revisions_label(rs), (x + 0.1, 0.5), fontsize=7, color="#d95f02", rotation=90, va="center",
                    gid="revision label")
    ax.set_ylim(-0.1, 1.1)
    if len(idx):
        ax.set_xlim(idx.min() - 0.7, idx.max() + 0.7)
    ax.xaxis.set_major_locator(matplotlib.ticker.MaxNLocator(integer=True))
    ax.set_xlabel("practice trial (numbered from 0, as in the practice log)")
    ax.set_yticks([0, 0.5, 1], ["fail", "0.5", "success"])
    ax.grid(alpha=0.3, lw=0.4)
    ax.legend(fontsize=7, loc="lower right")
    ax.set_title(title, fontsize=10)
    fig.tight_layout()
    return fig


def practice_plot(trials: Sequence[dict[str, Any]], revisions: Sequence[dict[str, Any]], path: str | os.PathLike,
                  title: str = "practice") -> Path:
    """Each practice trial as a dot (success up, failure down) with the judges' score; each revision
    as a line just before the first trial that ran the revised net."""
    return _save(practice_figure(trials, revisions, title), path)


def rates_figure(rows: Sequence[dict[str, Any]], title: str = "success rate") -> plt.Figure:
    """The figure of :func:`rates_plot`: each variant's name on its own line above its bar, the rate
    written right of the interval's upper end, so neither crosses an error bar."""
    fig, ax = plt.subplots(figsize=(8, 0.8 * len(rows) + 1.0))
    y = np.arange(len(rows))[::-1] * 1.6
    rate = np.array([r["rate"] for r in rows])
    lo = rate - np.array([r["low"] for r in rows])
    hi = np.array([r["high"] for r in rows]) - rate
    ax.barh(y, rate, height=0.7, color="#1f4e79", alpha=0.8, xerr=[lo, hi], capsize=3)
    ax.set_yticks([])
    for yy, r in zip(y, rows):
        ax.text(0.0, yy + 0.45, r["name"], va="bottom", ha="left", fontsize=8, gid="name")
        ax.text(r["high"] + 0.015, yy, f"{100 * r['rate']:.1f} % ({r['successes']}/{r['trials']})" if "trials" in r
                else f"{100 * r['rate']:.1f} %", va="center", fontsize=8, gid="rate")
    ax.set_xlim(0, 1.25)
    ax.set_ylim(-0.6, y.max() + 1.2 if len(y) else 1)
    ax.set_xticks(np.linspace(0, 1, 6), [f"{v:.0f} %" for v in np.linspace(0, 100, 6)])
    ax.set_xlabel("success rate (bar) with its Wilson 95 % interval (whiskers)")
    ax.set_title(title, fontsize=10)
    ax.grid(axis="x", alpha=0.3)
    fig.tight_layout()
    return fig


def rates_plot(rows: Sequence[dict[str, Any]], path: str | os.PathLike, title: str = "success rate") -> Path:
    """Horizontal bars of success rates with Wilson 95 % intervals (``name, rate, low, high``)."""
    return _save(rates_figure(rows, title), path)
