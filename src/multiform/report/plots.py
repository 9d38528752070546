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
import numpy as np  # noqa: E402

from ..io import atomic_path  # noqa: E402
from ..runtime.trace import Trace  # noqa: E402

PLACE_COLOURS = ["#e8f1fa", "#fdf0e2", "#e6f5ea", "#f3e8f7", "#fbe9e9", "#eef3e1", "#f5f5dc"]


def _save(fig: plt.Figure, path: str | os.PathLike) -> Path:
    path = Path(path)
    with atomic_path(path, suffix=path.suffix) as tmp:
        fig.savefig(tmp, format=path.suffix.lstrip(".") or "png", dpi=110, bbox_inches="tight")
    plt.close(fig)
    return path


def motion_plot(trace: Trace, variables: Sequence[tuple[str, str]], path: str | os.PathLike,
                title: str = "", commands: bool = True) -> Path:
    """One panel per variable ``(name, axis label)``; firings as vertical lines, places as shading."""
    t = trace.time
    n = len(variables) + (1 if commands else 0)
    fig, axes = plt.subplots(n, 1, figsize=(9, 1.6 * n + 0.6), sharex=True)
    axes = np.atleast_1d(axes)
    # token place per tick: the first marked non-final place
    marked = trace.marking > 0
    spans = []
    current, start = None, 0
    for k in range(len(t)):
        where = np.flatnonzero(marked[k])
        p = trace.place_ids[where[0]] if len(where) else None
        if p != current:
            if current is not None:
                spans.append((current, start, k))
            current, start = p, k
    if current is not None:
        spans.append((current, start, len(t)))
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
        ax.grid(alpha=0.3, lw=0.4)
        ax.tick_params(labelsize=8)
    top = axes[0]
    shown = 0.0
    for f in trace.firings:
        if f.time - shown > 0.04 * max(t[-1], 1e-9) or shown == 0.0:
            top.annotate(f.transition, (f.time, 1.0), xycoords=("data", "axes fraction"), fontsize=7,
                         color="#c0392b", ha="left", va="bottom")
            shown = f.time
    handles = [matplotlib.patches.Patch(color=colour[p], label=p) for p, _, _ in
               {s[0]: s for s in spans}.values()]
    axes[-1].set_xlabel("time [s]")
    fig.legend(handles=handles, loc="lower center", ncol=len(handles), fontsize=8, title="token in",
               title_fontsize=8, bbox_to_anchor=(0.5, -0.02))
    fig.suptitle(title or f"trial seed {trace.seed}: {trace.outcome}", fontsize=10)
    fig.tight_layout(rect=(0, 0.04, 1, 0.98))
    return _save(fig, path)


def practice_plot(trials: Sequence[dict[str, Any]], revisions: Sequence[dict[str, Any]], path: str | os.PathLike,
                  title: str = "practice") -> Path:
    """Each practice trial as a dot (success up, failure down) with the judges' score, revisions as lines."""
    fig, ax = plt.subplots(figsize=(9, 2.8))
    idx = np.arange(1, len(trials) + 1)
    ok = np.array([tr["success"] for tr in trials], dtype=float)
    score = np.array([tr.get("judge_score", np.nan) for tr in trials], dtype=float)
    explored = np.array([bool(tr.get("explored")) for tr in trials], dtype=bool)
    colours = ["#1b9e77" if s else "#c0392b" for s in ok]
    ax.scatter(idx[~explored], ok[~explored], c=[c for c, e in zip(colours, explored) if not e], s=18, zorder=3,
               label="outcome")
    if explored.any():
        ax.scatter(idx[explored], ok[explored], facecolors="none", edgecolors=[c for c, e in zip(colours, explored) if e],
                   s=18, zorder=3, label="outcome, exploring trial")
    ax.plot(idx, score, color="#7570b3", lw=1, marker=".", ms=4, label="judges' score")
    plain = ~explored
    if plain.sum() >= 2:            # the skill as it is: the exploring trials try variations of it
        w = min(10 if explored.any() else 5, int(plain.sum()))
        ax.plot(idx[plain], np.convolve(ok[plain], np.ones(w) / w, mode="full")[: int(plain.sum())], color="#555",
                lw=1, ls=":", label=f"success rate (last {w}{' plain' if explored.any() else ''})")
    for r in revisions:
        k = r.get("after_trial")
        if k is None:
            continue
        ax.axvline(k + 0.5, color="#d95f02", lw=1.2)
        ax.annotate(f"{r['operator']} {r['target']}", (k + 0.6, 0.5), fontsize=7, color="#d95f02", rotation=90,
                    va="center")
    ax.set_ylim(-0.1, 1.1)
    ax.set_xlabel("practice trial")
    ax.set_yticks([0, 0.5, 1], ["fail", "0.5", "success"])
    ax.grid(alpha=0.3, lw=0.4)
    ax.legend(fontsize=7, loc="lower right")
    ax.set_title(title, fontsize=10)
    fig.tight_layout()
    return _save(fig, path)


def rates_plot(rows: Sequence[dict[str, Any]], path: str | os.PathLike, title: str = "success rate") -> Path:
    """Horizontal bars of success rates with Wilson 95 % intervals (``name, rate, low, high``)."""
    fig, ax = plt.subplots(figsize=(7, 0.55 * len(rows) + 1.0))
    y = np.arange(len(rows))[::-1]
    rate = np.array([r["rate"] for r in rows])
    lo = rate - np.array([r["low"] for r in rows])
    hi = np.array([r["high"] for r in rows]) - rate
    ax.barh(y, rate, color="#1f4e79", alpha=0.8, xerr=[lo, hi], capsize=3)
    ax.set_yticks(y, [r["name"] for r in rows], fontsize=8)
    for yy, r in zip(y, rows):
        ax.text(min(r["rate"] + 0.02, 0.9), yy, f"{100 * r['rate']:.0f} %", va="center", fontsize=8)
    ax.set_xlim(0, 1.05)
    ax.set_xlabel("success rate (Wilson 95 % interval)")
    ax.set_title(title, fontsize=10)
    ax.grid(axis="x", alpha=0.3)
    fig.tight_layout()
    return _save(fig, path)
