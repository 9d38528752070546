"""Human teleoperation: a person demonstrates a skill with a joystick or the keyboard, then labels it.

A pygame window shows the scene (the env's ``rgb_array`` frames) with a status line. The person

* drives the end-effector command (the env's single command, ``v_cmd`` for the pendulum) with a
  joystick axis (``gain`` × deflection, with a small dead zone) or the left/right arrow keys (the
  command ramps towards ±``gain`` at ``key_accel`` m/s² while a key is held, and back to 0);
* marks the sub-procedure being executed with the number keys (key ``n`` → ``tags[n]``; by
  default 0-6 → ``t0``-``t6``) or joystick buttons (button ``n`` → ``tags[n]``); every sample
  is recorded with the tag marked last (``first_tag`` at the start);
* ends the demonstration with Escape, Enter or ``q`` (or it ends at ``max_duration`` or when the
  env terminates);
* then labels every segment (maximal run of one tag), shown one after the other with its last
  frame, with ``s`` (success) or ``f`` (failure); Backspace goes back one segment.

The simulation runs at the env's rate (1 kHz) in chunks of one display frame (``fps``); the
command is sampled once per frame and held (a zero-order hold, as a real joystick driver would).
With ``realtime`` the loop keeps pace with the wall clock (``time_scale`` < 1 slows the world
down for a beginner); without it, it runs as fast as it can (tests).

Headless: with ``SDL_VIDEODRIVER=dummy`` nothing is shown and the ``script`` callback, called
once per loop iteration with the stage (``"demo"`` or ``"label"``) and the iteration number, can
post events (``pygame.event.post``) as a person's keys would — which is how the tests drive it.
:func:`teleop_pendulum` is the entry point for ``multiform teleop pendulum``.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import gymnasium as gym
import mujoco
import numpy as np

from ..demos.episode import Episode, SegmentLabel

os.environ.setdefault("PYGAME_HIDE_SUPPORT_PROMPT", "1")

DEFAULT_TAGS = ("t0", "t1", "t2", "t3", "t4", "t5", "t6")
Script = Callable[[str, int], None]


class TeleopAborted(RuntimeError):
    """The window was closed before the demonstration ended."""


class _Input:
    """The person's input, tracked from events (so that posted events count as real ones)."""

    def __init__(self, gain: float, key_accel: float, dead_zone: float, axis: int):
        self.gain, self.key_accel, self.dead_zone, self.axis = gain, key_accel, dead_zone, axis
        self.left = self.right = False
        self.stick: float | None = None
        self.key_cmd = 0.0

    def handle(self, ev: Any, pygame: Any) -> None:
        if ev.type in (pygame.KEYDOWN, pygame.KEYUP):
            down = ev.type == pygame.KEYDOWN
            if ev.key == pygame.K_LEFT:
                self.left = down
            elif ev.key == pygame.K_RIGHT:
                self.right = down
        elif ev.type == pygame.JOYAXISMOTION and ev.axis == self.axis:
            v = float(ev.value)
            self.stick = 0.0 if abs(v) < self.dead_zone else v

    def command(self, dt: float) -> float:
        """The command for the next frame of duration ``dt``."""
        if self.left or self.right or self.stick is None:
            target = self.gain * ((1.0 if self.right else 0.0) - (1.0 if self.left else 0.0))
            step = self.key_accel * dt
            self.key_cmd += min(max(target - self.key_cmd, -step), step)
            return self.key_cmd
        self.key_cmd = 0.0
        return self.gain * self.stick


