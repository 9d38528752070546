"""Many mentors: the robot learns from several people of unequal skill, weighs each by how reliable
they prove, and is measured against pooling them blindly and against the best one alone.

Per task and job seed, the main job's pipeline (record, train, practise with repair and learning,
evaluate on the job's evaluation trials, half of them pushed for the pendulum) is run for:

* ``fused``       — 15 demonstrations, 5 each by the task's expert, average and poor mentors,
                    weighed by estimated trust (multiform's default with several mentors);
* ``pooled``      — the same 15, pooled as if one mentor made them (``--no-fusion``);
* ``expert``      — the expert's 5 alone (the same 5 demonstrations);
* ``expert_poor`` — the expert's 5 and 10 by the poor mentor, weighed.

It then prints the success rates side by side on the same trials (Wilson 95 % intervals), the
estimated reliabilities per maneuver after training (and after practice), and the judges' accuracy
on fresh demonstrations labelled honestly (every mentor's own verdicts with nothing flipped),
judges trained with the poor mentor's labels fused, pooled, and from the expert's labels alone.

    .venv/bin/python benchmarks/bench_mentors.py --out runs/mentors [--tasks pendulum nunchaku]
        [--seeds 0 1 2] [--variants fused pooled expert expert_poor] [--trials 200] [--workers 2]

Every run folder (``OUT/TASK/seed_S/VARIANT``) is kept and reused: a variant already evaluated is not
run again. About 6-10 minutes per pendulum run on a quiet 2-core machine. All figures are kept in
one dict (``FIGURES``), printed as JSON at the end and recorded (with every success rate and check as
a figure) in ``benchmarks/results/bench_mentors.json`` (``--results DIR``).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
import warnings
from pathlib import Path

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")
os.environ.setdefault("MUJOCO_GL", "egl")
warnings.filterwarnings("ignore", message="A single label was found", category=UserWarning)
warnings.filterwarnings("ignore", message="y_pred contains classes not in y_true", category=UserWarning)

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _results import Record, add_option, at_least  # noqa: E402

from multiform.evaluation import Variant, evaluate  # noqa: E402
from multiform.io import read_json, write_json  # noqa: E402
from multiform.job import Job, JobConfig  # noqa: E402
from multiform.learn.features import Segment  # noqa: E402
from multiform.learn.views import place_episode, value_matrix  # noqa: E402
from multiform.model import SkillModel  # noqa: E402
from multiform.stats import rate  # noqa: E402
from multiform.task import load_task  # noqa: E402
from multiform.teach.record import record_many  # noqa: E402

PLANS = {"fused": ((("expert", 5), ("average", 5), ("poor", 5)), True),
         "pooled": ((("expert", 5), ("average", 5), ("poor", 5)), False),
         "expert": ((("expert", 5),), True),
         "expert_poor": ((("expert", 5), ("poor", 10)), True)}
SLOPPY = {"pendulum": ("t3", "t1"), "nunchaku": ("t2", "t3")}      # where the poor mentor is sloppy
GOOD = {"pendulum": ("t2",), "nunchaku": ("t0",)}                  # where it is as good as anyone
TARGET = {"pendulum": 0.95, "nunchaku": 0.90}                      # the bar for the fused skill
FRESH_SEED = 900_000                                               # fresh labelled demos: never a job's demo seed
FIGURES: dict = {}


def run(task: str, out: Path, seed: int, variant: str, trials: int, workers: int, log) -> dict:
    """One variant's job on one seed: record, train, practise, evaluate (no ablations, no report)."""
    done = out / "variant_result.json"
    if done.exists():
        return read_json(done, "variant result")
    plan, fusion = PLANS[variant]
    out.mkdir(parents=True, exist_ok=True)
    job = Job(task, out, JobConfig(seed=seed, workers=workers, mentors=plan, fusion=fusion, eval_trials=trials,
                                   ablation_trials=0, videos=False), log=lambda *a: None, progress=False)
    t0 = time.perf_counter()
    demos = job.record()
    model = SkillModel(out / "model") if (out / "model" / "model.json").exists() else job.train(demos)
    job.practise(model)
    model = SkillModel(out / "model")
    specs = job.task.evaluation_specs(trials, seed, job.cfg.push_fraction)
    r = evaluate(job.task.spec or job.task.TASK, Variant(variant, str(model.path)), specs, workers)
    trust = model.fusion()
    res = {"variant": variant, "seed": seed, "successes": r["successes"], "trials": r["trials"],
           "rate": r["rate"], "low": r["low"], "high": r["high"],
           "pushed": [r["pushed"]["successes"], r["pushed"]["trials"]] if r.get("pushed") else None,
           "digests": [t["trace_digest"] for t in r["trials_detail"]],
           "success_by_trial": [bool(t["success"]) for t in r["trials_detail"]],
           "net_version": model.version, "minutes": round((time.perf_counter() - t0) / 60, 1),
           "trust_after_training": trust.history[0] if trust is not None else None,
           "trust_after_practice": trust.history[-1] if trust is not None else None,
           "labels": trust.table()["labels"] if trust is not None else None}
    write_json(done, res)
    log(f"  {task} seed {seed} {variant}: {100 * res['rate']:.1f} % ({res['successes']}/{res['trials']})"
        + (f", pushed {res['pushed'][0]}/{res['pushed'][1]}" if res["pushed"] else "") + f" in {res['minutes']} min")
    return res


