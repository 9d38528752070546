"""The run's report page: one self-contained HTML file beside the run's pictures and videos.

Built from ``metrics.json`` and the files the run wrote (paths relative to the run folder), so it
can be rebuilt any time with ``multiform report RUN_DIR``. A small script on the page records
whether every image loaded (``data-images-ok`` on ``<html>``), which the report test reads from
headless Chromium.

A run folder is data anyone may have edited: every value reaches the page through :func:`_h`
(markup written here, every argument escaped unless it is :class:`Html` made by ``_h`` itself),
and every link or source through :func:`_url`, which admits only a relative path inside the run
folder (no scheme, so no ``javascript:`` or ``data:`` URL).
"""

from __future__ import annotations

import html
import os
import re
from pathlib import Path, PurePosixPath
from typing import Any

from ..io import read_json, write_text
from ..stats import rate

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


class Html(str):
    """Markup made by :func:`_h` (a table cell shows it as it is; everything else is escaped)."""


WORDS = {   # how the page names the keys of metrics.json
    "record_s": "recording the demonstrations", "train_s": "training", "baselines_s": "queueing the baselines",
    "practice_s": "practice", "evaluate_s": "evaluation", "report_s": "pictures, videos and this page",
    "total_s": "total", "closed_loop_us_per_sim_ms": "closed loop, µs of wall time per simulated ms (median)",
    "own_motion_s": "own motion recorded [s]", "rows": "training rows", "n_train": "training rows used",
    "train_rms_torque_error": "RMS torque error on its training rows, per joint [N m]", "servo": "servo",
    "residual_gp": "residual GP", "n_inducing": "inducing points", "tracking": "tracking",
    "velocity_rms": "velocity RMS error", "hold_rms": "hold RMS error", "diverged": "diverged",
    "ratio": "learned / reference", "learned": "learned", "reference": "the env's controller",
    "set_condition": "new condition", "add_transition": "new transition", "add_place": "new place",
    "set_lambda": "new firing probabilities", "lower_lambda": "lower firing probability",
    "refit_law": "law refitted", "revise_judge": "judge revised", "revert": "revision reverted",
    "set_law": "law changed",
}


def _e(x: Any) -> Html:
    """``x`` as markup: :class:`Html` as it is, anything else as escaped text (the one place)."""
    return x if isinstance(x, Html) else Html(html.escape(str(x)))


def _h(template: str, *args: Any) -> Html:
    """Markup: ``template`` (written here, never from data) with ``{}`` filled by ``args``, each
    escaped by :func:`_e`."""
    return Html(template.format(*(_e(a) for a in args)))


def _join(parts: Any, sep: str = "") -> Html:
    return Html(sep.join(_e(x) for x in parts))


_SAFE_PATH = re.compile(r"[A-Za-z0-9_.\-/ ]+")


def _url(path: Any) -> str | None:
    """``path`` if it is a relative path inside the run folder (letters, digits, ``_ . - /``, no
    ``..``, no scheme): what a page of a run may link to; None for anything else."""
    if not isinstance(path, str) or not _SAFE_PATH.fullmatch(path) or path.startswith("/"):
        return None
    parts = PurePosixPath(path).parts
    return path if parts and ".." not in parts else None


def word(key: str) -> str:
    """A key of metrics.json (or a revision operator) in the words of the page."""
    return WORDS.get(key, key.replace("_", " "))


def _fmt(v: Any) -> str:
    """A value as a reader wants to see it: numbers to 4 significant digits, dicts and lists spelled out."""
    if v is None:
        return "–"
    if isinstance(v, bool):
        return "yes" if v else "no"
    if isinstance(v, float):
        return f"{v:.4g}"
    if isinstance(v, dict):
        return "; ".join(f"{word(k)} ({_fmt(x).replace('; ', ', ')})" if isinstance(x, dict) else f"{word(k)} {_fmt(x)}"
                         for k, x in v.items())
    if isinstance(v, (list, tuple)):
        return ", ".join(_fmt(x) for x in v)
    return str(v)


def _code(name: Any) -> Html:
    return _h("<code>{}</code>", name)


def _named(values: dict[str, Any]) -> Html:
    """Values keyed by the skill's own names (variables, transitions), the names set as code."""
    return _join((_h("{} {}", _code(k), _fmt(v)) for k, v in values.items()), ", ")


