"""Success against the number of demonstrations, with and without learning from practice.

For each demonstration count and job seed the main pipeline runs twice on the same demonstrations:
practice that repairs the net only (the paper's two scenarios), and practice that then goes on as
evaluated and learns from it (own graded segments refit the laws, the mentor grades some trials,
revisions that make things worse are reverted; ``multiform demo --learn-from-practice``). The
second run starts from a copy of the first's folder, so both share the demos, the trained model and
the repair scenarios. Each final skill is evaluated on the same randomised trials, half pushed.

Prints one row per (demos, seed, variant): success with its Wilson 95 % interval, unpushed and
pushed, practice trials, practice seconds of robot time (the anchor: PILCO needed 17.5 s of
interaction for a cart-pole swing-up), mentor-labelled trials; then the median over seeds per
(demos, variant); then, for the counts the task has a target for (:data:`TARGETS`), each seed's
figures against it, met or not. Writes ``OUT/data_efficiency.json`` and ``OUT/data_efficiency.png``,
and the figures of each demonstration count to
``benchmarks/results/bench_data_efficiency_<task>_<N>demos.json`` (``--results DIR``).

    .venv/bin/python benchmarks/bench_data_efficiency.py --out runs/data_efficiency \\
        [--demos 5 10 20 40] [--seeds 0 1 2] [--trials 200] [--workers 2] [--ray ADDRESS]

About 6-10 minutes per pipeline on a 2-core machine (the whole default grid is 24 pipelines: hours);
finished pipelines are reused from their folders, so an interrupted run goes on where it stopped.
With ``--ray`` (``auto``, ``local`` or a cluster address) the pipelines of each (demos, seed) run as
one Ray task on one CPU, in the worker's temporary folder; only their ``metrics.json`` come back,
written here by this process.
"""

from __future__ import annotations

import argparse
import os
import shutil
import statistics
import sys
import warnings
from pathlib import Path

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")
os.environ.setdefault("MUJOCO_GL", "egl")
warnings.filterwarnings("ignore", message="A single label was found", category=UserWarning)
warnings.filterwarnings("ignore", message="y_pred contains classes not in y_true", category=UserWarning)

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _results import Record, add_option  # noqa: E402
from multiform.io import read_json, write_json  # noqa: E402
from multiform.job import Job, JobConfig  # noqa: E402

VARIANTS = ("repair only", "learning from practice")


def pipeline(task: str, out: Path, demos: int, seed: int, learn: bool, trials: int, workers: int,
             budget: int) -> dict:
    """One pipeline's figures (its ``metrics.json``, reused when it exists)."""
    metrics = out / "metrics.json"
    if not metrics.exists():
        cfg = JobConfig(demos=demos, seed=seed, eval_trials=trials, ablation_trials=0, videos=False,
                        workers=workers, learn=learn, practice_budget=budget)
        Job(task, out, cfg, log=lambda *a: None, progress=False).run()
    m = read_json(metrics, "metrics")
    learned = [s for s in m["scenarios"].values() if "mentor_labelled_trials" in s]
    pushed = m.get("pushed") or {"successes": 0, "trials": 0}      # None: the task pushes nothing
    return {"demos": demos, "seed": seed, "variant": VARIANTS[learn], **m["success_rate"],
            "pushed": [pushed["successes"], pushed["trials"]],
            "unpushed": [m["success_rate"]["successes"] - pushed["successes"],
                         m["success_rate"]["trials"] - pushed["trials"]],
            "practice_trials": m["practice_trials"], "robot_seconds": m.get("practice_robot_seconds"),
            "mentor_labelled_trials": m.get("mentor_labelled_trials", 0),
            "own_segments": sum(s.get("own_segments", 0) for s in learned),
            "mentor_agreement": learned[0]["mentor_agreement"]["rate"] if learned else None,
            "revisions": [f"{r['operator']} {r['target']}" for r in m["revisions"]]}


def remote_pipelines(task: str, demos: int, seed: int, learns: list[bool], trials: int, budget: int) -> dict:
    """The pipelines ``learns`` of one (demos, seed), on a Ray worker in a temporary folder (the
    learning run starts from a copy of the repair run, as here); their metrics by variant."""
    import tempfile
    out = {}
    with tempfile.TemporaryDirectory(prefix="multiform-pipeline-") as tmp:
        base = Path(tmp) / "repair"
        for learn in sorted(set(learns) | ({False} if True in learns else set())):
            folder = Path(tmp) / ("learn" if learn else "repair")
            if learn:
                shutil.copytree(base, folder, ignore=shutil.ignore_patterns("metrics.json", "report.html"))
            cfg = JobConfig(demos=demos, seed=seed, eval_trials=trials, ablation_trials=0, videos=False,
                            workers=1, learn=learn, practice_budget=budget)
            Job(task, folder, cfg, log=lambda *a: None, progress=False).run()
            if learn in learns:
                out[VARIANTS[learn]] = read_json(folder / "metrics.json", "metrics")
    return out


