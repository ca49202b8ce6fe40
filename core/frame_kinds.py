"""The shipped frame kinds, one :class:`~exobench.core.kinds.FrameKind` record each.

Per kind: its frames with no return, with NaN and with absurd values (what
:mod:`exobench.core.faults` injects), how many NaN values a frame holds (what
:mod:`exobench.core.counters` counts) and its absurd-value rule (the limits of
:mod:`exobench.core.limits`, read from the calibration). The last lines register them; a new
kind writes the same parts in its own frame module and registers with one line.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import replace
from typing import Any

import numpy as np

from .calibration import Calibration, SensorMount
from .frames import (
    ContactSample,
    ImuSample,
    JointState,
    LidarScan,
    OdometrySample,
    PlaceLabel,
    RgbdFrame,
    SessionStart,
    ToFReading,
    TofStatus,
)
from .kinds import FrameKind, nan_in, nan_like, register_kind
from .limits import (
    JointLimits,
    RangeLimits,
    absurd_depth,
    contact_absurd,
    finite_rows,
    imu_absurd,
    max_depth_m,
    odometry_absurd,
)

# the absurd values the absurd forms write (see :mod:`exobench.core.limits` for what is absurd)
ABSURD_RANGES_M = (1e308, 0.0, 1e6)
ABSURD_POINT_M = 1e6
ABSURD_DEPTH_M = 1e6
ABSURD_VALUE = 1e308


def _mount(calibration: Calibration | None, sensor_id: str) -> SensorMount | None:
    if calibration is None:
        return None
    return next((m for m in calibration.mounts if m.sensor_id == sensor_id), None)


def per_mount(
    calibration: Calibration | None, limits: Callable[[SensorMount | None], Any]
) -> Callable[[str], Any]:
    """``sensor_id -> limits(mount)``, each mount's limits computed once (None: no such mount)."""
    cache: dict[str, Any] = {}

    def of(sensor_id: str) -> Any:
        if sensor_id not in cache:
            cache[sensor_id] = limits(_mount(calibration, sensor_id))
        return cache[sensor_id]

    return of


def _guard(count: Callable[[Any], int]) -> Callable[[Any], int]:
    """A counter that counts 0 for values that are not numbers (a frame holding a string)."""

    def guarded(frame: Any) -> int:
        try:
            return count(frame)
        except (TypeError, ValueError):
            return 0

    return guarded


# --- ToF -------------------------------------------------------------------------------------------
def _tof_absurd(f: ToFReading, variant: int) -> ToFReading:
    return replace(f, range_m=ABSURD_RANGES_M[variant % len(ABSURD_RANGES_M)], status=int(TofStatus.VALID))


def _tof_nan_values(f: ToFReading) -> int:
    return int(f.status == TofStatus.VALID and not math.isfinite(float(f.range_m)))


def _tof_rule(calibration: Calibration | None) -> Callable[[ToFReading], int]:
    limits = per_mount(calibration, RangeLimits.of_mount)
    return _guard(lambda f: int(f.status == TofStatus.VALID and limits(f.sensor_id).absurd(float(f.range_m))))


# --- IMU -------------------------------------------------------------------------------------------
def _imu_absurd(f: ImuSample, variant: int) -> ImuSample:
    big = ABSURD_VALUE
    return replace(f, quat_wxyz=np.full(4, big), gyro_rad_s=np.full(3, big), accel_m_s2=np.full(3, big))


_imu_nan_values = nan_in("quat_wxyz", "gyro_rad_s", "accel_m_s2")


def _imu_rule(calibration: Calibration | None) -> Callable[[ImuSample], int]:
    return _guard(lambda f: int(not _imu_nan_values(f) and imu_absurd(f)))  # imu_absurd also flags NaN


# --- joints (encoders) -------------------------------------------------------------------------
def _joints_absurd(f: JointState, variant: int) -> JointState:
    return replace(f, position_rad=np.full(np.shape(f.position_rad), ABSURD_VALUE))


