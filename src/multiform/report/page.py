"""The run's report page: one self-contained HTML file beside the run's pictures and videos.

Built from ``metrics.json`` and the files the run wrote (paths relative to the run folder), so it
can be rebuilt any time with ``multiform report RUN_DIR``. A small script on the page records
whether every image loaded (``data-images-ok`` on ``<html>``), which the report test reads from
headless Chromium.
"""

from __future__ import annotations

import html
import json
import os
from pathlib import Path
from typing import Any

from ..io import write_text

CSS = """
body{font-family:Helvetica,Arial,sans-serif;margin:2em auto;max-width:1100px;color:#222;line-height:1.45}
h1{font-size:1.6em;margin-bottom:.2em}h2{font-size:1.25em;border-bottom:1px solid #ddd;padding-bottom:.2em;margin-top:1.8em}
h3{font-size:1.05em}table{border-collapse:collapse;margin:.6em 0}td,th{border:1px solid #ccc;padding:.3em .6em;font-size:.9em;text-align:left}
th{background:#f3f3f3}.num{text-align:right;font-variant-numeric:tabular-nums}.ok{color:#1b7f5f;font-weight:bold}
.bad{color:#b03a2e;font-weight:bold}.fig{max-width:100%;border:1px solid #eee;margin:.4em 0}.nets{display:flex;flex-wrap:wrap;gap:1em}
.nets figure{flex:1 1 480px;margin:0}figcaption{font-size:.85em;color:#555}code{background:#f5f5f5;padding:0 .2em}
.summary td:first-child{font-weight:bold;width:15em}video{max-width:100%;border:1px solid #ddd}
"""

CHECK = """
<script>
window.addEventListener('load', function () {
  var imgs = Array.prototype.slice.call(document.images);
  var ok = imgs.filter(function (i) { return i.complete && i.naturalWidth > 0; }).length;
  document.documentElement.setAttribute('data-images', String(imgs.length));
  document.documentElement.setAttribute('data-images-ok', String(ok));
  document.documentElement.setAttribute('data-tables', String(document.querySelectorAll('table').length));
});
</script>
"""


def _e(x: Any) -> str:
    return html.escape(str(x))


def _pct(r: dict[str, Any]) -> str:
    return (f"{100 * r['rate']:.1f} % ({r['successes']}/{r['trials']}; 95 % CI "
            f"{100 * r['low']:.1f}–{100 * r['high']:.1f} %)")


def _img(src: str, alt: str, cls: str = "fig") -> str:
    return f'<img class="{cls}" src="{_e(src)}" alt="{_e(alt)}">'


def _table(rows: list[dict[str, Any]], cols: list[tuple[str, str]]) -> str:
    head = "".join(f"<th>{_e(label)}</th>" for _, label in cols)
    body = []
    for r in rows:
        cells = []
        for key, _ in cols:
            v = r.get(key, "")
            cls = ' class="num"' if isinstance(v, (int, float)) and not isinstance(v, bool) else ""
            if isinstance(v, float):
                v = f"{v:.4g}"
            cells.append(f"<td{cls}>{_e(v)}</td>")
        body.append("<tr>" + "".join(cells) + "</tr>")
    return f"<table><tr>{head}</tr>{''.join(body)}</table>"


def _learning(s: dict) -> str:
    """One sentence on what a scenario that learned from practice did ("" for the others)."""
    if "mentor_labelled_trials" not in s:
        return ""
    agree = s.get("mentor_agreement", {})
    text = (f"{s['trials']} trials, every other one exploring; {s['plain_successes']} of {s['plain_trials']} plain trials "
            f"succeeded; {s['own_segments']} segments of its own graded successful joined its laws' training data; "
            f"the mentor graded {s['mentor_labelled_trials']} trials")
    if agree.get("stays"):
        text += f" and agreed with the robot's own grade on {agree['agree']} of {agree['stays']} stays"
    stop = s.get("stop_reason", "")
    return text + f"; {s.get('robot_seconds', 0):.0f} s of robot time." + (f" Stopped: {stop}." if stop else "")


