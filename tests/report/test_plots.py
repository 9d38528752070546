"""The report's plots say what happened: every firing labelled, revisions where the new net first ran,
whole trial numbers, rate labels clear of the error bars."""

from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np
import pytest

from multiform.petri.firing import Firing
from multiform.report.plots import motion_figure, practice_figure, rates_figure, revision_lines
from multiform.runtime.trace import Trace


def trace_with(fired: list[tuple[float, str]], seconds: float = 10.0, dt: float = 0.001) -> Trace:
    n = int(seconds / dt)
    t = np.arange(n) * dt
    obs = np.stack([np.sin(t), np.cos(t)], axis=1).astype(np.float32)
    marking = np.zeros((n, 3), np.int16)
    marking[:, 1] = 1
    return Trace(seed=1, dt=dt, obs=obs, observation_names=("theta", "omega"), values=obs.copy(),
                 value_names=("theta", "omega"), commands=obs[:, :1].copy(), raw_commands=obs[:, :1].copy(),
                 command_names=("v_cmd",), marking=marking, dwell=np.zeros((n, 3), np.float32),
                 place_ids=("P0", "P1", "P2"), firings=[Firing(int(round(s / dt)), s, tr) for s, tr in fired],
                 outcome="success")


def _boxes(fig, gid):
    fig.canvas.draw()
    r = fig.canvas.get_renderer()
    return [(a.get_text(), a.get_window_extent(r)) for a in fig.findobj(lambda a: a.get_gid() == gid)]


def test_every_firing_is_labelled_in_order_and_no_label_hides_another():
    # the recovery trial of the issue: t3 and t7 a few ms apart, t1 right after t2
    fired = [(0.0, "t0"), (2.0, "t2"), (4.0, "t2"), (5.2, "t1"), (7.95, "t3"), (7.96, "t7"), (8.5, "t1"),
             (8.52, "t7"), (9.0, "t1"), (9.9, "t6")]
    tr = trace_with(fired)
    fig = motion_figure(tr, [("theta", "θ"), ("omega", "ω")], events=[(7.9, "push")])
    labels = sorted(_boxes(fig, "firing"), key=lambda x: (x[1].x0, x[1].y0))
    assert [text for text, _ in labels] == tr.fired()
    events = _boxes(fig, "event")
    assert [text for text, _ in events] == ["push"]
    boxes = [b for _, b in labels + events]
    assert not any(a.overlaps(b) for i, a in enumerate(boxes) for b in boxes[i + 1:])
    plt.close(fig)


TRIALS = [{"trial": k, "net_version": 0 if k < 3 else 1, "success": k >= 3, "judge_score": 0.1 if k < 3 else 0.9}
          for k in range(8)]
REVISION = {"version": 1, "operator": "set_condition", "target": "t1", "after_trial": 2}


def test_the_revision_line_stands_before_the_first_trial_that_ran_the_new_version():
    fig = practice_figure(TRIALS, [REVISION])
    (line,) = fig.findobj(lambda a: a.get_gid() == "revision v1")
    x = line.get_xdata()[0]
    dots = np.concatenate([c.get_offsets()[:, 0] for c in fig.findobj(lambda a: a.get_gid() == "outcome")])
    assert sorted(dots) == [t["trial"] for t in TRIALS]          # numbered as the practice log numbers them
    assert all(t["net_version"] < 1 for t in TRIALS if t["trial"] < x)
    assert all(t["net_version"] >= 1 for t in TRIALS if t["trial"] > x)
    assert x == pytest.approx(2.5)
    ax = fig.axes[0]
    assert all(float(v).is_integer() for v in ax.get_xticks())   # trial numbers are whole
    plt.close(fig)


def test_revisions_made_together_share_one_label():
    """A round of refits (one revision per law, the same trials before and after) is one line with
    one label that counts them, not labels printed over each other."""
    laws = ["pump", "swing", "release"]
    revs = [{"version": 1 + i, "operator": "refit_law", "target": law, "after_trial": 2} for i, law in enumerate(laws)]
    trials = [{**t, "net_version": 0 if t["trial"] < 3 else 3} for t in TRIALS]
    fig = practice_figure(trials, revs + [{"version": 4, "operator": "revert", "target": "version 0", "after_trial": 5}])
    labels = [a.get_text() for a in fig.findobj(lambda a: a.get_gid() == "revision label")]
    assert labels == ["v1–v3: law refitted ×3", "v4: revision reverted of version 0"]
    assert all(fig.findobj(lambda a, v=v: a.get_gid() == f"revision v{v}") for v in (1, 2, 3, 4))
    plt.close(fig)


def test_a_revision_no_trial_ran_goes_after_the_last_trial():
    assert revision_lines(TRIALS[:3], [{**REVISION}]) == [(2.5, REVISION)]


def test_few_trials_still_get_whole_numbers_on_the_axis():
    fig = practice_figure(TRIALS[:3], [])
    ax = fig.axes[0]
    ticks = [v for v in ax.get_xticks() if ax.get_xlim()[0] <= v <= ax.get_xlim()[1]]
    assert ticks and all(float(v).is_integer() for v in ticks)
    plt.close(fig)


def test_rate_and_name_labels_cross_no_error_bar():
    rows = [{"name": "multiform (definition + demonstration + evaluation, with repair)", "rate": 0.985,
             "low": 0.957, "high": 0.995, "successes": 197, "trials": 200},
            {"name": "definition + demonstration, no repair (t1 written workable by hand)", "rate": 0.5,
             "low": 0.404, "high": 0.596, "successes": 50, "trials": 100},
            {"name": "demonstration only", "rate": 0.0, "low": 0.0, "high": 0.037, "successes": 0, "trials": 100}]
    fig = rates_figure(rows)
    fig.canvas.draw()
    r = fig.canvas.get_renderer()
    ax = fig.axes[0]
    bars = [c for c in ax.containers if hasattr(c, "errorbar")][0]
    whiskers = [seg for coll in bars.errorbar.lines[2] for seg in coll.get_segments()]
    caps = [line for line in bars.errorbar.lines[1]]
    spans = [ax.transData.transform(seg) for seg in whiskers]
    spans += [ax.transData.transform(pt[None, :]) for c in caps for pt in np.column_stack(c.get_data())]
    texts = [a for a in fig.findobj(lambda a: a.get_gid() in ("rate", "name"))]
    assert len(texts) == 2 * len(rows)
    for t in texts:
        box = t.get_window_extent(r)
        for pts in spans:
            x0, y0 = pts.min(axis=0) - 4        # a cap is a marker a few points tall around its end
            x1, y1 = pts.max(axis=0) + 4
            assert not (box.x0 < x1 and box.x1 > x0 and box.y0 < y1 and box.y1 > y0), t.get_text()
    plt.close(fig)
