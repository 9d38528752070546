"""Write docs/measurements.md from the JSON records the benchmarks write (``benchmarks/results``).

    python scripts/measurements.py [--results DIR] [--out docs/measurements.md] [--check]

Run it after a benchmark has written its record, and commit both; a test checks that the page is
what this script renders from ``benchmarks/results``. ``--check`` only compares (exit status 1 when
the page is out of date).
"""

from __future__ import annotations

import argparse
import json
import re
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from multiform.errors import InvalidInput

ROOT = Path(__file__).resolve().parent.parent
RESULTS = ROOT / "benchmarks" / "results"
PAGE = ROOT / "docs" / "measurements.md"


@dataclass(frozen=True)
class Section:
    key: str
    title: str
    about: str
    benchmarks: tuple[str, ...]


SECTIONS = (
    Section("main", "The main jobs",
            "`multiform demo pendulum` and `multiform demo nunchaku` with their default settings: the final "
            "skill on 200 randomised evaluation trials (half of the pendulum's pushed while balancing), the "
            "ablations on the first of them, the practice it took and the job's wall time.",
            ("bench_main_job",)),
    Section("seeds", "Spread over job seeds",
            "The demonstrations, the learned conditions and the repairs all follow the job seed, so one seed "
            "says little: the main job's pipeline run from several job seeds, each final skill on the same "
            "evaluation trials.",
            ("bench_job_seeds",)),
    Section("data_efficiency", "Learning from few demonstrations",
            "The pipeline from 5 to 40 demonstrations, practice that repairs the net only against practice "
            "that also learns from its own graded trials, per job seed, with the practice and the robot time "
            "it took.",
            ("bench_data_efficiency",)),
    Section("repair", "Repair of injected mistakes",
            "Plausible mistakes written into the sound skill files, then practice and evaluation: how many "
            "made practice fail, how many practice repaired, and how close the repaired skill comes to the "
            "sound one.",
            ("bench_repair",)),
    Section("mentors", "Several mentors",
            "Demonstrations and labels by mentors of unequal skill: the skill learned with estimated trust "
            "(fusion) beside the same demonstrations pooled and beside the best mentor alone, on the same "
            "evaluation trials, and the judges' accuracy on fresh, honestly labelled segments.",
            ("bench_mentors",)),
    Section("components", "The learned components",
            "Held-out accuracy of what training learns: the control laws, the judges, the learned "
            "conditions; and how a law's fit shows in closed loop.",
            ("bench_laws", "bench_judges", "bench_condition", "bench_switch_settings", "bench_gp", "bench_law_fits")),
    Section("speed", "Latency and throughput",
            "What the 1 kHz control path costs on one core, how fast the simulations and whole trials run, "
            "and the evaluation backends.",
            ("bench_gp", "bench_condition", "bench_guards", "bench_closed_loop", "bench_arm_pendulum", "bench_ray",
             "bench_nunchaku")),
    Section("ball_in_cup", "Ball-in-a-cup from kinesthetic demonstrations",
            "`multiform demo ball_in_cup` from several job seeds: the final skill on 200 randomised evaluation "
            "trials, the ablations on the first of them, the practice trials to the first 5 successes in a row "
            "(Kober & Peters: consistent success after under a hundred trials on a real arm) and the job's wall "
            "time.",
            ("bench_ball_in_cup",)),
    Section("tasks", "The simulated tasks",
            "The nunchaku's simulation, its estimation from the wrist load and its scripted mentor.",
            ("bench_nunchaku",)),
)

INTRO = """\
# Measurements

Rendered by `python scripts/measurements.py` from the JSON records the benchmarks write to
`benchmarks/results/`; do not edit it by hand ([CONTRIBUTING.md](../CONTRIBUTING.md#benchmarks) says
how to add a figure). Every figure comes with the command that reproduces it (from the
repository's root), the date it was measured (UTC) and the commit it was measured at ("modified":
the working tree differed from that commit). Rates are given with their Wilson 95 % interval
(`multiform.stats`), latencies as the median and the 99th percentile over many calls. A figure no
benchmark has recorded yet is not listed.

The benchmarks ran on a machine shared with other work and often busy: each record's load average
is in [the last section](#where-they-were-measured). Times and throughputs vary by tens of percent
from one run to the next; success rates and trial outcomes do not depend on the load (every fit and
trial is seeded and single-threaded). The dated log of what was measured and tried while the method
was developed is [measurements-log.md](measurements-log.md).
"""


