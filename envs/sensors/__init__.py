"""Simulated sensors of the exoskeleton, one sub-package per kind: its config (units, frames,
rate, latency, noise, dropout, sources) and its model. Each kind's frame type is in
:mod:`exobench.core.frames`.

- :mod:`.tof`: :class:`ToFConfig` / :class:`ToFSensor`, calf VL53L1X ranging by ray casting.
- :mod:`.imu`: :class:`ImuConfig` / :class:`ImuSensor`, trunk IMU (AHRS quaternion, gyro, accelerometer).
- :mod:`.encoders`: :class:`EncoderConfig` / :class:`EncoderSensor`, leg joint encoders.
- :mod:`.contact`: :class:`ContactConfig` / :class:`ContactSensor`, heel/toe insole pads.
- :mod:`.rgbd`: :class:`RgbdConfig` / :class:`RgbdCamera`, rendered RealSense D455 colour and depth.
- :mod:`.lidar`: :class:`LidarConfig` / :class:`LidarSensor`, scanning LiDAR with per-point truth.

Every model draws from its own generators (:func:`sensor_rngs`, keyed by :func:`stable_int_key`
of the sensor id); frames carry the delivery time (measurement time plus latency) and dropped
frames are absent (:mod:`.common`). :class:`SensorsConfig` groups the scalar streams mounted
together. Each kind plugs into the simulation core (:mod:`exobench.envs.sim`) through its
``adapter`` module (:mod:`.adapter` says what an adapter is; :mod:`.kinds` lists them); the
camera odometry (:mod:`.odometry`) is a kind too.
"""

from .common import EXO_GROUP, WORLD_GROUP, check_timing, sample_times, sensor_rngs, stable_int_key
from .contact import ContactConfig, ContactSensor, contact_forces
from .encoders import ENCODER_ID, EncoderConfig, EncoderSensor
from .imu import ImuConfig, ImuSensor, imu_dynamics
from .lidar import LidarConfig, LidarPattern, LidarSensor
from .rgbd import RgbdCamera, RgbdConfig
from .rig import SensorsConfig
from .tof import ToFConfig, ToFSensor, cone_directions

__all__ = [
    "ENCODER_ID",
    "EXO_GROUP",
    "WORLD_GROUP",
    "ContactConfig",
    "ContactSensor",
    "EncoderConfig",
    "EncoderSensor",
    "ImuConfig",
    "ImuSensor",
    "LidarConfig",
    "LidarPattern",
    "LidarSensor",
    "RgbdCamera",
    "RgbdConfig",
    "SensorsConfig",
    "ToFConfig",
    "ToFSensor",
    "check_timing",
    "contact_forces",
    "cone_directions",
    "imu_dynamics",
    "sample_times",
    "sensor_rngs",
    "stable_int_key",
]
