"""The batch RANSAC baseline on synthetic two-beam sweeps of a whole step, generated here.

The frames come from the hand-written robot of test_perception_pipelines (the right calf on two
prismatic joints, two beams pitched down with 4 deg toe-out); the ranges are analytic ray-plane
intersections with the staircase profile of test_perception_staircase (riser 0.162 m, tread
0.28 m, first riser 0.30 m ahead of the stance ankle) plus 1.5 mm noise along the beam. The
calf stands still, sweeps up over the first step and stands still again above the second
tread, like the simulated climbing step, so both beams see the ground, both risers and both
treads. Truth is the analytic profile, never the pipeline's own output.
"""

import dataclasses

import numpy as np
import pytest
from test_perception_kinematics import _quat_wxyz, _rot
from test_perception_pipelines import CAL, R_PELVIS_IMU, SOLE_M, _true_ray
from test_perception_staircase import RISER_M, RISER_X_M, TREAD_M, stair_hit, sweep_stream

from exobench.core import ConfigError, ImuSample, JointState, ToFReading
from exobench.perception.stairs import BatchRansacStairs
from exobench.perception.stairs.ransac import ScanCloud, connected_support, tls_plane

THRESHOLD_M = 5e-3


def _sliders(t, duration_s, still_s):
    s = float(np.clip((t - still_s) / (duration_s - 2.0 * still_s), 0.0, 1.0))
    s = s * s * (3.0 - 2.0 * s)
    return {"slide_x": -0.60 + 1.0 * s, "slide_z": 0.22 + 0.40 * s - 0.85 - SOLE_M}


def step_frames(seed=0, yaw_deg=0.0, duration_s=3.0, still_s=0.4, noise_m=1.5e-3):
    """Frames of a whole step in time order and, per ToF frame, the true surface id."""
    rng = np.random.default_rng(seed)
    R_wp = _rot([0, 0, 1], np.radians(yaw_deg))
    quat = _quat_wxyz(R_wp @ R_PELVIS_IMU)
    frames, truth = [], []
    for k, t in enumerate(np.arange(0.0, duration_s, 0.01)):
        q = _sliders(t, duration_s, still_s)
        frames.append(JointState(t, "encoders", tuple(q), np.array(list(q.values()))))
        frames.append(ImuSample(t, "imu_trunk", quat, np.zeros(3), np.array([0.0, 0.0, 9.81])))
        if k % 2 == 0:  # ToF at 50 Hz
            for sid in ("tof_r_lat", "tof_r_med"):
                o, u = _true_ray(q, R_wp, sid)
                r, surface = stair_hit(o, u)
                frames.append(ToFReading(t + 0.001, sid, r + noise_m * rng.standard_normal()))
                truth.append(surface)
    return frames, np.array(truth)


def true_plane(index):
    """(unit normal out of the solid, point) of surface ``index`` in the stance frame."""
    k = (index + 1) // 2
    if index % 2 == 0:
        return np.array([0.0, 0.0, 1.0]), np.array([0.0, 0.0, k * RISER_M])
    return np.array([-1.0, 0.0, 0.0]), np.array([RISER_X_M + (k - 1) * TREAD_M, 0.0, 0.0])


def _run(frames, config=None):
    pipe = BatchRansacStairs(config)
    pipe.reset(CAL)
    for f in frames:
        assert pipe.process(f) is None  # offline: nothing before finalize
    return pipe.finalize()


def _angle_deg(a, b):
    return float(np.degrees(np.arccos(np.clip(np.dot(a, b) / np.linalg.norm(a) / np.linalg.norm(b), -1.0, 1.0))))


@pytest.mark.parametrize("yaw_deg", [0.0, 15.0, -15.0])
@pytest.mark.parametrize("seed", [0, 1])
def test_batch_recovers_s0_to_s4_in_walking_order(seed, yaw_deg):
    frames, truth = step_frames(seed=seed, yaw_deg=yaw_deg)
    est = _run(frames)
    assert [p.index for p in est.planes if p.index <= 4] == [0, 1, 2, 3, 4]
    for i in range(5):
        p = est.plane(i)
        n, point = true_plane(i)
        assert p.reliable and min(p.n_points.values()) >= 5
        assert _angle_deg(p.normal, n) < 2.0, (i, p.normal)  # also the sign: treads up, risers -x
        assert abs(np.dot(p.centroid - point, n)) < 3e-3, (i, p.centroid)
    assert abs(est.riser_height_m - RISER_M) < 3e-3
    assert abs(est.tread_depth_m - TREAD_M) < 5e-3
    # every used point labelled with its true surface, except a few at the stair edges
    got = np.array([a.surface_index for a in est.assignments])
    assert len(got) == len(truth) and np.all(got >= -1)
    assert np.mean(got == truth) > 0.9
    points = np.array([a.point for a in est.assignments])
    for i in range(5):  # a label holds points of its surface, or ones as close to its plane
        n, point = true_plane(i)
        mine = got == i
        assert np.mean(truth[mine] == i) > 0.75
        assert np.all((truth[mine] == i) | (np.abs((points[mine] - point) @ n) < THRESHOLD_M + 2e-3))


