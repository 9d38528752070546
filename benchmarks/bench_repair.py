"""Fault-injection benchmark of repair: plausible mistakes written into the sound skill files, then
practice, then evaluation.

Each *kind* of mistake is injected into the sound definition (``pendulum`` or ``nunchaku``) at several
*strengths*; the faulty definition runs with the laws, judges, regions and inverse model of a model
trained from the demonstrations (the mistake is in the definition, not in what was demonstrated).
For each fault: whether practice (the task's first scenario, ``--max-trials`` trials) reached its
success streak, how many trials it took, which revisions it made and which stayed, and the success
rate of the final net over ``--eval-trials`` evaluation trials (the task's physical check), beside
the sound skill's on the same trials. The kind ``none`` is the sound skill itself: practice should
leave it alone.

    PYTHONPATH=src .venv/bin/python benchmarks/bench_repair.py --pendulum-model RUN/model \\
        --nunchaku-model NRUN/model --out /tmp/bench_repair
    # a reduced run: two kinds, one strength each, 20 evaluation trials
    ... --kinds strict_switch,early_giveup_swing --strengths 0 --eval-trials 20

``RUN/model`` is any trained model of the task (e.g. a ``multiform demo`` run's ``model``
directory, or ``multiform train``'s output); its own skill file is not used. Results go to
``OUT/results.json`` (one record per fault and seed, written after each) and a table on stdout; the
summary of every fault in ``OUT/results.json`` to ``benchmarks/results/bench_repair.json``
(``--results DIR``).
"""

from __future__ import annotations

import argparse
import copy
import json
import shutil
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _results import Record, add_option  # noqa: E402


@dataclass(frozen=True)
class Kind:
    """A kind of mistake: ``inject(skill data, strength)`` edits a copy of the sound definition."""

    name: str
    task: str
    what: str
    strengths: tuple[Any, ...]
    inject: Callable[[dict[str, Any], Any], None]
    cannot: str = ""             # why the operators cannot repair it ("" = they are meant to)


def _cond(t: str, text: str) -> Callable[[dict[str, Any], Any], None]:
    def f(d: dict[str, Any], s: Any) -> None:
        d["transitions"][t]["condition"] = text.format(s=s)
    return f


def _scaled_t1(d: dict[str, Any], s: float) -> None:
    d["transitions"]["t1"]["condition"] = (f"abs(theta) < {0.3 * s:.4g} and abs(omega) < {2.0 * s:.4g} "
                                           f"and abs(x) < {0.25 * s:.4g}") if s else "theta == 0 and omega == 0 and x == 0"


def _lambda_zero(d: dict[str, Any], t: str) -> None:
    d["transitions"][t]["lambda"] = 0.0


def _extra(tid: str, spec: dict[str, Any]) -> Callable[[dict[str, Any], Any], None]:
    def f(d: dict[str, Any], s: Any) -> None:
        d["transitions"][tid] = {k: (v.format(s=s) if isinstance(v, str) else v) for k, v in spec.items()}
    return f


def _drop(t: str) -> Callable[[dict[str, Any], Any], None]:
    def f(d: dict[str, Any], s: Any) -> None:
        del d["transitions"][t]
    return f


def _law(t: str, law: str) -> Callable[[dict[str, Any], Any], None]:
    def f(d: dict[str, Any], s: Any) -> None:
        d["transitions"][t]["law"] = law
    return f


def _scaled_release(d: dict[str, Any], s: float) -> None:
    d["transitions"]["t2"]["condition"] = f"fires_t1 >= 1 and phi > {2.31 * s:.4g} and omega > {7.5 * s:.4g}"