def _pct(r: dict[str, Any]) -> str:
    return (f"{100 * r['rate']:.1f} % ({r['successes']}/{r['trials']}; 95 % CI "
            f"{100 * r['low']:.1f}–{100 * r['high']:.1f} %)")


def _img(src: Any, alt: Any) -> Html:
    """An image of the run folder (nothing for a source that is not one: see :func:`_url`)."""
    url = _url(src)
    return _h('<img class="fig" src="{}" alt="{}">', url, alt) if url else Html("")


def _p(text: Any) -> Html:
    """A paragraph, or nothing for no text (the page has no empty paragraphs)."""
    return _h("<p>{}</p>", text) if str(text).strip() else Html("")


def _table(rows: list[dict[str, Any]], cols: list[tuple[str, str]], cls: str = "") -> Html:
    head = _join(_h("<th>{}</th>", label) for _, label in cols)
    body = []
    for r in rows:
        cells = []
        for key, _ in cols:
            v = r.get(key, "")
            num = isinstance(v, (int, float)) and not isinstance(v, bool)
            cells.append(_h("<td class=num>{}</td>" if num else "<td>{}</td>", v if isinstance(v, Html) else _fmt(v)))
        body.append(_h("<tr>{}</tr>", _join(cells)))
    table = "<table class={}><tr>{}</tr>{}</table>" if cls else "<table{}><tr>{}</tr>{}</table>"
    return _h(table, cls, head, _join(body))


def _learning(s: dict) -> str:
    """One sentence on what a scenario that learned from practice did ("" for the others)."""
    if "mentor_labelled_trials" not in s:
        return ""
    agree = s.get("mentor_agreement", {})
    text = (f"{s['trials']} trials, every other one exploring; {s['plain_successes']} of {s['plain_trials']} plain trials "
            f"succeeded; {s['own_segments']} of its own segments, graded successful by its judges, joined its laws' "
            "training data; "
            + (f"the mentor graded or took over {s['mentor_labelled_trials']} trials (it took over {s['mentor_takeovers']} "
               f"failed ones, demonstrating from where the robot knew least)" if s.get("mentor_takeovers")
               else f"the mentor graded {s['mentor_labelled_trials']} trials"))
    if agree.get("stays"):
        text += f" and agreed with the robot's own grade on {agree['agree']} of {agree['stays']} stays"
    stop = s.get("stop_reason", "")
    return text + f"; {s.get('robot_seconds', 0):.0f} s of robot time." + (f" Stopped: {stop}." if stop else "")


def _practice_summary(s: dict) -> str:
    """What a repair scenario did, in a sentence."""
    if "mentor_labelled_trials" in s:
        return _learning(s)
    revs = s.get("revisions", [])
    text = f"{s.get('trials', 0)} trials, {s.get('successes', 0)} successful"
    if s.get("first_success_trial") is not None:
        text += f"; the first success was trial {s['first_success_trial']} (trials are numbered from 0)"
    text += "; " + ("revisions: " + ", ".join(f"version {r['version']} ({word(r['operator'])} of {r['target']}, "
                                               f"after trial {r['after_trial']})" for r in revs)
                    if revs else "no revision")
    if s.get("stop_reason"):
        text += f"; stopped: {s['stop_reason']}"
    return text + f"; {s.get('robot_seconds', 0):.0f} s of robot time."


def _split(m: dict[str, Any]) -> dict[str, Any]:
    """Pushed and unpushed rates; for a run whose metrics lack the unpushed split, it is what the
    overall counts leave after the pushed ones."""
    pushed, plain = m.get("pushed"), m.get("unpushed")
    sr = m.get("success_rate")
    if plain is None and sr is not None:
        n = sr["trials"] - (pushed["trials"] if pushed else 0)
        k = sr["successes"] - (pushed["successes"] if pushed else 0)
        plain = rate(k, n) if n > 0 else None
    return {"pushed": pushed, "unpushed": plain}


def _plot_entry(v: Any) -> dict[str, Any]:
    return v if isinstance(v, dict) else {"file": v}


