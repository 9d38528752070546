"""The bundled Gymnasium envs: their ids, where each lives, and its time limit. Registering them
imports no env: Gymnasium loads an env's module when it is first made (which also registers the
arm's servo, see :mod:`multiform.envs`)."""

from __future__ import annotations

ENVS = {   # id -> (entry point, max_episode_steps: a skill's default max_duration at 1 ms a step)
    "multiform/ArmPendulum-v0": ("multiform.envs.arm_pendulum:ArmPendulumEnv", 60_000),
    "multiform/Nunchaku-v0": ("multiform.envs.nunchaku:NunchakuEnv", 15_000),
    "multiform/BallInCup-v0": ("multiform.envs.ball_in_cup:BallInCupEnv", 20_000),
}


def register_envs() -> None:
    """Register the bundled envs with Gymnasium (once; an id already registered is left as it is)."""
    from gymnasium.envs.registration import register, registry
    for env_id, (entry_point, steps) in ENVS.items():
        if env_id not in registry:
            register(id=env_id, entry_point=entry_point, max_episode_steps=steps)