def load_records(folder: Path) -> list[dict[str, Any]]:
    """Every ``*.json`` record in ``folder``, checked; ordered by benchmark and variant."""
    records = []
    for path in sorted(Path(folder).glob("*.json")):
        try:
            rec = json.loads(path.read_text(encoding="utf-8"))
        except (json.JSONDecodeError, UnicodeDecodeError) as exc:
            raise InvalidInput(f"not valid JSON ({exc})", file=str(path)) from None
        _check(rec, path)
        records.append(rec)
    return sorted(records, key=lambda r: (r["benchmark"], _natural(r.get("variant") or "")))


def _natural(variant: str) -> tuple:
    """Variants of the pendulum (the first task) first, then in natural order (5 demos before 10)."""
    parts = tuple(int(p) if p.isdigit() else p for p in re.split(r"(\d+)", variant))
    return (not variant.startswith("pendulum"), parts)


def _check(rec: Any, path: Path) -> None:
    if not isinstance(rec, dict):
        raise InvalidInput("a benchmark record must be a JSON object", file=str(path))
    for key in ("benchmark", "title", "section", "command", "date", "git", "machine", "figures"):
        if key not in rec:
            raise InvalidInput(f"the record has no '{key}'", file=str(path), element=key)
    if not isinstance(rec["figures"], list):
        raise InvalidInput("'figures' must be a list", file=str(path), element="figures")
    for i, fig in enumerate(rec["figures"]):
        for key in ("key", "label", "value", "unit"):
            if not isinstance(fig, dict) or key not in fig:
                raise InvalidInput(f"figure {i} has no '{key}'", file=str(path), element=f"figures[{i}]")


# -- formatting --------------------------------------------------------------------------------------
def num(x: Any) -> str:
    """A number with as many digits as a measurement on a shared machine carries."""
    if isinstance(x, bool):
        return "yes" if x else "no"
    if not isinstance(x, (int, float)):
        return str(x)
    if isinstance(x, int) or float(x).is_integer() and abs(x) >= 1:
        return f"{int(x):,}"
    return f"{x:,.0f}" if abs(x) >= 100 else f"{x:.3g}"


def pct(x: float) -> str:
    return f"{100 * x:.1f} %"


def _with_unit(x: Any, unit: str) -> str:
    if x is None:
        return "—"
    if unit == "%" and isinstance(x, (int, float)) and not isinstance(x, bool):
        return pct(x)
    return num(x) + (f" {unit}" if unit and not isinstance(x, (bool, str)) else "")


UNIT_SUFFIXES = {"_s": "s", "_ms": "ms", "_us": "µs", "_rad": "rad"}


def _extra(name: str, v: Any) -> str:
    """``name value``; a name ending in a unit (``record_s``) puts it after the value (``record 5 s``)."""
    unit = next((u for suffix, u in UNIT_SUFFIXES.items() if name.endswith(suffix)), "")
    if unit:
        name = name[: name.rindex("_")]
    if isinstance(v, list):
        v = ", ".join(num(x) for x in v) or "none"
    elif isinstance(v, dict):
        v = ", ".join(f"{k} {num(x)}" for k, x in v.items()) or "none"
    else:
        v = num(v)
    return f"{name.replace('_', ' ')} {v}" + (f" {unit}" if unit else "")


def measured(fig: dict[str, Any]) -> str:
    """The figure's value(s) as a reader reads them."""
    unit = fig["unit"]
    if "trials" in fig:
        text = (f"{pct(fig['value'])} ({fig['successes']}/{fig['trials']}; {100 * fig['low']:.1f}–"
                f"{100 * fig['high']:.1f} %)") if fig["trials"] else "no trials"
    elif fig.get("values"):
        text = ", ".join(f"{name} {_with_unit(v, unit)}" for name, v in fig["values"].items())
    else:
        text = _with_unit(fig["value"], unit)
    parts = [f"{name} {k}/{n}" for name, (k, n) in (fig.get("counts") or {}).items() if n]
    parts += [_extra(name, v) for name, v in (fig.get("extra") or {}).items()]
    if parts:
        text += "; " + ", ".join(parts)
    if fig.get("note"):
        text += f" ({fig['note']})"
    return text