def build_report(run_dir: str | os.PathLike, metrics: dict[str, Any] | None = None) -> Path:
    """Write ``run_dir/report.html`` from ``metrics`` (default: ``run_dir/metrics.json``)."""
    run = Path(run_dir)
    if metrics is None:
        metrics = read_json(run / "metrics.json", "run metrics")
    write_text(run / "report.html", page_html(metrics))
    return run / "report.html"


def page_html(m: dict[str, Any]) -> str:
    """The report page of a run's metrics (a self-contained HTML document)."""
    art = m.get("artifacts", {})
    revisions = m.get("revisions", [])
    plots = art.get("plots", {})
    tr = m.get("training", {})
    parts: list[str] = [_h("<h1>multiform — {}</h1>", _code(m.get("skill", ""))), _p(m.get("description", ""))]
    parts += _summary(m, revisions)
    parts += _configuration(m, revisions)
    parts += _demonstrations(m.get("demos"))
    parts += _mentors(m.get("mentors"))
    parts += _revisions(m, revisions)
    parts += _nets(art.get("nets", []), revisions)
    parts += _scenarios(m.get("scenarios", {}))
    parts += _trial_plots(plots)
    parts += _evaluation(m, plots, revisions)
    parts += _views(art.get("views", {}))
    parts += _videos(art.get("videos", {}), plots)
    parts += _laws(tr.get("laws"))
    parts += _judges(tr.get("judges"))
    if tr.get("inverse_model"):
        parts.append(Html("<h2>The auxiliary inverse model</h2>"))
        parts.append(_table([{"k": word(k), "v": _code(v) if isinstance(v, str) else v}
                             for k, v in tr["inverse_model"].items()],
                            [("k", "quantity"), ("v", "value")]))
    if "timings" in m:
        parts.append(_h("<h2>Timings</h2>{}", _table([{"k": word(k), "v": v} for k, v in m["timings"].items()],
                                                     [("k", "stage"), ("v", "seconds")])))
    body = _join((x for x in parts if x), "\n")
    return _h("<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'><title>multiform — {}</title>"
              "<style>{}</style>{}</head><body>{}</body></html>\n", m.get("skill", ""), Html(CSS), Html(CHECK), body)


def _summary(m: dict[str, Any], revisions: list[dict[str, Any]]) -> list[str]:
    """The summary table and the robot's verdicts against the physical check."""
    rows: list[tuple[str, Any]] = []
    if "demos" in m:
        d = m["demos"]
        rows.append(("demonstrations", f"{d['count']} by the scripted mentor" + (
            f"; the mentor's own success {_pct(d['mentor_success_rate'])}" if "mentor_success_rate" in d else "")))
    if "practice_trials" in m:
        rows.append(("practice trials", m["practice_trials"]))
    rows.append(("revisions of the net", len(revisions)))
    if "success_rate" in m:
        sr = m["success_rate"]
        ok = sr["rate"] >= m.get("target_success_rate", 0.95)
        rows.append(("final success rate (physical check)",
                     _h('<span class="ok">{}</span>{}' if ok else '<span class="bad">{}</span>{}', _pct(sr),
                        f"; target {100 * m.get('target_success_rate', 0.95):.0f} %")))
        split = _split(m)
        if split["pushed"]:
            rows.append(("pushed trials", _pct(split["pushed"])))
            if split["unpushed"]:
                rows.append(("trials not pushed", _pct(split["unpushed"])))
        else:
            rows.append(("pushed trials", "none: no evaluation trial of this task was pushed"))
    if "self_assessed" in m:
        sa = m["self_assessed"]
        agree = m.get("agreement_with_physical_check")
        text = f"{_pct(sa)} of its trials graded successful by its own judges"
        if agree is not None:
            text += f"; its verdict agreed with the physical check on {100 * agree:.1f} % of the trials"
        rows.append(("the robot's own verdict", text))
    if "timings" in m:
        rows.append(("wall time", f"{m['timings'].get('total_s', 0):.0f} s"))
    parts = [_h("<h2>Summary</h2><table class='summary'>{}</table>",
                _join(_h("<tr><td>{}</td><td>{}</td></tr>", k, v) for k, v in rows))]
    if m.get("verdicts"):
        v = m["verdicts"]
        parts.append(_h("<h3>The robot's verdict against the physical check (evaluation trials)</h3>{}", _table(
            [{"robot": "success", "ok": v["both_success"], "bad": v["robot_only"]},
             {"robot": "failure", "ok": v["check_only"], "bad": v["both_failure"]}],
            [("robot", "the robot's judges said"), ("ok", "physical check: success"),
             ("bad", "physical check: failure")], cls="verdicts")))
    return parts


