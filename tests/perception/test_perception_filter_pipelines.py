"""Filter pipelines (seeds/003 eq. 4.15-4.19) and the kiss-icp adapter on constructed frames."""

import dataclasses
import math

import numpy as np
import pytest

from exobench.core.frames import ContactSample, ImuSample, JointState, LidarScan
from exobench.core.transforms import matrix_to_quat_wxyz, rot_x, rot_y, rot_z
from exobench.perception.lidar_filter import (
    IntensityBandConfig,
    IntensityThresholdFilter,
    NaiveGroundConfig,
    NaiveGroundFilter,
    NoFilter,
    NormalGroundConfig,
    NormalGroundFilter,
)
from exobench.perception.lidar_filter.pipelines import FILTER_PIPELINES, FilterNaiveGround, FilterNormalGround

LIDAR = "lidar_trunk"


@pytest.fixture(scope="module")
def calibration():
    from exobench.models.exo import exo_calibration
    from exobench.models.exo_spec import ExoSpec

    return exo_calibration(ExoSpec())


def _joint_names(cal):
    import pinocchio as pin

    model = pin.buildModelFromXML(cal.robot_urdf)
    return [model.names[j] for j in range(1, model.njoints) if model.joints[j].nq in (1, 2)]


def _angles(cal):
    rng = np.random.default_rng(3)
    return {n: float(rng.uniform(-0.3, 0.3)) for n in _joint_names(cal)}


def _expected_T(cal, angles, R_world_imu, side):
    """Independent forward kinematics (pinocchio, written out here) of the footprint frame."""
    import pinocchio as pin

    model = pin.buildModelFromXML(cal.robot_urdf)
    data = model.createData()
    q = np.array(pin.neutral(model), dtype=float)
    for j in range(1, model.njoints):
        jm, name = model.joints[j], model.names[j]
        a = angles.get(name, 0.0)
        if jm.nq == 1:
            q[jm.idx_q] = a
        elif jm.nq == 2:
            q[jm.idx_q : jm.idx_q + 2] = (math.cos(a), math.sin(a))
    pin.forwardKinematics(model, data, q)
    pin.updateFramePlacements(model, data)
    oMb = data.oMf[model.getFrameId(cal.base_link, pin.FrameType.BODY)]

    def T_base(link, T_ps):
        return (oMb.inverse() * data.oMf[model.getFrameId(link, pin.FrameType.BODY)]).homogeneous @ T_ps

    mounts = {m.sensor_id: m for m in cal.mounts}
    R_b_imu = T_base(mounts["imu_trunk"].parent_link, np.asarray(mounts["imu_trunk"].T_parent_sensor))[:3, :3]
    R_wb = R_world_imu @ R_b_imu.T
    T_bl = T_base(mounts[LIDAR].parent_link, np.asarray(mounts[LIDAR].T_parent_sensor))
    p_ankle = (oMb.inverse() * data.oMi[model.getJointId(f"ankle_{side}")]).translation
    T = np.eye(4)
    T[:3, :3] = R_wb @ T_bl[:3, :3]
    T[:3, 3] = R_wb @ (T_bl[:3, 3] - p_ankle) + [0.0, 0.0, cal.sole_height_m]
    yaw = math.atan2(R_wb[1, 0], R_wb[0, 0])
    T_f = np.eye(4)
    T_f[:3, :3] = rot_z(-yaw)
    return T_f @ T