def fresh_stays(task: str, n: int, workers: int) -> list[tuple[object, int, int, str, bool]]:
    """Fresh demonstrations by each mentor, labelled honestly (nothing flipped): (episode, start,
    end, place, verdict) of every labelled stay."""
    t = load_task(task)
    out = []
    for k, name in enumerate(("expert", "average", "poor")):
        kw = {**t.mentor_kwargs(name), "label_flip": 0.0}
        seeds = [FRESH_SEED + 1000 * k + i for i in range(n)]
        for ep in record_many(task, seeds, t.DEMO_ENV_KWARGS, mentor_kwargs=kw, workers=workers):
            out.append(ep)
    return out


def judge_accuracy(model: SkillModel, episodes: list) -> dict:
    """The model's judges on every honestly labelled stay of ``episodes``: accuracy per place and overall."""
    apn = model.history.version(0)
    judges = model.judges()
    right: dict[str, list[bool]] = {}
    for i, ep in enumerate(episodes):
        for lab in place_episode(apn, ep).labels:
            judge = judges.get(lab.transition)
            if judge is None:
                continue
            V = value_matrix(apn, ep, judge.variables)
            seg = Segment(V[lab.start:lab.end], tuple(judge.variables), ep.dt, f"fresh_{i}", lab.start, lab.end,
                          lab.transition)
            right.setdefault(lab.transition, []).append(bool(judge.predict([seg])[0]) == bool(lab.success))
    allv = [v for vs in right.values() for v in vs]
    return {"overall": round(float(np.mean(allv)), 4), "stays": len(allv),
            **{p: round(float(np.mean(v)), 4) for p, v in sorted(right.items())}}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", default="runs/mentors")
    ap.add_argument("--tasks", nargs="+", default=["pendulum", "nunchaku"])
    ap.add_argument("--seeds", nargs="+", type=int, default=[0, 1, 2])
    ap.add_argument("--variants", nargs="+", default=list(PLANS), choices=list(PLANS))
    ap.add_argument("--trials", type=int, default=200)
    ap.add_argument("--fresh", type=int, default=10, help="fresh labelled demonstrations per mentor for the judges")
    ap.add_argument("--workers", type=int, default=2)
    add_option(ap)
    args = ap.parse_args()
    rec = Record(__file__, "Several mentors: fusion against pooling and the best mentor alone", section="mentors",
                 variant="_".join(args.tasks) if args.tasks != ["pendulum", "nunchaku"] else None)
    out = Path(args.out)
    log = lambda text: print(text, flush=True)  # noqa: E731
    for task in args.tasks:
        fig = FIGURES.setdefault(task, {"seeds": {}})
        fresh = None
        for seed in args.seeds:
            rows = {v: run(task, out / task / f"seed_{seed}" / v, seed, v, args.trials, args.workers, log)
                    for v in args.variants}
            same = len({r["trials"] for r in rows.values()}) == 1      # the same job seed: the same trial seeds
            if fresh is None and any(v in rows for v in ("fused", "pooled", "expert")):
                fresh = fresh_stays(task, args.fresh, args.workers)
            judges = {v: judge_accuracy(SkillModel(out / task / f"seed_{seed}" / v / "model"), fresh)
                      for v in ("fused", "pooled", "expert") if v in rows}
            fig["seeds"][seed] = {"rates": {v: {k: r[k] for k in ("successes", "trials", "rate", "low", "high",
                                                                   "pushed", "net_version")}
                                            for v, r in rows.items()},
                                  "same_trials": same, "judge_accuracy": judges,
                                  "trust": {v: {"after_training": r["trust_after_training"],
                                                "after_practice": r["trust_after_practice"], "labels": r["labels"]}
                                            for v, r in rows.items() if r["trust_after_training"]}}
        report(task, fig, args.variants)
        record(rec, task, fig)
    print(json.dumps(FIGURES, indent=1, default=str))
    rec.details["figures"] = FIGURES
    rec.write(args.results)


