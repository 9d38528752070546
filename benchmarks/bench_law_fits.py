"""How one law's fit changes the closed loop: refit a law of a trained model with other GP settings on
the same demonstrations, and run each fit on the same evaluation trials.

For each ``--inducing`` count, each ``--subset-noise`` setting (1: the posterior's noise scaled to
the density of the hyperparameter subset, :meth:`~multiform.learn.gp.GPLaw.posterior_noise`), each
``--hyper-subsets`` count (the hyperparameters the median over that many subsets), each ``--mean``
and each fitting seed of ``--fit-seeds`` (the hyperparameter subset, the k-means draw),
the law is refitted from the mentor's successful segments (the model's original net, as the job
fits it), on all samples or the job's random subset (``--max-train 20000``), in a copy of the model
directory; then the task's evaluation trials run (``--pushed-only`` keeps the pushed ones). Prints
per fit: held-out NRMSE, the law's command at probe states (the pendulum spinning over the top), and
the failed trials; ``--json`` also writes them with the failed trials' seeds. For the pendulum's
swing-up it first prints how many of the law's samples lie at each energy above the top. Why:
held-out error and closed-loop success need not agree, and one fit says little.

    .venv/bin/python benchmarks/bench_law_fits.py RUN/model --law swing_up --inducing 300 1000 2000 \\
        --trials 60 --pushed-only [--subset-noise 0 1] [--hyper-subsets 1 7] [--mean skill linear] \\
        [--fit-seeds 0 1 2] [--seed 0] [--max-train 20000] [--out /tmp/law_fits] [--json fits.json] [--results DIR]
"""

from __future__ import annotations

import argparse
import itertools
import json
import os
import shutil
import tempfile
from pathlib import Path

os.environ.setdefault("MUJOCO_GL", "egl")
for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import numpy as np  # noqa: E402
from _results import Record, add_option  # noqa: E402

from multiform.evaluation import Evaluator, Variant  # noqa: E402
from multiform.learn.training import LawSettings, fit_law  # noqa: E402
from multiform.model import SkillModel  # noqa: E402
from multiform.task import load_task  # noqa: E402

PROBES = {"swing_up": [("upright, spinning", 0.0, 4.3), ("past upright, spinning", 0.5, 4.0),
                       ("horizontal, fast", 1.5, 6.0), ("turning point", 1.0, 0.0)]}


def refit(model_dir: Path, copy: Path, law: str, settings: LawSettings, seed: int) -> dict:
    """A copy of ``model_dir`` whose ``law`` is refitted with ``settings``; the fit's summary."""
    shutil.copytree(model_dir, copy)
    model = SkillModel(copy)
    fitted, info = fit_law(model.history.version(0), model.episodes, law, seed=seed, settings=settings)
    model.save_law(model.apn.laws[law].fit_name, fitted)
    return info


def probe(model: SkillModel, law: str) -> list[tuple[str, float]]:
    """The law's command at the pendulum's probe states (θ, ω; hand centred)."""
    gp = model.laws()[law]
    out = []
    for name, th, om in PROBES.get(law, []):
        x = np.array([[np.sin(th), np.cos(th), om, 0.0]])
        out.append((name, float(gp.predict(x).ravel()[0])))
    return out


