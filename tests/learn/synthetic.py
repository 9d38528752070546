"""Synthetic pendulum-like data for the learning-from-evaluation tests and benchmarks.

Not physics: closed-form trajectory shapes and a known labelling rule, so a test can check that a
judge recovers the rule, a condition holds where the positives are, a region contains its states.
The lead re-runs the same code paths on real demonstrations (``benchmarks/bench_judges.py --dataset``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from multiform.demos.episode import Episode, SegmentLabel
from multiform.learn.features import Segment

NAMES = ("theta", "omega", "x", "xdot")
DT = 0.01


def wrap(a: np.ndarray) -> np.ndarray:
    return (a + np.pi) % (2 * np.pi) - np.pi


def swing_segment(rng: np.random.Generator, end: tuple[float, float] | None = None) -> tuple[np.ndarray, bool]:
    """A swing-up-like trajectory from hanging to (theta_end, omega_end); success iff the end state
    lies in the ellipse (theta/0.35)² + (omega/2.5)² < 1 and the cart stayed within |x| < 0.3."""
    T = int(rng.integers(150, 300))
    t = np.linspace(0, 1, T)
    if end is None:
        th_end = rng.uniform(-1.2, 1.2)
        om_end = rng.uniform(-5, 5)
    else:
        th_end, om_end = end
    th0 = np.pi * rng.choice([-1, 1]) + rng.normal(0, 0.05)
    s = t * t * (3 - 2 * t)
    osc = 0.4 * np.sin(2 * np.pi * rng.uniform(2, 4) * t) * (1 - t) * t
    theta = th0 + (th_end - th0) * s + osc
    omega = np.gradient(theta, DT)
    omega[-20:] = np.linspace(omega[-20], om_end, 20)               # end at the chosen velocity
    amp = rng.uniform(0.05, 0.35)
    x = amp * np.sin(2 * np.pi * rng.uniform(1, 2) * t + rng.uniform(0, 2 * np.pi))
    xdot = np.gradient(x, DT)
    success = (th_end / 0.35) ** 2 + (om_end / 2.5) ** 2 < 1 and np.abs(x).max() < 0.3
    return np.stack([wrap(theta), omega, x, xdot], axis=1), bool(success)


def balance_segment(rng: np.random.Generator, amp_range: tuple[float, float] = (0.02, 0.45),
                    x_range: tuple[float, float] = (0.0, 0.35)) -> tuple[np.ndarray, bool]:
    """A balancing-like trajectory near upright; success iff |theta| stayed below 0.25 and the cart
    ended within |x| < 0.2. ``x_range`` bounds |x| at the end."""
    T = int(rng.integers(200, 500))
    t = np.arange(T) * DT
    amp = rng.uniform(*amp_range)
    theta = amp * np.exp(-t * rng.uniform(0, 1.0)) * np.sin(2 * np.pi * rng.uniform(0.5, 1.5) * t + rng.uniform(0, 6))
    omega = np.gradient(theta, DT)
    x_end = rng.uniform(*x_range) * rng.choice([-1, 1])
    x = x_end * t / t[-1] + 0.02 * np.sin(3 * t)
    xdot = np.gradient(x, DT)
    success = np.abs(theta).max() < 0.25 and abs(x[-1]) < 0.2
    return np.stack([theta, omega, x, xdot], axis=1), bool(success)


def segments(place: str, n: int, seed: int, **kw) -> tuple[list[Segment], np.ndarray]:
    """``n`` labelled segments of ``place`` ("P1" swing-up, "P2" balance); ``kw`` go to the maker."""
    rng = np.random.default_rng(seed)
    make = swing_segment if place == "P1" else balance_segment
    segs, y = [], []
    for i in range(n):
        v, ok = make(rng, **kw)
        segs.append(Segment(v, NAMES, DT, source=f"syn_{place}_{seed}_{i}", start=0, end=len(v),
                            transition="t0" if place == "P1" else "t1"))
        y.append(ok)
    return segs, np.array(y)


def balanced_segments(place: str, n: int, seed: int) -> tuple[list[Segment], np.ndarray]:
    """Like :func:`segments`, but about half successes (rejection by label)."""
    segs, y = segments(place, 6 * n, seed)
    pos, neg = np.flatnonzero(y)[: n // 2], np.flatnonzero(~y)[: n - n // 2]
    idx = np.sort(np.concatenate([pos, neg]))
    return [segs[i] for i in idx], y[idx]


def episode(seed: int) -> Episode:
    """An episode: one swing-up segment (t0, token in P1) then a balance segment (t1, token in P2),
    labelled by the rules above."""
    rng = np.random.default_rng(seed)
    sw, ok1 = swing_segment(rng)
    ba, ok2 = balance_segment(rng)
    ba[:, 0] += sw[-1, 0]
    obs = np.concatenate([sw, ba])
    tags = np.array(["t0"] * len(sw) + ["t1"] * len(ba))
    labels = [SegmentLabel(0, len(sw), "t0", ok1), SegmentLabel(len(sw), len(obs), "t1", ok2)]
    return Episode(obs=obs, actions=np.zeros((len(obs), 1)), transitions=tags, observation_names=NAMES,
                   command_names=("v_cmd",), dt=DT, seed=seed, labels=labels,
                   outcome="success" if ok1 and ok2 else "failure")


@dataclass
class Switches:
    positives: np.ndarray       # (n, 2) theta, omega within a short window after a switch
    negatives: np.ndarray       # (m, 2) swing states far from any switch
    near: np.ndarray            # held-out switch states with |theta| < 0.15


def switch_data(seed: int, n_switch: int = 40, n_neg: int = 6000) -> Switches:
    """(theta, omega) states: the mentor switched near upright with small velocity; during the
    swing (negatives) the pendulum is elsewhere — on orbits of lower energy or passing fast."""
    rng = np.random.default_rng(seed)
    th0 = rng.normal(0, 0.07, n_switch)
    om0 = rng.normal(0, 0.7, n_switch)
    window = []
    for a, b in zip(th0, om0):                       # 20 ms after each switch, 1 ms steps
        k = np.arange(21) * 1e-3
        window.append(np.stack([a + b * k, b + 9.0 * np.sin(a) * k], axis=1))
    pos = np.concatenate(window)
    E = rng.uniform(0.1, 2.6, n_neg)                 # energy levels (upright needs 2)
    th = rng.uniform(-np.pi, np.pi, n_neg)
    pot = 1 - np.cos(np.pi - np.abs(th))             # 0 hanging, 2 upright
    ok = E > pot
    th, E, pot = th[ok], E[ok], pot[ok]
    om = np.sqrt(2 * 9.0 * (E - pot)) * rng.choice([-1, 1], len(th))
    far = (np.abs(th) > 0.45) | (np.abs(om) > 3.0)
    neg = np.stack([th[far], om[far]], axis=1)
    near = np.stack([rng.uniform(-0.15, 0.15, 400), rng.normal(0, 0.7, 400)], axis=1)
    return Switches(pos, neg, near)


def place_states(seed: int, n: int = 3000) -> dict[str, np.ndarray]:
    """(theta, omega) while the token was in P1 (swinging up: orbits of growing energy) and in P2
    (balancing: near upright, small velocity)."""
    rng = np.random.default_rng(seed)
    E = rng.uniform(0.2, 2.05, n)
    th = rng.uniform(-np.pi, np.pi, n)
    pot = 1 - np.cos(np.pi - np.abs(th))
    ok = E > pot
    om = np.sqrt(2 * 9.0 * (E[ok] - pot[ok])) * rng.choice([-1, 1], ok.sum())
    p1 = np.stack([th[ok], om], axis=1)
    p2 = np.stack([rng.normal(0, 0.06, n), rng.normal(0, 0.4, n)], axis=1)
    return {"P1": p1, "P2": p2}
