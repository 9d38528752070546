"""MuJoCo environments with Gymnasium's API; importing this package registers them.

Gymnasium 1.x loads no plugins (it dropped the ``gymnasium.envs`` entry-point group in 1.0), so an
env id of a package needs that package imported first; ``import multiform`` alone registers
nothing. Either import this package, or let Gymnasium import it from the id::

    gymnasium.make("multiform.envs:multiform/ArmPendulum-v0")   # no import of multiform needed


* ``multiform/ArmPendulum-v0`` — a 6-axis arm with the AUBO i5's kinematics carrying an inverted
  pendulum (:mod:`multiform.envs.arm_pendulum`).
* ``multiform/Nunchaku-v0`` — a hand that flips a nunchaku (:mod:`multiform.envs.nunchaku`).
* ``multiform/BallInCup-v0`` — the same arm holding a cup with a ball on a string
  (:mod:`multiform.envs.ball_in_cup`).

Every env here exposes ``observation_names`` (one name per observation entry) and
``command_names`` (one name per entry of the end-effector command), so that a skill file can name
its state variables and the library never needs to know which env it drives.

Importing this package picks MuJoCo's offscreen renderer (:mod:`multiform.envs.rendering`); the arm's
servo for its inverse model (:mod:`multiform.envs.arm_servo`) is named in :mod:`multiform.registry`.
All step 1 ms of physics per call, so ``render_fps`` is 1000 (a video of every frame plays in
real time), unless ``frame_skip`` makes each step longer (``render_fps`` ``1000 / frame_skip``:
what keeps Gymnasium's ``RecordVideo`` to a few hundred MB, see
:mod:`multiform.envs.arm_pendulum`), and are registered with a time limit (``max_episode_steps``,
counted in steps) that a ``gymnasium.make`` argument overrides. ``RecordVideo`` needs moviepy:
``pip install 'multiform[video]'``.
"""

from .rendering import BACKEND as GL_BACKEND  # noqa: F401  (sets MUJOCO_GL before mujoco is imported)
from ..registry import register_envs  # noqa: E402

register_envs()
