"""Fault injection (exobench.core.faults): what each fault does to each frame kind."""

import numpy as np
import pytest

from exobench.core import ImuSample, LidarScan, RgbdFrame, ToFReading, TofStatus
from exobench.core.faults import inject_faults, no_return, with_nan


def _tof(t, r=0.5):
    return ToFReading(t, "tof_a", r)


def _scan(t):
    n = 5
    return LidarScan(t, "lidar", np.ones((n, 3)), np.arange(n, dtype=np.uint8), np.arange(n), np.zeros(n), t - 0.1)


def test_no_return_per_kind():
    f = no_return(_tof(0.0))
    assert np.isnan(f.range_m) and f.status == TofStatus.NO_TARGET and not f.valid
    s = no_return(_scan(1.0))
    assert s.points_xyz.shape == (0, 3) and len(s.intensity) == len(s.ring) == len(s.time_offset_s) == 0
    d = RgbdFrame(0.0, "cam", np.zeros((2, 3, 3), np.uint8), np.full((2, 3), 1.5, np.float32), np.eye(3))
    assert not no_return(d).depth_m.any() and no_return(d).depth_m.dtype == np.float32
    imu = ImuSample(0.0, "imu", np.array([1.0, 0, 0, 0]), np.zeros(3), np.zeros(3))
    assert no_return(imu) is imu


def test_with_nan_keeps_shapes_and_stamps():
    s = with_nan(_scan(2.0))
    assert s.points_xyz.shape == (5, 3) and np.isnan(s.points_xyz).all() and s.stamp_s == 2.0
    t = with_nan(_tof(1.0))
    assert np.isnan(t.range_m) and t.status == TofStatus.VALID
    with pytest.raises(TypeError):
        with_nan({"stamp_s": 0.0})


def test_inject_faults_marks_each_stream_once_and_drops_one_frame():
    frames = []
    for k in range(8):
        frames += [_tof(0.1 * k), ToFReading(0.1 * k, "tof_b", 0.7)]
    frames.append(ToFReading(0.9, "tof_short", 0.3))  # a stream of one frame is left alone
    out = inject_faults(frames)
    assert len(out) == len(frames) - 2  # one dropped per stream of >= 4 frames
    for sid in ("tof_a", "tof_b"):
        stream = [f for f in out if f.sensor_id == sid]
        assert len(stream) == 7
        assert sum(f.status == TofStatus.NO_TARGET for f in stream) == 1
        assert sum(f.status == TofStatus.VALID and np.isnan(f.range_m) for f in stream) == 1
        assert [f.stamp_s for f in stream] == sorted(f.stamp_s for f in stream)
    assert out[-1].sensor_id == "tof_short" and out[-1].range_m == 0.3
    again = inject_faults(frames)  # deterministic: the same frames faulted and dropped
    assert [(f.sensor_id, f.stamp_s, f.status) for f in again] == [(f.sensor_id, f.stamp_s, f.status) for f in out]