def _configuration(m: dict[str, Any], revisions: list[dict[str, Any]]) -> list[str]:
    cfg = m.get("config", {})
    if not cfg:
        return []
    trained_inverse = "inverse_model" in m.get("training", {})
    conf = [("task", m.get("task", "")), ("skill definition", _code(m.get("skill", ""))), ("seed", cfg.get("seed")),
            ("multiform version", m.get("version", "not recorded by this run")),
            ("final net version", m.get("net_version", len(revisions))),
            ("demonstrations", cfg.get("demos")), ("evaluation trials", cfg.get("eval_trials")),
            ("ablation trials (the first of the evaluation trials)", cfg.get("ablation_trials")),
            ("practice trials per scenario at most", cfg.get("practice_max_trials")),
            ("learning from practice", cfg.get("learn")),
            ("fraction of evaluation trials pushed", cfg.get("push_fraction") if m.get("pushed") else "none pushed"),
            ("joints driven by", "the learned auxiliary inverse model" if trained_inverse
             else "the env's own servos (no inverse model)"),
            ("worker processes", cfg.get("workers"))]
    return [_h("<h2>Configuration</h2>{}", _table([{"k": k, "v": v if isinstance(v, Html) else _fmt(v)}
                                                    for k, v in conf], [("k", "setting"), ("v", "value")]))]


def _demonstrations(d: Any) -> list[str]:
    if not isinstance(d, dict):
        return []
    parts = [Html("<h2>Demonstrations</h2>")]
    dur = d.get("duration_s", {})
    who = d.get("mentors")
    by = (", ".join(f"{v['demos']} by {m}" for m, v in who.items()) if isinstance(who, dict) and len(who) > 1
          else "by the scripted mentor")
    text = [_h("{} demonstrations {} in {}", d["count"], by, _code(d.get("file", "demos.h5")))]
    if dur:
        text.append(f", {dur['total']:.0f} s in all (each {dur['min']:.1f}–{dur['max']:.1f} s)")
    if "samples" in d:
        text.append(f", {d['samples']} samples")
    if "mentor_success_rate" in d:
        text.append(f"; the mentor succeeded in {_pct(d['mentor_success_rate'])} (its deliberate mistakes included)")
    parts.append(_p(_join([*text, "."])))
    if d.get("samples_per_transition"):
        parts.append(_table([{"t": _code(t), "n": n} for t, n in d["samples_per_transition"].items()],
                            [("t", "transition the mentor tagged"), ("n", "samples")]))
    return parts


def _mentors(trust: Any) -> list[str]:
    """With several mentors: how far each is trusted per maneuver and per place, with the evidence,
    and how practice moved the weights (``mentors.json``, :mod:`multiform.learn.fusion`)."""
    if not isinstance(trust, dict) or not isinstance(trust.get("estimates"), dict):
        return []
    est, history = trust["estimates"], trust.get("history") or []
    last = history[-1]["maneuvers"] if history else {}
    first = history[0]["maneuvers"] if history else {}
    rows = []
    for t, per in est.get("maneuvers", {}).items():
        for who, d in per.items():
            s, f = (d.get("practice") or [0, 0])[:2]
            rows.append({"t": Html(_code(t)), "m": who, "seg": f"{d.get('successes')}/{d.get('segments')}",
                         "prec": d.get("precision"), "ok": d.get("success"),
                         "w0": first.get(t, {}).get(who), "w": d.get("weight"),
                         "prac": f"{s:.1f} / {f:.1f}" if s or f else "–"})
    parts = ["<h2>Several mentors: how far each is trusted</h2>",
             _p(_e(f"{len(est.get('mentors', []))} mentors ({', '.join(est.get('mentors', []))}). Per maneuver, "
                   "a mentor's weight is its estimated success (its segments the fused verdicts call successful, "
                   "and the robot's graded practice where it followed that mentor) times the precision of its "
                   "commands, relative to the best mentor; laws keep that share of its samples, switch conditions "
                   "learn from mentors weighted at least 0.5. Per place, each annotator's agreement with the fused "
                   "(Dawid–Skene) verdicts; 'outcome' is the net's own reading of what happened next.")),
             _table(rows, [("t", "maneuver"), ("m", "mentor"), ("seg", "segments succeeded"), ("prec", "precision"),
                           ("ok", "success estimate"), ("w0", "weight after training"), ("w", "weight now"),
                           ("prac", "practice evidence (success / failure)")])]
    labels = [{"p": Html(_code(p)), "w": w, "n": d.get("items"), "a": d.get("agreement"),
               "se": d.get("sensitivity"), "sp": d.get("specificity")}
              for p, per in est.get("labels", {}).items() for w, d in per.items()]
    if labels:
        parts.append(_table(labels, [("p", "place"), ("w", "annotator"), ("n", "stays labelled"),
                                     ("a", "agreement with fused verdicts"), ("se", "sensitivity"),
                                     ("sp", "specificity")]))
    if len(history) > 1:
        parts.append(_p(_e(f"Practice updated the estimates {len(history) - 1} time(s); the weights after training "
                           "and now are side by side above.")))
    return parts


