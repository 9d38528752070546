"""Teach the mountain car: demonstrations, training, practice (repair, then learning), evaluation."""
import sys
from pathlib import Path

import multiform
from mountain_car import MountainCar

out = Path(sys.argv[1] if len(sys.argv) > 1 else "mountain_car_run")
task = MountainCar()
demos = multiform.record(task, out / "demos.h5", demos=task.DEMOS)
model = multiform.train(task.SKILL, demos, out / "model", task=task)
for scenario in multiform.scenario_names(task):      # "practice" repairs the net, "keep" also learns
    state = multiform.practise(model, task, scenario=scenario, max_trials=40)
    print(f"{scenario}: {len(state.trials)} trials ({sum(t.explored for t in state.trials)} exploring), "
          f"{sum(t.own_segments for t in state.trials)} segments of its own kept for its laws; {state.stop_reason}")
    for r in state.revisions:
        print(f"revision {r.version}: {r.operator} {r.target} — {r.reason}")
result = multiform.evaluate(model, task, trials=20)
print(f"success {result['successes']}/{result['trials']} (95 % CI {result['low']:.2f}-{result['high']:.2f})")
