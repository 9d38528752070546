"""Evaluating every condition of the pendulum net for one tick (target: median ≤ 5 µs on one core).

Measures the two parts of a tick the guards cost: loading the state into the value slots
(`NetRunner.observe`, which also computes the derived variables and clocks) and evaluating the
condition of every transition. Prints medians and p99 over 20,000 ticks.
"""

import numpy as np

from _timing import describe, latencies
from multiform.petri.firing import NetRunner
from multiform.petri.skillfile import load_skill

apn = load_skill("pendulum")
names = ["theta", "omega", "x", "xdot"]
runner = NetRunner(apn, names, rng=0)
runner.tick([np.pi, 0.0, 0.0, 0.0], 0.0)        # token in P1
state = [0.4, 1.2, 0.05, -0.2]
guards = runner._guards
values = runner.observe(state, 0.5)


def all_conditions():
    return [g(values) for g in guards]


def observe_and_all_conditions():
    v = runner.observe(state, 0.5)
    return [g(v) for g in guards]


def tick():
    return runner.candidates()


print(f"pendulum net: {len(guards)} conditions")
print(describe("all conditions of the net, one tick", latencies(all_conditions, 20_000, batch=10)))
print(describe("observe state + all conditions", latencies(observe_and_all_conditions, 20_000, batch=10)))
print(describe("candidates of the marked place (what a tick runs)", latencies(tick, 20_000, batch=10)))
med = np.median(latencies(all_conditions, 20_000, batch=10)) * 1e6
print(f"target: all conditions ≤ 5 µs median — {'met' if med <= 5 else 'NOT met'} ({med:.2f} µs)")
