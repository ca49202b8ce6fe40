"""Gymnasium environments of exobench (registered by string entry point in :mod:`exobench.envs`).

- ``exobench/StairClimb-v0``: :class:`exobench.envs.gym.stair_climb.StairClimbEnv`.
"""
