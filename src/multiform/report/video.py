"""Videos of demonstrations and trials: render simulator poses and write them to MP4.

A trial or demo keeps joint-position snapshots (``qpos``), not images; :func:`render_qpos` turns
them into frames with MuJoCo's offscreen renderer (``MUJOCO_GL=egl`` works without a display or
GPU), and :func:`write_mp4` encodes frames with the ``ffmpeg`` program (H.264 by libx264), atomically (a temporary file in the
same directory, renamed when complete). :func:`replay` rebuilds the snapshots of a recorded
episode by replaying its commands from its seed.
"""

from __future__ import annotations

import functools
import os
import re
import shutil
import subprocess
import tempfile
from collections.abc import Iterable, Iterator, Sequence
from pathlib import Path
from typing import Any

import gymnasium as gym
import mujoco
import numpy as np

from ..demos.episode import Episode
from ..envs.rendering import make_renderer
from ..io import atomic_path


FFMPEG_HINT = "install the ffmpeg program (Debian: apt-get install ffmpeg) or name it in MULTIFORM_FFMPEG"


def ffmpeg() -> str:
    """The ``ffmpeg`` program videos are encoded with: ``MULTIFORM_FFMPEG``, else the one on the
    PATH (Debian's: GPL-2+, with libx264). multiform ships no ffmpeg of its own."""
    exe = shutil.which(os.environ.get("MULTIFORM_FFMPEG") or "ffmpeg")
    if not exe:
        raise RuntimeError(f"videos need ffmpeg: {FFMPEG_HINT}")
    return exe


def write_mp4(frames: Iterable[np.ndarray], path: str | os.PathLike, fps: float = 30.0, quality: int = 7) -> Path:
    """Encode ``frames`` (H×W×3 uint8, all the same size) as an H.264 MP4 at ``path``, atomically.

    ``frames`` may be a generator; it is consumed once. ``quality`` 0..10 (higher is better; 7 is
    libx264's CRF 15). Returns the path. Raises ``ValueError`` when there are no frames or they are
    not RGB images of one size, ``RuntimeError`` when ffmpeg is missing or fails.
    """
    path = Path(path)
    it = iter(frames)
    first = next(it, None)
    if first is None:
        raise ValueError("no frames to write")
    first = _check_frame(first, None)
    h, w = first.shape[:2]
    crf = int(round((1.0 - min(max(quality, 0), 10) / 10.0) * 51))
    with atomic_path(path, suffix=".mp4") as tmp:
        cmd = [ffmpeg(), "-hide_banner", "-loglevel", "error", "-y", "-f", "rawvideo", "-pix_fmt", "rgb24",
               "-s", f"{w}x{h}", "-r", f"{float(fps):g}", "-i", "-", "-an", "-c:v", "libx264", "-pix_fmt", "yuv420p",
               "-crf", str(crf), "-f", "mp4", str(tmp)]
        with tempfile.TemporaryFile() as err:
            proc = subprocess.Popen(cmd, stdin=subprocess.PIPE, stdout=subprocess.DEVNULL, stderr=err)
            try:
                proc.stdin.write(np.ascontiguousarray(first).tobytes())
                for frame in it:
                    proc.stdin.write(np.ascontiguousarray(_check_frame(frame, (h, w))).tobytes())
                proc.stdin.close()
            except BrokenPipeError:
                pass
            finally:
                if proc.poll() is None and not proc.stdin.closed:
                    proc.stdin.close()
                code = proc.wait()
            if code:
                err.seek(0)
                raise RuntimeError(f"ffmpeg could not write {path} (exit {code}): "
                                   f"{err.read().decode(errors='replace').strip()[-500:]}")
    return path


def read_mp4(path: str | os.PathLike) -> np.ndarray:
    """Every frame of a video as one (frames, H, W, 3) uint8 array, decoded by the same ffmpeg."""
    probe = subprocess.run([ffmpeg(), "-hide_banner", "-i", str(path)], capture_output=True, text=True)
    size = re.search(r"Video:.*?(\d{2,5})x(\d{2,5})", probe.stderr)
    if size is None:
        raise ValueError(f"{path}: no video stream found")
    w, h = int(size.group(1)), int(size.group(2))
    out = subprocess.run([ffmpeg(), "-hide_banner", "-loglevel", "error", "-i", str(path), "-f", "rawvideo",
                          "-pix_fmt", "rgb24", "-"], capture_output=True, check=True)
    return np.frombuffer(out.stdout, dtype=np.uint8).reshape(-1, h, w, 3)


def _check_frame(frame: Any, size: tuple[int, int] | None) -> np.ndarray:
    a = np.asarray(frame)
    if a.ndim != 3 or a.shape[2] != 3 or a.dtype != np.uint8:
        raise ValueError(f"a frame must be an H×W×3 uint8 image, got shape {a.shape} dtype {a.dtype}")
    if a.shape[0] % 2 or a.shape[1] % 2:
        raise ValueError(f"frame size {a.shape[1]}×{a.shape[0]} must be even for H.264")
    if size is not None and a.shape[:2] != size:
        raise ValueError(f"frame size changed from {size[1]}×{size[0]} to {a.shape[1]}×{a.shape[0]}")
    return a