def teleop(env: gym.Env, seed: int = 0, options: Mapping[str, Any] | None = None, *, gain: float = 1.0,
           key_accel: float = 6.0, dead_zone: float = 0.05, axis: int = 0, tags: Sequence[str] = DEFAULT_TAGS,
           first_tag: str | None = None, fps: float = 30.0, max_duration: float = 60.0, realtime: bool = True,
           time_scale: float = 1.0, joystick: bool = True, script: Script | None = None,
           labeller: str = "human", window_title: str = "multiform teleop") -> Episode:
    """Record one demonstration by a person on ``env`` (made with ``render_mode="rgb_array"``).

    Returns the :class:`Episode` with the person's per-segment labels (``labeller``); its
    ``outcome`` is ``"success"`` when every segment was labelled a success. Raises
    :class:`TeleopAborted` if the window is closed during the demonstration.
    """
    import pygame

    base = env.unwrapped
    if len(base.command_names) != 1:
        raise ValueError(f"teleop drives one command; this env has {list(base.command_names)}")
    if getattr(base, "render_mode", None) != "rgb_array":
        raise ValueError('teleop needs an env made with render_mode="rgb_array" to show the scene')
    tags = tuple(tags)
    tag = first_tag if first_tag is not None else tags[0]
    dt = float(base.dt)
    per_frame = max(1, int(round(1.0 / (fps * dt))))
    max_steps = int(round(max_duration / dt))

    pygame.display.init()
    pygame.font.init()
    sticks = []
    if joystick:
        pygame.joystick.init()
        sticks = [pygame.joystick.Joystick(i) for i in range(pygame.joystick.get_count())]
    try:
        obs, info = env.reset(seed=seed, options=dict(options) if options else None)
        frame = env.render()
        h, w = frame.shape[:2]
        screen = pygame.display.set_mode((w, h + 44))
        pygame.display.set_caption(window_title)
        font = pygame.font.Font(None, 22)
        inp = _Input(gain, key_accel, dead_zone, axis)
        obs_rows, cmd_rows, tag_rows, snaps, it = _record(pygame, env, screen, font, obs, inp, tags, tag, per_frame,
                                                          max_steps, realtime, time_scale, script)
        if not obs_rows:
            raise TeleopAborted("the demonstration ended before its first sample")
        episode = Episode(obs=np.asarray(obs_rows), actions=np.asarray(cmd_rows).reshape(-1, 1),
                          transitions=np.asarray(tag_rows, dtype=str),
                          observation_names=tuple(base.observation_names),
                          command_names=tuple(base.command_names), dt=dt, seed=seed,
                          reset_options=dict(options or {}))
        episode.labels = _label(pygame, env, screen, font, episode, snaps, script, labeller, it)
        if len(episode.labels) == len(episode.segments()):
            episode.outcome = "success" if all(lab.success for lab in episode.labels) else "failure"
        return episode
    finally:
        for js in sticks:
            js.quit()
        pygame.quit()


def _record(pygame: Any, env: gym.Env, screen: Any, font: Any, obs: np.ndarray, inp: _Input, tags: tuple[str, ...],
            tag: str, per_frame: int, max_steps: int, realtime: bool, time_scale: float, script: Script | None
            ) -> tuple[list[np.ndarray], list[float], list[str], list[tuple[int, np.ndarray]], int]:
    """The demonstration itself: each frame, read the person's input, step the env ``per_frame``
    times with their command and show the scene, until they end it, the episode ends or
    ``max_steps``. Returns the observations, commands and step tags per step, the poses shown
    (step, qpos) and the number of frames."""
    base = env.unwrapped
    dt = float(base.dt)
    obs_rows: list[np.ndarray] = []
    cmd_rows: list[float] = []
    tag_rows: list[str] = []
    snaps: list[tuple[int, np.ndarray]] = []
    wall0 = time.perf_counter()
    it = 0
    while len(obs_rows) < max_steps:
        if script is not None:
            script("demo", it)
        running, tag = _events(pygame, inp, tags, tag)
        if not running:
            break
        cmd = inp.command(per_frame * dt)
        action = np.array([cmd])
        done = False
        for _ in range(per_frame):
            obs_rows.append(np.asarray(obs, dtype=np.float64))
            cmd_rows.append(cmd)
            tag_rows.append(tag)
            obs, _, terminated, truncated, info = env.step(action)
            if terminated or truncated or len(obs_rows) >= max_steps:
                done = True
                break
        snaps.append((len(obs_rows) - 1, base.data.qpos.copy()))
        frame = env.render()
        status = f"t = {len(obs_rows) * dt:5.1f} s   {tag}   command {cmd:+.2f}"
        _show(pygame, screen, font, frame, status, "arrows / stick: move   0-9: mark step   Esc: end")
        it += 1
        if done:
            break
        if realtime:
            lag = wall0 + len(obs_rows) * dt / time_scale - time.perf_counter()
            if lag > 0:
                time.sleep(lag)
    return obs_rows, cmd_rows, tag_rows, snaps, it


