"""Hand-made trial traces for diagnosis and repair tests (the executor's tests cover real runs)."""

import numpy as np

from multiform.petri.firing import Choice, Firing
from multiform.petri.net import APN
from multiform.runtime.trace import Trace


def make_trace(apn: APN, firings: list[tuple[int, str]], values: np.ndarray, outcome: str,
               choices: list[tuple[int, str, tuple[str, ...]]] = (), enabled=None, held=None, dt: float = 0.01) -> Trace:
    n = len(values)
    names = tuple(list(apn.variables) + list(apn.derived))
    m = apn.m0.astype(int).copy()
    marking = np.zeros((n, len(apn.places)), np.int16)
    fi = sorted(firings)
    j = 0
    for k in range(n):
        while j < len(fi) and fi[j][0] == k:
            m = m + apn.incidence[:, apn.transition_index(fi[j][1])]
            j += 1
        marking[k] = m
    return Trace(seed=0, dt=dt, obs=values.astype(np.float32), observation_names=names,
                 values=values.astype(np.float32), value_names=names,
                 commands=np.zeros((n, 1), np.float32), raw_commands=np.zeros((n, 1), np.float32),
                 command_names=("v_cmd",), marking=marking, dwell=np.zeros((n, len(apn.places)), np.float32),
                 place_ids=apn.place_ids, firings=[Firing(k, k * dt, t) for k, t in fi], outcome=outcome,
                 choices=[Choice(*c) for c in choices], enabled_ticks=dict(enabled or {}), held_ticks=dict(held or {}))
