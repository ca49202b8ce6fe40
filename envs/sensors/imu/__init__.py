"""Trunk IMU: :class:`ImuConfig` and :class:`ImuSensor` (AHRS orientation, gyro, accelerometer)."""

from .config import ImuConfig
from .model import ImuSensor, imu_dynamics

__all__ = ["ImuConfig", "ImuSensor", "imu_dynamics"]
