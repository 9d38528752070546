"""The nunchaku task module: its interface to the main job, the experimenter's physical check, the
learned flip closed loop on the robot's own estimates, and (slow) a small end-to-end job."""

from __future__ import annotations

import json

import gymnasium as gym
import numpy as np
import pytest

import multiform.envs  # noqa: F401
from multiform.teach.record import record_episode
from multiform.envs.nunchaku import COMMAND_NAMES, OBSERVATION_NAMES
from multiform.learn.training import LawSettings, fit_law
from multiform.petri.firing import Firing
from multiform.petri.skillfile import load_skill
from multiform.runtime.executor import Executor
from multiform.runtime.trace import Trace
from multiform.task import load_task
from multiform.tasks import nunchaku

task = load_task("nunchaku")


def test_task_interface():
    assert isinstance(task, nunchaku.Nunchaku) and load_task("nunchaku") is task
    apn = load_skill(task.SKILL)
    assert apn.env == task.ENV_ID
    for name, _ in task.PLOT_VARIABLES:
        assert name in OBSERVATION_NAMES or name in apn.derived
    assert task.train_inverse_model is None and task.robot_env_kwargs(False) == {}
    specs = task.evaluation_specs(120, 0, 0.5)
    assert len(specs) == 120 and len({s.seed for s in specs}) == 120
    assert all(s.push is None and s.options == {"randomize": True} for s in specs)
    assert not {s.seed for s in specs} & {s.seed for s in task.evaluation_specs(120, 1, 0.5)}
    for sc in task.scenarios():
        assert sc.perturb is None and sc.options(3) == {"randomize": True}
    repair, learn = task.scenarios()
    assert not repair.learn and learn.learn and learn.mentor is not None and learn.takeover is None


def _trace(grip, touch, held: str, outcome: str = "success", dt: float = 0.001) -> Trace:
    n = len(grip)
    obs = np.zeros((n, len(OBSERVATION_NAMES)), np.float32)
    obs[:, OBSERVATION_NAMES.index("grip")] = grip
    obs[:, OBSERVATION_NAMES.index("touch")] = touch
    z = np.zeros((n, 0), np.float32)
    cmd = np.zeros((n, len(COMMAND_NAMES)), np.float32)
    return Trace(seed=0, dt=dt, obs=obs, observation_names=OBSERVATION_NAMES, values=z, value_names=(),
                 commands=cmd, raw_commands=cmd, command_names=COMMAND_NAMES, marking=np.zeros((n, 1), np.int16),
                 dwell=np.zeros((n, 1), np.float32), place_ids=("P0",), firings=[Firing(0, 0.0, "t0")],
                 outcome=outcome, final_info={"scene": {"held": held}})


def _flip(hold_ticks: int = 600, touch_at: int | None = 1150):
    """Held 1 s, released 0.3 s (touch on the back at ``touch_at``), then held ``hold_ticks``."""
    grip = np.r_[np.ones(1000), np.zeros(300), np.ones(hold_ticks)]
    touch = np.zeros(len(grip))
    if touch_at is not None:
        touch[touch_at:touch_at + 30] = 5.0
    return grip, touch


def test_physical_success_needs_the_whole_flip():
    assert task.physical_success(_trace(*_flip(), held="b"))
    ev = nunchaku.flip_events(_trace(*_flip(), held="b"))
    assert ev["release"] == pytest.approx(1.0) and ev["touch"] == pytest.approx(1.15)
    assert ev["catch"] == pytest.approx(1.3) and ev["held_for"] == pytest.approx(0.6)
    assert not task.physical_success(_trace(*_flip(), held="a"))             # caught the rod it let go
    assert not task.physical_success(_trace(*_flip(touch_at=None), held="b"))  # chain never on the back
    assert not task.physical_success(_trace(*_flip(hold_ticks=300), held="b"))  # not held long enough
    assert not task.physical_success(_trace(*_flip(), held="b", outcome="diverged"))
    grip, touch = _flip()
    assert not task.physical_success(_trace(np.ones_like(grip), touch, held="a"))  # never let go
    assert not task.physical_success(_trace(np.r_[grip, np.zeros(10)], np.r_[touch, np.zeros(10)], held=""))