KINDS = [
    # -- pendulum ------------------------------------------------------------------------------------
    Kind("strict_switch", "pendulum", "t1 (switch to balancing) demands a near-perfect swing-up: its bounds "
         "scaled by the strength (0: exactly upright, at rest, centred)", (0.3, 0.1, 0), _scaled_t1),
    Kind("loose_switch", "pendulum", "t1's bounds scaled up by the strength: it switches to balancing far from upright",
         (3.0, 5.0, 8.0), _scaled_t1),
    Kind("early_giveup_swing", "pendulum", "t4 gives up the swing-up after this many repeats (sound: 12)",
         (1, 2, 3), _cond("t4", "fires_t2 >= {s}")),
    Kind("fast_repeat_swing", "pendulum", "t2 repeats the swing-up every this many seconds (sound: 2), so t4's "
         "repeat limit ends the swing-up early", (0.5, 0.25, 0.1), _cond("t2", "dwell > {s}")),
    Kind("tight_fall_angle", "pendulum", "t5 declares the balance lost at this angle (sound: 0.8 rad)",
         (0.4, 0.3, 0.2), _cond("t5", "abs(theta) > {s} or fires_t3 >= 10")),
    Kind("early_giveup_balance", "pendulum", "t5 declares the balance lost after this many balance repeats (sound: 10)",
         (1, 2), _cond("t5", "abs(theta) > 0.8 or fires_t3 >= {s}")),
    Kind("late_stop", "pendulum", "t6 (success stop) asks the balance to last this long (sound: 5.5 s)",
         (25.0, 40.0, 100.0), _cond("t6", "dwell > {s} and abs(theta) < 0.25")),
    Kind("zero_weight", "pendulum", "λ = 0 on this transition (a weight the mentor set to nothing)",
         ("t1", "t6", "t0"), _lambda_zero),
    Kind("wrong_branch", "pendulum", "an extra way from swung-up to balancing, taken when |θ| is under the strength",
         (1.0, 1.5, 2.5), _extra("t8", {"label": "balance early", "in": ["P1"], "out": ["P2"], "law": "balance",
                                        "lambda": 1.0, "condition": "abs(theta) < {s}"})),
    Kind("wrong_maneuver_loop", "pendulum", "an extra repeat in swung-up that runs the balance law every this many s",
         (0.5, 1.0, 1.5), _extra("t8", {"label": "steady", "in": ["P1"], "out": ["P1"], "law": "balance",
                                        "lambda": 1.0, "condition": "dwell > {s}"})),
    Kind("wrong_law", "pendulum", "t1 runs the swing-up law instead of the balance law", (None,),
         _law("t1", "swing_up")),
    Kind("missing_stop", "pendulum", "the success stop t6 is missing (the mentor never tags a stop: its "
         "demonstrations just end, balanced)", (None,), _drop("t6")),
    # plain mistakes written in other forms than the ones above (no bound to move, a clock, a weight
    # that is not zero, a repeat's law)
    Kind("switch_always", "pendulum", "t1 written as always true: it switches to balancing with the pendulum hanging",
         (None,), _cond("t1", "true")),
    Kind("switch_on_a_clock", "pendulum", "t1 written as a clock: it switches to balancing this many s into the "
         "swing-up, wherever the pendulum is", (0.1, 1.0), _cond("t1", "dwell > {s}")),
    Kind("switch_unbounded", "pendulum", "t1 with a bound no state crosses", (4.0,), _cond("t1", "abs(theta) < {s}")),
    Kind("switch_strict_rate", "pendulum", "t1 demands the pendulum at rest to this angular velocity (sound: 2 rad/s)",
         (0.05, 0.01), _cond("t1", "abs(theta) < 0.3 and abs(omega) < {s} and abs(x) < 0.25")),
    Kind("low_weight", "pendulum", "λ of t1 is this small beside its sibling t2's 1.0", (0.001,),
         lambda d, s: d["transitions"]["t1"].update(**{"lambda": s})),
    Kind("repeat_wrong_law", "pendulum", "t3 (repeat balancing) runs the swing-up law", (None,),
         _law("t3", "swing_up")),
    Kind("giveup_on_a_clock", "pendulum", "t4 gives up the swing-up at this trial time (sound: after 12 repeats)",
         (3.0, 6.0), _cond("t4", "time > {s}")),
    # -- nunchaku ------------------------------------------------------------------------------------
    Kind("strict_release", "nunchaku", "t2 (release) demands more rod angle and speed: bounds scaled by the strength",
         (1.3, 1.6), _scaled_release,
         cannot="a release too strict fires late rather than never: at 1.3x the robot still flips in about 70 % "
                "of trials, so practice never fails constantly; at 1.6x t2 is relearned, but the learned "
                "condition releases early (its boundary lies between the mentor's releases and the states far "
                "from them)"),
    Kind("early_giveup_regrasp", "nunchaku", "t7 gives up waiting for the catch after this many s (sound: 1.2)",
         (0.3, 0.15), _cond("t7", "dwell > {s}")),
    Kind("late_stop_nunchaku", "nunchaku", "t5 (success stop) asks the catch to be held this long (sound: 0.5 s)",
         (20.0, 50.0), _cond("t5", "grip > 0.5 and dwell > {s}")),
    Kind("zero_weight_nunchaku", "nunchaku", "λ = 0 on this transition", ("t4", "t2"), _lambda_zero),
    Kind("early_giveup_swing_nunchaku", "nunchaku", "t6 gives up the swing-up after this many s (sound: 10)",
         (1.5, 1.0), _cond("t6", "fires_t1 >= 3 and dwell > 1.0 or time > {s}")),
    Kind("missing_stop_nunchaku", "nunchaku", "the success stop t5 is missing (the mentor's demonstrations tag it)",
         (None,), _drop("t5")),
    Kind("release_always", "nunchaku", "t2 (release) written as always true after the first swing: it lets go at "
         "once", (None,), _cond("t2", "fires_t1 >= 1")),
    Kind("wrong_branch_nunchaku", "nunchaku", "an extra release from swung-up taken when φ exceeds the strength",
         (1.0, 0.5), _extra("t9", {"label": "release early", "in": ["P1"], "out": ["P2"], "law": "release",
                                   "lambda": 1.0, "condition": "fires_t1 >= 1 and phi > {s}"})),
]
SOUND = {"pendulum": "pendulum", "nunchaku": "nunchaku"}


