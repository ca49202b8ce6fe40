"""Simulated sensors of the exoskeleton: configs and models in one place.

- :class:`ToFConfig` / :class:`ToFSensor`: calf VL53L1X ranging by MuJoCo ray casting.
- :class:`ImuConfig` / :class:`ImuSensor`: trunk IMU (AHRS quaternion, gyro, accelerometer).
- :class:`EncoderConfig` / :class:`EncoderSensor`: leg joint encoders.
- :class:`ContactConfig` / :class:`ContactSensor`: heel/toe insole pads.

Every model draws from its own generators (:func:`sensor_rngs`, keyed by
:func:`stable_int_key` of the sensor id); frames carry the delivery time (measurement time plus
latency) and dropped frames are absent. :func:`exobench.envs.sim.record` runs them on a motion.
"""

from .imu import ImuSensor, imu_dynamics
from .proprio import ENCODER_ID, ContactSensor, EncoderSensor, contact_forces
from .sensor_config import (
    ContactConfig,
    EncoderConfig,
    ImuConfig,
    SensorsConfig,
    ToFConfig,
    sample_times,
    sensor_rngs,
    stable_int_key,
)
from .tof import ToFSensor, cone_directions

__all__ = [
    "ENCODER_ID",
    "ContactConfig",
    "ContactSensor",
    "EncoderConfig",
    "EncoderSensor",
    "ImuConfig",
    "ImuSensor",
    "SensorsConfig",
    "ToFConfig",
    "ToFSensor",
    "contact_forces",
    "cone_directions",
    "imu_dynamics",
    "sample_times",
    "sensor_rngs",
    "stable_int_key",
]
