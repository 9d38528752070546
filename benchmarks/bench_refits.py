"""What each refit from practice is worth: the final skill beside the same skill with each refitted
law put back to the fit it had before practice's first refit, on the same evaluation trials.

Learning from practice refits a law from the robot's own graded successes, and practice examines the
refit on ten replayed trials: enough to see a refit that breaks the skill, not one that costs a few
points. This benchmark takes a practised model and runs, on the job's own evaluation trials (half
pushed where the task pushes), the final net as it is, the final net with each refitted law put back
(one at a time), and with all of them put back. Each variant runs in a copy of the model with one
more ``refit_law`` revision pointing the law at its earlier fit; the given model is never changed.

With ``--kernels``, a refit's worth is split into its data and its kernel: each refitted law (and
all together) solved again on its last refit's data, the mentor's and its own, with the
hyperparameters of its earlier fit, so only the data differs from the earlier law and only the
kernel from the final one.

    .venv/bin/python benchmarks/bench_refits.py --model runs/bic/model --seed 7 [--trials 200]
        [--push-fraction 0.5] [--workers 2] [--kernels] [--label 'ball-in-cup job seed 7'] [--results DIR]

``--seed`` is the job seed whose evaluation trials to run (``multiform evaluate --seed``).
"""

from __future__ import annotations

import argparse
import os
import shutil
import sys
import tempfile
import time
import warnings
from pathlib import Path

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")
os.environ.setdefault("MUJOCO_GL", "egl")
warnings.filterwarnings("ignore", category=UserWarning)

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _results import Record, add_option  # noqa: E402

from multiform.adapt.experience import Experience  # noqa: E402
from multiform.adapt.practice import PracticeConfig  # noqa: E402
from multiform.adapt.practice.learning import fit_refit  # noqa: E402
from multiform.evaluation import Variant, evaluate  # noqa: E402
from multiform.learn.gp import GPLaw  # noqa: E402
from multiform.model import SkillModel  # noqa: E402
from multiform.petri.revision import refit_law  # noqa: E402
from multiform.task import task_for_env  # noqa: E402


def refitted(model: SkillModel) -> tuple[int, dict[str, tuple[str, str]]]:
    """The version before practice's first refit, and per law refitted since: (fit then, fit now)."""
    versions = [r.version for r in model.history.revisions() if r.operator == "refit_law"]
    if not versions:
        raise SystemExit(f"{model.path}: practice refitted no law; nothing to put back")
    before = model.history.version(min(versions) - 1)
    now = model.apn
    return min(versions) - 1, {law: (before.laws[law].fit_name, spec.fit_name) for law, spec in now.laws.items()
                               if law in before.laws and before.laws[law].fit_name != spec.fit_name}


def put_back(source: Path, dest: Path, fits: dict[str, str | GPLaw]) -> Path:
    """A copy of the model at ``dest`` whose latest net runs ``fits``: law -> its earlier fit's name,
    or a law fitted here (saved as ``<law>_earlier_kernel``)."""
    shutil.copytree(source, dest)
    model = SkillModel(dest)
    apn = model.apn
    for law, fit in fits.items():
        reason = "put back to its fit before practice's first refit (bench_refits)"
        if not isinstance(fit, str):
            model.save_law(f"{law}_earlier_kernel", fit)
            fit, reason = f"{law}_earlier_kernel", "its last refit's data, its earlier fit's kernel (bench_refits)"
        apn, rev = refit_law(apn, law, fit, reason)
        model.history.record(rev)
    return dest


def earlier_kernel(model: SkillModel, law: str, base: int, practice_seed: int) -> tuple[GPLaw, dict]:
    """``law`` solved on the data of its last refit (the mentor's, the takeovers and the own samples that
    refit learned from, chosen as practice chose them) with the hyperparameters of its fit at version
    ``base``. Returns the law and the fit's summary."""
    rev = [r for r in model.history.revisions() if r.operator == "refit_law" and r.target == law][-1]
    experience = Experience(model.path)
    sources = set(rev.evidence.get("sources", ()))
    own = experience.law_episodes(law, [s for s in experience.segments() if s.source in sources and law in s.laws])
    takeovers = experience.takeovers()
    taken = [takeovers[k] for k in rev.evidence.get("takeovers", ()) if k in takeovers]
    earlier = model.laws(model.history.version(base))[law]
    return fit_refit(model, law, own, taken, model.history.version(rev.version - 1), practice_seed,
                     PracticeConfig().novelty, theta=earlier.theta_)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--model", type=Path, required=True, help="a practised model directory (not changed)")
    ap.add_argument("--seed", type=int, default=0, help="the job seed whose evaluation trials to run")
    ap.add_argument("--trials", type=int, default=200)
    ap.add_argument("--push-fraction", type=float, default=0.5, help="share of the trials pushed, where the task pushes")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--kernels", action="store_true",
                    help="also each refitted law on its refit's data with its earlier fit's hyperparameters")
    ap.add_argument("--label", default=None, help="what the model is, for the record (e.g. 'pendulum job seed 2')")
    add_option(ap)
    args = ap.parse_args()

    source = SkillModel(args.model)
    task = task_for_env(source.manifest["env"])
    base, laws = refitted(source)
    label = args.label or str(args.model)
    rec = Record(__file__, f"what each refit from practice is worth ({label})", section="components",
                 variant=args.label.replace(" ", "_") if args.label else None)
    print(f"{label}: refitted since version {base}: " + ", ".join(f"{k} ({a} -> {b})" for k, (a, b) in laws.items()))
    specs = task.evaluation_specs(args.trials, args.seed, args.push_fraction)
    plans: dict[str, dict[str, str | GPLaw]] = {"final": {}, **{f"{law} put back": {law: a} for law, (a, _) in laws.items()}}
    if len(laws) > 1:
        plans["all put back"] = {law: a for law, (a, _) in laws.items()}
    what = {name: f", {name}" if fits else "" for name, fits in plans.items()}     # each variant, for the record
    if args.kernels:
        learning = [i for i, sc in enumerate(task.scenarios()) if sc.learn]
        practice_seed = args.seed + (learning[0] if learning else 0)    # as the job seeds its scenarios
        fitted = {}
        for law in laws:
            fitted[law], info = earlier_kernel(source, law, base, practice_seed)
            print(f"  {law} with its earlier kernel: {info.get('n_mentor')} mentor and {info.get('n_own')} own samples",
                  flush=True)
        for law, f in fitted.items():
            plans[f"{law} earlier kernel"] = {law: f}
            what[f"{law} earlier kernel"] = f", {law} on its refit's data with its earlier fit's kernel"
        if len(fitted) > 1:
            plans["all earlier kernels"] = fitted
            what["all earlier kernels"] = ", every refitted law on its refit's data with its earlier fit's kernel"
    results = {}
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="bench_refits_") as tmp:
        for i, (name, fits) in enumerate(plans.items()):
            path = args.model if not fits else put_back(args.model, Path(tmp) / f"v{i}", fits)
            r = evaluate(task.TASK, Variant(name, str(path)), specs, args.workers)
            pushed = r.get("pushed")
            results[name] = r
            print(f"  {name}: {r['successes']}/{r['trials']}"
                  + (f" (pushed {pushed['successes']}/{pushed['trials']})" if pushed else ""), flush=True)
    print(f"{time.perf_counter() - t0:.0f} s")

    for name, r in results.items():
        rec.rate(name.replace(" ", "_"), f"{label}: the final skill{what[name]}"
                 f" ({args.trials} evaluation trials of job seed {args.seed})", r["successes"], r["trials"])
    rec.write(args.results)


if __name__ == "__main__":
    main()
