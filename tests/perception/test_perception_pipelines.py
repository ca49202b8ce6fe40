"""Stairs pipelines end to end on frames generated here: encoders, trunk IMU and ToF ranges.

A hand-written robot (test_perception_kinematics) carries the right calf on two prismatic
joints, so the test can sweep the beams along the same path as test_perception_staircase; the
ranges come from the analytic staircase by ray intersection, with the true sensor poses
computed by the independent numpy chain.
"""

import dataclasses

import numpy as np
import pytest
from test_perception_kinematics import _T, _quat_wxyz, _rot, chain_T, tiny_urdf
from test_perception_staircase import RISER_M, RISER_X_M, stair_hit

from exobench.core import (
    Calibration,
    ConfigError,
    ContactSample,
    ImuSample,
    JointState,
    Pipeline,
    PlaneEstimate,
    SensorMount,
    ToFReading,
    TofStatus,
    UnknownNameError,
    config_from_dict,
)
from exobench.perception.stairs import BatchRansacStairs, RtlsHtvrStairs, RtlsStairs, sensor_flags
from exobench.perception.stairs.readout import riser_height_m, tread_depth_m

SOLE_M = 0.07
JOINTS = [
    ("slide_x", "pelvis", "carriage", (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), (1, 0, 0), "prismatic"),
    ("slide_z", "carriage", "shank_r", (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), (0, 0, 1), "prismatic"),
    ("ankle_l", "pelvis", "foot_l", (0.0, 0.1, -0.85), (0.0, 0.0, 0.0), (0, -1, 0), "revolute"),
]


def _beam_mount(pitch_deg, yaw_deg, y):
    return _T(_rot([0, 0, 1], np.radians(yaw_deg)) @ _rot([0, 1, 0], np.radians(90 + pitch_deg)), (0.0, y, 0.0))


R_PELVIS_IMU = _rot([0.3, -0.5, 1.0], 0.4)
MOUNTS = (
    SensorMount("tof_r_lat", "tof", "shank_r", _beam_mount(33.0, -4.0, -0.04)),
    SensorMount("tof_r_med", "tof", "shank_r", _beam_mount(33.0, 4.0, 0.04)),
    SensorMount("tof_l_med", "tof", "foot_l", _beam_mount(10.0, 0.0, 0.0)),
    SensorMount("imu_trunk", "imu", "pelvis", _T(R_PELVIS_IMU, (-0.1, 0.0, 0.3))),
)
CAL = Calibration(tiny_urdf(JOINTS), "pelvis", ("slide_x", "slide_z", "ankle_l"), MOUNTS, SOLE_M, 0.26, 0.065)
MOUNT = {m.sensor_id: m for m in MOUNTS}


def _sliders(t, duration_s):
    s = t / duration_s
    return {"slide_x": -0.55 + 0.6 * s, "slide_z": 0.22 + 0.25 * s - 0.85 - SOLE_M}


def _true_ray(q, R_world_pelvis, sensor_id):
    T_p_s = chain_T(MOUNT[sensor_id].parent_link, q, JOINTS) @ MOUNT[sensor_id].T_parent_sensor
    p_ankle = chain_T("foot_l", q, JOINTS)[:3, 3]
    o = R_world_pelvis @ (T_p_s[:3, 3] - p_ankle) + np.array([0.0, 0.0, SOLE_M])
    return o, R_world_pelvis @ T_p_s[:3, 2]


def make_frames(seed=0, yaw_deg=0.0, duration_s=2.0, noise_m=1.5e-3):
    """Frames in time order and, per ToF frame, the true surface id (-1 for other sensors)."""
    rng = np.random.default_rng(seed)
    R_wp = _rot([0, 0, 1], np.radians(yaw_deg))
    quat = _quat_wxyz(R_wp @ R_PELVIS_IMU)
    frames, truth = [], []
    for k, t in enumerate(np.arange(0.0, duration_s, 0.01)):
        q = _sliders(t, duration_s)
        frames.append(JointState(t, "encoders", tuple(q), np.array(list(q.values()))))
        frames.append(ImuSample(t, "imu_trunk", quat, np.zeros(3), np.array([0.0, 0.0, 9.81])))
        if k % 2 == 0:  # ToF at 50 Hz
            for sid in ("tof_r_lat", "tof_r_med"):
                o, u = _true_ray(q, R_wp, sid)
                r, surface = stair_hit(o, u)
                frames.append(ToFReading(t + 0.001, sid, r + noise_m * rng.standard_normal()))
                truth.append(surface)
            frames.append(ToFReading(t + 0.001, "tof_l_med", 0.3))
            truth.append(-1)
            frames.append(ContactSample(t, "contact_l_heel", 300.0, True))
    return frames, np.array(truth)