def faulty_model(base: Path, task: str, kind: Kind | None, strength: Any, folder: Path):
    """A model directory with the sound definition (or ``kind`` injected at ``strength``) and ``base``'s
    learned pieces."""
    from multiform.model import SkillModel
    from multiform.petri.skillfile import load_skill, skill_to_data
    data = skill_to_data(load_skill(SOUND[task]))
    if kind is not None:
        data = copy.deepcopy(data)
        kind.inject(data, strength)
        data["skill"] = f"{task}_{kind.name}"
    if folder.exists():
        shutil.rmtree(folder)
    folder.mkdir(parents=True)
    skill = folder / "definition.yaml"
    skill.write_text(yaml.safe_dump(data, sort_keys=False))
    src = SkillModel(base)
    m = src.manifest
    model = SkillModel.create(folder / "model", skill, m["demos"], m["env"], m.get("env_kwargs", {}))
    model.adopt(src, ("law", "judge", "regions", "inverse_model"))
    if (src.path / "labels.jsonl").exists():
        shutil.copyfile(src.path / "labels.jsonl", model.path / "labels.jsonl")
    return model


def run_one(base: Path, task_name: str, kind: Kind | None, strength: Any, seed: int, out: Path,
            max_trials: int, eval_trials: int, workers: int, log=print) -> dict[str, Any]:
    from multiform.evaluation import Variant, evaluate
    from multiform.adapt.practice import Practice
    from multiform.task import load_task
    task = load_task(task_name)
    name = kind.name if kind else "none"
    folder = out / task_name / f"{name}_{strength}_s{seed}"
    t0 = time.perf_counter()
    model = faulty_model(base, task_name, kind, strength, folder)
    sc = task.scenarios()[0]
    cfg = sc.practice_config(max_trials=max_trials, seed=seed)
    state = Practice(model, folder / "practice", cfg, options=sc.options, name=sc.name).run()
    first_fail = next((t.trial for t in state.trials if not t.success), None)
    revs = [r for r in state.revisions if r.version is not None]
    reverted = {r.reason.split(" did not help")[0] for r in revs if r.operator == "revert"}
    history = model.history.revisions()
    kept = _kept(history)
    streak = state.stop_reason.endswith("successes in a row")
    rec: dict[str, Any] = {
        "task": task_name, "kind": name, "strength": strength, "seed": seed,
        "what": kind.what if kind else "the sound skill", "cannot": kind.cannot if kind else "",
        "practice_trials": len(state.trials), "failed_trials": sum(not t.success for t in state.trials),
        "first_failure": first_fail, "reached_streak": streak, "stop_reason": state.stop_reason,
        "revisions": [{"version": r.version, "operator": r.operator, "target": r.target, "after_trial": r.after_trial,
                       "candidate": _candidate(history, r.version), "reason": r.reason[:300]} for r in revs],
        "tried": list(state.tried), "reverted": sorted(reverted), "kept": kept,
        "no_operator": sum(r.operator == "none" for r in state.revisions),
        "net_version": model.version}
    if eval_trials > 0:
        specs = task.evaluation_specs(eval_trials, seed, 0.0)
        res = evaluate(task_name, Variant(name, str(model.path)), specs, workers=workers)
        rec["eval"] = {"successes": res["successes"], "trials": res["trials"], "rate": res["rate"]}
    rec["wall_s"] = round(time.perf_counter() - t0, 1)
    log(f"{task_name:9s} {name:28s} {str(strength):6s} s{seed}: streak {'yes' if streak else 'no ':3s} "
        f"trials {len(state.trials):3d} kept {', '.join(kept) or '-':40s} "
        + (f"eval {rec['eval']['successes']}/{rec['eval']['trials']}" if "eval" in rec else "") + f"  ({rec['wall_s']} s)")
    return rec


