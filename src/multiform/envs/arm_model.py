"""The bundled arm-pendulum MJCF model (``assets/arm_pendulum.xml``): the env and the reference
controller each load their own copy."""

from __future__ import annotations

from importlib import resources

import mujoco


def model_path() -> str:
    """Path of the bundled MJCF model."""
    return str(resources.files("multiform") / "envs" / "assets" / "arm_pendulum.xml")


def load_model() -> mujoco.MjModel:
    """A fresh copy of the arm-pendulum model. MuJoCo's automatic reset on bad values is off: a
    non-finite state stays visible (and ends the step as ``non_finite``) instead of silently
    teleporting the arm home."""
    m = mujoco.MjModel.from_xml_path(model_path())
    m.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_AUTORESET)
    return m