def _run(pipe, frames):
    pipe.reset(CAL)
    online = [pipe.process(f) for f in frames]
    return pipe.finalize(), online


def _angle_deg(a, b):
    return float(np.degrees(np.arccos(min(1.0, abs(np.dot(a, b)) / np.linalg.norm(a) / np.linalg.norm(b)))))


@pytest.mark.parametrize("cls", [RtlsStairs, RtlsHtvrStairs, BatchRansacStairs])
@pytest.mark.parametrize("yaw_deg", [0.0, 10.0])
def test_pipeline_reconstructs_the_first_step(cls, yaw_deg):
    frames, truth = make_frames(seed=1, yaw_deg=yaw_deg)
    est, online = _run(cls(), frames)
    assert isinstance(cls(), Pipeline) and est.frame_id == "stance_ground"
    S0, S1, S2 = est.plane(0), est.plane(1), est.plane(2)
    assert S0.reliable and S1.reliable and S2.reliable
    assert _angle_deg(S2.normal, [0, 0, 1]) < 3.0 and S2.normal[2] > 0
    assert abs(S2.centroid[2] - RISER_M) < 3e-3
    # the riser plane x = RISER_X_M in the stance frame, normal facing the walker (-x)
    assert abs(S1.centroid[0] - RISER_X_M) < 3e-3 and _angle_deg(S1.normal, [1, 0, 0]) < 3.0
    assert S1.normal[0] < 0
    assert abs(est.riser_height_m - RISER_M) < 5e-3
    assert np.isnan(est.tread_depth_m)  # S3 was not seen
    # one assignment per ToF frame, aligned with the truth; other sensors are not used
    assert len(est.assignments) == len(truth)
    got = np.array([a.surface_index for a in est.assignments])
    assert np.all(got[truth == -1] == -2)
    used = got >= 0
    assert used.mean() > 0.25 and (got[used] == truth[used]).mean() > 0.9
    assert len(est.compute_time_s) == est.counts["tof"].used == int(np.sum(truth >= 0))
    assert np.all(est.compute_time_s > 0)
    tof_stamps = {a.stamp_s for a in est.assignments}
    assert S2.reliable_stamp_s in tof_stamps
    assert S2.n_points["tof_r_lat"] >= 5 and S2.n_points["tof_r_med"] >= 5
    if cls is BatchRansacStairs:
        assert all(o is None for o in online)
    else:
        assert online[0] is None and online[-1] is not None
        assert online[-1].plane(2).reliable and online[-1].assignments == ()


def test_batch_ransac_is_deterministic():
    frames, _ = make_frames(seed=2)
    a, _ = _run(BatchRansacStairs(), frames)
    b, _ = _run(BatchRansacStairs(), frames)
    assert [p.index for p in a.planes] == [p.index for p in b.planes]
    for p, q in zip(a.planes, b.planes, strict=True):
        np.testing.assert_array_equal(p.normal, q.normal)
    assert [x.surface_index for x in a.assignments] == [x.surface_index for x in b.assignments]