def _candidate(history, version: int) -> str:
    for r in history:
        if r.version == version:
            return r.evidence.get("candidate", "")
    return ""


def _kept(history) -> list[str]:
    """The revisions in the final net: replayed with reverts undoing what they went back over."""
    stack: list[tuple[int, str]] = []
    for r in history:
        if r.operator == "revert":
            to = r.params["to_version"]
            stack = [s for s in stack if s[0] <= to]
        else:
            stack.append((r.version, f"{r.operator} {r.target}"))
    return [s for _, s in stack]


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--pendulum-model", help="a trained pendulum model directory")
    p.add_argument("--nunchaku-model", help="a trained nunchaku model directory")
    p.add_argument("--out", default="bench_repair_out", help="working folder and results.json")
    p.add_argument("--kinds", default="all", help="comma-separated kinds (and 'none' for the sound skill), or all")
    p.add_argument("--strengths", default="all",
                   help="comma-separated indices into each kind's strengths (0 = the first, -1 = the last), or all")
    p.add_argument("--seeds", default="0", help="comma-separated practice/evaluation seeds")
    p.add_argument("--max-trials", type=int, default=30)
    p.add_argument("--eval-trials", type=int, default=100)
    p.add_argument("--workers", type=int, default=1)
    p.add_argument("--list", action="store_true", help="list the kinds and exit")
    add_option(p)
    a = p.parse_args(argv)
    if a.list:
        for k in KINDS:
            print(f"{k.task:9s} {k.name:28s} strengths {k.strengths}: {k.what}" + (f" [cannot: {k.cannot}]" if k.cannot else ""))
        return 0
    record = Record(__file__, "Repair of injected mistakes", section="repair",
                    argv=None if argv is None else [__file__, *argv])
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    wanted = None if a.kinds == "all" else set(a.kinds.split(","))
    idx = None if a.strengths == "all" else [int(i) for i in a.strengths.split(",")]
    bases = {"pendulum": a.pendulum_model, "nunchaku": a.nunchaku_model}
    results_path = out / "results.json"
    results = json.loads(results_path.read_text()) if results_path.exists() else []
    done = {(r["task"], r["kind"], str(r["strength"]), r["seed"]) for r in results}
    jobs: list[tuple[str, Kind | None, Any]] = []
    for task in ("pendulum", "nunchaku"):
        if not bases[task]:
            continue
        if wanted is None or "none" in wanted:
            jobs.append((task, None, None))
        for k in KINDS:
            if k.task == task and (wanted is None or k.name in wanted):
                for i, s in enumerate(k.strengths):
                    if idx is None or i in idx or i - len(k.strengths) in idx:
                        jobs.append((task, k, s))
    for seed in [int(s) for s in a.seeds.split(",")]:
        for task, kind, s in jobs:
            key = (task, kind.name if kind else "none", str(s), seed)
            if key in done:
                continue
            rec = run_one(Path(bases[task]), task, kind, s, seed, out, a.max_trials, a.eval_trials, a.workers)
            results.append(rec)
            results_path.write_text(json.dumps(results, indent=1))
    _table(results)
    record_summary(record, results)
    record.write(a.results)
    return 0


