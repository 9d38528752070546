"""The main job's first stage reuses a demonstration file only if it is the one it would record."""

from __future__ import annotations

from multiform.demos.dataset import read_dataset
from multiform.job import Job, JobConfig
from multiform.tasks.pendulum import Pendulum


def test_demos_are_reused_only_when_seeds_and_start_options_match(tmp_path, monkeypatch):
    lines: list[str] = []
    job = Job("pendulum", tmp_path, JobConfig(demos=2, workers=1), log=lines.append, progress=False)
    tmp_path.mkdir(exist_ok=True)
    path = job.record()
    first = [(e.seed, e.reset_options) for e in read_dataset(path)]
    stamp = path.stat().st_mtime_ns
    assert job.record() == path and path.stat().st_mtime_ns == stamp
    assert any("reusing" in s for s in lines)

    lines.clear()                       # the task now starts its demos elsewhere: the old file is stale
    monkeypatch.setattr(Pendulum, "demo_options", lambda self, seed: {"randomize": True, "x0": 0.1})
    job.record()
    assert not any("reusing" in s for s in lines)
    now = [(e.seed, e.reset_options) for e in read_dataset(path)]
    assert [s for s, _ in now] == [s for s, _ in first] and all(o["x0"] == 0.1 for _, o in now)