def build_report(run_dir: str | os.PathLike, metrics: dict[str, Any] | None = None) -> Path:
    """Write ``run_dir/report.html`` from ``metrics`` (default: ``run_dir/metrics.json``)."""
    run = Path(run_dir)
    if metrics is None:
        metrics = json.loads((run / "metrics.json").read_text())
    m = metrics
    art = m.get("artifacts", {})
    parts: list[str] = [f"<h1>multiform — {_e(m.get('skill', ''))}</h1>",
                        f"<p>{_e(m.get('description', ''))}</p>"]

    rows = []
    if "demos" in m:
        d = m["demos"]
        rows.append(("demonstrations", f"{d['count']} by the scripted mentor; mentor's own success "
                                       f"{_pct(d['mentor_success_rate'])}" if "mentor_success_rate" in d else d))
    if "practice_trials" in m:
        rows.append(("practice trials", m["practice_trials"]))
    if "revisions" in m:
        rows.append(("revisions of the net", len(m["revisions"])))
    if "success_rate" in m:
        sr = m["success_rate"]
        ok = "ok" if sr["rate"] >= m.get("target_success_rate", 0.95) else "bad"
        rows.append(("final success rate", f'<span class="{ok}">{_e(_pct(sr))}</span>'))
    if "timings" in m:
        rows.append(("wall time", f"{m['timings'].get('total_s', 0):.0f} s"))
    parts.append("<h2>Summary</h2><table class='summary'>" + "".join(
        f"<tr><td>{_e(k)}</td><td>{v if isinstance(v, str) and v.startswith('<span') else _e(v)}</td></tr>"
        for k, v in rows) + "</table>")

    if m.get("revisions"):
        parts.append("<h2>How the robot revised the definition</h2>")
        parts.append(_table(m["revisions"], [("version", "version"), ("scenario", "scenario"),
                                             ("after_trial", "after trial"), ("operator", "operator"),
                                             ("target", "target"), ("reason", "reason")]))
    nets = art.get("nets", [])
    if nets:
        parts.append("<h2>The net before and after each revision</h2><div class='nets'>")
        for n in nets:
            parts.append(f"<figure>{_img(n['file'], n['caption'])}<figcaption>{_e(n['caption'])}</figcaption></figure>")
        parts.append("</div>")

    scen = m.get("scenarios", {})
    if scen:
        parts.append("<h2>Practice scenarios</h2>")
        for key, s in scen.items():
            parts.append(f"<h3>{_e(s.get('title', key))}</h3><p>{_e(s.get('summary', '') or _learning(s))}</p>")
            if s.get("plot"):
                parts.append(_img(s["plot"], f"practice {key}"))
    plots = art.get("plots", {})
    for key, label in (("success_trial", "A successful trial (motion variables, transitions marked — cf. the paper's Fig. 7)"),
                       ("recovery_trial", "Recovery from a push: the added transition backs up to swing-up"),
                       ("evaluation", "Evaluation and ablations")):
        if key in plots:
            parts.append(f"<h2>{_e(label)}</h2>{_img(plots[key], label)}")
    if m.get("ablation"):
        parts.append("<h2>Ablations (same seeds, same demonstrations)</h2>")
        rows = [{**r, "success": _pct(r)} for r in m["ablation"]]
        parts.append(_table(rows, [("name", "variant"), ("success", "success rate"), ("notes", "what it lacks")]))
    vids = art.get("videos", {})
    if vids:
        parts.append("<h2>Videos</h2>")
        for key, v in vids.items():
            parts.append(f"<h3>{_e(v.get('caption', key))}</h3><video controls muted src='{_e(v['file'])}'></video>")
    tr = m.get("training", {})
    if tr.get("laws"):
        parts.append("<h2>Laws learned from demonstration</h2>")
        parts.append(_table([{"law": k, **v} for k, v in tr["laws"].items()],
                            [("law", "law"), ("n", "training samples"), ("mode", "GP"), ("heldout_nrmse", "held-out NRMSE"),
                             ("length_scales", "length scales"), ("signal_std", "σf"), ("noise_std", "σn")]))
    if tr.get("judges"):
        parts.append("<h2>Judges learned from evaluation</h2>")
        parts.append(_table([{"place": k, **v} for k, v in tr["judges"].items()],
                            [("place", "place"), ("kernel", "chosen kernel"), ("cv_score", "CV accuracy"),
                             ("heldout_accuracy", "held-out accuracy"), ("segments", "labelled segments")]))
    if tr.get("inverse_model"):
        parts.append("<h2>The auxiliary inverse model</h2>")
        parts.append(_table([tr["inverse_model"]], [(k, k) for k in tr["inverse_model"]]))
    if "timings" in m:
        parts.append("<h2>Timings</h2>" + _table([m["timings"]], [(k, k) for k in m["timings"]]))
    body = "\n".join(parts)
    page = (f"<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'><title>multiform — {_e(m.get('skill', ''))}</title>"
            f"<style>{CSS}</style>{CHECK}</head><body>{body}</body></html>\n")
    out = run / "report.html"
    write_text(out, page)
    return out
