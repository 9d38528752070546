"""Benchmark figures as data: each run writes one JSON record that ``scripts/measurements.py`` renders
into ``docs/measurements.md``.

A record says what produced it (the benchmark, the exact command line, the UTC date, the git commit
and whether the working tree differed from it, the machine and its load) and holds the figures as
structured data. A figure has a ``key``, a human-readable ``label``, a ``value`` with its ``unit``,
optionally named ``values`` (a latency's median and p99), ``counts`` (``[successes, trials]`` of
parts, e.g. pushed and unpushed trials) and ``extra`` figures; a rate also has ``successes``,
``trials`` and its Wilson 95 % interval (``low``, ``high``, from :func:`multiform.stats.wilson`).
Where an issue sets a target, the figure has the ``target`` (a text, and the bound it compares
against where one number decides) and ``met``.

Usage in a benchmark::

    rec = Record(__file__, "GP control law: fit time and one-state latency", section="speed")
    rec.latency("exact_mean", "exact GP n = 2,000, mean only", seconds, target=at_most(25, of="p99"))
    rec.rate("accuracy", "held-out accuracy", 391, 416, target=at_least(0.95))
    rec.write(args.results)                  # add_option(parser) gives the --results DIR option
"""

from __future__ import annotations

import argparse
import datetime as dt
import os
import platform
import shlex
import subprocess
import sys
from importlib import metadata
from pathlib import Path
from typing import Any

import numpy as np

from multiform.io import write_json
from multiform.stats import wilson

ROOT = Path(__file__).resolve().parent.parent
RESULTS = ROOT / "benchmarks" / "results"
PACKAGES = ("multiform", "numpy", "scipy", "scikit-learn", "numba", "mujoco", "gymnasium", "threadpoolctl", "ray")
SCHEMA = 1


def add_option(parser: argparse.ArgumentParser) -> None:
    """The ``--results DIR`` option every benchmark takes (default ``benchmarks/results``)."""
    parser.add_argument("--results", type=Path, default=RESULTS, metavar="DIR",
                        help="folder the JSON record of the figures is written to (default: benchmarks/results)")


def at_least(bound: float, of: str | None = None, text: str | None = None) -> dict[str, Any]:
    """A target the figure's value (or its named value ``of``) must reach."""
    return {"op": ">=", "bound": bound, "of": of, "text": text}


def at_most(bound: float, of: str | None = None, text: str | None = None) -> dict[str, Any]:
    """A target the figure's value (or its named value ``of``) must not exceed."""
    return {"op": "<=", "bound": bound, "of": of, "text": text}


def _bound_text(target: dict[str, Any], unit: str) -> str:
    sign = "≥" if target["op"] == ">=" else "≤"
    bound = target["bound"]
    shown = f"{100 * bound:g} %" if unit == "%" else f"{bound:g}" + (f" {unit}" if unit else "")
    return (f"{target['of']} " if target["of"] else "") + f"{sign} {shown}"


