"""Calibration: what a pipeline knows about the device, carried with the frames.

A pipeline receives the calibration in ``reset`` and never sees the simulator. The robot
description is a URDF string generated from the same parameters as the MuJoCo model, so an
estimator can load it with pinocchio (``pinocchio.buildModelFromXML``) and compute forward
kinematics from encoder angles, exactly as the staircase paper does on the real device.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .errors import UnknownNameError


@dataclass(frozen=True, eq=False)
class SensorMount:
    """Where a sensor sits on the robot.

    Attributes:
        sensor_id: unique id, e.g. ``"tof_r_lat"``, ``"imu_trunk"``.
        kind: ``"tof"``, ``"imu"``, ``"rgbd"``, ``"lidar"`` or ``"contact"``.
        parent_link: URDF link the sensor is rigidly attached to.
        T_parent_sensor: 4x4 pose of the sensor frame in the parent link frame. For a ToF
            sensor the beam is the sensor's +z axis (MuJoCo's rangefinder convention); for a
            camera +z is the optical axis, +x right, +y down.
        params: sensor parameters (rate, range limits, noise) as plain numbers, SI units.
    """

    sensor_id: str
    kind: str
    parent_link: str
    T_parent_sensor: np.ndarray
    params: dict[str, Any] = field(default_factory=dict)


@dataclass(frozen=True, eq=False)
class Calibration:
    """Everything about the device that a pipeline may use.

    Attributes:
        robot_urdf: URDF text of the exoskeleton with its user (links and joints only).
        base_link: link whose orientation the trunk IMU reports (the pelvis/trunk).
        joint_names: encoder joint names, in the order of :class:`JointState`.
        mounts: every sensor mount.
        sole_height_m: height of the ankle joint centre above the sole of the foot, m. The
            staircase estimator's frame has its origin on the ground below the stance ankle.
        foot_length_m: foot length, m, and ``heel_to_ankle_m``: heel to ankle distance, m.
        extra: other calibration values (documented where produced).
    """

    robot_urdf: str
    base_link: str
    joint_names: tuple[str, ...]
    mounts: tuple[SensorMount, ...]
    sole_height_m: float
    foot_length_m: float
    heel_to_ankle_m: float
    extra: dict[str, Any] = field(default_factory=dict)

    def mount(self, sensor_id: str) -> SensorMount:
        for m in self.mounts:
            if m.sensor_id == sensor_id:
                return m
        raise UnknownNameError("sensor", sensor_id, [m.sensor_id for m in self.mounts])

    def mounts_of_kind(self, kind: str) -> tuple[SensorMount, ...]:
        return tuple(m for m in self.mounts if m.kind == kind)