def target(fig: dict[str, Any]) -> str:
    t = fig.get("target")
    if not t:
        return ""
    verdict = {True: "met", False: "**not met**"}.get(fig.get("met"), "")
    return t["text"] + (f": {verdict}" if verdict else "")


def _cell(text: str) -> str:
    return text.replace("|", "\\|").replace("\n", " ")


def commit(rec: dict[str, Any]) -> str:
    c = (rec["git"] or {}).get("commit")
    if not c:
        return "unknown"
    return f"`{c[:10]}`" + (", modified" if rec["git"].get("dirty") else "")


# -- the page ----------------------------------------------------------------------------------------
def _rows(records: list[dict[str, Any]], section: Section) -> list[str]:
    order = {b: i for i, b in enumerate(section.benchmarks)}
    rows = []
    for rec in sorted(records, key=lambda r: order.get(r["benchmark"], len(order))):
        for fig in rec["figures"]:
            if fig.get("section", rec["section"]) != section.key:
                continue
            rows.append("| " + " | ".join(_cell(x) for x in (
                fig["label"], measured(fig), target(fig), f"`{rec['command']}`", rec["date"][:10], commit(rec))) + " |")
    return rows


def _machines(records: list[dict[str, Any]]) -> list[str]:
    out = ["## Where they were measured", "",
           "| benchmark | date | cores | CPU | load average at start → end (1, 5, 15 min) | Python, NumPy, "
           "scikit-learn, MuJoCo | run time |",
           "|---|---|---|---|---|---|---|"]
    for rec in records:
        m = rec["machine"]
        load = m.get("load_average") or {}
        fmt = lambda v: " / ".join(f"{x:.1f}" for x in v) if v else "?"  # noqa: E731
        pk = m.get("packages") or {}
        versions = ", ".join(str(v) for v in (m.get("python"), pk.get("numpy"), pk.get("scikit-learn"), pk.get("mujoco")))
        name = rec["benchmark"] + (f" ({rec['variant']})" if rec.get("variant") else "")
        out.append("| " + " | ".join(_cell(str(x)) for x in (
            name, rec["date"][:10], m.get("cores", "?"), m.get("cpu", "?"),
            f"{fmt(load.get('start'))} → {fmt(load.get('end'))}", versions,
            f"{num(rec['seconds'])} s" if rec.get("seconds") is not None else "?")) + " |")
    return out


def render(results: Path = RESULTS) -> str:
    """The page for the records in ``results``."""
    records = load_records(results)
    known = {s.key for s in SECTIONS}
    extra = sorted({f.get("section", r["section"]) for r in records for f in r["figures"]} - known)
    sections = list(SECTIONS) + [Section(k, k.replace("_", " ").capitalize(), "", ()) for k in extra]
    lines = [INTRO]
    for s in sections:
        lines += [f"## {s.title}", ""]
        if s.about:
            lines += [s.about, ""]
        rows = _rows(records, s)
        if rows:
            lines += ["| figure | measured | target | reproduced by | date | commit |",
                      "|---|---|---|---|---|---|", *rows, ""]
        else:
            names = ", ".join(f"`benchmarks/{b}.py`" for b in s.benchmarks)
            lines += [f"Not measured yet ({names} write{'s' if len(s.benchmarks) == 1 else ''} these figures).", ""]
    if records:
        lines += _machines(records) + [""]
    return "\n".join(lines).rstrip() + "\n"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--results", type=Path, default=RESULTS, help="folder of the benchmarks' JSON records")
    ap.add_argument("--out", type=Path, default=PAGE, help="the page to write")
    ap.add_argument("--check", action="store_true", help="only check that the page is up to date")
    a = ap.parse_args(argv)
    try:
        page = render(a.results)
    except InvalidInput as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    if a.check:
        same = a.out.exists() and a.out.read_text(encoding="utf-8") == page
        print(f"{a.out}: {'up to date' if same else 'out of date: run python scripts/measurements.py'}", file=sys.stderr)
        return 0 if same else 1
    from multiform.io import write_text
    write_text(a.out, page)
    print(f"wrote {a.out}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