def _events(pygame: Any, inp: _Input, tags: tuple[str, ...], tag: str) -> tuple[bool, str]:
    """This frame's window events: the person's input, a step marked by a number key or a
    joystick button. Returns whether the demonstration goes on, and the step tag now."""
    running = True
    for ev in pygame.event.get():
        if ev.type == pygame.QUIT:
            raise TeleopAborted("the teleoperation window was closed")
        if ev.type == pygame.KEYDOWN:
            if ev.key in (pygame.K_ESCAPE, pygame.K_RETURN, pygame.K_q):
                running = False
            elif pygame.K_0 <= ev.key <= pygame.K_9 and ev.key - pygame.K_0 < len(tags):
                tag = tags[ev.key - pygame.K_0]
        elif ev.type == pygame.JOYBUTTONDOWN and ev.button < len(tags):
            tag = tags[ev.button]
        inp.handle(ev, pygame)
    return running, tag


def _show(pygame: Any, screen: Any, font: Any, frame: np.ndarray, line1: str, line2: str) -> None:
    surf = pygame.surfarray.make_surface(np.ascontiguousarray(frame.swapaxes(0, 1)))
    screen.fill((20, 22, 26))
    screen.blit(surf, (0, 0))
    h = frame.shape[0]
    screen.blit(font.render(line1, True, (240, 240, 240)), (6, h + 4))
    screen.blit(font.render(line2, True, (170, 175, 185)), (6, h + 24))
    pygame.display.flip()


def _frame_at(env: gym.Env, qpos: np.ndarray) -> np.ndarray:
    base = env.unwrapped
    base.data.qpos[:] = qpos
    base.data.qvel[:] = 0.0
    mujoco.mj_forward(base.model, base.data)
    return env.render()


def _label(pygame: Any, env: gym.Env, screen: Any, font: Any, episode: Episode,
           snaps: list[tuple[int, np.ndarray]], script: Script | None, labeller: str, it: int) -> list[SegmentLabel]:
    """Ask the person for success/failure of every segment; returns the labels given."""
    segments = episode.segments()
    verdicts: list[bool | None] = [None] * len(segments)
    sample_index = np.array([k for k, _ in snaps])
    i = 0
    k = 0
    shown = -1
    while i < len(segments):
        start, end, tag = segments[i]
        if shown != i:
            j = int(np.searchsorted(sample_index, end - 1)) if len(snaps) else 0
            frame = _frame_at(env, snaps[min(j, len(snaps) - 1)][1]) if snaps else env.render()
            line = (f"segment {i + 1}/{len(segments)}: {tag}, {start * episode.dt:.1f}-{end * episode.dt:.1f} s"
                    "   success? s / f   (Backspace: back)")
            _show(pygame, screen, font, frame, line, "label every segment as you judged it")
            shown = i
        if script is not None:
            script("label", k)
        k += 1
        events = pygame.event.get()
        if not events and script is None:
            events = [pygame.event.wait(100)]
        for ev in events:
            if ev.type == pygame.QUIT:
                return _labels(segments, verdicts, labeller)
            if ev.type != pygame.KEYDOWN:
                continue
            if ev.key in (pygame.K_s, pygame.K_f):
                verdicts[i] = ev.key == pygame.K_s
                i += 1
            elif ev.key == pygame.K_BACKSPACE and i > 0:
                i -= 1
            if i >= len(segments):
                break
        if script is not None and k > 100_000:
            raise RuntimeError("the script never labelled all segments")
    return _labels(segments, verdicts, labeller)


def _labels(segments: list[tuple[int, int, str]], verdicts: list[bool | None], labeller: str) -> list[SegmentLabel]:
    return [SegmentLabel(s, e, t, bool(v), labeller) for (s, e, t), v in zip(segments, verdicts) if v is not None]


def teleop_pendulum(seed: int = 0, options: Mapping[str, Any] | None = None, width: int = 640, height: int = 480,
                    **kwargs: Any) -> Episode:
    """Teleoperate the arm-pendulum (``multiform teleop pendulum``); keyword arguments go to :func:`teleop`.

    The default key gain is 1.0 m/s; the right arrow moves the hand towards +x (right on screen).
    """
    from ..envs.arm_pendulum import ArmPendulumEnv

    env = ArmPendulumEnv(render_mode="rgb_array", width=width, height=height)
    try:
        return teleop(env, seed=seed, options=options, window_title="multiform teleop: pendulum", **kwargs)
    finally:
        env.close()