def _scan(rng, stamp, n=400, T_footprint_sensor=None):
    """Floor points (1.2 m below, or on the footprint's ground plane when the transform is given),
    a wall at x = 3 m; weak floor and bright/dim spurious intensities."""
    floor = np.column_stack([rng.uniform(1, 4, n), rng.uniform(-2, 2, n), np.full(n, -1.2) + rng.normal(0, 0.005, n)])
    if T_footprint_sensor is not None:
        floor[:, 2] += 1.2
        T_sf = np.linalg.inv(T_footprint_sensor)
        floor = floor @ T_sf[:3, :3].T + T_sf[:3, 3]
    wall = np.column_stack([np.full(n, 3.0), rng.uniform(-2, 2, n), rng.uniform(-1.0, 1.0, n)])
    pts = np.vstack([floor, wall])
    psi = np.concatenate([rng.uniform(2, 14, n), rng.choice([5.0, 50.0, 150.0], n)])
    return LidarScan(stamp_s=stamp, sensor_id=LIDAR, points_xyz=pts, intensity=psi, ring=np.zeros(2 * n, np.uint16),
                     time_offset_s=np.linspace(0, 0.09, 2 * n), sweep_start_s=stamp - 0.1)


def _states(cal, stamp, R_world_imu, stance="l"):
    angles = _angles(cal)
    frames = [
        JointState(stamp, "encoders", tuple(angles), np.array(list(angles.values()))),
        ImuSample(stamp, "imu_trunk", matrix_to_quat_wxyz(R_world_imu), np.zeros(3), np.zeros(3)),
    ]
    for side in ("l", "r"):
        for pad in ("heel", "toe"):
            frames.append(ContactSample(stamp, f"contact_{side}_{pad}", 300.0 if side == stance else 0.0, side == stance))
    return angles, frames


def _run(cls, cal, frames, config=None):
    p = cls(config)
    p.reset(cal)
    for f in frames:
        p.process(f)
    return p.finalize()


R_TILT = rot_z(0.7) @ rot_y(0.12) @ rot_x(-0.05)  # R_world_imu: heading, pitch and roll


def test_footprint_transform_equals_independent_kinematics(calibration):
    angles, states = _states(calibration, 0.0, R_TILT, stance="r")
    scan = _scan(np.random.default_rng(0), 0.1)
    est = _run(FilterNaiveGround, calibration, [*states, scan])
    T = est.stats["T_footprint_sensor"][0]
    np.testing.assert_allclose(T, _expected_T(calibration, angles, R_TILT, "r"), atol=1e-9)
    assert est.stats["stance_side"] == ["r"]
    # the sensor is above the ground and its frame is tilted, not level
    assert T[2, 3] > 0.5 and abs(T[2, 2] - 1.0) > 1e-3


def test_masks_equal_the_filter_functions(calibration):
    rng = np.random.default_rng(1)
    angles, states = _states(calibration, 0.0, R_TILT)
    scans = [_scan(rng, 0.1 * (k + 1)) for k in range(3)]
    T = _expected_T(calibration, angles, R_TILT, "l")
    filters = {
        "none": NoFilter(), "threshold": IntensityThresholdFilter(IntensityBandConfig()),
        "naive-ground": NaiveGroundFilter(NaiveGroundConfig()), "normal-ground": NormalGroundFilter(NormalGroundConfig()),
        "floor-ground": NaiveGroundFilter(NaiveGroundConfig(ground_test="plane-band")),
    }  # fmt: skip
    for kind, cls in FILTER_PIPELINES.items():
        est = _run(cls, calibration, [*states, *scans])
        assert len(est.keep) == 3 and est.time_per_scan_s.shape == (3,)
        np.testing.assert_array_equal(est.stamps_s, [s.stamp_s for s in scans])
        for s, k in zip(scans, est.keep, strict=True):
            expected = filters[kind].apply(s.points_xyz, s.intensity, T).keep
            np.testing.assert_array_equal(k, expected, err_msg=kind)
    # the ground-aware filters rescue the weak floor (tilted sensor: transform needed)
    again = _run(FilterNormalGround, calibration, [*states, *scans])  # same input, same output
    first = _run(FilterNormalGround, calibration, [*states, *scans])
    for a, b in zip(first.keep, again.keep, strict=True):
        np.testing.assert_array_equal(a, b)
    on_ground = _scan(rng, 0.5, T_footprint_sensor=T)
    for cls in (FilterNaiveGround, FilterNormalGround):
        assert _run(cls, calibration, [*states, on_ground]).keep[0][:400].mean() > 0.9
    assert _run(FILTER_PIPELINES["threshold"], calibration, [*states, on_ground]).keep[0][:400].mean() < 0.1


