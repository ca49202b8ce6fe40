"""Gymnasium environments of exobench (registered by string entry point in :mod:`exobench.envs`).

- ``exobench/StairClimb-v0``: :class:`exobench.envs.gym.stair_climb.StairClimbEnv`.

An environment is stepped through the simulation core (:mod:`exobench.envs.sim`), not beside it:
its world is a scenario's, composed with its rig by :func:`~exobench.envs.sim.compose.compose_rig`,
its motion is the walker's (:mod:`exobench.envs.motion`), and its sensors are sampled by the
recorder stepped as the motion grows (:meth:`~exobench.envs.sim.recorder.Recorder.advance_to`),
so its frames are those :func:`~exobench.envs.sim.recorder.record` gives for the same motion and seed.
"""
