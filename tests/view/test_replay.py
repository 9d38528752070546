"""`multiform replay`: a recorded demonstration replays on its env to the recorded states, into a
rerun recording and an MP4 whose frames carry the overlay."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("rerun")

from multiform.cli import main  # noqa: E402
from multiform.demos.dataset import read_dataset, write_dataset  # noqa: E402
from multiform.tasks.pendulum_mentor import PendulumMentor  # noqa: E402
from multiform.teach.record import PushDuring, record_episode  # noqa: E402
from multiform.report.video import read_mp4  # noqa: E402
from multiform.envs.arm_pendulum import ArmPendulumEnv  # noqa: E402
from multiform.view.replay import labels, replay_demo  # noqa: E402
from multiform.view.stream import read_recording  # noqa: E402


@pytest.fixture(scope="module")
def demos(tmp_path_factory):
    env = ArmPendulumEnv(action_mode="ee")
    push = PushDuring(tags=("t1", "t3"), after=0.5, size=0.5, duration=0.1)
    ep = record_episode(env, PendulumMentor(mistake="none", recover=0), seed=3, options={"randomize": True},
                        push=push, max_steps=9000)
    env.close()
    path = tmp_path_factory.mktemp("demos") / "demos.h5"
    write_dataset(path, [ep], "pendulum", "multiform/ArmPendulum-v0", {"action_mode": "ee"})
    return path


def test_replay_reproduces_the_demo_into_the_view_and_a_video_with_overlays(demos, tmp_path):
    ep = read_dataset(demos).episodes[0]
    assert ep.reset_options.get("disturbances"), "the demo was meant to hold a push"
    rrd, mp4 = tmp_path / "demo.rrd", tmp_path / "demo.mp4"
    assert main(["replay", str(demos), "--demo", "0", "--rrd", str(rrd), "--video", str(mp4), "--fps", "10"]) == 0
    rec = read_recording(rrd)
    for j, name in enumerate(ep.observation_names):
        got = rec[f"/state/{name}"]
        order = np.argsort(np.array(got["tick"], dtype=np.int64))
        values = np.array([got["Scalars:scalars"][i][0] for i in order])
        assert len(values) == ep.num_samples and np.abs(values - ep.obs[:, j]).max() <= 1e-9, name
    texts = [t[0] for t in rec["/events"]["TextLog:text"]]
    assert "push" in texts and [t for t in texts if t.startswith("the mentor: ")] == \
        [f"the mentor: {t}" for _, _, t in ep.segments()]
    assert any(e.startswith("/scene/") for e in rec)

    r = replay_demo(demos, 0, every=100)
    try:
        frames = read_mp4(mp4)
        assert len(frames) == len(r.qpos)
        push_frame = next(i for i in range(len(r.qpos)) if "PUSH" in labels(r, i))
        quiet = 0
        for i in (quiet, push_frame):
            band = frames[i][4:60, 4:120].astype(int)
            assert (band.sum(axis=2) < 60).mean() > 0.3             # the dark band behind the text
            assert (band.min(axis=2) > 200).any()                    # white text on it
        red = lambda f: ((f[:, :, 0] > 180) & (f[:, :, 1] < 120)).sum()  # noqa: E731
        assert red(frames[push_frame][:90, :160]) > red(frames[quiet][:90, :160]) + 10   # "PUSH" in red
    finally:
        r.env.close()


def test_replay_refuses_a_demo_that_is_not_in_the_file(demos, capsys):
    assert main(["replay", str(demos), "--demo", "5"]) == 2
    assert "there is no demo 5" in capsys.readouterr().err


def test_a_saved_trace_replays_into_the_view_as_recorded(tmp_path):
    import gymnasium as gym
    import yaml

    from multiform.petri.skillfile import parse_skill
    from multiform.runtime.executor import Executor

    from ..runtime.test_executor import NET, Const, Spring
    env = gym.make("multiform/ArmPendulum-v0", action_mode="ee")
    trace = Executor(parse_skill(yaml.safe_dump(NET)), env, {"go": Const(0.8), "back": Spring()}).run(seed=3)
    env.close()
    trace.save(tmp_path / "trial.npz")
    assert main(["replay", str(tmp_path / "trial.npz")]) == 0
    rec = read_recording(tmp_path / "trial.rrd")
    assert [t[0] for t in rec["/net/fired"]["TextLog:text"]] == trace.fired()
    got = rec["/state/x"]
    order = np.argsort(np.array(got["tick"], dtype=np.int64))
    assert np.array_equal(np.array([got["Scalars:scalars"][i][0] for i in order], np.float32), trace.value("x"))
    for i, place in enumerate(trace.place_ids):
        m = rec[f"/net/marking/{place}"]
        last = {int(k): v[0] for k, v in zip(m["tick"], m["Scalars:scalars"])}
        assert all(trace.marking[k, i] == v for k, v in last.items())
    assert main(["replay", str(tmp_path / "trial.npz"), "--video", str(tmp_path / "t.mp4")]) == 2   # no scene
