"""What counts as absurd (exobench.core.limits) and the absurd frames of exobench.core.faults."""

import math

import numpy as np

from exobench.core import Calibration, ImuSample, JointState, LidarScan, RgbdFrame, SensorMount, ToFReading
from exobench.core.faults import absurd, inject_absurd, n_absurd_points
from exobench.core.limits import (
    JointLimits,
    RangeLimits,
    absurd_depth,
    finite_rows,
    imu_absurd,
    max_depth_m,
    scrub_points,
    urdf_joint_limits,
)

TOF = SensorMount("tof_a", "tof", "shank", np.eye(4),
                  {"min_range_m": 0.04, "max_range_m": 4.0, "noise_sigma_m": 0.005, "resolution_m": 0.001})
URDF = """<robot name="r"><link name="a"/><link name="b"/>
<joint name="knee" type="revolute"><parent link="a"/><child link="b"/>
<limit lower="-2.0" upper="0.1" effort="1" velocity="1"/></joint></robot>"""


def test_finite_rows_marks_every_row_with_a_non_finite_value():
    bad = (math.nan, math.inf, -math.inf)
    rows = [[1.0, 2.0, 3.0], [1e308, -1e308, 0.0]] + [[v if i == c else 0.5 for i in range(3)] for c in range(3) for v in bad]
    expected = [True, True] + [False] * 9
    assert finite_rows(np.array(rows)).tolist() == expected
    assert finite_rows(np.array(rows[2:], dtype=np.float32)).tolist() == expected[2:]
    assert finite_rows(np.zeros((0, 3))).shape == (0,)


def test_range_limits_from_the_mount():
    lim = RangeLimits.of_mount(TOF)
    assert math.isclose(lim.low_m, 0.009) and math.isclose(lim.high_m, 4.031)
    for r in (1e308, 0.0, 1e6, -0.1, 4.2, 0.005):
        assert lim.absurd(r), r
    for r in (0.04, 0.02, 0.5, 4.0, 4.02, math.nan):
        assert not lim.absurd(r), r
    assert RangeLimits.of_mount(None).absurd(1e308) and not RangeLimits.of_mount(None).absurd(50.0)


def test_absurd_points_and_scrub():
    lim = RangeLimits(0.9, 100.0)
    p = np.array([[1.0, 0, 0], [0, 0, 0], [1e6, 0, 0], [np.nan, 0, 0], [0.5, 0, 0], [1e308, 1e308, 0]])
    assert lim.absurd_points(p).tolist() == [False, True, True, False, True, True]
    q, n = scrub_points(p, lim)
    assert n == 4 and np.isnan(q[[1, 2, 4, 5]]).all() and q[0, 0] == 1.0
    clean = p[:1]
    assert scrub_points(clean, lim) == (clean, 0)


def test_depth_imu_and_joint_limits():
    cam = SensorMount("cam", "rgbd", "head", np.eye(4), {"max_depth_m": 6.0})
    assert max_depth_m(cam) == 6.0 and max_depth_m(None) > 100
    d = np.array([[0.0, 3.0, 1e6], [-1.0, np.nan, 6.0]])
    assert absurd_depth(d, 6.0).tolist() == [[False, False, True], [True, False, False]]
    ok = ImuSample(0.0, "imu", np.array([1.0, 0, 0, 0]), np.zeros(3), np.array([0, 0, 9.81]))
    assert not imu_absurd(ok)
    assert imu_absurd(absurd(ok)) and imu_absurd(ImuSample(0.0, "imu", np.array([3.0, 0, 0, 0]), np.zeros(3), np.zeros(3)))
    assert urdf_joint_limits(URDF) == {"knee": (-2.0, 0.1)}
    lim = JointLimits(Calibration(URDF, "a", ("knee",), (), 0.1, 0.25, 0.05))
    js = JointState(0.0, "encoders", ("knee",), np.array([-1.0]))
    assert not lim.absurd(js)
    for q in (0.7, -2.6, math.nan, math.inf, 1e308):
        assert lim.absurd(JointState(0.0, "encoders", ("knee",), np.array([q]))), q
    assert lim.absurd(JointState(0.0, "encoders", ("knee", "hip"), np.array([0.0])))  # names and angles differ


def test_absurd_frames_and_injector():
    tofs = [ToFReading(0.1 * i, "tof_a", 0.5) for i in range(10)]
    n = 10
    scan = LidarScan(1.0, "lidar", np.ones((n, 3)), np.zeros(n, np.uint8), np.zeros(n, int), np.zeros(n), 0.9)
    frames, made = inject_absurd(tofs)
    assert [frames[i].range_m for i in made] == [1e308, 0.0, 1e6] and all(frames[i].valid for i in made)
    a = absurd(scan)
    r = np.linalg.norm(a.points_xyz, axis=1)
    assert n_absurd_points(scan) == 5 == np.count_nonzero((r == 0) | (r >= 1e6 - 1))
    assert RangeLimits(0.9, 100.0).absurd_points(a.points_xyz).sum() == 5
    d = RgbdFrame(0.0, "cam", np.zeros((2, 2, 3), np.uint8), np.ones((2, 2), np.float32), np.eye(3))
    assert (absurd(d).depth_m == 1e6).all() and absurd(d).depth_m.dtype == np.float32
