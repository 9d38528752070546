"""The bundled Gymnasium envs (their ids, where each lives, and its time limit) and the bundled
robots' servos (what an inverse model names). Registering them imports no env: Gymnasium loads an
env's module when it is first made, and a servo's module is imported when a model first names it."""

from __future__ import annotations

ENVS = {   # id -> (entry point, max_episode_steps: a skill's default max_duration at 1 ms a step)
    "multiform/ArmPendulum-v0": ("multiform.envs.arm_pendulum:ArmPendulumEnv", 60_000),
    "multiform/Nunchaku-v0": ("multiform.envs.nunchaku:NunchakuEnv", 15_000),
    "multiform/BallInCup-v0": ("multiform.envs.ball_in_cup:BallInCupEnv", 20_000),
}

SERVOS = {   # name -> the function that builds it (see multiform.learn.servos)
    "arm_pendulum": "multiform.envs.arm_servo:arm_pendulum_servo",
}


def register_envs() -> None:
    """Register the bundled envs with Gymnasium (once; an id already registered is left as it is)."""
    from gymnasium.envs.registration import register, registry
    for env_id, (entry_point, steps) in ENVS.items():
        if env_id not in registry:
            register(id=env_id, entry_point=entry_point, max_episode_steps=steps)