def run_on_ray(args: argparse.Namespace, out: Path) -> None:
    """Every pipeline without a ``metrics.json`` here, as Ray tasks; the driver writes the metrics."""
    from multiform.parallel import ray_backend
    todo = []
    for demos in args.demos:
        for seed in args.seeds:
            learns = [learn for learn in (False, True) if ("learn" if learn else "repair") in args.variants
                      and not (out / f"d{demos}_s{seed}_{'learn' if learn else 'repair'}" / "metrics.json").exists()]
            if learns:
                todo.append((args.task, demos, seed, learns, args.trials, args.budget))
    print(f"{len(todo)} (demos, seed) pair(s) to run on Ray ({args.ray})", flush=True)
    for i, metrics in ray_backend().run_tasks(remote_pipelines, todo, args.ray, num_cpus=args.workers):
        _, demos, seed, *_ = todo[i]
        for variant, m in metrics.items():
            folder = out / f"d{demos}_s{seed}_{'learn' if variant == VARIANTS[1] else 'repair'}"
            write_json(folder / "metrics.json", m)
        print(f"  done: {demos} demos, seed {seed}", flush=True)


# What learning from few demonstrations must reach (demos -> rule): every job seed at least ``rate``
# (pushed trials at least ``pushed``) within ``practice`` practice trials of which at most ``mentor``
# took the mentor's time; or the median over the seeds at least ``rate``.
TARGETS = {
    "pendulum": {10: {"rule": "every seed", "rate": 0.95, "pushed": 0.90, "practice": 100, "mentor": 20},
                 5: {"rule": "median", "rate": 0.90}},
    "nunchaku": {10: {"rule": "every seed", "rate": 0.90}},
}


def check_targets(task: str, rows: list[dict]) -> list[dict]:
    """One verdict per (demos, variant) the task has a target for: ``demos``, ``variant``, ``target``
    (its text), ``met`` and ``text`` (each seed's figures, met or not)."""
    out = []
    for demos, t in sorted(TARGETS.get(task, {}).items()):
        for variant in VARIANTS:
            sel = sorted((r for r in rows if r["demos"] == demos and r["variant"] == variant), key=lambda r: r["seed"])
            if not sel:
                continue
            if t["rule"] == "median":
                med = statistics.median(r["rate"] for r in sel)
                ok = med >= t["rate"]
                bar = f"median over the seeds ≥ {100 * t['rate']:.0f} %"
                out.append({"demos": demos, "variant": variant, "target": bar, "met": ok,
                            "text": f"median over {len(sel)} seeds {100 * med:.1f} %"})
                continue
            parts, met = [], True
            for r in sel:
                checks = [r["rate"] >= t["rate"]]
                text = f"seed {r['seed']} {100 * r['rate']:.1f} %"
                if "pushed" in t and r["pushed"][1]:
                    checks.append(r["pushed"][0] >= t["pushed"] * r["pushed"][1])
                    text += f", pushed {r['pushed'][0]}/{r['pushed'][1]}"
                if "practice" in t:
                    checks.append(r["practice_trials"] <= t["practice"] and r["mentor_labelled_trials"] <= t["mentor"])
                    text += f", {r['practice_trials']} practice / {r['mentor_labelled_trials']} with the mentor"
                parts.append(text + ("" if all(checks) else " (short)"))
                met = met and all(checks)
            bar = f"≥ {100 * t['rate']:.0f} %" + (f", pushed ≥ {100 * t['pushed']:.0f} %" if "pushed" in t else "") + \
                (f", ≤ {t['practice']} practice and ≤ {t['mentor']} mentor trials" if "practice" in t else "")
            out.append({"demos": demos, "variant": variant, "target": f"every seed {bar}", "met": met,
                        "text": "; ".join(parts)})
    return out


def target_lines(verdicts: list[dict]) -> list[str]:
    return [f"  {v['demos']:3d} demos, {v['variant']}: {v['target']}: {v['text']}: {'met' if v['met'] else 'NOT met'}"
            for v in verdicts]


def record_rows(rec: Record, task: str, demos: int, rows: list[dict]) -> None:
    """The figures of one demonstration count: per variant and job seed the final success (unpushed /
    pushed), the practice trials, how many took the mentor's time and the robot's time in practice;
    per variant the median and range over the seeds; and the task's target, where it has one."""
    sel = [r for r in rows if r["demos"] == demos]
    verdicts = {v["variant"]: v for v in check_targets(task, sel)}
    for variant in VARIANTS:
        vrows = sorted((r for r in sel if r["variant"] == variant), key=lambda r: r["seed"])
        if not vrows:
            continue
        short = "learn" if variant == VARIANTS[1] else "repair"
        for r in vrows:
            counts = {"unpushed": r["unpushed"]}
            if r["pushed"][1]:
                counts["pushed"] = r["pushed"]
            rec.rate(f"{short}_seed_{r['seed']}", f"{task} from {demos} demos, {variant}, job seed {r['seed']}: "
                     f"success on {r['trials']} evaluation trials", r["successes"], r["trials"], counts=counts,
                     extra={"practice_trials": r["practice_trials"],
                            "mentor_labelled_trials": r["mentor_labelled_trials"],
                            "robot_seconds_in_practice": r["robot_seconds"]})
        rates = [r["rate"] for r in vrows]
        v = verdicts.get(variant)
        rec.figure(f"{short}_median", f"{task} from {demos} demos, {variant}: median over job seeds "
                   f"{', '.join(str(r['seed']) for r in vrows)}", statistics.median(rates), "%",
                   values={"median": statistics.median(rates), "min": min(rates), "max": max(rates)},
                   target=v["target"] if v else None, met=v["met"] if v else None)
    rec.details["rows"] = sel


