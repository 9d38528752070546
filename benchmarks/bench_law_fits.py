"""How one law's fit changes the closed loop: refit a law of a trained model with other GP settings on
the same demonstrations, and run each fit on the same evaluation trials.

For each ``--inducing`` count the law is refitted from the mentor's successful segments (the model's
original net, as the job fits it) with that many inducing points of the sparse posterior, on all
samples or the default random subset (``--max-train``), in a copy of the model directory; then the
task's evaluation trials run (``--pushed-only`` keeps the pushed ones). Prints per fit: held-out
NRMSE, the law's command at probe states (``--probe``: the pendulum spinning over the top), and the
failed trials. Why: held-out error and closed-loop success need not agree.

    .venv/bin/python benchmarks/bench_law_fits.py RUN/model --law swing_up --inducing 300 1000 2000 \\
        --trials 60 --pushed-only [--seed 0] [--out /tmp/law_fits]
"""

from __future__ import annotations

import argparse
import os
import shutil
import tempfile
from pathlib import Path

os.environ.setdefault("MUJOCO_GL", "egl")
for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import numpy as np  # noqa: E402

from multiform.adapt.evaluation import Evaluator, Variant  # noqa: E402
from multiform.learn.training import LawSettings, fit_law  # noqa: E402
from multiform.model import SkillModel  # noqa: E402
from multiform.task import load_task  # noqa: E402

PROBES = {"swing_up": [("upright, spinning", 0.0, 4.3), ("past upright, spinning", 0.5, 4.0),
                       ("horizontal, fast", 1.5, 6.0), ("turning point", 1.0, 0.0)]}


def refit(model_dir: Path, copy: Path, law: str, inducing: int, max_train: int, seed: int) -> dict:
    """A copy of ``model_dir`` whose ``law`` is refitted with ``inducing`` points; the fit's summary."""
    shutil.copytree(model_dir, copy)
    model = SkillModel(copy)
    fitted, info = fit_law(model.history.version(0), model.episodes, law, seed=seed,
                           settings=LawSettings(n_inducing=inducing, max_train=max_train))
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


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("model")
    ap.add_argument("--task", default="pendulum")
    ap.add_argument("--law", default="swing_up")
    ap.add_argument("--inducing", type=int, nargs="+", default=[300, 1000, 2000])
    ap.add_argument("--max-train", type=int, default=10**7, help="samples the posterior is fitted on (default: all)")
    ap.add_argument("--trials", type=int, default=60)
    ap.add_argument("--pushed-only", action="store_true")
    ap.add_argument("--seed", type=int, default=0, help="evaluation seed (the job seed)")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--out", default=None, help="keep the refitted model copies here")
    a = ap.parse_args()
    task = load_task(a.task)
    specs = task.evaluation_specs(400, a.seed, 0.5)
    specs = [s for s in specs if s.push or not a.pushed_only][: a.trials]
    root = Path(a.out) if a.out else Path(tempfile.mkdtemp(prefix="law-fits-"))
    root.mkdir(parents=True, exist_ok=True)
    print(f"{a.law}: {len(specs)} {'pushed ' if a.pushed_only else ''}evaluation trials of seed {a.seed}")
    with Evaluator(a.task, a.workers) as ev:
        for m in a.inducing:
            copy = root / f"inducing_{m}"
            if copy.exists():
                shutil.rmtree(copy)
            info = refit(Path(a.model), copy, a.law, m, a.max_train, seed=0)
            variant = Variant(f"{a.law} with {m} inducing points", str(copy))
            r = ev.collect(variant, ev.submit(variant, specs))
            probes = ", ".join(f"{n} {v:+.2f}" for n, v in probe(SkillModel(copy), a.law))
            print(f"  {m:5d} inducing points, {info['n_fit']} samples: held-out NRMSE {info['heldout_nrmse']:.2f}; "
                  f"failed {r['trials'] - r['successes']}/{r['trials']}" + (f"; command at {probes}" if probes else ""),
                  flush=True)
    if not a.out:
        shutil.rmtree(root)


if __name__ == "__main__":
    main()
