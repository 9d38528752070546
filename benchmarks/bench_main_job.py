"""The main job's figures: run ``multiform demo TASK`` (the command a user runs, with its defaults) and
record what its ``metrics.json`` says.

Records, for the final skill on the job's evaluation trials (half of the pendulum's pushed): its
success with the Wilson 95 % interval, unpushed and pushed, the practice trials (and how many took
the mentor's time) and the robot's time in practice; how often the robot's own verdict agrees with
the physical check; each ablation on the first evaluation trials; the mentor's own success over its
demonstrations; each law's held-out error and the learned inverse model's tracking against the
reference controller; and the job's wall time by stage (``timings.closed_loop_us_per_sim_ms`` tells
a slow run from a busy machine).

    .venv/bin/python benchmarks/bench_main_job.py pendulum --out runs/pendulum [-- DEMO OPTIONS]
    .venv/bin/python benchmarks/bench_main_job.py nunchaku --out runs/nunchaku

Options after ``--`` go to ``multiform demo`` as they are (``--seed 1``, ``--workers 1``...). Use a
new run folder: ``multiform demo`` resumes an existing one, reusing what it finds, and the wall time
is then that of the stages it ran. About 5 minutes for the pendulum and 10-17 for the nunchaku on a
2-core machine. The figures go to ``benchmarks/results/bench_main_job_<task>.json`` (``--results DIR``).
"""

from __future__ import annotations

import argparse
import subprocess
import sys
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _results import Record, add_option, at_least, at_most  # noqa: E402
from multiform.io import read_json  # noqa: E402

WALL_TIME_S = {"pendulum": 300, "nunchaku": 600}   # the issues' bounds on the job's wall time
NRMSE = 0.2                                          # a law's held-out error the issues ask for
TRACKING = 2.0                                       # learned inverse model's tracking error / the reference's


def record_metrics(rec: Record, m: dict[str, Any], resumed: bool = False) -> None:
    """The figures of one main job's ``metrics.json``."""
    task, cfg = m["task"], m["config"]
    how = "learning from practice" if cfg.get("learn") else "practice repairs the net only"
    sr = m["success_rate"]
    counts = ({name: [m[name]["successes"], m[name]["trials"]] for name in ("unpushed", "pushed")}
              if m.get("pushed") and m.get("unpushed") else None)
    rec.rate("final", f"{task}: the final skill on {sr['trials']} evaluation trials (job seed {cfg['seed']}, "
             f"{cfg['demos']} demonstrations, {how})", sr["successes"], sr["trials"], counts=counts,
             target=at_least(m["target_success_rate"]),
             extra={"practice_trials": m["practice_trials"], "mentor_labelled_trials": m.get("mentor_labelled_trials", 0),
                    "robot_seconds_in_practice": m.get("practice_robot_seconds")})
    v = m.get("verdicts")
    if v:
        rec.rate("verdict", f"{task}: the robot's own verdict (its judges) agrees with the physical check",
                 v["both_success"] + v["both_failure"], sum(v.values()),
                 counts={"robot says success, check says failure": [v["robot_only"], sum(v.values())]})
    for i, row in enumerate(m["ablation"][1:]):
        rec.rate(f"ablation_{i}", f"{task}, ablation: {row['name']}", row["successes"], row["trials"])
    ms = m["demos"]["mentor_success_rate"]
    rec.rate("mentor", f"{task}: the scripted mentor's own success over its {m['demos']['count']} demonstrations",
             ms["successes"], ms["trials"])
    for name, law in (m.get("training", {}).get("laws") or {}).items():
        if law.get("heldout_nrmse") is not None:
            rec.figure(f"nrmse_{name}", f"{task}: law {name}, held-out NRMSE (successful segments of unseen "
                       f"demonstrations)", law["heldout_nrmse"], "", target=at_most(NRMSE), section="components",
                       extra={"samples": law.get("n"), "mode": law.get("mode")})
    tracking = ((m.get("training", {}).get("inverse_model") or {}).get("tracking") or {}).get("ratio")
    if tracking is not None:
        rec.figure("tracking", f"{task}: the learned inverse model's tracking error over the reference "
                   "controller's", tracking, "", target=at_most(TRACKING), section="components")
    t = m.get("timings") or {}
    if "total_s" in t:
        stages = {k: v for k, v in t.items() if k.endswith("_s") and k != "total_s"}
        rec.figure("wall_time", f"{task}: the job's wall time" + (" (a resumed run folder: the stages it ran)"
                                                                   if resumed else ""),
                   t["total_s"], "s", target=at_most(WALL_TIME_S[task]) if task in WALL_TIME_S and not resumed else None,
                   extra={**stages, "µs_per_simulated_ms_of_closed_loop": t.get("closed_loop_us_per_sim_ms")})
    rec.details.update(config=cfg, revisions=[f"{r['scenario']}: {r['operator']} {r['target']}" for r in m["revisions"]],
                       version=m.get("version"), net_version=m.get("net_version"))


def main() -> int:
    argv = sys.argv[1:]
    demo_args = argv[argv.index("--") + 1:] if "--" in argv else []
    own = argv[: argv.index("--")] if "--" in argv else argv
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("task", help="a bundled task name (pendulum, nunchaku) or any task spec multiform demo takes")
    ap.add_argument("--out", required=True, help="the run folder (best a new one)")
    add_option(ap)
    args = ap.parse_args(own)
    rec = Record(__file__, "The main job", section="main")
    out = Path(args.out)
    resumed = out.exists() and any(out.iterdir())
    if resumed:
        print(f"{out} exists: multiform demo resumes it, and the wall time is that of the stages it runs", flush=True)
    cmd = [sys.executable, "-m", "multiform", "demo", args.task, "--out", str(out), *demo_args]
    done = subprocess.run(cmd)
    if done.returncode != 0:
        return done.returncode
    metrics = read_json(out / "metrics.json", "run metrics")
    rec.variant = metrics["task"]
    record_metrics(rec, metrics, resumed)
    rec.write(args.results)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
