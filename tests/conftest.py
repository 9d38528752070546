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


@pytest.fixture(scope="session")
def trained_car(tmp_path_factory, mountain_car_class):
    """The tutorial's task and a model directory trained from six of its demonstrations, shared by the
    tests that practise it (they copy it before changing it)."""
    import multiform
    task = mountain_car_class()
    out = tmp_path_factory.mktemp("car")
    demos = multiform.record(task, out / "demos.h5", demos=6)
    model = multiform.train(task.SKILL, demos, out / "model", task=task, log=lambda s: None)
    return task, model.path


@pytest.fixture(scope="session")
def hostile_lab(tmp_path_factory) -> Path:
    """Four pendulum mentor demos and a model trained from them (the env takes the hand command
    itself), shared by the hostile-input tests, which copy it and never change it."""
    from multiform.demos.dataset import write_dataset
    from multiform.teach.record import record_many
    from multiform.trainer import train_model
    from multiform.model import SkillModel
    from multiform.task import load_task
    task = load_task("pendulum")
    root = tmp_path_factory.mktemp("hostile")
    eps = record_many("pendulum", [0, 1, 2, 9], task.DEMO_ENV_KWARGS)
    demos = write_dataset(root / "demos.h5", eps, task.SKILL, task.ENV_ID, task.DEMO_ENV_KWARGS)
    model = SkillModel.create(root / "model", task.SKILL, demos, task.ENV_ID, task.DEMO_ENV_KWARGS)
    train_model(model, seed=0, log=lambda *a: None)
    (root / "run").mkdir()
    return root