def test_each_scan_s_mask_is_returned_online_and_kiss_icp_registers_those(calibration):
    """process() returns a scan's own FilterEstimate (its stamp, its mask, nothing for other
    frames); kiss-icp's filter stage registers exactly those masks."""
    from exobench.core.estimates import FilterEstimate
    from exobench.mapping.odometry.kiss_icp import KissConfig, KissIcpPipeline, run_kiss_icp
    from exobench.perception.lidar_filter import FilterStageConfig

    rng = np.random.default_rng(2)
    _, states = _states(calibration, 0.0, R_TILT)
    scans = [_scan(rng, 0.1 * (k + 1), n=2000) for k in range(4)]
    pipe = FilterNaiveGround()
    pipe.reset(calibration)
    online = [pipe.process(f) for f in [*states, *scans]]
    assert online[: len(states)] == [None] * len(states)
    final = pipe.finalize()
    for scan, est, keep in zip(scans, online[len(states):], final.keep, strict=True):
        assert isinstance(est, FilterEstimate) and len(est.keep) == 1
        np.testing.assert_array_equal(est.stamps_s, [scan.stamp_s])
        np.testing.assert_array_equal(est.keep[0], keep)
    config = KissConfig(filter=FilterStageConfig(kind="naive-ground"), voxel_size_m=0.2)
    staged = _run(KissIcpPipeline, calibration, [*states, *scans], config)
    direct = run_kiss_icp(scans, list(final.keep), dataclasses.replace(config, filter=FilterStageConfig()))
    np.testing.assert_array_equal(staged.T_world_sensor, direct.T_world_sensor)
    assert staged.stats["points_used"] == direct.stats["points_used"] == sum(int(k.sum()) for k in final.keep)


def test_faults_never_raise_and_are_counted(calibration):
    rng = np.random.default_rng(2)
    empty = LidarScan(0.05, LIDAR, np.zeros((0, 3)), np.zeros(0), np.zeros(0, np.uint16), np.zeros(0), -0.05)
    early = _scan(rng, 0.1)  # before any kinematic state: band only
    _, states = _states(calibration, 0.15, R_TILT)
    bad_imu = ImuSample(0.16, "imu_trunk", np.array([np.nan, 0, 0, 0]), np.zeros(3), np.zeros(3))
    nan_scan = _scan(rng, 0.2)
    pts = nan_scan.points_xyz.copy()
    pts[:10] = np.nan
    nan_scan = LidarScan(0.2, LIDAR, pts, nan_scan.intensity, nan_scan.ring, nan_scan.time_offset_s, 0.1)
    for cls in (FilterNaiveGround, FilterNormalGround):
        est = _run(cls, calibration, [empty, early, *states, bad_imu, nan_scan])
        st = est.stats
        assert len(est.keep) == 3 and len(est.keep[0]) == 0
        assert st["empty_scans"] == 1 and st["no_kinematics"] == 1 and st["invalid_points"] >= 10
        band = IntensityThresholdFilter(IntensityBandConfig()).apply(early.points_xyz, early.intensity).keep
        np.testing.assert_array_equal(est.keep[1], band)
        assert not est.keep[2][:10].any() and np.isfinite(st["T_footprint_sensor"][2]).all()


def test_bad_config_raises_config_error():
    from exobench.core.errors import ConfigError

    with pytest.raises(ConfigError):
        FilterNaiveGround.Config(intensity_min=50.0, intensity_max=10.0)
    with pytest.raises(ConfigError):
        FilterNormalGround.Config(epsilon_eta=0.0)


