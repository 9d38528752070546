"""MuJoCo's offscreen renderer, with a message that says what to install when it cannot start, and
the envs' frame skip (fewer, longer env steps: the rate at which frames are rendered and recorded).
The OpenGL backend itself is chosen by :mod:`multiform._gl` before MuJoCo is imported."""

from __future__ import annotations

import os

from .._gl import BACKEND, INSTALL_HINT, _egl_available, _osmesa_available, choose_gl  # noqa: F401


def make_renderer(model, height: int, width: int):
    """``mujoco.Renderer(model, height, width)``, or a RuntimeError that says what to install."""
    import mujoco
    gl = os.environ.get("MUJOCO_GL")
    if not gl:
        why = ("mujoco was imported before multiform, with no MUJOCO_GL set"
               if _egl_available() or _osmesa_available() else "no EGL or OSMesa library found")
        raise RuntimeError(f"cannot render offscreen: {why}; {INSTALL_HINT} (e.g. MUJOCO_GL=egl)")
    try:
        return mujoco.Renderer(model, height, width)
    except Exception as exc:     # the GL libraries raise many types; all mean "this backend does not work"
        raise RuntimeError(f"cannot render offscreen with MUJOCO_GL={gl} ({type(exc).__name__}: {exc}); "
                           f"{INSTALL_HINT}") from exc


def check_frame_skip(frame_skip: int) -> int:
    """``frame_skip`` as a whole number of at least 1 (physics steps per env step)."""
    if isinstance(frame_skip, bool) or int(frame_skip) != frame_skip or frame_skip < 1:
        raise ValueError(f"frame_skip must be a whole number of at least 1, got {frame_skip!r}")
    return int(frame_skip)


def skip_frames(physics_step, action, frame_skip: int):
    """``frame_skip`` physics steps with ``action`` held, as one env step: the last step's
    observation and info, the summed reward; stops early when a step terminates or truncates."""
    reward = 0.0
    for _ in range(frame_skip):
        obs, r, terminated, truncated, info = physics_step(action)
        reward += r
        if terminated or truncated:
            break
    return obs, reward, terminated, truncated, info


class FramedEnv:
    """What the bundled MuJoCo envs share: ``step`` as ``frame_skip`` calls of their
    ``_physics_step`` (one 1 ms step when it is 1), and ``render``/``close`` of an offscreen renderer
    (``render_mode`` ``"rgb_array"``, ``height``, ``width``, ``shadows``) looking through
    :meth:`_render_camera`."""

    def step(self, action):
        if self.frame_skip == 1:
            return self._physics_step(action)
        return skip_frames(self._physics_step, action, self.frame_skip)

    @staticmethod
    def _reset_options(options, known) -> dict:
        """``options`` as a dict, refused if it names an option outside ``known``."""
        options = dict(options or {})
        unknown = sorted(set(options) - set(known))
        if unknown:
            raise ValueError(f"unknown reset option(s) {unknown}; known: {list(known)}")
        return options

    def _render_camera(self):
        """The camera the frames are taken from (the env's ``camera``: a name or an id)."""
        return self.camera

    def render(self):
        if self.render_mode != "rgb_array":
            return None
        if self._renderer is None:
            import mujoco
            self._renderer = make_renderer(self.model, self.height, self.width)
            self._renderer.scene.flags[mujoco.mjtRndFlag.mjRND_SHADOW] = self.shadows
        self._renderer.update_scene(self.data, camera=self._render_camera())
        return self._renderer.render().copy()

    def close(self):
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None