def record_summary(rec: Record, results: list[dict[str, Any]]) -> None:
    """Per task (and over both): of the injected faults, how many made practice fail, were repaired
    before practice (the demonstrations replayed), reached the success streak, and ended within 5
    points of the sound skill on the evaluation trials; the evaluation trials of all of them; the
    sound skill's own."""
    sound = {(r["task"], r["seed"]): r["eval"]["rate"] for r in results if r["kind"] == "none" and "eval" in r}
    tasks = sorted({r["task"] for r in results}, key=lambda t: (t != "pendulum", t))
    for task in tasks + (["all"] if len(tasks) > 1 else []):
        faults = [r for r in results if r["kind"] != "none" and task in ("all", r["task"])]
        what = f"{task}: of {len(faults)} injected faults" if task != "all" else f"all tasks: of {len(faults)} faults"
        if faults:
            rec.rate(f"{task}_made_fail", f"{what}, those that made practice fail",
                     sum(r["first_failure"] is not None for r in faults), len(faults))
            rec.rate(f"{task}_before_practice", f"{what}, those repaired before the first trial (the demonstrations "
                     "replayed through the net)",
                     sum(any(str(v.get("candidate", "")).startswith("demonstrations:") for v in r["revisions"])
                         for r in faults), len(faults))
            rec.rate(f"{task}_streak", f"{what}, those after which practice reached its success streak",
                     sum(bool(r["reached_streak"]) for r in faults), len(faults))
        judged = [r for r in faults if "eval" in r and (r["task"], r["seed"]) in sound]
        if judged:
            rec.rate(f"{task}_within_5", f"{what}, those whose final skill ends within 5 points of the sound skill "
                     "on the same evaluation trials", sum(r["eval"]["rate"] >= sound[(r["task"], r["seed"])] - 0.05
                                                          for r in judged), len(judged))
        evaluated = [r for r in faults if "eval" in r]
        if evaluated:
            rec.rate(f"{task}_eval", f"{what}, the final skills' evaluation trials",
                     sum(r["eval"]["successes"] for r in evaluated), sum(r["eval"]["trials"] for r in evaluated))
        sounds = [r for r in results if r["kind"] == "none" and "eval" in r and task in ("all", r["task"])]
        if sounds and task != "all":
            rec.rate(f"{task}_sound", f"{task}: the sound skill's evaluation trials (practice leaves it alone: "
                     f"{sum(not r['revisions'] for r in sounds)} of {len(sounds)} runs made no revision)",
                     sum(r["eval"]["successes"] for r in sounds), sum(r["eval"]["trials"] for r in sounds))
    rec.details["faults"] = [{k: r.get(k) for k in ("task", "kind", "strength", "seed", "first_failure", "reached_streak",
                                                     "kept", "eval", "practice_trials")} for r in results]


def _table(results: list[dict[str, Any]]) -> None:
    sound = {(r["task"], r["seed"]): r.get("eval", {}).get("rate") for r in results if r["kind"] == "none"}
    print("\n| task | kind | strength | seed | failed before repair | streak | trials | kept revisions | tried, reverted "
          "| eval | sound eval |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for r in results:
        ev = r.get("eval")
        s = sound.get((r["task"], r["seed"]))
        ev_text = f"{ev['successes']}/{ev['trials']}" if ev else ""
        sound_text = "" if s is None else f"{100 * s:.0f} %"
        print(f"| {r['task']} | {r['kind']} | {r['strength']} | {r['seed']} | {r['first_failure'] is not None} | "
              f"{'yes' if r['reached_streak'] else 'no'} | {r['practice_trials']} | {'; '.join(r['kept']) or '-'} | "
              f"{len(r['tried'])}, {len(r['reverted'])} | "
              f"{ev_text} | {sound_text} |")


if __name__ == "__main__":
    raise SystemExit(main())
