"""The counter vocabulary (exobench.core.counters): what each rule counts, on hand-made streams."""

import math

import numpy as np
import pytest

from exobench.core import (
    Calibration,
    ContactSample,
    ImuSample,
    JointState,
    LidarScan,
    OdometrySample,
    RgbdFrame,
    SensorMount,
    ToFReading,
    TofStatus,
)
from exobench.core.counters import (
    COUNTERS,
    FrameCounts,
    StreamCounters,
    admitted,
    count_metrics,
    nan_values,
    stream_rates,
)
from exobench.core.faults import STREAM_FAULTS, inject_stream_faults
from exobench.core.limits import MAX_FORCE_N, contact_absurd, odometry_absurd


def _tof(t, sid="tof_a", r=0.5, status=TofStatus.VALID):
    return ToFReading(t, sid, r, status)


def _scan(stamp, start, n=4, sid="lidar"):
    return LidarScan(stamp, sid, np.ones((n, 3)), np.zeros(n, np.uint8), np.zeros(n, int), np.zeros(n), start)


def test_repeated_and_out_of_order_frames_are_counted_and_refused_per_stream():
    c = StreamCounters()
    stamps = [0.0, 0.1, 0.1, 0.2, 0.15, 0.3, math.nan, 0.3, 0.4]
    use = [c.admit(_tof(t)) is not None for t in stamps]
    # same instant as the last: repeated; older than the last (or no time): out of order; the
    # stream goes on from the newest instant used (0.3 after 0.15 was refused)
    assert use == [True, True, False, True, False, True, False, False, True]
    # another sensor of the same kind is its own stream: 0.1 after tof_a's 0.4 is in order
    assert c.admit(_tof(0.1, "tof_b")) is not None
    counts = c.snapshot()["tof"]
    assert (counts.seen, counts.repeated, counts.out_of_order, counts.ignored) == (10, 2, 2, 0)
    assert counts.sensors == ("tof_a", "tof_b")
    assert c.admit(_tof(0.5, "tof_c"), consumed=False) is None
    after = c.snapshot()["tof"]
    assert (after.seen, after.ignored, after.sensors) == (11, 1, ("tof_a", "tof_b"))  # ignored: not read


def test_content_does_not_make_a_repeat_new():
    c = StreamCounters()
    assert c.admit(_tof(0.2, r=0.5)) is not None
    assert c.admit(_tof(0.2, r=0.9)) is None  # another range at the same instant: still a repeat
    assert c.snapshot()["tof"].repeated == 1


def test_a_lidar_sweep_is_ordered_by_its_start():
    c = StreamCounters()
    assert c.admit(_scan(0.2, 0.0)) is not None
    assert c.admit(_scan(0.3, 0.1)) is not None
    # delivered after the sweep that started at 0.1, with a later stamp, but started before it
    assert c.admit(_scan(0.35, 0.05)) is None
    assert c.admit(_scan(0.3, 0.1)) is None  # the same sweep again
    lidar = c.snapshot()["lidar"]
    assert (lidar.out_of_order, lidar.repeated) == (1, 1)


def test_gaps_count_dropped_frames_only_where_the_rate_is_known():
    c = StreamCounters({"tof_a": 50.0})
    # 50 Hz: 0.02 s apart; 0.04 -> 0.10 misses 0.06 and 0.08; 0.10 -> 0.13 is within 1.5 periods
    for t in (0.0, 0.02, 0.04, 0.10, 0.13, 0.17):
        c.admit(_tof(t))
        c.admit(_tof(t, "tof_b"))  # no rate: never counted
    counts = c.snapshot()["tof"]
    assert counts.dropped == 2 + 1  # 0.13 -> 0.17 is two periods: one frame lost


def test_stream_rates_from_the_calibration():
    mounts = (SensorMount("tof_a", "tof", "shank", np.eye(4), {"rate_hz": 50.0}),
              SensorMount("cam", "rgbd", "head", np.eye(4), {"rate_hz": "bad"}),
              SensorMount("imu", "imu", "trunk", np.eye(4), {}))  # fmt: skip
    cal = Calibration("", "trunk", (), mounts, 0.1, 0.26, 0.05, {"encoders": {"rate_hz": 200.0}})
    assert stream_rates(cal) == {"tof_a": 50.0, "encoders": 200.0}
    assert stream_rates(None) == {}


def test_frame_counts_add_values_and_frames():
    c = FrameCounts()
    c.add_nan(0)
    c.add_nan(7)
    c.add_absurd()
    c.add_absurd(3)
    assert (c.nan, c.nan_values, c.absurd, c.absurd_values) == (1, 7, 2, 4)
    assert list(c.as_dict()) == list(COUNTERS)


def test_judge_counts_a_whole_frame_used_nan_or_absurd():
    c = FrameCounts()
    good, nan = _tof(0.0), _tof(0.1, r=math.nan)
    assert c.judge(good, False) is True
    assert c.judge(nan, True) is False  # bad and holding a NaN: counted NaN
    assert c.judge(good, True) is False  # bad with finite values: counted absurd
    assert (c.used, c.nan, c.nan_values, c.absurd, c.absurd_values) == (1, 1, 1, 1, 1)