def record(rec: Record, task: str, fig: dict) -> None:
    """Every variant's success rate per seed (the fused one against the task's bar) and every
    check, as figures of the results record."""
    for seed, d in fig["seeds"].items():
        for v, r in d["rates"].items():
            plan = " + ".join(f"{m} {n}" for m, n in PLANS[v][0]) + ("" if PLANS[v][1] else ", pooled")
            rec.rate(f"{task}_seed_{seed}_{v}", f"{task}, job seed {seed}: {v} ({plan})", r["successes"], r["trials"],
                     target=at_least(TARGET[task]) if v == "fused" else None,
                     counts={"pushed": r["pushed"]} if r["pushed"] else None)
        if d["judge_accuracy"]:
            rec.figure(f"{task}_seed_{seed}_judges",
                       f"{task}, job seed {seed}: the judges' accuracy on fresh, honestly labelled stays",
                       d["judge_accuracy"].get("fused", {}).get("overall"), "%",
                       values={v: a["overall"] for v, a in d["judge_accuracy"].items()},
                       target="fused within 2 points of the expert's alone",
                       met=(None if not {"fused", "expert"} <= set(d["judge_accuracy"]) else
                            d["judge_accuracy"]["fused"]["overall"] >= d["judge_accuracy"]["expert"]["overall"] - 0.02))
    for i, (name, vals) in enumerate(fig.get("checks", {}).items()):
        rec.figure(f"{task}_check_{i}", f"{task}: {name}, per seed", f"{sum(vals)} of {len(vals)} seeds",
                   target="every seed", met=all(vals))
    ranks = fig.get("ranking_expert_average_poor", [])
    if ranks:
        rec.figure(f"{task}_ranking", f"{task}: estimated trust ranks expert > average > poor where the poor mentor "
                   "is sloppy (per seed and maneuver)", f"{sum(r[2] for r in ranks)} of {len(ranks)}",
                   target="every one", met=all(r[2] for r in ranks))


def report(task: str, fig: dict, variants: list[str]) -> None:
    """The figures of one task, printed."""
    print(f"\n== {task}: success on the same evaluation trials (95 % Wilson interval; pushed)")
    for seed, d in fig["seeds"].items():
        cells = []
        for v in variants:
            r = d["rates"].get(v)
            if r is None:
                continue
            pushed = f", pushed {r['pushed'][0]}/{r['pushed'][1]}" if r["pushed"] else ""
            cells.append(f"{v} {100 * r['rate']:.1f} % ({100 * r['low']:.1f}-{100 * r['high']:.1f}{pushed})")
        print(f"  seed {seed}: " + " | ".join(cells))
    means = {v: float(np.mean([d["rates"][v]["rate"] for d in fig["seeds"].values() if v in d["rates"]]))
             for v in variants if any(v in d["rates"] for d in fig["seeds"].values())}
    print("  mean: " + ", ".join(f"{v} {100 * m:.1f} %" for v, m in means.items()))
    fig["mean_rate"] = means
    checks = {}
    for seed, d in fig["seeds"].items():
        r = d["rates"]
        if {"fused", "pooled", "expert"} <= set(r):
            checks.setdefault("fused >= max(pooled, expert)", []).append(
                r["fused"]["rate"] >= max(r["pooled"]["rate"], r["expert"]["rate"]))
        if "fused" in r:
            pushed = r["fused"]["pushed"]
            checks.setdefault(f"fused >= {100 * TARGET[task]:.0f} %" + (" and pushed >= 90 %" if pushed else ""),
                              []).append(r["fused"]["rate"] >= TARGET[task]
                                         and (not pushed or pushed[0] >= 0.9 * pushed[1]))
        if {"expert_poor", "expert"} <= set(r):
            checks.setdefault("expert+poor no worse than the expert (at least as high, or the intervals overlap)",
                              []).append(r["expert_poor"]["rate"] >= r["expert"]["rate"]
                                         or r["expert_poor"]["high"] >= r["expert"]["low"])
    fig["checks"] = checks
    for name, vals in checks.items():
        print(f"  {name}: {vals}")
    print(f"\n== {task}: estimated weight per maneuver after training (after practice), fused run")
    ranks = []
    for seed, d in fig["seeds"].items():
        tr = d["trust"].get("fused")
        if not tr:
            continue
        first, last = tr["after_training"]["maneuvers"], tr["after_practice"]["maneuvers"]
        for t in sorted(first):
            print(f"  seed {seed} {t}: " + ", ".join(f"{m} {w:.2f} ({last.get(t, {}).get(m, w):.2f})"
                                                   for m, w in sorted(first[t].items())))
        for t in SLOPPY[task]:
            w = first.get(t, {})
            ranks.append((seed, t, w.get("expert", 0) > w.get("average", 0) > w.get("poor", 0)))
        for t in GOOD[task]:
            w = first.get(t, {})
            print(f"  seed {seed}: the poor mentor's good maneuver {t}: weight {w.get('poor', float('nan')):.2f} vs "
                  f"the others' {', '.join(f'{v:.2f}' for m, v in sorted(w.items()) if m != 'poor')}")
        print(f"  seed {seed} labels: " + "; ".join(
            f"{p}: " + ", ".join(f"{w} {v['agreement']:.2f}" for w, v in sorted(a.items()))
            for p, a in (tr["labels"] or {}).items()))
    fig["ranking_expert_average_poor"] = ranks
    print(f"  expert > average > poor where the poor mentor is sloppy: {ranks}")
    print(f"\n== {task}: judges' accuracy on fresh, honestly labelled stays")
    for seed, d in fig["seeds"].items():
        print(f"  seed {seed}: " + " | ".join(f"{v} {100 * a['overall']:.1f} % of {a['stays']}"
                                              + "".join(f", {p} {100 * x:.1f}" for p, x in a.items()
                                                        if p not in ("overall", "stays"))
                                              for v, a in d["judge_accuracy"].items()))


if __name__ == "__main__":
    main()
