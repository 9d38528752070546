"""MuJoCo environments with Gymnasium's API; importing this package registers them.

* ``multiform/ArmPendulum-v0`` — a 6-axis arm with the AUBO i5's kinematics carrying an inverted
  pendulum (:mod:`multiform.envs.arm_pendulum`).
* ``multiform/Nunchaku-v0`` — a hand that flips a nunchaku (:mod:`multiform.envs.nunchaku`).

Every env here exposes ``observation_names`` (one name per observation entry) and
``command_names`` (one name per entry of the end-effector command), so that a skill file can name
its state variables and the library never needs to know which env it drives.
"""

from gymnasium.envs.registration import register, registry

if "multiform/ArmPendulum-v0" not in registry:
    register(id="multiform/ArmPendulum-v0",
             entry_point="multiform.envs.arm_pendulum:ArmPendulumEnv")
if "multiform/Nunchaku-v0" not in registry:
    register(id="multiform/Nunchaku-v0",
             entry_point="multiform.envs.nunchaku:NunchakuEnv")
