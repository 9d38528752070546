"""Evaluating every condition of the pendulum net for one tick (target: median ≤ 5 µs on one core).

Measures the two parts of a tick the guards cost: loading the state into the value slots
(`NetRunner.observe`, which also computes the derived variables and clocks) and evaluating the
condition of every transition. Prints medians and p99 over 20,000 ticks.

    .venv/bin/python benchmarks/bench_guards.py [--results DIR]
"""

import argparse

import numpy as np

from _results import Record, add_option, at_most
from _timing import describe, latencies
from multiform.petri.firing import NetRunner
from multiform.petri.skillfile import load_skill


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_option(ap)
    args = ap.parse_args()
    rec = Record(__file__, "Guards: every condition of the pendulum net for one tick", section="speed")
    apn = load_skill("pendulum")
    runner = NetRunner(apn, ["theta", "omega", "x", "xdot"], rng=0)
    runner.tick([np.pi, 0.0, 0.0, 0.0], 0.0)        # token in P1
    state = [0.4, 1.2, 0.05, -0.2]
    guards = runner._guards
    values = runner.observe(state, 0.5)

    def all_conditions():
        return [g(values) for g in guards]

    def observe_and_all_conditions():
        v = runner.observe(state, 0.5)
        return [g(v) for g in guards]

    print(f"pendulum net: {len(guards)} conditions")
    timed = {"all conditions of the net, one tick": latencies(all_conditions, 20_000, batch=10),
             "observe state + all conditions": latencies(observe_and_all_conditions, 20_000, batch=10),
             "candidates of the marked place (what a tick runs)": latencies(runner.candidates, 20_000, batch=10)}
    for name, t in timed.items():
        print(describe(name, t))
    again = latencies(all_conditions, 20_000, batch=10)
    med = np.median(again) * 1e6
    print(f"target: all conditions ≤ 5 µs median — {'met' if med <= 5 else 'NOT met'} ({med:.2f} µs)")
    rec.latency("all_conditions", f"all {len(guards)} conditions of the pendulum net, one tick", again,
                target=at_most(5, of="median"))
    rec.latency("observe_and_conditions", "observe the state + all conditions", timed["observe state + all conditions"])
    rec.latency("candidates", "candidates of the marked place (what a tick runs)",
                timed["candidates of the marked place (what a tick runs)"])
    rec.write(args.results)


if __name__ == "__main__":
    main()
