"""Which OpenGL MuJoCo renders offscreen with, chosen before MuJoCo is imported (this module
imports neither MuJoCo nor Gymnasium).

MuJoCo reads ``MUJOCO_GL`` once, when it is first imported; without it, it takes GLFW, which needs
a display, and a headless process then fails at the first frame ("OpenGL platform library has not
been loaded"). Importing :mod:`multiform` (or :mod:`multiform.envs`) therefore sets ``MUJOCO_GL``
when the user has not: ``egl`` if an EGL library with a vendor driver is installed (Debian:
``libegl1`` and ``libegl-mesa0``), else ``osmesa`` (``libosmesa6``). A value the user set is kept.
"""

from __future__ import annotations

import ctypes.util
import glob
import os
import sys

INSTALL_HINT = ("install EGL (Debian: libegl1 libegl-mesa0) or OSMesa (libosmesa6), "
                "or set MUJOCO_GL before Python starts")


def _egl_available() -> bool:
    vendors = glob.glob("/usr/share/glvnd/egl_vendor.d/*.json") + glob.glob("/etc/glvnd/egl_vendor.d/*.json")
    return ctypes.util.find_library("EGL") is not None and (
        bool(vendors) or ctypes.util.find_library("EGL_mesa") is not None)


def _osmesa_available() -> bool:
    return ctypes.util.find_library("OSMesa") is not None


def choose_gl() -> str | None:
    """Set ``MUJOCO_GL`` if unset and MuJoCo not yet imported; returns the backend in effect
    (None: nothing offscreen found, or MuJoCo was imported first with its own default)."""
    chosen = os.environ.get("MUJOCO_GL")
    if chosen:
        return chosen
    if "mujoco" in sys.modules:
        return None
    for name, available in (("egl", _egl_available), ("osmesa", _osmesa_available)):
        if available():
            os.environ["MUJOCO_GL"] = name
            return name
    return None


BACKEND = choose_gl()
