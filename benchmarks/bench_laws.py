"""The pendulum's GP laws against the mentor: held-out error, and success-only against all segments
in closed loop.

1. Each law of the skill is fitted on the mentor's successful segments of 80 % of the
   demonstrations and scored on the successful segments of the other 20 % (normalised RMSE =
   RMSE / std of the held-out commands; issue 4 asks ≤ 0.2). The mentor's own command noise puts a
   floor under it: the same state gives different commands (perception noise, reaction delay drawn
   per demo, a quantised 100 Hz stick), which the script estimates as the NRMSE of a k-nearest-
   neighbour average on the held-out data itself.
2. The swing-up law fitted on successful segments only, against the same law fitted on *all*
   segments (failed ones included), each run closed loop from hanging on ``--trials`` seeded,
   randomised pendulums (reference controller, so only the law differs): success = the pendulum
   reaches |θ| < 0.3 rad with |ω| < 2.5 rad/s within 12 s.

    .venv/bin/python benchmarks/bench_laws.py [--dataset runs/pendulum/demos.h5] [--trials 50] [--results DIR]
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("MUJOCO_GL", "egl")

import gymnasium as gym  # noqa: E402
import numpy as np  # noqa: E402
import yaml  # noqa: E402
from _results import Record, add_option, at_most  # noqa: E402

import multiform.envs  # noqa: E402,F401
from multiform.demos.dataset import read_dataset  # noqa: E402
from multiform.teach.record import record_many  # noqa: E402
from multiform.learn.training import fit_law  # noqa: E402
from multiform.learn.views import law_data  # noqa: E402
from multiform.petri.skillfile import load_skill, parse_skill, skill_to_data  # noqa: E402
from multiform.runtime.executor import Executor  # noqa: E402
from multiform.stats import rate  # noqa: E402
from multiform.task import load_task  # noqa: E402
task = load_task("pendulum")

ROOT = Path(__file__).resolve().parents[1]


def noise_floor(X: np.ndarray, y: np.ndarray, k: int = 20) -> float:
    """NRMSE of the mean command of the k nearest states (standardised inputs, other demos' samples
    excluded only by thinning): how much of the command the state cannot explain."""
    from sklearn.neighbors import KNeighborsRegressor
    Xs = (X - X.mean(0)) / X.std(0)
    idx = np.random.default_rng(0).permutation(len(X))[:20000]
    Xs, y = Xs[idx], y[idx].reshape(len(idx), -1)
    half = len(idx) // 2
    knn = KNeighborsRegressor(k).fit(Xs[:half], y[:half])
    err = np.sqrt(np.mean((knn.predict(Xs[half:]) - y[half:]) ** 2, axis=0))
    return float(np.max(err / y[half:].std(0)))


def swing_net(apn):
    d = skill_to_data(apn)
    d = {k: d[k] for k in ("skill", "variables", "derived", "commands", "laws", "safety") if k in d}
    d.update(places={"A": {}, "B": {}, "up": {"final": "success"}}, initial_marking={"A": 1},
             transitions={"go": {"in": ["A"], "out": ["B"], "law": "swing_up", "condition": "true"},
                          "reach": {"in": ["B"], "out": ["up"], "condition": "abs(theta) < 0.3 and abs(omega) < 2.5"}})
    return parse_skill(yaml.safe_dump(d))


def closed_loop(apn, law, trials: int) -> dict:
    env = gym.make(task.ENV_ID, action_mode="ee")
    ex = Executor(swing_net(apn), env, {"swing_up": law})
    ok = 0
    for k in range(trials):
        seed = 70_000 + k
        ok += ex.run(seed=seed, options=task.trial_options(seed), max_duration=12.0).outcome == "success"
    env.close()
    return rate(ok, trials)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--dataset", default=str(ROOT / "runs" / "pendulum" / "demos.h5"))
    ap.add_argument("--demos", type=int, default=40, help="demos to record if --dataset does not exist")
    ap.add_argument("--trials", type=int, default=50)
    add_option(ap)
    args = ap.parse_args()
    rec = Record(__file__, "The pendulum's GP laws against the mentor", section="components")
    if Path(args.dataset).exists():
        eps = list(read_dataset(args.dataset))
    else:
        print(f"{args.dataset} not found: recording {args.demos} mentor demos")
        eps = record_many("pendulum", list(range(args.demos)), task.DEMO_ENV_KWARGS, workers=2)
    apn = load_skill(task.SKILL_SOUND)
    print(f"{len(eps)} demos, {sum(e.outcome == 'success' for e in eps)} successful")
    for name in apn.laws:
        law, info = fit_law(apn, eps, name)
        d = law_data(apn, eps, name, success_only=True)
        floor = noise_floor(d.X, d.Y)
        print(f"law {name}: n={info['n']}, held-out NRMSE {info['heldout_nrmse']:.3f} (target <= 0.2); "
              f"the mentor's own noise floor (k-NN on the same samples) {floor:.3f}")
        rec.figure(f"nrmse_{name}", f"pendulum law {name} from {len(eps)} demos: held-out NRMSE (successful segments "
                   "of unseen demos)", info["heldout_nrmse"], "", target=at_most(0.2),
                   extra={"mentor_noise_floor": round(floor, 3), "samples": info["n"]})
    ok_law, _ = fit_law(apn, eps, "swing_up", success_only=True)
    all_law, _ = fit_law(apn, eps, "swing_up", success_only=False)
    a = closed_loop(apn, ok_law, args.trials)
    b = closed_loop(apn, all_law, args.trials)
    rec.rate("closed_loop_success_only", f"swing-up from hanging in closed loop, law fitted on successful segments "
             f"only ({len(eps)} demos)", a["successes"], a["trials"])
    rec.rate("closed_loop_all_segments", "the same, law fitted on all segments (failed ones included)",
             b["successes"], b["trials"])
    print(f"swing-up in closed loop, {args.trials} seeded trials: success-only law {a['successes']}/{a['trials']} "
          f"({100 * a['rate']:.0f} %, 95 % CI {100 * a['low']:.0f}-{100 * a['high']:.0f}); all-segments law "
          f"{b['successes']}/{b['trials']} ({100 * b['rate']:.0f} %, 95 % CI {100 * b['low']:.0f}-{100 * b['high']:.0f})")
    rec.write(args.results)


if __name__ == "__main__":
    main()