_joints_nan_values = nan_in("position_rad")


def _joints_rule(calibration: Calibration | None) -> Callable[[JointState], int]:
    limits = JointLimits(calibration)
    return _guard(lambda f: int(not _joints_nan_values(f) and limits.absurd(f)))


# --- contact -------------------------------------------------------------------------------------
def _contact_nan_values(f: ContactSample) -> int:
    return int(not math.isfinite(float(f.force_n)))


def _contact_rule(calibration: Calibration | None) -> Callable[[ContactSample], int]:
    return _guard(lambda f: int(contact_absurd(f)))


# --- LiDAR ----------------------------------------------------------------------------------------
def _empty_scan(f: LidarScan) -> LidarScan:
    return replace(
        f,
        points_xyz=np.zeros((0, 3)),
        intensity=np.zeros(0, dtype=np.asarray(f.intensity).dtype),
        ring=np.zeros(0, dtype=np.asarray(f.ring).dtype),
        time_offset_s=np.zeros(0),
    )


def _lidar_absurd(f: LidarScan, variant: int) -> LidarScan:
    """Every other point absurd, alternately at 1e6 m along its ray and at the origin."""
    p = np.array(f.points_xyz, dtype=float).reshape(-1, 3)
    n = len(p)
    far, origin = np.arange(0, n, 4), np.arange(2, n, 4)
    with np.errstate(invalid="ignore", divide="ignore"):
        r = np.linalg.norm(p[far], axis=1, keepdims=True)
        u = np.where(r > 0, p[far] / np.where(r > 0, r, 1.0), np.array([1.0, 0.0, 0.0]))
    p[far] = ABSURD_POINT_M * u
    p[origin] = 0.0
    return replace(f, points_xyz=p)


def _lidar_nan_values(f: LidarScan) -> int:
    ok = finite_rows(f.points_xyz)
    return len(ok) - int(np.count_nonzero(ok))


def _lidar_rule(calibration: Calibration | None) -> Callable[[LidarScan], int]:
    limits = per_mount(calibration, RangeLimits.of_mount)
    return _guard(lambda f: int(np.count_nonzero(limits(f.sensor_id).absurd_points(f.points_xyz))))


# --- RGB-D ----------------------------------------------------------------------------------------
def _rgbd_nan_values(f: RgbdFrame) -> int:
    return int(np.count_nonzero(~np.isfinite(np.asarray(f.depth_m, dtype=float))))


def _rgbd_rule(calibration: Calibration | None) -> Callable[[RgbdFrame], int]:
    high = per_mount(calibration, max_depth_m)
    return _guard(lambda f: int(np.count_nonzero(absurd_depth(f.depth_m, high(f.sensor_id)))))


# --- odometry ------------------------------------------------------------------------------------
def _odometry_absurd(f: OdometrySample, variant: int) -> OdometrySample:
    T = np.array(f.T_odom_body, dtype=float)
    T[:3, 3] = ABSURD_VALUE
    return replace(f, T_odom_body=T)


_odometry_nan_values = nan_in("T_odom_body", "v_odom_m_s")


def _odometry_rule(calibration: Calibration | None) -> Callable[[OdometrySample], int]:
    return _guard(lambda f: int(odometry_absurd(f)))


# --- episode marks: session starts and place labels ----------------------------------------------
# A faulty driver writes NaN where the session, day or label should be (one value per frame, as
# the other scalar kinds count); absurd is what no session or building can be: a negative
# session or day, a label that is a number.
def _isnan(v: Any) -> bool:
    return isinstance(v, float) and math.isnan(v)


def _session_nan_values(f: SessionStart) -> int:
    return int(_isnan(f.session) or _isnan(f.day))


def _session_rule(calibration: Calibration | None) -> Callable[[SessionStart], int]:
    return _guard(lambda f: int(not _session_nan_values(f) and (float(f.session) < 0 or float(f.day) < 0)))


