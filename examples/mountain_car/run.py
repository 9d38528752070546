"""Teach the mountain car: scripted demonstrations, training, practice with a repair, evaluation."""

import sys
from pathlib import Path

import multiform
from mountain_car import MountainCar

out = Path(sys.argv[1] if len(sys.argv) > 1 else "mountain_car_run")
task = MountainCar()
demos = multiform.record(task, out / "demos.h5", demos=task.DEMOS)
model = multiform.train(task.SKILL, demos, out / "model", task=task)
state = multiform.practise(model, task, max_trials=15)
print(*(f"revision {r.version}: {r.operator} {r.target} — {r.reason}" for r in state.revisions), sep="\n")
result = multiform.evaluate(model, task, trials=20)
print(f"success {result['successes']}/{result['trials']} (95 % CI {result['low']:.2f}-{result['high']:.2f})")
