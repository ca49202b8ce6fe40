"""Faulty sensor data on demand: frames with no return, with NaN, and streams with gaps.

Real logs contain what a simulation rarely does: a ToF that sees nothing, a LiDAR sweep that
came back empty, a depth image of zeros, a driver that wrote NaN, a frame that never arrived.
These functions make such frames from good ones, so that tests (and users checking their own
pipelines) can feed every pipeline the faults it must survive and count. They change values
only: stamps, sensor ids and array shapes stay as they were, except an empty sweep.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import replace

import numpy as np

from .frames import (
    ContactSample,
    Frame,
    ImuSample,
    JointState,
    LidarScan,
    OdometrySample,
    RgbdFrame,
    ToFReading,
    TofStatus,
)


def _nan_like(a: np.ndarray) -> np.ndarray:
    return np.full(np.shape(a), np.nan, dtype=np.result_type(np.asarray(a).dtype, np.float32))


def _empty_scan(f: LidarScan) -> LidarScan:
    return replace(
        f,
        points_xyz=np.zeros((0, 3)),
        intensity=np.zeros(0, dtype=np.asarray(f.intensity).dtype),
        ring=np.zeros(0, dtype=np.asarray(f.ring).dtype),
        time_offset_s=np.zeros(0),
    )


# frame type -> the same frame as the sensor reports when it measured nothing
_NO_RETURN: dict[type, Callable[[Frame], Frame]] = {
    ToFReading: lambda f: replace(f, range_m=float("nan"), status=int(TofStatus.NO_TARGET)),
    LidarScan: _empty_scan,
    RgbdFrame: lambda f: replace(f, depth_m=np.zeros_like(f.depth_m)),
}

# frame type -> the same frame with NaN wherever it carries a measured number
_NAN: dict[type, Callable[[Frame], Frame]] = {
    ToFReading: lambda f: replace(f, range_m=float("nan"), status=int(TofStatus.VALID)),
    ImuSample: lambda f: replace(
        f, quat_wxyz=_nan_like(f.quat_wxyz), gyro_rad_s=_nan_like(f.gyro_rad_s), accel_m_s2=_nan_like(f.accel_m_s2)
    ),
    JointState: lambda f: replace(f, position_rad=_nan_like(f.position_rad)),
    ContactSample: lambda f: replace(f, force_n=float("nan")),
    LidarScan: lambda f: replace(f, points_xyz=_nan_like(f.points_xyz)),
    RgbdFrame: lambda f: replace(f, depth_m=_nan_like(f.depth_m).astype(np.asarray(f.depth_m).dtype)),
    OdometrySample: lambda f: replace(f, T_odom_body=_nan_like(f.T_odom_body), v_odom_m_s=_nan_like(f.v_odom_m_s)),
}


def no_return(frame: Frame) -> Frame:
    """The frame as its sensor reports a measurement that found nothing (ToF: NaN range with
    status NO_TARGET; LiDAR: an empty sweep; RGB-D: depth 0 everywhere, the invalid value).
    Sensors without such a state (IMU, encoders, contacts, odometry) are returned unchanged."""
    fn = _NO_RETURN.get(type(frame))
    return frame if fn is None else fn(frame)


def with_nan(frame: Frame) -> Frame:
    """The frame with NaN in every measured value (a faulty driver), shapes kept."""
    fn = _NAN.get(type(frame))
    if fn is None:
        raise TypeError(f"not an exobench frame: {type(frame).__name__}")
    return fn(frame)


def inject_faults(frames: Sequence[Frame], at: tuple[float, float, float] = (0.25, 0.5, 0.75)) -> tuple[Frame, ...]:
    """Every sensor stream of ``frames`` with three faults: at the fractions ``at`` of each
    stream's length, one frame with no return, one with NaN, and one dropped. Deterministic;
    a stream of fewer than four frames is left as it is. Time order is kept."""
    by_sensor: dict[str, list[int]] = {}
    for i, f in enumerate(frames):
        by_sensor.setdefault(f.sensor_id, []).append(i)
    replaced: dict[int, Frame | None] = {}
    for idx in by_sensor.values():
        if len(idx) < 4:
            continue
        k_none, k_nan, k_drop = (idx[min(len(idx) - 1, int(a * len(idx)))] for a in at)
        replaced[k_none] = no_return(frames[k_none])
        replaced[k_nan] = with_nan(frames[k_nan])
        replaced[k_drop] = None
    out = (replaced.get(i, f) for i, f in enumerate(frames))
    return tuple(f for f in out if f is not None)
