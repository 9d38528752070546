"""Trials beyond one process pool: a two-node Ray cluster on this machine gives the local pool's
records trial for trial, and all of them when a worker is killed mid-run; the model travels as
bytes and is verified where it lands; the local pool with the spawn start method gives the fork
pool's records."""

from __future__ import annotations

import json
import os
import secrets
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pytest

import multiform
from multiform.evaluation import Variant, evaluate
from multiform.cli import main
from multiform.demos.dataset import read_dataset, write_dataset
from multiform.teach.record import record_many
from multiform.errors import InvalidInput
from multiform.job import train_model
from multiform.model import SkillModel
from multiform.petri.skillfile import resolve_skill
from multiform.task import load_task
task = load_task("pendulum")

pytestmark = pytest.mark.slow

RAY = Path(sys.executable).with_name("ray")
SRC = str(Path(multiform.__file__).resolve().parents[1])
TRIAL_TITLE = b"ray::evaluation_trial"
TOKEN = secrets.token_hex(16)              # the test cluster's own token: no other client joins it


def same_trials(a: list[dict], b: list[dict]) -> None:
    """Trial for trial the same record (the wall-clock time aside)."""
    assert len(a) == len(b)
    for x, y in zip(a, b):
        assert {k: v for k, v in x.items() if k != "wall"} == {k: v for k, v in y.items() if k != "wall"}


@pytest.fixture(scope="module")
def lab(tmp_path_factory) -> Path:
    """A model trained from four mentor demos, on a copy of the pendulum skill whose trials end
    after 4 s (the env takes the hand command itself), so 40 trials take seconds."""
    root = tmp_path_factory.mktemp("ray")
    eps = record_many("pendulum", [0, 1, 2, 9], task.DEMO_ENV_KWARGS)
    demos = write_dataset(root / "demos.h5", eps, task.SKILL, task.ENV_ID, task.DEMO_ENV_KWARGS)
    skill = root / "pendulum_short.yaml"
    text = resolve_skill(task.SKILL).read_text()
    assert "max_duration: 30.0" in text
    skill.write_text(text.replace("max_duration: 30.0", "max_duration: 4.0"))
    model = SkillModel.create(root / "model", skill, demos, task.ENV_ID, task.DEMO_ENV_KWARGS)
    train_model(model, seed=0, log=lambda *a: None)
    return root


def _env() -> dict[str, str]:
    return {**os.environ, "PYTHONPATH": SRC + os.pathsep + os.environ.get("PYTHONPATH", ""),
            "RAY_USAGE_STATS_ENABLED": "0", "MUJOCO_GL": "egl", "RAY_AUTH_MODE": "token", "RAY_AUTH_TOKEN": TOKEN,
            "RAY_worker_niceness": "0"}


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _cluster_cpus(address: str) -> float:
    out = subprocess.run([str(RAY), "status", "--address", address], capture_output=True, text=True,
                         env=_env(), timeout=60)
    for line in out.stdout.splitlines():
        if line.strip().endswith(" CPU") and "/" in line:
            return float(line.split("/")[1].split()[0])
    return 0.0


@pytest.fixture(scope="module")
def cluster():
    """A head and a second node, one CPU each, started here as `ray start --block` processes and
    stopped by their ids (SIGTERM: each stops what it started), failure or not."""
    port = _free_port()
    address = f"127.0.0.1:{port}"
    temp = tempfile.mkdtemp(prefix="mfray")          # short: Ray's socket paths must fit 107 bytes
    common = ["--num-cpus", "1", "--object-store-memory", str(200 * 2**20), "--block",
              "--disable-usage-stats"]
    procs: list[subprocess.Popen] = []
    try:
        procs.append(subprocess.Popen(
            [str(RAY), "start", "--head", "--port", str(port), "--node-ip-address", "127.0.0.1",
             "--include-dashboard", "false", "--temp-dir", temp, *common],
            env=_env(), stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True))
        _wait(lambda: _cluster_cpus(address) >= 1, 120, "the head node")
        procs.append(subprocess.Popen(
            [str(RAY), "start", "--address", address, "--node-ip-address", "127.0.0.1", *common],
            env=_env(), stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True))
        _wait(lambda: _cluster_cpus(address) >= 2, 120, "the second node")
        yield address, temp
    finally:
        for p in reversed(procs):
            p.send_signal(signal.SIGTERM)
            try:
                p.wait(timeout=60)
            except subprocess.TimeoutExpired:
                os.killpg(p.pid, signal.SIGKILL)
                p.wait()
        shutil.rmtree(temp, ignore_errors=True)


def _wait(ok, seconds: float, what: str) -> None:
    end = time.monotonic() + seconds
    while not ok():
        if time.monotonic() > end:
            raise TimeoutError(f"{what} did not come up in {seconds} s")
        time.sleep(1.0)


def _cmdline(pid: int) -> bytes:
    try:
        return Path(f"/proc/{pid}/cmdline").read_bytes()
    except OSError:
        return b""


def _trial_workers(temp: str) -> list[int]:
    """PIDs of Ray workers running a trial, whose raylet belongs to the cluster in ``temp``."""
    out = []
    for d in Path("/proc").iterdir():
        if d.name.isdigit() and _cmdline(int(d.name)).startswith(TRIAL_TITLE):
            try:
                ppid = int((d / "stat").read_text().rsplit(")", 1)[1].split()[1])
            except (OSError, IndexError, ValueError):
                continue
            if temp.encode() in _cmdline(ppid):
                out.append(int(d.name))
    return out


