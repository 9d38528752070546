import os
import sys
from pathlib import Path

import pytest

os.environ.setdefault("MUJOCO_GL", "egl")
for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")


MOUNTAIN_CAR = Path(__file__).resolve().parents[1] / "examples" / "mountain_car"


@pytest.fixture(scope="session")
def mountain_car_class():
    """The tutorial's task class (``examples/mountain_car``), imported as the tutorial's script does."""
    sys.path.insert(0, str(MOUNTAIN_CAR))
    try:
        from mountain_car import MountainCar
    finally:
        sys.path.remove(str(MOUNTAIN_CAR))
    return MountainCar