def _revisions(m: dict[str, Any], revisions: list[dict[str, Any]]) -> list[str]:
    if not revisions:
        return []
    titles = {k: s.get("title", k) for k, s in m.get("scenarios", {}).items()}
    return [Html("<h2>How the robot revised the definition</h2>"),
            _table([{**r, "operator": word(r["operator"]), "target": _code(r["target"]),
                     "scenario": titles.get(r.get("scenario")) or _code(r.get("scenario", ""))}
                    for r in revisions],
                   [("version", "version"), ("scenario", "practice scenario"),
                    ("after_trial", "after trial"), ("operator", "change"), ("target", "of"),
                    ("reason", "why (the evidence from the traces)")])]


def _nets(nets: list[dict[str, Any]], revisions: list[dict[str, Any]]) -> list[str]:
    if not nets:
        return []
    head = ("The net before and after each revision" if revisions
            else "The net as the mentor wrote it (practice revised nothing)")
    return [_h("<h2>{}</h2><div class='nets'>{}</div>", head,
               _join(_h("<figure>{}<figcaption>{}</figcaption></figure>", _img(n["file"], n["caption"]), n["caption"])
                     for n in nets))]


def _scenarios(scen: dict[str, Any]) -> list[str]:
    if not scen:
        return []
    parts = [Html("<h2>Practice scenarios</h2>")]
    for key, s in scen.items():
        parts.append(_h("<h3>{}</h3>{}", s.get("title", key), _p(s.get("summary", "") or _practice_summary(s))))
        if s.get("plot"):
            parts.append(_img(s["plot"], f"practice {s.get('title', key)}"))
            parts.append(_p("Each dot is a trial, numbered from 0 as in the practice log; an orange line "
                            "stands just before the first trial that ran the revised net."
                            if s.get("revisions") else "Each dot is a trial, numbered from 0 as in the practice log."))
    return parts


def _trial_plots(plots: dict[str, Any]) -> list[str]:
    """The plots of a successful trial and of a recovery from a push."""
    parts = []
    for key in ("success_trial", "recovery_trial"):
        if key not in plots:
            continue
        e = _plot_entry(plots[key])
        caption = e.get("caption", "a successful trial" if key == "success_trial" else "recovery from a push")
        caption = str(caption)
        fig = f" (cf. the paper's {e['figure']})" if e.get("figure") else ""
        parts.append(_h("<h2>{}</h2>{}", caption[:1].upper() + caption[1:], _img(e.get("file"), caption)))
        text = [f"Motion variables and commands, the token's place shaded, every firing labelled{fig}."]
        if e.get("fired"):
            text.append(_h(" Fired in order: {}.", _join((_code(t) for t in e["fired"]), " ")))
        if e.get("push_time") is not None:
            text.append(f" The experimenter pushed at {e['push_time']:.2f} s (dashed line).")
        parts.append(_p(_join(text)))
    return parts