def render_qpos(env: gym.Env, qpos: Iterable[np.ndarray], camera: str | None = None,
                width: int = 480, height: int = 360) -> Iterator[np.ndarray]:
    """Frames of ``env``'s scene posed at each ``qpos`` snapshot (set qpos, ``mj_forward``, render).

    A generator: the env's simulator state is saved first and restored when it is exhausted or
    closed. Without ``camera``, an env created with ``render_mode="rgb_array"`` renders its own view;
    otherwise a renderer of ``width``×``height`` uses the named camera (or MuJoCo's default one).
    Snapshots must come from an episode with the same model parameters as the env has now (e.g.
    the pendulum's length): reset the env with that episode's seed and options first.
    """
    base = env.unwrapped
    m, d = base.model, base.data
    saved = (d.qpos.copy(), d.qvel.copy(), d.act.copy(), float(d.time))
    own = camera is not None or getattr(base, "render_mode", None) != "rgb_array"
    renderer = make_renderer(m, height, width) if own else None
    try:
        for q in qpos:
            d.qpos[:] = q
            d.qvel[:] = 0.0
            mujoco.mj_forward(m, d)
            if renderer is not None:
                renderer.update_scene(d, camera=camera if camera is not None else -1)
                yield renderer.render().copy()
            else:
                yield base.render()
    finally:
        d.qpos[:], d.qvel[:], d.act[:] = saved[0], saved[1], saved[2]
        d.time = saved[3]
        mujoco.mj_forward(m, d)
        if renderer is not None:
            renderer.close()


def replay(env: gym.Env, episode: Episode, qpos_every: int = 0) -> tuple[np.ndarray, list[np.ndarray]]:
    """Replay ``episode``'s commands on ``env`` from its seed and reset options.

    Returns the observations seen (one row per command, as recorded) and, with ``qpos_every`` > 0,
    a ``qpos`` snapshot every that many steps (for :func:`render_qpos`). A deterministic env
    reproduces the recorded observations exactly.
    """
    base = env.unwrapped
    obs, _ = env.reset(seed=episode.seed, options=dict(episode.reset_options) or None)
    rows = np.empty_like(episode.obs)
    snaps: list[np.ndarray] = []
    n = 0
    for k, cmd in enumerate(episode.actions):
        rows[k] = obs
        n = k + 1
        if qpos_every and k % qpos_every == 0:
            snaps.append(base.data.qpos.copy())
        obs, _, terminated, truncated, _ = env.step(cmd)
        if terminated or truncated:
            break
    return rows[:n], snaps


def episode_video(env: gym.Env, episode: Episode, path: str | os.PathLike, fps: float = 25.0,
                  camera: str | None = None, width: int = 480, height: int = 360) -> Path:
    """Write an MP4 of a recorded ``episode`` (replayed on ``env``) at ``fps`` frames per second."""
    every = max(1, int(round(1.0 / (fps * episode.dt))))
    _, snaps = replay(env, episode, qpos_every=every)
    return write_mp4(render_qpos(env, snaps, camera, width, height), path, fps=1.0 / (every * episode.dt))


def frame_labels(trace: Any, every: int, count: int, push_time: float | None = None,
                 push_shown: float = 0.6) -> list[list[str]]:
    """The overlay lines of ``count`` frames taken every ``every`` ticks of ``trace``: the time, the
    marked place(s), the transition being executed, and "PUSH" for ``push_shown`` s from the push."""
    tags = trace.tags()
    out = []
    for i in range(count):
        k = min(i * every, trace.num_ticks - 1)
        t = k * trace.dt
        places = [p for p, n in zip(trace.place_ids, trace.marking[k]) if n > 0]
        lines = [f"t = {t:6.2f} s", f"place: {', '.join(places) or '-'}", f"transition: {tags[k] or '-'}"]
        if push_time is not None and push_time <= t < push_time + push_shown:
            lines.append("PUSH")
        out.append(lines)
    return out


@functools.lru_cache(maxsize=4)
def _font(size: int) -> Any:
    from PIL import ImageFont
    return ImageFont.load_default(size=size)


def draw_lines(frame: np.ndarray, lines: Sequence[str]) -> np.ndarray:
    """``frame`` with ``lines`` written in its top-left corner on a dark band (Pillow's bitmap font);
    a line reading "PUSH" is drawn in red."""
    from PIL import Image, ImageDraw
    img = Image.fromarray(np.ascontiguousarray(frame))
    draw = ImageDraw.Draw(img)
    font = _font(max(11, frame.shape[0] // 28))
    y = 4
    for line in lines:
        box = draw.textbbox((6, y), line, font=font)
        draw.rectangle((box[0] - 3, box[1] - 2, box[2] + 3, box[3] + 2), fill=(0, 0, 0))
        draw.text((6, y), line, font=font, fill=(255, 80, 80) if line == "PUSH" else (255, 255, 255))
        y = box[3] + 5
    return np.asarray(img)


def overlay_frames(frames: Iterable[np.ndarray], trace: Any, push_time: float | None = None) -> Iterator[np.ndarray]:
    """Frames of a trial (one per ``trace.qpos_every`` ticks) with :func:`frame_labels` drawn on each."""
    every = max(1, int(trace.qpos_every))
    count = int(np.ceil(trace.num_ticks / every))
    labels = frame_labels(trace, every, count, push_time)
    for i, frame in enumerate(frames):
        yield draw_lines(frame, labels[min(i, count - 1)])
