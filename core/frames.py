"""Sensor frames: what a pipeline receives, live or from a recorded session.

Each frame is a frozen dataclass with a time stamp ``stamp_s`` (seconds since the start of the
episode, on the exoskeleton's clock: the time the measurement was *delivered*, latency included)
and the ``sensor_id`` of the mount that produced it (see :class:`exobench.core.calibration`).
A dropped frame is simply absent from the stream. Ground truth is never part of a frame.

What else a kind is (its fault forms, NaN and absurd-value rules) is its record in
:mod:`exobench.core.frame_kinds`; the table of kinds, :data:`~exobench.core.kinds.KINDS`
(``FRAME_TYPES``, ``frame_kind``), is :mod:`exobench.core.kinds`.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import IntEnum

import numpy as np


class TofStatus(IntEnum):
    """Range status codes of the ST VL53L1X ULD API (the subset exobench emits)."""

    VALID = 0
    SIGMA_FAIL = 1
    SIGNAL_FAIL = 2
    OUT_OF_BOUNDS = 4
    WRAP_AROUND = 7
    NO_TARGET = 255


@dataclass(frozen=True, eq=False)
class ToFReading:
    """One single-beam time-of-flight range.

    Attributes:
        stamp_s: delivery time, s.
        sensor_id: mount id, e.g. ``"tof_r_lat"``.
        range_m: measured distance along the beam (sensor +z axis), m; NaN when there is no
            valid target (then ``status`` is not VALID).
        status: a :class:`TofStatus` code.
    """

    stamp_s: float
    sensor_id: str
    range_m: float
    status: int = TofStatus.VALID

    @property
    def valid(self) -> bool:
        return self.status == TofStatus.VALID and bool(np.isfinite(self.range_m))


@dataclass(frozen=True, eq=False)
class ImuSample:
    """One IMU sample in the IMU's own frame.

    Attributes:
        stamp_s: delivery time, s.
        sensor_id: mount id, e.g. ``"imu_trunk"``.
        quat_wxyz: orientation estimate of the IMU frame in a gravity-aligned world frame
            (``R_world_imu``), as an AHRS would report it; shape (4,).
        gyro_rad_s: angular velocity in the IMU frame, rad/s; shape (3,).
        accel_m_s2: specific force in the IMU frame (gravity included, +9.81 up at rest),
            m/s^2; shape (3,).
    """

    stamp_s: float
    sensor_id: str
    quat_wxyz: np.ndarray
    gyro_rad_s: np.ndarray
    accel_m_s2: np.ndarray


@dataclass(frozen=True, eq=False)
class JointState:
    """Joint encoder readings.

    Attributes:
        stamp_s: delivery time, s.
        sensor_id: ``"encoders"``.
        names: joint names, as in the robot description.
        position_rad: measured joint angles, rad; shape (len(names),).
    """

    stamp_s: float
    sensor_id: str
    names: tuple[str, ...]
    position_rad: np.ndarray

    def as_dict(self) -> dict[str, float]:
        return {n: float(v) for n, v in zip(self.names, self.position_rad)}


@dataclass(frozen=True, eq=False)
class ContactSample:
    """Force under one foot region (heel or toe pad of an insole).

    Attributes:
        stamp_s: delivery time, s.
        sensor_id: e.g. ``"contact_r_heel"``.
        force_n: normal force, N (>= 0).
        in_contact: force above the contact threshold.
    """

    stamp_s: float
    sensor_id: str
    force_n: float
    in_contact: bool


@dataclass(frozen=True, eq=False)
class LidarScan:
    """One LiDAR sweep, points in the sensor frame at their own firing time (not deskewed).

    Attributes:
        stamp_s: delivery time of the sweep, s (end of the sweep plus latency).
        sensor_id: mount id, e.g. ``"lidar_trunk"``.
        points_xyz: returns in the sensor frame (x forward, y left, z up), m; shape (N, 3).
        intensity: calibrated reflectivity byte 0-255 (0-100 diffuse, 101-255 retro), (N,).
        ring: laser channel index, (N,) int.
        time_offset_s: firing time of each point relative to the start of the sweep, s, (N,).
        sweep_start_s: time the sweep started, s.
    """

    stamp_s: float
    sensor_id: str
    points_xyz: np.ndarray
    intensity: np.ndarray
    ring: np.ndarray
    time_offset_s: np.ndarray
    sweep_start_s: float


@dataclass(frozen=True, eq=False)
class RgbdFrame:
    """One RGB-D image pair, registered to the depth camera's optical frame.

    Attributes:
        stamp_s: delivery time, s.
        sensor_id: mount id, e.g. ``"rgbd_head"``.
        rgb: colour image, (H, W, 3) uint8.
        depth_m: depth along the optical axis (z), float32 metres, (H, W); 0 where invalid.
        K: 3x3 pinhole intrinsics of both images (pixels).
    """

    stamp_s: float
    sensor_id: str
    rgb: np.ndarray
    depth_m: np.ndarray
    K: np.ndarray


@dataclass(frozen=True, eq=False)
class OdometrySample:
    """One pose from an odometry source (e.g. a visual-inertial odometry running on the device).

    The pose is in the odometry's own gravity-aligned world frame ``odom`` (z up), which may drift
    away from the true world; pipelines must not assume it equals the truth.

    Attributes:
        stamp_s: time the pose refers to, s.
        sensor_id: the tracked body, e.g. ``"odom_head"`` (a camera/IMU body).
        T_odom_body: 4x4 pose of the tracked body in the odometry frame.
        v_odom_m_s: linear velocity of the body's origin in the odometry frame, m/s, (3,).
    """

    stamp_s: float
    sensor_id: str
    T_odom_body: np.ndarray
    v_odom_m_s: np.ndarray


@dataclass(frozen=True, eq=False)
class SessionStart:
    """The start of one session of a multi-session episode (one building over several days):
    every frame after it, up to the next mark, belongs to this session. Stamps keep increasing
    across sessions; one calibration serves them all.

    Attributes:
        stamp_s: time of the mark, s (before the session's first frame).
        sensor_id: ``"session"``.
        session: session id, 0, 1, ... in episode order.
        day: the day the building stands as (0 = as furnished; several sessions may share one).
    """

    stamp_s: float
    sensor_id: str
    session: int
    day: int


@dataclass(frozen=True, eq=False)
class PlaceLabel:
    """The type of place the walker is in (``"corridor"``, ``"office"``, ``"meeting"``, ...), as a
    user or a room classifier gives it; it holds from its stamp until the next label. It may be
    wrong (:func:`exobench.core.faults.swap_place_labels`).

    Attributes:
        stamp_s: time the label was given, s.
        sensor_id: ``"place_label"``.
        label: the place type; ``""`` when none was given.
    """

    stamp_s: float
    sensor_id: str
    label: str


Frame = ToFReading | ImuSample | JointState | ContactSample | LidarScan | RgbdFrame | OdometrySample | SessionStart | PlaceLabel