def _evaluation(m: dict[str, Any], plots: dict[str, Any], revisions: list[dict[str, Any]]) -> list[str]:
    if not m.get("ablation"):
        return []
    parts = [Html("<h2>Evaluation and ablations (same seeds, same demonstrations)</h2>")]
    if "evaluation" in plots:
        parts.append(_img(_plot_entry(plots["evaluation"])["file"], "success over the evaluation trials"))
    rows = [{**r, "success": _pct(r)} for r in m["ablation"]]
    if not revisions and rows and rows[0].get("notes") == "the robot's revised net":
        rows[0]["notes"] = "the mentor's net: practice revised nothing"
    parts.append(_table(rows, [("name", "variant"), ("success", "success rate"), ("notes", "what it lacks")]))
    return parts


def _views(views: dict[str, Any]) -> list[str]:
    if not views:
        return []
    items = []
    for v in views.values():
        url = _url(v.get("file"))
        link = _h("<a href='{}'>{}</a>", url, url) if url else _e(v.get("file"))
        items.append(_h("<li>{}: {}</li>", link, v.get("caption", "")))
    return [Html("<h2>Recordings for rerun's viewer</h2>"),
            _p(_h("Open one with <code>rerun FILE</code> (or drop it on the web viewer): the state and commands "
                  "over time, the net with its marking at each firing, the scene, pushes, clips and grades.")),
            _h("<ul>{}</ul>", _join(items))]


def _videos(vids: dict[str, Any], plots: dict[str, Any]) -> list[str]:
    if not vids:
        return []
    pushed = any(_plot_entry(v).get("push_time") is not None for v in plots.values())
    return ([Html("<h2>Videos</h2>"),
             _p("Each frame shows the time, the place the token is in and the transition being executed"
                + (", and for 0.6 s from it, the push." if pushed else "."))]
            + [_h("<h3>{}</h3><video controls muted src='{}'></video>", v.get("caption", key), _url(v.get("file")))
               for key, v in vids.items() if _url(v.get("file"))])


def _laws(laws_m: dict[str, Any] | None) -> list[str]:
    """The laws learned from demonstration, with a word on any that does worse than the mean command."""
    if not laws_m:
        return []
    laws = []
    worse = []
    for k, v in laws_m.items():
        nrmse = v.get("heldout_nrmse")
        note = ""
        if nrmse is not None and nrmse > 1:
            note = "worse than predicting the mean command"
            worse.append(k)
        laws.append({**v, "law": _code(k), "length_scales": _named(v.get("length_scales", {})),
                     "mode": "sparse (inducing points)" if v.get("mode") == "sparse" else "exact", "note": note})
    parts = [Html("<h2>Laws learned from demonstration</h2>"),
             _table(laws, [("law", "law"), ("n", "training samples"), ("mode", "GP"),
                           ("heldout_nrmse", "held-out NRMSE"), ("note", "note"),
                           ("length_scales", "length scales"), ("signal_std", "σf"), ("noise_std", "σn")])]
    if worse:
        parts.append(_p(_h(
            "NRMSE is the held-out error divided by the spread of the commands; above 1 the law predicts the "
            "mentor's commands on unseen demonstrations worse than their mean would. {} {} such a law: the skill "
            "works through the net's closed loop, not through imitation accuracy, and a law this loose is the "
            "first place to look when its sub-procedure fails.", _join((_code(w) for w in worse), " "),
            "is" if len(worse) == 1 else "are")))
    return parts


def _judges(judges_m: dict[str, Any] | None) -> list[str]:
    if not judges_m:
        return []
    judges = []
    for k, v in judges_m.items():
        n, acc = v.get("heldout_segments"), v.get("heldout_accuracy")
        held = "–" if acc is None else (f"{round(acc * n)}/{n} ({100 * acc:.0f} %)" if n else f"{100 * acc:.1f} %")
        cv = v.get("cv_score")
        judges.append({"place": _code(k), "kernel": v.get("kernel", ""),
                       "cv": "–" if cv is None else f"{100 * cv:.1f} %", "held": held,
                       "segments": v.get("segments"), "success": v.get("success_labels")})
    return [Html("<h2>Judges learned from evaluation</h2>"),
            _table(judges, [("place", "place"), ("kernel", "chosen kernel"), ("cv", "cross-validated accuracy"),
                            ("held", "held-out segments right"), ("segments", "labelled segments"),
                            ("success", "of them success")])]