@pytest.mark.parametrize("cls", [RtlsStairs, RtlsHtvrStairs, BatchRansacStairs])
def test_faulty_input_is_counted_not_fatal(cls):
    frames, _ = make_frames(seed=3)
    rng = np.random.default_rng(0)
    bad = []
    # ToF before any state: the first frames are JointState, ImuSample; put two ToF in front
    bad += [ToFReading(-0.02, "tof_r_lat", 0.5), ToFReading(-0.02, "tof_r_med", 0.5)]
    n_nan = n_none = n_neg = n_late = 0
    for i, f in enumerate(frames):
        if isinstance(f, ToFReading) and f.sensor_id != "tof_l_med" and rng.random() < 0.25:
            kind = int(rng.integers(4))
            if kind == 0:
                f, n_nan = ToFReading(f.stamp_s, f.sensor_id, float("nan"), TofStatus.VALID), n_nan + 1
            elif kind == 1:
                f, n_none = ToFReading(f.stamp_s, f.sensor_id, float("nan"), TofStatus.NO_TARGET), n_none + 1
            elif kind == 2:
                f, n_none = ToFReading(f.stamp_s, f.sensor_id, 0.3, TofStatus.SIGMA_FAIL), n_none + 1
            else:
                f, n_neg = ToFReading(f.stamp_s, f.sensor_id, -0.1), n_neg + 1
        elif i > 1 and rng.random() < 0.1:
            continue  # dropped frame (not the very first encoder and IMU states)
        bad.append(f)
        if isinstance(f, JointState) and rng.random() < 0.05:  # a stale copy arrives late
            bad.append(dataclasses.replace(f, stamp_s=f.stamp_s - 0.05))
            n_late += 1
    bad.append(ImuSample(0.5, "imu_other", np.array([1.0, 0, 0, 0]), np.zeros(3), np.zeros(3)))
    bad.append(ToFReading(float("nan"), "tof_r_lat", 0.5))
    # broken states are ignored (the previous state stays); readings after them remain usable
    t_end = bad[-3].stamp_s + 0.01
    bad.append(JointState(t_end, "encoders", ("slide_x", "slide_z"), np.array([np.nan, 0.0])))
    bad.append(ImuSample(t_end, "imu_trunk", np.zeros(4), np.zeros(3), np.zeros(3)))
    bad.append(ToFReading(t_end + 0.001, "tof_r_lat", 0.4))
    est, _ = _run(cls(), bad)
    st, counts = est.stats, est.counts
    assert (counts["joints"].nan, counts["imu"].absurd) == (1, 1) and est.assignments[-1].surface_index != -2
    assert np.all(np.isfinite(est.assignments[-1].point))
    assert st["n_without_state"] == 2
    assert counts["tof"].nan == n_nan and st["n_no_return"] == n_none and counts["tof"].absurd == n_neg
    assert (counts["joints"].out_of_order, counts["tof"].out_of_order) == (n_late, 1)
    assert sum(c.seen for c in counts.values()) == len(bad)
    assert counts["imu"].ignored == 1 and counts["tof"].ignored == sum(f.sensor_id == "tof_l_med" for f in bad)
    n_tof = sum(isinstance(f, ToFReading) for f in bad)
    assert len(est.assignments) == n_tof
    n_skipped = sum(a.surface_index == -2 for a in est.assignments)
    n_left = sum(isinstance(f, ToFReading) and f.sensor_id == "tof_l_med" for f in bad)
    assert n_skipped == 2 + n_nan + n_none + n_neg + 1 + n_left
    assert counts["tof"].used == n_tof - n_skipped == len(est.compute_time_s)
    assert est.plane(0) is not None and est.plane(0).reliable  # still estimates from what is left


def test_no_state_at_all_gives_an_empty_estimate():
    pipe = RtlsStairs()
    pipe.reset(CAL)
    for t in range(10):
        assert pipe.process(ToFReading(0.02 * t, "tof_r_lat", 0.5)) is None
    est = pipe.finalize()
    assert est.planes == () and np.isnan(est.riser_height_m) and est.stats["n_without_state"] == 10
    b = BatchRansacStairs()
    b.reset(CAL)
    assert b.finalize().planes == ()


def test_configs_validate_and_convert():
    with pytest.raises(ConfigError):
        RtlsStairs.Config(leg="x")
    with pytest.raises(ConfigError):
        RtlsStairs.Config(th_z_m=-1.0)
    with pytest.raises(ConfigError):
        RtlsHtvrStairs.Config(queue_q=1)
    with pytest.raises(ConfigError):
        RtlsStairs.Config(riser_flat_low="maybe")
    with pytest.raises(ConfigError):
        BatchRansacStairs.Config(distance_threshold_m=0.0)
    cfg = config_from_dict(RtlsStairs.Config, {"queue_q": "7", "th_pl_m": "0.12"})
    assert cfg.queue_q == 7 and cfg.th_pl_m == 0.12
    assert (RtlsStairs.name, RtlsHtvrStairs.name, BatchRansacStairs.name) == ("rtls", "rtls-htvr", "batch-ransac")
    assert RtlsStairs.track == RtlsHtvrStairs.track == BatchRansacStairs.track == "stairs"
    assert sensor_flags("r") == {"tof_r_lat": "r", "tof_r_med": "l"}
    with pytest.raises(UnknownNameError):  # the calibration has no left-leg lateral sensor
        RtlsStairs(RtlsStairs.Config(leg="l")).reset(CAL)


