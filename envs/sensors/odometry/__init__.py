"""Visual(-inertial) odometry of a camera: :class:`OdometryConfig`; the drift model is
:func:`exobench.envs.motion.odometry.drift_odometry` (the true optical-frame motion, degraded)."""

from .config import OdometryConfig

__all__ = ["OdometryConfig"]
