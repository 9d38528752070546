"""MuJoCo's offscreen renderer, with a message that says what to install when it cannot start.
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