@pytest.fixture(scope="module")
def learned():
    """Laws fitted by the library on 20 mentor demonstrations (small GP settings for speed)."""
    env = gym.make(task.ENV_ID)
    mentor = task.make_mentor()
    eps = [record_episode(env, mentor, seed=s, options=task.demo_options(s)) for s in range(20)]
    env.close()
    apn = load_skill(task.SKILL)
    settings = LawSettings(n_hyper=500, n_restarts=0, sparse_threshold=3000, max_train=3000)
    laws = {name: fit_law(apn, eps, name, heldout=0, settings=settings)[0] for name in apn.laws}
    return apn, laws, eps


class _Blind(gym.Wrapper):
    """Hides everything but the observation: what the robot may read."""

    def reset(self, **kw):
        obs, _ = self.env.reset(**kw)
        return obs, {}

    def step(self, action):
        obs, r, term, trunc, info = self.env.step(action)
        return obs, r, term, trunc, {"diverged": info["diverged"], "dropped": info["dropped"]}


def test_learned_flip_closed_loop_on_estimates(learned):
    """The learned laws flip the nunchaku under the bundled net; the robot's commands are the same
    whether or not the env also reports ground truth, so nothing but the estimates is read."""
    apn, laws, eps = learned
    assert sum(e.outcome == "success" for e in eps) >= 10
    seeing = Executor(apn, gym.make(task.ENV_ID), laws)
    blind = Executor(apn, _Blind(gym.make(task.ENV_ID)), laws)
    flips = 0
    for seed in range(70_000_000, 70_000_004):
        tr = seeing.run(seed=seed, options=task.trial_options(seed))
        flips += task.physical_success(tr)
        tb = blind.run(seed=seed, options=task.trial_options(seed))
        assert tb.fired() == tr.fired() and np.array_equal(tb.commands, tr.commands)
    assert flips >= 3


@pytest.mark.slow
def test_small_nunchaku_job_end_to_end(tmp_path):
    from multiform.job import Job, JobConfig
    out = tmp_path / "run"
    cfg = JobConfig(demos=20, eval_trials=12, ablation_trials=6, practice_max_trials=6, practice_budget=12, workers=2)
    m = Job("nunchaku", out, cfg, log=lambda s: None, progress=False).run()
    disk = json.loads((out / "metrics.json").read_text())
    assert disk["task"] == "nunchaku" and disk["success_rate"]["trials"] == 12
    sr = disk["success_rate"]
    assert 0.0 <= sr["low"] <= sr["rate"] <= sr["high"] <= 1.0
    assert sr["rate"] >= 0.5                                   # learned from 20 demos, not the target run
    assert 0.0 < disk["demos"]["mentor_success_rate"]["rate"] <= 1.0
    names = [r["name"] for r in disk["ablation"]]
    assert any(n.startswith("demonstration only") for n in names)
    assert set(disk["training"]["laws"]) == set(load_skill(task.SKILL).laws)
    html = (out / "report.html").read_text()
    assert "nunchaku" in html and len(html) > 2000
    video = out / m["artifacts"]["videos"]["success_trial"]["file"]
    assert video.exists() and video.stat().st_size > 10_000
    assert (out / "demos.h5").exists() and list((out / "nets").glob("net_v0.svg"))
    # the report in the nunchaku's own words (its figure, no revision, no push)
    from multiform.report.browser import chromium, render
    if chromium() is not None:
        page = render(out / "report.html")
        assert page["images_ok"] == page["images"] >= 3 and page["console_errors"] == []
        text = page["text"]
        assert "Fig. 11" in text and "Fig. 7" not in text
        if not disk["revisions"]:
            assert "practice revised nothing" in text and "before and after each revision" not in text
        assert "no evaluation trial of this task was pushed" in text and "the robot's own verdict" in text
        assert "Fired in order: " + " ".join(m["artifacts"]["plots"]["success_trial"]["fired"]) in text
