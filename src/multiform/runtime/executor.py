"""The executor: runs a skill (net + laws + inverse model) on a Gymnasium env at the control rate.

One tick (see "Tick semantics" in docs/skill-files.md): read the state → the net observes it and fires at
most one transition → the active law(s) compute the end-effector command → the safety limits clip
it → the inverse model (if any) turns it into joint torques, clipped to the actuator limits → the
env steps. The executor reads only the env's observations (the robot's own sensors); it never
looks at simulator internals, except to keep poses for a video when asked; the env's last ``info``
goes into the trace (``Trace.final_info``) for the experimenter's physical success check only.

Works on any env that meets the env contract (:mod:`.contract`): ``observation_names``,
``command_names`` and ``dt`` (read through the wrapper chain) matching the skill's variables,
commands and control rate. A state beyond the skill's divergence threshold, or an
env that terminates on divergence, ends the trial as ``diverged`` (a failure of the skill). A
non-finite value anywhere in the tick (an observation, a law's output, a torque, or a simulator
that reset on bad values) ends it at once as a ``fault``: the value never reaches the simulator,
``Trace.fault`` says where it arose, and a fault is never evidence about the skill.
"""

from __future__ import annotations

import contextlib
import gc
import math
import operator
import time as _time
from collections.abc import Mapping, Sequence
from typing import Any, Protocol

import gymnasium as gym
import numpy as np

from ..errors import InvalidInput
from ..petri.firing import LearnedCondition, NetRunner
from ..petri.net import APN
from .contract import check_control_rate, env_contract
from .safety import Saturator
from .trace import Trace


class Law(Protocol):
    """A fitted control law (e.g. :class:`multiform.learn.gp.GPLaw`)."""

    def predict_one(self, x: np.ndarray) -> np.ndarray: ...


class InverseModel(Protocol):
    """Maps the robot's observation and an end-effector command to joint torques."""

    def torques(self, obs: np.ndarray, command: Sequence[float]) -> np.ndarray: ...


class Perturbation(Protocol):
    """The experimenter acting on the env during a trial (not the robot: it reads the net's state
    only to decide *when*, as a person pushing a balanced pendulum watches for it to balance)."""

    def __call__(self, tick: int, runner: NetRunner, env: gym.Env) -> None: ...


class Observer(Protocol):
    """Watches a trial as it runs (e.g. :class:`multiform.view.stream.TrialStream`); reads what it is
    given and changes nothing, so a trial runs the same with and without one."""

    def start(self, executor: Executor, seed: int) -> None: ...

    def fired(self, tick: int, runner: NetRunner) -> None: ...

    def tick(self, tick: int, values: list[float], command: list[float], info: Mapping[str, Any]) -> None: ...

    def end(self, trace: Trace) -> None: ...