def test_count_metrics_are_flat_and_cover_every_streamed_kind():
    counts = {"tof": FrameCounts(seen=5, used=3, repeated=2)}
    m = count_metrics(counts, ("tof", "imu"))
    assert set(m) == {f"frames.{k}.{c}" for k in ("tof", "imu") for c in COUNTERS}
    assert (m["frames.tof.seen"], m["frames.tof.used"], m["frames.tof.repeated"], m["frames.imu.seen"]) == (5, 3, 2, 0)
    assert all(type(v) is int for v in m.values())


def test_nan_values_per_kind():
    assert nan_values(_tof(0.0, r=math.nan)) == 1
    assert nan_values(_tof(0.0, r=math.nan, status=TofStatus.NO_TARGET)) == 0  # no target is a measurement
    p = np.ones((5, 3))
    p[1, 2] = np.nan
    p[3] = np.inf
    assert nan_values(LidarScan(0.1, "l", p, np.zeros(5), np.zeros(5, int), np.zeros(5), 0.0)) == 2
    depth = np.ones((2, 3), np.float32)
    depth[0, :2] = np.nan
    assert nan_values(RgbdFrame(0.0, "cam", np.zeros((2, 3, 3), np.uint8), depth, np.eye(3))) == 2
    imu = ImuSample(0.0, "imu", np.array([1.0, 0, 0, 0]), np.array([0.0, np.nan, 0.0]), np.zeros(3))
    assert nan_values(imu) == 1
    assert nan_values(JointState(0.0, "encoders", ("a",), np.array([0.1]))) == 0
    assert nan_values(ContactSample(0.0, "contact_l_heel", math.nan, False)) == 1
    odo = OdometrySample(0.0, "odom", np.eye(4), np.array([0.0, 0.0, np.nan]))
    assert nan_values(odo) == 1


def test_absurd_contact_and_odometry():
    assert contact_absurd(ContactSample(0.0, "c", -1.0, False)) and contact_absurd(ContactSample(0.0, "c", 2 * MAX_FORCE_N, True))
    assert not contact_absurd(ContactSample(0.0, "c", 700.0, True)) and not contact_absurd(ContactSample(0.0, "c", math.nan, True))
    T = np.eye(4)
    T[1, 3] = 2e4
    assert odometry_absurd(OdometrySample(0.0, "o", T, np.zeros(3)))
    T[1, 3] = np.nan  # NaN is NaN, not absurd
    assert not odometry_absurd(OdometrySample(0.0, "o", T, np.zeros(3)))
    assert not odometry_absurd(OdometrySample(0.0, "o", np.eye(4), np.zeros(3)))


def test_inject_stream_faults_puts_one_of_each_in_every_long_stream():
    frames = [f for k in range(20) for f in (_tof(0.02 * k), _tof(0.02 * k, "tof_b"))] + [_tof(0.5, "tof_short")]
    faulty, injected = inject_stream_faults(frames)
    assert set(injected) == {"tof_a", "tof_b"}
    assert all(list(v) == list(STREAM_FAULTS) and all(len(fs) == 1 for fs in v.values()) for v in injected.values())
    assert injected["tof_a"]["repeated"][0] is not frames[26] and injected["tof_a"]["repeated"][0].stamp_s == frames[26].stamp_s
    a = [f for f in faulty if f.sensor_id == "tof_a"]
    stamps = [round(f.stamp_s / 0.02) for f in a]
    # index 2 removed, 17 after 18, 13 twice; 5 NaN, 9 absurd
    assert stamps == [0, 1, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 13, 14, 15, 16, 18, 17, 19]
    assert math.isnan(a[4].range_m) and a[8].range_m > 1e300
    c = StreamCounters({"tof_a": 50.0})
    for f in faulty:
        got = c.admit(f, consumed=f.sensor_id == "tof_a")
        if got is not None:
            got.add_nan(nan_values(f))
            got.add_absurd(int(f.range_m > 1e300))
    tof = c.snapshot()["tof"]
    assert (tof.repeated, tof.out_of_order, tof.nan, tof.absurd, tof.dropped) == (1, 1, 1, 1, 2)
    assert tof.ignored == 20 + 1  # tof_b (as many frames as it began with) and tof_short


def test_admitted_is_the_same_rule_offline():
    frames = [_scan(0.2, 0.1), _scan(0.2, 0.1), _scan(0.3, 0.2), _scan(0.25, 0.15), _scan(0.4, 0.3)]
    assert admitted(frames) == [True, False, True, False, True]


@pytest.mark.parametrize("bad", [math.inf, -math.inf, "0.1s"])
def test_infinite_time_is_out_of_order(bad):
    c = StreamCounters()
    assert c.admit(_tof(bad)) is None and c.snapshot()["tof"].out_of_order == 1
