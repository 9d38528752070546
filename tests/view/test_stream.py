"""A trial streamed to rerun while it runs: the recording, read back with rerun's own reader, holds
the trace's series, firings and marking; the trial itself is the same with and without the view."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
import yaml

pytest.importorskip("rerun")

import multiform.envs  # noqa: F401,E402
from multiform.runtime.perturb import PushInPlace  # noqa: E402
from multiform.petri.skillfile import parse_skill  # noqa: E402
from multiform.runtime.executor import Executor  # noqa: E402
from multiform.view.stream import TrialStream, read_recording  # noqa: E402

from ..runtime.test_executor import NET, Const, Spring  # noqa: E402


@pytest.fixture
def env():
    e = gym.make("multiform/ArmPendulum-v0", action_mode="ee")
    yield e
    e.close()


def _by_tick(ent: dict[str, list], component: str) -> dict[int, object]:
    return {int(k): v for k, v in zip(ent["tick"], ent[component]) if k is not None and v is not None}


def test_a_streamed_trial_reads_back_equal_to_its_trace(env, tmp_path):
    apn = parse_skill(yaml.safe_dump(NET))
    ex = Executor(apn, env, {"go": Const(0.8), "back": Spring()})
    plain = ex.run(seed=3, perturb=PushInPlace("P1", 0.1, 0.3, 0.05))
    view = TrialStream(apn, tmp_path / "trial.rrd", title="a short trial", flush_every=37)
    trace = ex.run(seed=3, perturb=PushInPlace("P1", 0.1, 0.3, 0.05), observer=view)
    view.close()
    # the view changes nothing about the trial
    for name in ("obs", "values", "commands", "raw_commands", "marking"):
        assert np.array_equal(getattr(plain, name), getattr(trace, name)), name
    assert plain.fired() == trace.fired() and trace.outcome == "success"

    rec = read_recording(tmp_path / "trial.rrd")
    ticks = np.arange(trace.num_ticks)
    for j, name in enumerate(trace.value_names):
        got = _by_tick(rec[f"/state/{name}"], "Scalars:scalars")
        assert sorted(got) == ticks.tolist(), name
        assert np.array_equal(np.array([got[k][0] for k in ticks], np.float32), trace.values[:, j]), name
    for j, name in enumerate(trace.command_names):
        got = _by_tick(rec[f"/command/{name}"], "Scalars:scalars")
        assert np.array_equal(np.array([got[k][0] for k in ticks], np.float32), trace.commands[:, j]), name
    fired = rec["/net/fired"]
    rows = [(int(k), t[0]) for k, t in zip(fired["tick"], fired["TextLog:text"]) if t is not None]
    assert [t for _, t in rows] == trace.fired()
    assert [k for k, _ in rows] == [f.tick for f in trace.firings]
    for i, place in enumerate(trace.place_ids):       # the marking at the start and after every firing
        got = _by_tick(rec[f"/net/marking/{place}"], "Scalars:scalars")
        assert sorted(got) == sorted({0} | {f.tick for f in trace.firings})
        assert all(got[k][0] == trace.marking[k, i] for k in got), place
    events = [t[0] for t in rec["/events"]["TextLog:text"] if t is not None]   # rows of other components: None
    assert any(e.startswith("push:") for e in events) and "push ends" in events
    assert any(e.startswith("safety clip: command v_cmd bounds") for e in events)
    assert events[-1] == "outcome: success"
    bodies = [e for e in rec if e.startswith("/scene/") and "Transform3D:translation" in rec[e] and "tick" in rec[e]]
    assert bodies, "no body poses in the scene"
    nodes = [n for n in rec["/net/graph"]["GraphNodes:node_ids"] if n is not None]
    assert nodes[-1][: len(trace.place_ids)] == list(trace.place_ids)