def test_batch_is_deterministic():
    frames, _ = step_frames(seed=3, yaw_deg=10.0)
    a, b = _run(frames), _run(frames)
    assert [p.index for p in a.planes] == [p.index for p in b.planes]
    for p, q in zip(a.planes, b.planes, strict=True):
        np.testing.assert_array_equal(p.normal, q.normal)
        np.testing.assert_array_equal(p.centroid, q.centroid)
        assert p.n_points == q.n_points and p.reliable_stamp_s == q.reliable_stamp_s
    assert [x.surface_index for x in a.assignments] == [x.surface_index for x in b.assignments]
    # a different sampling seed finds the same surfaces
    c = _run(frames, BatchRansacStairs.Config(seed=7))
    assert [p.index for p in c.planes if p.index <= 4] == [0, 1, 2, 3, 4]
    for p in c.planes:
        assert _angle_deg(p.normal, a.plane(p.index).normal) < 0.5


def test_offline_planes_become_reliable_at_the_end_of_the_stream():
    frames, _ = step_frames(seed=4)
    est = _run(frames)
    used = [a.stamp_s for a in est.assignments if a.surface_index != -2]
    complete = est.stats["data_complete_stamp_s"]
    for p in est.planes:
        assert p.reliable and p.reliable_stamp_s == max(used)
        # when the plane's 5th point of each sensor arrived: its 5th-earliest of each sensor
        stamps = {sid: sorted(a.stamp_s for a in est.assignments if a.surface_index == p.index and a.sensor_id == sid) for sid in p.n_points}
        assert complete[f"S{p.index}"] == max(s[4] for s in stamps.values())


def test_a_single_beam_gives_no_planes():
    # one beam's sweep is nearly planar itself; without the other beam nothing is reliable
    frames, _ = step_frames(seed=5)
    est = _run([f for f in frames if not (isinstance(f, ToFReading) and f.sensor_id == "tof_r_med")])
    assert est.planes == () and np.isnan(est.riser_height_m)


# --- the helpers on independent point streams ------------------------------------------------
def _sweep_cloud(seed=0, yaw_deg=0.0):
    stream = sweep_stream(seed=seed, yaw_deg=yaw_deg)
    pts = np.array([p for _, _, p, _ in stream])
    beam = np.array([0 if f == "r" else 1 for _, f, _, _ in stream])
    stamps = np.array([t for t, _, _, _ in stream])
    sid = np.array([s for _, _, _, s in stream])
    return ScanCloud.of(pts, beam, stamps), sid


def _support(cloud, normal, point):
    inliers = np.abs((cloud.points - point) @ normal) <= THRESHOLD_M
    return connected_support(cloud, inliers, min_run=3, max_gap=2, link_radius_m=0.16)


@pytest.mark.parametrize("yaw_deg", [0.0, 10.0])
def test_connected_support_keeps_surfaces_and_rejects_accidental_planes(yaw_deg):
    cloud, sid = _sweep_cloud(yaw_deg=yaw_deg)
    beam = cloud.sensor
    # the true first tread: connected support from both beams, nearly all its points
    n, point = true_plane(2)
    sup = _support(cloud, n, point)
    assert set(beam[sup]) == {0, 1} and np.mean(sid[sup] == 2) > 0.9
    assert np.isin(np.flatnonzero(sid == 2), sup).mean() > 0.9
    # "rolled" plane through beam 0's track on the tread and beam 1's on the ground: the two
    # tracks are exactly coplanar, but a riser apart
    rolled = ((sid == 2) & (beam == 0)) | ((sid == 0) & (beam == 1))
    n, c, _ = tls_plane(cloud.points[rolled])
    assert np.mean(np.abs((cloud.points[rolled] - c) @ n) <= THRESHOLD_M) > 0.9  # many inliers...
    sup = _support(cloud, n, c)
    assert np.isin(np.flatnonzero(rolled), sup).mean() < 0.5  # ...but not connected
    # one beam's whole sweep: a plane of many inliers, none of the other beam
    n, c, _ = tls_plane(cloud.points[beam == 0])
    sup = _support(cloud, n, c)
    assert len(sup) == 0 or np.isin(np.flatnonzero(beam == 0), sup).mean() < 0.5


def test_scan_cloud_counts_a_dwelt_spot_as_few_cells():
    rng = np.random.default_rng(0)
    spot = np.array([0.1, 0.2, 0.3]) + 1e-4 * rng.standard_normal((40, 3))  # the beam stood still
    line = np.column_stack([np.linspace(0.0, 0.3, 30), np.zeros(30), np.zeros(30)])  # swept 1 cm apart
    cloud = ScanCloud.of(np.vstack([spot, line]), np.r_[np.zeros(40), np.ones(30)], np.arange(70) * 0.02, voxel_m=0.005)
    assert cloud.score(np.arange(40)) <= 8 and cloud.score(np.arange(40, 70)) == 30
    means = cloud.cell_means(np.arange(40, 70))
    np.testing.assert_allclose(np.sort(means[:, 0]), line[:, 0], atol=1e-12)
    assert list(cloud.seq[:3]) == [0, 1, 2] and list(cloud.seq[40:43]) == [0, 1, 2]
    # exact plane: TLS recovers it
    n, c, sigma = tls_plane(np.vstack([line, line + [0.0, 0.1, 0.0]]))
    assert abs(abs(n[2]) - 1.0) < 1e-12 and sigma < 1e-12 and abs(c[1] - 0.05) < 1e-12


def test_batch_config_validates():
    for bad in (
        {"link_radius_m": 0.0},
        {"voxel_m": -1.0},
        {"min_run_points": 1},
        {"sample_window": 0},
        {"min_plane_cells": 2},
        {"refine_iterations": -1},
        {"seed": -1},
        {"max_run_gap": 1.5},
    ):
        with pytest.raises(ConfigError):
            BatchRansacStairs.Config(**bad)
    cfg = BatchRansacStairs.Config()
    assert dataclasses.replace(cfg, seed=3).seed == 3