def energy_coverage(model: SkillModel, law: str) -> str:
    """For the pendulum's swing-up: the law's samples (mentor's successful segments and their mirror
    images) by energy above the top, ``E / g = (λω²/2 + g(cos θ − 1)) / g`` with the mentor's ``λ``."""
    from multiform.tasks.pendulum_mentor import G, NOMINAL, equivalent_length
    from multiform.learn.views import law_data, mirror_episode

    apn, eps = model.history.version(0), model.episodes
    X = np.concatenate([law_data(apn, e, law, success_only=True).X
                        for e in (eps, [mirror_episode(apn, ep) for ep in eps])])
    names = list(apn.laws[law].inputs)
    c, om = X[:, names.index("c")], X[:, names.index("omega")]
    e = (0.5 * equivalent_length(NOMINAL["length"]) * om ** 2 + G * (c - 1.0)) / G
    edges = [-np.inf, 0.0, 0.2, 0.5, np.inf]
    counts = [int(np.sum((e >= lo) & (e < hi))) for lo, hi in zip(edges[:-1], edges[1:])]
    return (f"{len(X)} samples; energy above the top E/g < 0: {counts[0]}, 0-0.2: {counts[1]}, "
            f"0.2-0.5: {counts[2]}, > 0.5: {counts[3]}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("model")
    ap.add_argument("--task", default="pendulum")
    ap.add_argument("--law", default="swing_up")
    ap.add_argument("--inducing", type=int, nargs="+", default=[300, 1000, 2000])
    ap.add_argument("--subset-noise", type=int, nargs="+", default=[0], choices=[0, 1],
                    help="1: the posterior's noise scaled to the hyperparameter subset's density "
                         "(LawSettings.subset_noise)")
    ap.add_argument("--hyper-subsets", type=int, nargs="+", default=[1],
                    help="hyperparameters: the median over this many subsets (LawSettings.hyper_subsets)")
    ap.add_argument("--mean", nargs="+", default=["skill"], choices=["skill", "constant", "linear"],
                    help="the GP's mean function (LawSettings.mean; skill: the skill file's choice)")
    ap.add_argument("--fit-seeds", type=int, nargs="+", default=[0],
                    help="fitting seeds (hyperparameter subset, k-means)")
    ap.add_argument("--max-train", type=int, default=10**7,
                    help="samples the posterior is fitted on (default: all; the job: 20000)")
    ap.add_argument("--trials", type=int, default=60)
    ap.add_argument("--pushed-only", action="store_true")
    ap.add_argument("--seed", type=int, default=0, help="evaluation seed (the job seed)")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--out", default=None, help="keep the refitted model copies here")
    ap.add_argument("--json", default=None, help="write every fit's figures here")
    add_option(ap)
    a = ap.parse_args()
    rec = Record(__file__, "How one law's fit shows in closed loop", section="components", variant=f"{a.task}_{a.law}")
    task = load_task(a.task)
    specs = task.evaluation_specs(400, a.seed, 0.5)
    specs = [s for s in specs if s.push or not a.pushed_only][: a.trials]
    root = Path(a.out) if a.out else Path(tempfile.mkdtemp(prefix="law-fits-"))
    root.mkdir(parents=True, exist_ok=True)
    print(f"{a.law}: {len(specs)} {'pushed ' if a.pushed_only else ''}evaluation trials of seed {a.seed}")
    if a.task == "pendulum" and a.law == "swing_up":
        print("  " + energy_coverage(SkillModel(Path(a.model)), a.law), flush=True)
    rows = []
    with Evaluator(a.task, a.workers) as ev:
        grid = itertools.product(a.inducing, a.subset_noise, a.hyper_subsets, a.mean, a.fit_seeds)
        for m, sn, hs, mean, fs in grid:
            name = (f"inducing_{m}" + ("_subset_noise" if sn else "") + (f"_hyper_{hs}" if hs != 1 else "")
                    + (f"_{mean}_mean" if mean != "skill" else "") + (f"_seed_{fs}" if fs else ""))
            copy = root / name
            if copy.exists():
                shutil.rmtree(copy)
            settings = LawSettings(n_inducing=m, subset_noise=bool(sn), hyper_subsets=hs,
                                   mean=None if mean == "skill" else mean, max_train=a.max_train)
            info = refit(Path(a.model), copy, a.law, settings, seed=fs)
            variant = Variant(f"{a.law}: {name}", str(copy))
            r = ev.collect(variant, ev.submit(variant, specs))
            probes = probe(SkillModel(copy), a.law)
            failed = [t["seed"] for t in r["trials_detail"] if not t["success"]]
            text = ", ".join(f"{n} {v:+.2f}" for n, v in probes)
            print(f"  {m:5d} inducing points, {'subset' if sn else 'fitted'} noise, hyperparameters of {hs} subset(s), "
                  f"{mean} mean, fitting seed {fs}, "
                  f"{info['n_fit']} samples: held-out NRMSE {info['heldout_nrmse']:.2f}; "
                  f"failed {len(failed)}/{r['trials']}"
                  + (f"; command at {text}" if text else ""), flush=True)
            rows.append({"inducing": m, "subset_noise": bool(sn), "hyper_subsets": hs, "mean": mean, "fit_seed": fs,
                         "n_fit": info["n_fit"], "heldout_nrmse": info["heldout_nrmse"], "trials": r["trials"],
                         "failed": len(failed), "failed_seeds": failed, "probes": dict(probes)})
            rec.rate(name, f"{a.task} law {a.law} refitted: {m} inducing points, {'subset' if sn else 'fitted'} noise, "
                     f"hyperparameters of {hs} subset(s), {mean} mean, fitting seed {fs}: success on "
                     f"{'pushed ' if a.pushed_only else ''}evaluation trials of job seed {a.seed}",
                     r["trials"] - len(failed), r["trials"],
                     extra={"heldout_nrmse": round(info["heldout_nrmse"], 3), "samples": info["n_fit"]})
    if a.json:
        Path(a.json).write_text(json.dumps({"model": a.model, "law": a.law, "seed": a.seed, "fits": rows}, indent=1))
    rec.details["fits"] = rows
    rec.write(a.results)
    if not a.out:
        shutil.rmtree(root)


if __name__ == "__main__":
    main()
