"""Teleoperation driven headless: SDL's dummy video driver and scripted key and joystick events."""

from __future__ import annotations

import os

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
os.environ.setdefault("SDL_AUDIODRIVER", "dummy")

import numpy as np  # noqa: E402
import pygame  # noqa: E402
import pytest  # noqa: E402

from multiform.teach.teleop import TeleopAborted, teleop, teleop_pendulum  # noqa: E402
from multiform.envs.arm_pendulum import ArmPendulumEnv  # noqa: E402


def key(k: int, down: bool = True) -> None:
    pygame.event.post(pygame.event.Event(pygame.KEYDOWN if down else pygame.KEYUP, key=k, mod=0, unicode="",
                                         scancode=0))


@pytest.fixture()
def env():
    e = ArmPendulumEnv(render_mode="rgb_array", width=160, height=120)
    yield e
    e.close()


def test_keyboard_demo_marks_steps_and_is_labelled(env):
    demo = {0: [(pygame.K_RIGHT, True)], 15: [(pygame.K_RIGHT, False), (pygame.K_2, True)],
            20: [(pygame.K_LEFT, True)], 35: [(pygame.K_LEFT, False), (pygame.K_1, True)],
            45: [(pygame.K_ESCAPE, True)]}
    answers = [pygame.K_s, pygame.K_f, pygame.K_BACKSPACE, pygame.K_s, pygame.K_s]

    def script(stage: str, i: int) -> None:
        if stage == "demo":
            for k, down in demo.get(i, []):
                key(k, down)
        elif i < len(answers):
            key(answers[i])

    ep = teleop(env, seed=3, fps=50, realtime=False, gain=0.8, script=script)
    per_frame = 20
    assert ep.num_samples == 45 * per_frame
    assert [t for _, _, t in ep.segments()] == ["t0", "t2", "t1"]
    assert ep.segments()[1][0] == 15 * per_frame and ep.segments()[2][0] == 35 * per_frame
    a = ep.actions[:, 0]
    assert a[: 15 * per_frame].max() == pytest.approx(0.8)      # the right arrow ramps up to the gain
    assert a[1] > 0 and np.all(np.diff(a[: 6 * per_frame: per_frame]) > 0)
    assert a[20 * per_frame: 35 * per_frame].min() < -0.5         # the left arrow
    x = ep.column("x")
    assert x[15 * per_frame] > 0.05 and x[-1] < x[20 * per_frame]  # the hand went right, then left
    assert [(lab.transition, lab.success, lab.labeller) for lab in ep.labels] == [
        ("t0", True, "human"), ("t2", True, "human"), ("t1", True, "human")]   # 'f' was taken back
    assert ep.outcome == "success"
    assert ep.observation_names == env.observation_names and ep.command_names == ("v_cmd",)
    assert ep.seed == 3 and ep.dt == 0.001


def test_joystick_axis_and_buttons(env):
    def script(stage: str, i: int) -> None:
        if stage == "demo":
            if i == 0:
                pygame.event.post(pygame.event.Event(pygame.JOYAXISMOTION, joy=0, instance_id=0, axis=0, value=-0.5))
            elif i == 5:
                pygame.event.post(pygame.event.Event(pygame.JOYBUTTONDOWN, joy=0, instance_id=0, button=3))
                pygame.event.post(pygame.event.Event(pygame.JOYAXISMOTION, joy=0, instance_id=0, axis=0, value=0.02))
            elif i == 8:
                key(pygame.K_q)
        else:
            key(pygame.K_f if i == 0 else pygame.K_s)

    ep = teleop(env, seed=0, fps=50, realtime=False, gain=1.2, script=script)
    a = ep.actions[:, 0]
    assert a[0] == pytest.approx(-0.6) and a[5 * 20] == 0.0       # dead zone
    assert [t for _, _, t in ep.segments()] == ["t0", "t3"]
    assert [lab.success for lab in ep.labels] == [False, True]
    assert ep.outcome == "failure"


def test_closing_the_window_aborts(env):
    def script(stage: str, i: int) -> None:
        if i == 2:
            pygame.event.post(pygame.event.Event(pygame.QUIT))

    with pytest.raises(TeleopAborted):
        teleop(env, seed=0, fps=50, realtime=False, script=script)


def test_max_duration_ends_the_demo_and_realtime_paces_it(env):
    import time

    def script(stage: str, i: int) -> None:
        if stage == "label":
            key(pygame.K_s)

    t0 = time.perf_counter()
    ep = teleop(env, seed=0, fps=25, max_duration=0.4, realtime=True, script=script)
    assert ep.num_samples == 400
    assert time.perf_counter() - t0 >= 0.35


def test_teleop_pendulum_entry_point():
    def script(stage: str, i: int) -> None:
        key(pygame.K_ESCAPE if stage == "demo" and i == 1 else pygame.K_s)

    ep = teleop_pendulum(seed=1, options={"length": 0.45}, width=320, height=240, fps=50, realtime=False,
                         script=script)
    assert ep.reset_options == {"length": 0.45}
    assert ep.num_samples == 20 and ep.labels and ep.labels[0].success


def test_rejects_envs_it_cannot_drive():
    with pytest.raises(ValueError, match="render_mode"):
        teleop(ArmPendulumEnv(), realtime=False)