def test_a_two_node_cluster_gives_the_local_pools_trials_even_when_a_worker_dies(lab, cluster, tmp_path):
    address, temp = cluster
    model = str(lab / "model")
    assert main(["evaluate", model, "--trials", "40", "--workers", "2", "--out", str(tmp_path / "local")]) == 0
    local = json.loads((tmp_path / "local" / "evaluation.json").read_text())

    driver = subprocess.Popen(
        [sys.executable, "-m", "multiform.cli", "evaluate", model, "--trials", "40", "--ray", address,
         "--out", str(tmp_path / "ray")],
        env=_env(), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=tmp_path)
    killed = None
    try:
        _wait(lambda: len(_trial_workers(temp)) >= 2 or driver.poll() is not None, 240, "two trial workers")
        time.sleep(3.0)                                   # both busy; some trials done, most to come
        assert driver.poll() is None, "the run ended before a worker could be killed"
        killed = _trial_workers(temp)[0]
        os.kill(killed, signal.SIGKILL)
        out, err = driver.communicate(timeout=600)
    finally:
        if driver.poll() is None:
            driver.kill()
            driver.wait()
    assert driver.returncode == 0, err[-2000:]
    assert not Path(f"/proc/{killed}").exists()
    remote = json.loads((tmp_path / "ray" / "evaluation.json").read_text())
    assert remote["trials"] == 40 and len(remote["trials_detail"]) == 40
    same_trials(local["trials_detail"], remote["trials_detail"])
    assert [t["seed"] for t in remote["trials_detail"]] == [50_000_000 + i for i in range(40)]
    assert len({t["trace_digest"] for t in remote["trials_detail"]}) == 40      # 40 different trials
    assert {k: remote[k] for k in ("successes", "rate", "low", "high", "agreement")} == \
           {k: local[k] for k in ("successes", "rate", "low", "high", "agreement")}


def test_demonstrations_recorded_on_the_cluster_are_the_local_ones(cluster, tmp_path):
    address, _ = cluster
    out = tmp_path / "demos.h5"
    run = subprocess.run([sys.executable, "-m", "multiform.cli", "record", "pendulum", "--demos", "2", "--seed", "7",
                          "--ray", address, "--out", str(out)], env=_env(), capture_output=True, text=True, timeout=600)
    assert run.returncode == 0, run.stderr[-2000:]
    here = record_many("pendulum", [700_000, 700_001], task.DEMO_ENV_KWARGS)
    for a, b in zip(here, read_dataset(out).episodes, strict=True):
        # the file stores observations as float32: the local recording, so rounded, to the bit
        assert np.array_equal(a.obs.astype(np.float32), b.obs) and np.array_equal(a.actions, b.actions)
        assert a.labels == b.labels and a.outcome == b.outcome and a.reset_options == b.reset_options


def test_the_model_travels_as_bytes_and_is_verified_where_it_lands(lab, tmp_path):
    from multiform import cluster
    pack = cluster.pack_model(lab / "model")
    names = set(pack["files"])
    assert {"model.json", "skill.yaml", "labels.jsonl", "regions.npz", "laws/swing_up.npz", "judges/P1.npz"} <= names
    assert not any(n.startswith(("experience/", "practice/")) for n in names)
    where = cluster.materialise(pack, tmp_path)
    assert where.name == pack["digest"] and where.parent == tmp_path / "multiform-models"
    for name, data in pack["files"].items():
        assert (where / name).read_bytes() == data
    SkillModel(where).verify()
    assert cluster.materialise(pack, tmp_path) == where             # once per node
    # damaged on the way: refused before anything is written
    bad = {**pack, "files": {**pack["files"], "laws/balance.npz": pack["files"]["laws/balance.npz"][:-1] + b"x"}}
    with pytest.raises(InvalidInput, match="damaged"):
        cluster.materialise(bad, tmp_path / "other")
    assert not (tmp_path / "other").exists()
    # changed by its sender consistently (the digest recomputed): the model's own hashes refuse it
    forged = {"files": bad["files"], "digest": cluster.pack_digest(bad["files"])}
    with pytest.raises(InvalidInput, match="SHA-256"):
        cluster.materialise(forged, tmp_path / "other")


def test_a_spawned_pool_runs_the_same_trials_and_demos_as_a_forked_one(lab):
    variant = Variant("short", str(lab / "model"))
    specs = task.evaluation_specs(4, 3, 0.5)
    fork = evaluate("pendulum", variant, specs, workers=2, start_method="fork")
    spawn = evaluate("pendulum", variant, specs, workers=2, start_method="spawn")
    same_trials(fork["trials_detail"], spawn["trials_detail"])
    here = record_many("pendulum", [5, 6], task.DEMO_ENV_KWARGS, workers=1)
    spawned = record_many("pendulum", [5, 6], task.DEMO_ENV_KWARGS, workers=2, start_method="spawn")
    for a, b in zip(here, spawned):
        assert np.array_equal(a.obs, b.obs) and np.array_equal(a.actions, b.actions)
        assert a.labels == b.labels and a.outcome == b.outcome
    with pytest.raises(InvalidInput, match="start method"):
        evaluate("pendulum", variant, specs, workers=2, start_method="thread")