def _label_rule(calibration: Calibration | None) -> Callable[[PlaceLabel], int]:
    return lambda f: int(not isinstance(f.label, str) and not _isnan(f.label))


TOF = FrameKind(
    "tof", ToFReading,
    nan=lambda f: replace(f, range_m=float("nan"), status=int(TofStatus.VALID)),
    nan_values=_guard(_tof_nan_values), absurd=_tof_absurd, absurd_values=_tof_rule,
    no_return=lambda f: replace(f, range_m=float("nan"), status=int(TofStatus.NO_TARGET)),
)  # fmt: skip
IMU = FrameKind(
    "imu", ImuSample,
    nan=lambda f: replace(f, quat_wxyz=nan_like(f.quat_wxyz), gyro_rad_s=nan_like(f.gyro_rad_s), accel_m_s2=nan_like(f.accel_m_s2)),
    nan_values=_guard(_imu_nan_values), absurd=_imu_absurd, absurd_values=_imu_rule,
)  # fmt: skip
JOINTS = FrameKind(
    "joints", JointState, nan=lambda f: replace(f, position_rad=nan_like(f.position_rad)),
    nan_values=_guard(_joints_nan_values), absurd=_joints_absurd, absurd_values=_joints_rule,
)  # fmt: skip
CONTACT = FrameKind(
    "contact", ContactSample, nan=lambda f: replace(f, force_n=float("nan")),
    nan_values=_guard(_contact_nan_values), absurd=lambda f, variant: replace(f, force_n=ABSURD_VALUE),
    absurd_values=_contact_rule,
)  # fmt: skip
LIDAR = FrameKind(
    "lidar", LidarScan, nan=lambda f: replace(f, points_xyz=nan_like(f.points_xyz)),
    nan_values=_guard(_lidar_nan_values), absurd=_lidar_absurd, absurd_values=_lidar_rule,
    no_return=_empty_scan, measured="sweep_start_s",
)  # fmt: skip
RGBD = FrameKind(
    "rgbd", RgbdFrame, nan=lambda f: replace(f, depth_m=nan_like(f.depth_m).astype(np.asarray(f.depth_m).dtype)),
    nan_values=_guard(_rgbd_nan_values), absurd=lambda f, variant: replace(f, depth_m=np.full_like(f.depth_m, ABSURD_DEPTH_M)),
    absurd_values=_rgbd_rule, no_return=lambda f: replace(f, depth_m=np.zeros_like(f.depth_m)),
)  # fmt: skip
ODOMETRY = FrameKind(
    "odometry", OdometrySample, nan=lambda f: replace(f, T_odom_body=nan_like(f.T_odom_body), v_odom_m_s=nan_like(f.v_odom_m_s)),
    nan_values=_guard(_odometry_nan_values), absurd=_odometry_absurd, absurd_values=_odometry_rule,
)  # fmt: skip

SESSION = FrameKind(
    "session", SessionStart, nan=lambda f: replace(f, session=float("nan"), day=float("nan")),
    nan_values=_guard(_session_nan_values), absurd=lambda f, variant: replace(f, session=-1, day=-1),
    absurd_values=_session_rule,
)  # fmt: skip
PLACE_LABEL = FrameKind(
    "place_label", PlaceLabel, nan=lambda f: replace(f, label=float("nan")), nan_values=lambda f: int(_isnan(f.label)),
    absurd=lambda f, variant: replace(f, label=ABSURD_VALUE), absurd_values=_label_rule,
    no_return=lambda f: replace(f, label=""),
)  # fmt: skip

# the table of shipped kinds: one line each (the order is that of the counters in a record)
register_kind(TOF)
register_kind(IMU)
register_kind(JOINTS)
register_kind(CONTACT)
register_kind(LIDAR)
register_kind(RGBD)
register_kind(ODOMETRY)
register_kind(SESSION)
register_kind(PLACE_LABEL)
