"""exobench.envs: gait, sensors, simulation loop, sessions and the gymnasium environments.

Importing the package imports :mod:`exobench.envs.gl_platform`, so that the OpenGL platform is
chosen before anything below imports MuJoCo, and registers ``exobench/StairClimb-v0`` with
gymnasium by string entry point (the environment module, and MuJoCo with it, is imported only by
``gymnasium.make``).
"""

import gymnasium

from . import gl_platform  # noqa: F401  (gymnasium does not import mujoco)

if "exobench/StairClimb-v0" not in gymnasium.registry:
    gymnasium.register(
        id="exobench/StairClimb-v0",
        entry_point="exobench.envs.gym.stair_climb:StairClimbEnv",
        max_episode_steps=12,
    )