class Executor:
    """Runs trials of one net version with its laws on one env.

    ``laws`` maps law names to fitted laws; ``learned`` maps learned-condition names to models;
    with an ``inverse_model`` the env must take joint torques, without one it must take the
    end-effector command itself (the two action modes of :mod:`.contract`).
    """

    def __init__(self, apn: APN, env: gym.Env, laws: Mapping[str, Law],
                 learned: Mapping[str, LearnedCondition] | None = None,
                 inverse_model: InverseModel | None = None, net_version: int = 0):
        self.apn, self.env, self.laws, self.inverse_model = apn, env, dict(laws), inverse_model
        self.net_version = net_version
        self.obs_names, self.cmd_names, self.dt = env_contract(env)
        check_control_rate(apn.control_rate, self.dt)
        missing = [c for c in apn.commands if c not in self.cmd_names]
        if missing:
            raise InvalidInput(f"the env has no command(s) {', '.join(missing)}", element="commands")
        used = {t.law for t in apn.transitions if t.law}
        absent = sorted(used - set(self.laws))
        if absent:
            raise InvalidInput(f"no fitted law for {', '.join(absent)}", element="laws")
        self.runner = NetRunner(apn, self.obs_names, learned)
        slots = self.runner.slots
        self._n_state = len(apn.variables)
        self._value_names = apn.value_names[:len(apn.variables) + len(apn.derived)]   # the runner's first slots
        self._cmd_index = {c: i for i, c in enumerate(self.cmd_names)}
        self._plans: dict[str, tuple[Law, Any, np.ndarray, list[int]]] = {}
        for name, law in self.laws.items():
            spec = apn.laws.get(name)
            if spec is None:
                continue
            idx = [slots[v] if v in slots else None for v in spec.inputs]
            if None in idx:
                raise InvalidInput(f"law {name} reads {spec.inputs}, not all are net variables", element=f"laws.{name}")
            getter = operator.itemgetter(*idx)
            outs = [self._cmd_index[c] for c in spec.outputs]
            self._plans[name] = (law, getter, np.empty(len(idx)), outs)
        torque_low = torque_high = None
        if inverse_model is not None:
            space = env.action_space
            torque_low, torque_high = space.low.astype(float), space.high.astype(float)
        self.saturator = Saturator(apn.safety, self.cmd_names, slots, self.dt, torque_low, torque_high)

    def run(self, seed: int, options: Mapping[str, Any] | None = None, max_duration: float | None = None,
            qpos_every: int = 0, perturb: Perturbation | None = None, observer: Observer | None = None) -> Trace:
        """One trial from the initial marking.

        ``qpos_every`` > 0 keeps simulator poses every that many ticks for a video. ``perturb`` is
        the experimenter's hand (e.g. a push when the skill has balanced for a while): called every
        tick with the tick, the net's runner and the env, before the env steps. ``observer`` is told
        of the start, each firing, each stepped tick (after the step) and the finished trace.

        The cyclic garbage collector is paused for the trial: the tick allocates small arrays that
        reference counting frees, and a collection pass in the middle of a 1 ms tick is a latency
        spike the loop has no use for.
        """
        with _gc_paused():
            trace = self._run(seed, options, max_duration, qpos_every, perturb, observer)
        if observer is not None:
            observer.end(trace)
        return trace

    # One function on purpose: its loop is the 1 kHz tick, where locals beat attribute look-ups and
    # every extra call per tick shows in the closed loop's speed (benchmarks/bench_closed_loop.py).
    def _run(self, seed: int, options: Mapping[str, Any] | None, max_duration: float | None,
             qpos_every: int, perturb: Perturbation | None, observer: Observer | None = None) -> Trace:
        env, runner, sat = self.env, self.runner, self.saturator
        runner.rng = np.random.default_rng([seed, 2])
        runner.reset()
        sat.reset()
        wall0 = _time.perf_counter()
        obs, info = env.reset(seed=seed, options=dict(options) if options else None)
        if observer is not None:
            observer.start(self, seed)
        n_ticks = int(round((max_duration or self.apn.max_duration) / self.dt)) + 1
        n_obs, n_cmd, n_val = len(self.obs_names), len(self.cmd_names), len(self._value_names)
        n_places = len(self.apn.places)
        rec_obs = np.zeros((n_ticks, n_obs), np.float32)
        # every value slot of the net, one list per tick: copying the list is 0.3 µs where writing it
        # into a float32 row costs 3.4 µs (numpy's sequence path); converted once at the end
        slot_rows: list[list[float]] = []
        rec_cmd = np.zeros((n_ticks, n_cmd), np.float32)
        rec_raw = np.zeros((n_ticks, n_cmd), np.float32)
        marks: list[tuple[int, list[int]]] = [(0, list(runner.marking))]    # (tick, marking) at each change
        dwell_slots = runner.dwell_slots
        poses: list[np.ndarray] = []
        data = getattr(env.unwrapped, "data", None)
        cmd = [0.0] * n_cmd
        plan: list[tuple[Law, Any, np.ndarray, list[int]]] = []
        n_fired = 0
        inverse = self.inverse_model
        outcome, fault = "timeout", ""
        k = 0
        dt = self.dt
        for k in range(n_ticks):
            t = k * dt
            olist = obs.tolist()
            s = sum(olist)
            if s - s:                    # NaN or ±inf somewhere (finite sums give 0.0)
                outcome, fault = "fault", _first_bad("observation", self.obs_names, olist)
                break
            if runner.tick(olist, t):
                marks.append((k, list(runner.marking)))
                if observer is not None:
                    observer.fired(k, runner)
            values = runner.values
            rec_obs[k] = obs
            slot_rows.append(values[:])
            if qpos_every and k % qpos_every == 0 and data is not None:
                poses.append(data.qpos.copy())
            if runner.outcome is not None:
                outcome = runner.outcome
                rec_cmd[k] = cmd
                rec_raw[k] = cmd
                break
            if sat.diverged(values, self._n_state):
                outcome = "diverged"
                break
            if len(runner.firings) != n_fired:
                n_fired = len(runner.firings)
                plan = [self._plans[name] for name in dict.fromkeys(runner.active_laws.values())]
            bad = False
            for law, getter, buf, outs in plan:
                buf[:] = getter(values)
                for c, i in zip(law.predict_one(buf).tolist(), outs):
                    bad |= not math.isfinite(c)
                    cmd[i] = c
            if bad:                      # a law that cannot say what to do ends the trial, never the robot
                outcome = "fault"
                fault = self._law_fault(plan, values)
                rec_raw[k] = [c if math.isfinite(c) else 0.0 for c in cmd]
                break
            rec_raw[k] = cmd
            cmd = sat.command(cmd, values, k)
            rec_cmd[k] = cmd
            if inverse is not None:
                tau = inverse.torques(obs, cmd)
                tlist = tau.tolist()
                s = sum(tlist)
                if s - s:
                    outcome, fault = "fault", _first_bad("inverse model torque", range(len(tlist)), tlist)
                    break
                action = sat.torque(tau, k)
            else:
                action = np.asarray(cmd)
            if perturb is not None:
                perturb(k, runner, env)
            obs, _, terminated, truncated, info = env.step(action)
            if observer is not None:
                observer.tick(k, values, cmd, info)
            if terminated:
                if info.get("non_finite"):
                    outcome, fault = "fault", "simulator state (non-finite; the simulator reset)"
                else:
                    outcome = "diverged" if info.get("diverged", True) else "failure"
                k += 1
                break
        n = min(k + 1, n_ticks)
        if outcome == "fault" and len(slot_rows) < n:
            n = max(len(slot_rows), 1)   # a fault before the net saw the tick's state keeps what it had
            if not slot_rows:
                slot_rows.append([0.0] * len(runner.values))
        if outcome == "timeout":
            n = n_ticks
        rec_mark = np.zeros((n, n_places), np.int16)
        for (k0, mk), (k1, _) in zip(marks, marks[1:] + [(n, None)]):
            rec_mark[k0:k1] = mk
        if len(slot_rows) < n:           # the env terminated the trial: its last row stays zero, as obs's does
            slot_rows += [[0.0] * len(runner.values)] * (n - len(slot_rows))
        rec_slots = np.array(slot_rows[:n], np.float32).reshape(n, len(runner.values))
        rec_val, rec_dwell = rec_slots[:, :n_val].copy(), rec_slots[:, dwell_slots]
        return Trace(seed=seed, dt=dt, obs=rec_obs[:n], observation_names=self.obs_names, values=rec_val,
                     value_names=self._value_names, commands=rec_cmd[:n], raw_commands=rec_raw[:n],
                     command_names=self.cmd_names, marking=rec_mark, dwell=rec_dwell,
                     place_ids=self.apn.place_ids, firings=list(runner.firings), outcome=outcome,
                     choices=list(runner.choices),
                     net_version=self.net_version, options=dict(options or {}), clips=sat.log.to_json(),
                     enabled_ticks=dict(zip(self.apn.transition_ids, runner.enabled_ticks)),
                     held_ticks=dict(zip(self.apn.transition_ids, runner.held_ticks)),
                     qpos=np.array(poses) if poses else None, qpos_every=qpos_every,
                     wall_time=_time.perf_counter() - wall0, final_info=dict(info or {}), fault=fault)

    def _law_fault(self, plan: list[tuple[Law, Any, np.ndarray, list[int]]], values: list[float]) -> str:
        """Which law gave which non-finite command (asked again: only on the fault's path)."""
        for law, getter, buf, outs in plan:
            buf[:] = getter(values)
            for c, i in zip(law.predict_one(buf).tolist(), outs):
                if not math.isfinite(c):
                    name = next(n for n, p in self._plans.items() if p[0] is law)
                    return f"law {name} output {self.cmd_names[i]} = {c}"
        return "law output"


def _first_bad(what: str, names: Sequence[Any], values: Sequence[float]) -> str:
    """``what name`` of the first non-finite value (the fault's place in a trace)."""
    for name, v in zip(names, values):
        if not math.isfinite(v):
            return f"{what} {name} = {v}".strip()
    return what


@contextlib.contextmanager
def _gc_paused():
    """Pause the cyclic garbage collector, restoring its previous state afterwards."""
    was = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if was:
            gc.enable()