# --- read-out on exact planes ---------------------------------------------------------------
def _plane(index, normal, centroid):
    n = np.asarray(normal, float) / np.linalg.norm(normal)
    return PlaneEstimate(index, n, np.asarray(centroid, float), {"a": 9, "b": 9}, 0.001, True, 0.0)


def test_readout_on_exact_planes():
    r, t = 0.17, 0.29
    h = np.array([np.cos(0.4), np.sin(0.4), 0.0])  # the staircase's climbing direction
    planes = [
        _plane(0, [0, 0, 1], [0.1, 0.2, 0.0]),
        _plane(1, -h, 0.3 * h + [0, 0, 0.08]),
        _plane(2, [0, 0, 1], 0.45 * h + [0, 0.1, r]),
        _plane(3, -h, (0.3 + t) * h + [0.05 * -h[1], 0.05 * h[0], 1.5 * r]),
        _plane(4, [0, 0, 1], [1.0, 0.8, 2 * r]),
    ]
    assert abs(riser_height_m(planes) - r) < 1e-12
    assert abs(tread_depth_m(planes) - t) < 1e-12
    # a tilted tread: heights are compared at the midpoint of the two centroids
    tilted = _plane(2, [0.1, 0.0, 1.0], [0.5, 0.0, r])
    mid_x = 0.5 * (0.1 + 0.5)
    expected = r - 0.1 * (mid_x - 0.5) / 1.0
    assert abs(riser_height_m([planes[0], tilted]) - expected) < 1e-12
    unreliable = dataclasses.replace(planes[3], reliable=False)
    assert np.isnan(tread_depth_m(planes[:3] + [unreliable]))
    assert np.isnan(riser_height_m(planes[1:2]))


def _fitted(index, X):
    """PlaneEstimate of the points X (total least squares) with their scatter."""
    e = X.mean(axis=0)
    S = (X - e).T @ (X - e)
    n = np.linalg.eigh(S)[1][:, 0]
    return PlaneEstimate(index, n if n[2] > 0 else -n, e, {"a": 9, "b": 9}, 0.001, True, 0.0, scatter=S)


def test_parallel_riser_readout_on_inclined_treads_and_a_tilted_short_tread():
    """Treads z = 0.03 x + k r (parallel, inclined by 1.7 deg) sampled on a grid: the parallel read-out
    gives r exactly; with S2 seen on 4 cm and two of its points 2 cm low (a riser's top) it stays
    within 1 %, while comparing S2 with its neighbours at a centroid is off by tens of percent; with
    S2 unreliable it reads (S4 - S0) / 2; planes with one imposed normal and no scatter work too."""
    r, slope = 0.17, 0.03
    g = np.stack(np.meshgrid(np.linspace(0.0, 0.2, 6), np.linspace(-0.1, 0.1, 5)), -1).reshape(-1, 2)

    def tread(k, xy):
        return np.column_stack([xy, slope * xy[:, 0] + k * r])

    lo, hi = tread(0, g + [0.0, 0.0]), tread(2, g + [0.6, 0.0])
    mid = tread(1, np.column_stack([np.tile(np.linspace(0.3, 0.34, 5), 2), np.repeat([-0.05, 0.08], 5)]))  # two beams
    exact = [_fitted(0, lo), _fitted(2, mid), _fitted(4, hi)]
    assert abs(riser_height_m(exact, "parallel") - r) < 1e-12
    bad = mid.copy()
    bad[:2, 2] -= 0.02
    planes = [exact[0], _fitted(2, bad), exact[2]]
    assert abs(riser_height_m(planes, "parallel") - r) / r < 0.01
    assert abs(riser_height_m(planes, "upper_centroid") - r) / r > 0.1
    no_s2 = [exact[0], dataclasses.replace(planes[1], reliable=False), exact[2]]
    assert abs(riser_height_m(no_s2, "parallel") - r) < 1e-12
    assert np.isnan(riser_height_m(no_s2, "upper_centroid"))
    flat = [_plane(k, [0, 0, 1], [0.3 * k, 0.0, k / 2 * r]) for k in (0, 2, 4)]  # HTVR: no scatter
    assert abs(riser_height_m(flat, "parallel") - r) < 1e-12
    with pytest.raises(ValueError, match="scatter"):
        riser_height_m([exact[0], flat[1]], "parallel")