def test_kiss_icp_keeps_last_pose_on_empty_scans(calibration):
    from exobench.mapping.odometry.kiss_icp import KissConfig, KissIcpPipeline
    from exobench.perception.lidar_filter import FilterStageConfig

    rng = np.random.default_rng(4)
    # a static box room seen from the origin: the pose must stay at the identity
    def room(stamp):
        n = 3000
        u = rng.uniform(-1, 1, (n, 2))
        faces = [np.column_stack([np.full(n, 4.0), 4 * u[:, 0], 1.5 * u[:, 1]]),
                 np.column_stack([4 * u[:, 0], np.full(n, 3.0), 1.5 * u[:, 1]]),
                 np.column_stack([4 * u[:, 0], np.full(n, -3.0), 1.5 * u[:, 1]]),
                 np.column_stack([4 * u[:, 0], 3 * u[:, 1], np.full(n, -1.5)])]  # fmt: skip
        p = np.vstack(faces)
        return LidarScan(stamp, LIDAR, p, np.full(len(p), 40.0), np.zeros(len(p), np.uint16),
                         np.linspace(0, 0.099, len(p)), stamp - 0.1)
    empty = LidarScan(0.25, LIDAR, np.zeros((0, 3)), np.zeros(0), np.zeros(0, np.uint16), np.zeros(0), 0.15)
    frames = [room(0.1), room(0.2), empty, room(0.35)]
    est = _run(KissIcpPipeline, calibration, frames, KissConfig(filter=FilterStageConfig(kind="threshold"), voxel_size_m=0.2))
    assert est.status == ("ok", "ok", "empty_scan", "ok")
    assert est.stats["empty_scans"] == 1 and est.T_world_sensor.shape == (4, 4, 4)
    np.testing.assert_array_equal(est.T_world_sensor[2], est.T_world_sensor[1])
    assert np.abs(est.T_world_sensor[:, :3, 3]).max() < 0.05


def _ring_scan_of_box(x_sensor: float) -> np.ndarray:
    """A 16-ring, 1-degree sweep of the walls of a 10 x 6 m room (floor and ceiling out of reach) from (x_sensor, 0, 0), sensor frame."""
    el = np.deg2rad(np.arange(-15.0, 16.0, 2.0))
    az = np.deg2rad(np.arange(0.0, 360.0, 1.0))
    E, A = np.meshgrid(el, az, indexing="ij")
    d = np.column_stack([(np.cos(E) * np.cos(A)).ravel(), (np.cos(E) * np.sin(A)).ravel(), np.sin(E).ravel()])
    o = np.array([x_sensor, 0.0, 0.0])
    lo, hi = np.array([-5.0, -3.0, -3.0]), np.array([5.0, 3.0, 3.0])
    with np.errstate(divide="ignore"):
        t = np.where(d > 0, (hi - o) / d, np.where(d < 0, (lo - o) / d, np.inf)).min(axis=1)
    return t[:, None] * d


def test_kiss_icp_single_downsample_registers_the_half_voxel_scan():
    """downsample="single" (Table 5.4's KISS-ICP): the registration source is the scan at half the
    voxel size, one point per occupied voxel, where kiss-icp as released keeps one per 1.5 voxels."""
    from kiss_icp.kiss_icp import KissICP

    from exobench.mapping.odometry.kiss_icp import KissConfig, _single_downsample_class

    voxel = 0.6
    frame = _ring_scan_of_box(0.0)
    sizes = {}
    for mode, cls in (("double", KissICP), ("single", _single_downsample_class())):
        odom = cls(KissConfig(voxel_size_m=voxel, deskew=False, downsample=mode).kiss_config())
        _, source = odom.register_frame(frame, np.zeros(len(frame)))
        sizes[mode] = len(source)
    half_voxels = len(np.unique(np.floor(frame / (0.5 * voxel)).astype(np.int64), axis=0))
    assert sizes["single"] == half_voxels
    assert sizes["double"] < 0.5 * sizes["single"]


def test_kiss_icp_downsample_must_be_named():
    from exobench.core.errors import ConfigError
    from exobench.mapping.odometry.kiss_icp import KissConfig

    with pytest.raises(ConfigError, match="downsample"):
        KissConfig(downsample="triple")