def _plain(x: Any) -> Any:
    """Numpy scalars and arrays as plain JSON numbers and lists."""
    if isinstance(x, np.generic):
        return x.item()
    if isinstance(x, np.ndarray):
        return x.tolist()
    if isinstance(x, dict):
        return {str(k): _plain(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_plain(v) for v in x]
    return x


class Record:
    """The figures of one benchmark run, written atomically as ``<benchmark>[_<variant>].json``."""

    def __init__(self, script: str, title: str, section: str, variant: str | None = None,
                 argv: list[str] | None = None):
        self.benchmark = Path(script).stem
        self.title, self.section, self.variant = title, section, variant
        self.argv = list(sys.argv if argv is None else argv)
        self.started = dt.datetime.now(dt.timezone.utc)
        self.load_start = _load()
        self.figures: list[dict[str, Any]] = []
        self.details: dict[str, Any] = {}

    # -- figures -------------------------------------------------------------------------------
    def figure(self, key: str, label: str, value: float | int | bool | str | None, unit: str = "", *,
               values: dict[str, float] | None = None, counts: dict[str, list[int]] | None = None,
               extra: dict[str, Any] | None = None, target: dict[str, Any] | str | None = None,
               met: bool | None = None, section: str | None = None, note: str | None = None) -> dict[str, Any]:
        """Add one figure. ``target`` is :func:`at_least` / :func:`at_most` (``met`` is then worked
        out), or a text with ``met`` given by the benchmark (a target no one number decides)."""
        if any(f["key"] == key for f in self.figures):
            raise ValueError(f"{self.benchmark}: figure key {key!r} used twice")
        fig: dict[str, Any] = {"key": key, "label": label, "value": _plain(value), "unit": unit}
        if values:
            fig["values"] = _plain(values)
        if counts:
            fig["counts"] = _plain(counts)
        if extra:
            fig["extra"] = _plain(extra)
        if isinstance(target, str):
            target = {"text": target}
        if target is not None:
            target = dict(target)
            if "op" in target:
                got = fig["value"] if target.get("of") is None else fig["values"][target["of"]]
                if met is None and got is not None:
                    met = bool(got >= target["bound"] if target["op"] == ">=" else got <= target["bound"])
                target["text"] = target.get("text") or _bound_text(target, unit)
            fig["target"] = {k: v for k, v in target.items() if v is not None}
            fig["met"] = met
        if section:
            fig["section"] = section
        if note:
            fig["note"] = note
        self.figures.append(fig)
        return fig

    def rate(self, key: str, label: str, successes: int, trials: int, **kw: Any) -> dict[str, Any]:
        """A success rate (a fraction, shown in %) with its Wilson 95 % interval."""
        fig = self.figure(key, label, successes / trials if trials else None, "%", **kw)
        low, high = wilson(successes, trials)
        fig.update(successes=int(successes), trials=int(trials), low=low, high=high)
        return fig

    def latency(self, key: str, label: str, seconds: np.ndarray, **kw: Any) -> dict[str, Any]:
        """Per-call times (seconds) as their median and p99 in µs; the value is the median."""
        us = np.asarray(seconds, dtype=float) * 1e6
        stats = {"median": float(np.median(us)), "p99": float(np.percentile(us, 99))}
        extra = {"samples": int(len(us)), **(kw.pop("extra", None) or {})}
        return self.figure(key, label, stats["median"], "µs", values=stats, extra=extra, **kw)

    # -- writing -------------------------------------------------------------------------------
    def data(self) -> dict[str, Any]:
        """The record as plain JSON data."""
        now = dt.datetime.now(dt.timezone.utc)
        return {"schema": SCHEMA, "benchmark": self.benchmark, "variant": self.variant, "title": self.title,
                "section": self.section, "command": command_line(self.argv),
                "date": now.isoformat(timespec="seconds"), "seconds": round((now - self.started).total_seconds(), 1),
                "git": git_state(), "machine": {**machine(), "load_average": {"start": self.load_start, "end": _load()}},
                "figures": self.figures, "details": _plain(self.details)}

    def write(self, directory: str | os.PathLike = RESULTS) -> Path:
        """Write ``directory/<benchmark>[_<variant>].json`` atomically; returns its path."""
        name = self.benchmark + (f"_{self.variant}" if self.variant else "")
        path = Path(directory) / f"{name}.json"
        write_json(path, self.data())
        print(f"figures written to {path}", flush=True)
        return path


def command_line(argv: list[str]) -> str:
    """The command as a user types it from the repository's root: ``python benchmarks/x.py ARGS``."""
    script = Path(argv[0]).resolve() if argv else Path("?")
    try:
        script_text = str(script.relative_to(ROOT))
    except ValueError:
        script_text = argv[0]
    return shlex.join(["python", script_text, *argv[1:]])


def git_state() -> dict[str, Any]:
    """The commit checked out and whether the code that produced the figures differs from it (tracked
    files under src/ and benchmarks/, pyproject.toml, requirements.lock; the results folder excepted)."""
    def git(*args: str) -> str | None:
        try:
            r = subprocess.run(["git", "-C", str(ROOT), *args], capture_output=True, text=True, timeout=30)
        except (OSError, subprocess.TimeoutExpired):
            return None
        return r.stdout.strip() if r.returncode == 0 else None
    commit = git("rev-parse", "HEAD")
    status = git("status", "--porcelain", "--untracked-files=no", "--", "src", "benchmarks", "pyproject.toml",
                 "requirements.lock", ":(exclude)benchmarks/results")
    return {"commit": commit, "dirty": None if status is None else bool(status)}


def machine() -> dict[str, Any]:
    """Cores, CPU model, OS, Python and the versions of the packages the figures depend on."""
    versions = {}
    for name in PACKAGES:
        try:
            versions[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            versions[name] = None
    return {"cores": os.cpu_count(), "cpu": _cpu_model(), "system": f"{platform.system()} {platform.machine()}",
            "python": platform.python_version(), "packages": versions,
            "threads": {k: os.environ.get(k) for k in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")}}


def _cpu_model() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.lower().startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown"


def _load() -> list[float] | None:
    try:
        return [round(x, 2) for x in os.getloadavg()]
    except OSError:
        return None