def plot(rows: list[dict], path: Path) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(6, 4))
    for variant, marker in zip(VARIANTS, "os"):
        counts = sorted({r["demos"] for r in rows if r["variant"] == variant})
        if not counts:
            continue
        med = [statistics.median(r["rate"] for r in rows if r["variant"] == variant and r["demos"] == n) for n in counts]
        ax.plot(counts, [100 * v for v in med], marker=marker, label=f"{variant} (median over seeds)")
        pts = [(r["demos"], 100 * r["rate"]) for r in rows if r["variant"] == variant]
        if pts:
            ax.scatter(*zip(*pts), marker=marker, alpha=0.35, s=18)
    ax.set_xscale("log", base=2)
    ax.set_xlabel("demonstrations")
    ax.set_ylabel("success over the evaluation trials [%]")
    ax.set_ylim(0, 102)
    ax.axhline(95, color="grey", lw=0.8, ls="--")
    ax.legend(loc="lower right")
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--task", default="pendulum")
    ap.add_argument("--out", default="runs/data_efficiency")
    ap.add_argument("--demos", type=int, nargs="+", default=[5, 10, 20, 40])
    ap.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    ap.add_argument("--trials", type=int, default=200)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--budget", type=int, default=100, help="practice trials per pipeline at most")
    ap.add_argument("--variants", nargs="+", choices=["repair", "learn"], default=["repair", "learn"])
    ap.add_argument("--ray", metavar="ADDRESS", default=None,
                    help="run the pipelines as Ray tasks: auto, local (with --workers CPUs) or a cluster address")
    add_option(ap)
    args = ap.parse_args()
    records = {n: Record(__file__, "Success against the number of demonstrations", section="data_efficiency",
                         variant=f"{args.task}_{n}demos") for n in args.demos}
    out = Path(args.out)
    if args.ray:
        run_on_ray(args, out)
    rows = []
    print(f"{'demos':>5} {'seed':>4} {'variant':<24} {'success':>22} {'unpushed':>9} {'pushed':>8} "
          f"{'practice':>8} {'robot s':>8} {'mentor':>6}", flush=True)
    for demos in args.demos:
        for seed in args.seeds:
            base = out / f"d{demos}_s{seed}_repair"
            for learn in (False, True):
                if ("learn" if learn else "repair") not in args.variants:
                    continue
                folder = out / f"d{demos}_s{seed}_{'learn' if learn else 'repair'}"
                if learn and not folder.exists() and (base / "model").exists():
                    shutil.copytree(base, folder, ignore=shutil.ignore_patterns("metrics.json", "report.html"))
                r = pipeline(args.task, folder, demos, seed, learn, args.trials, args.workers, args.budget)
                rows.append(r)
                print(f"{demos:5d} {seed:4d} {r['variant']:<24} {100 * r['rate']:6.1f} % ({100 * r['low']:4.1f}-"
                      f"{100 * r['high']:5.1f} %) {r['unpushed'][0]:4d}/{r['unpushed'][1]:<4d} "
                      f"{r['pushed'][0]:3d}/{r['pushed'][1]:<4d} {r['practice_trials']:8d} "
                      f"{r['robot_seconds'] or 0:8.0f} {r['mentor_labelled_trials']:6d}", flush=True)
    print("\nmedian over seeds:")
    for demos in args.demos:
        for variant in VARIANTS:
            sel = [r for r in rows if r["demos"] == demos and r["variant"] == variant]
            if sel:
                rates = [100 * r["rate"] for r in sel]
                print(f"  {demos:3d} demos, {variant:<24} {statistics.median(rates):5.1f} % "
                      f"(range {min(rates):.1f}-{max(rates):.1f} %, {len(sel)} seeds)")
    lines = target_lines(check_targets(args.task, rows))
    if lines:
        print("\nagainst the targets:")
        print("\n".join(lines))
    out.mkdir(parents=True, exist_ok=True)
    write_json(out / "data_efficiency.json", rows)
    plot(rows, out / "data_efficiency.png")
    print(f"wrote {out / 'data_efficiency.json'} and {out / 'data_efficiency.png'}")
    for demos, rec in records.items():
        record_rows(rec, args.task, demos, rows)
        rec.write(args.results)


if __name__ == "__main__":
    main()
