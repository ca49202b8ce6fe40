"""Any sensor on any world: an office walk carrying a thigh RGB-D camera, its IMU and the trunk LiDAR."""

import mujoco
import numpy as np
import pytest

from exobench.core import ImuSample, LidarScan, RgbdFrame
from exobench.core.truth import ReturnKind
from exobench.envs.sensors import RgbdConfig
from exobench.envs.sim import OfficeScenario, camera_rig, simulate_office
from exobench.envs.sim.scenarios.office import plan_office_walk


@pytest.fixture(scope="module")
def office_with_camera():
    sc = OfficeScenario(max_distance_m=0.8, lidar_noise_m=0.0, lidar_resolution_m=0.0)
    cam = RgbdConfig(width_px=33, height_px=25, rate_hz=5.0, subpixel=0.0, resolution_m=0.0, min_depth_m=0.05,
                      edge_threshold_rel=0.0)
    rig = (*sc.rig(), *camera_rig("thigh", cam))
    return sc, rig, simulate_office(sc, 4, rig=rig)


def test_office_walk_carries_camera_imu_and_lidar(office_with_camera):
    sc, rig, ep = office_with_camera
    ids = {f.sensor_id for f in ep.frames}
    assert {"lidar_trunk", "imu_trunk", "imu_thigh_r", "rgbd_thigh_r", "encoders"} <= ids
    assert any(isinstance(f, RgbdFrame) for f in ep.frames) and any(isinstance(f, LidarScan) for f in ep.frames)
    stamps = [f.stamp_s for f in ep.frames]
    assert stamps == sorted(stamps)
    mounts = {m.sensor_id: m for m in ep.calibration.mounts}
    assert mounts["imu_thigh_r"].parent_link == "thigh_r" and mounts["rgbd_thigh_r"].params["width_px"] == 33
    assert ep.calibration.extra["camera"] == "rgbd_thigh_r" and ep.calibration.extra["camera_imu"] == "imu_thigh_r"
    # the camera IMU at rest reads gravity in its own frame
    imu = [f for f in ep.frames if isinstance(f, ImuSample) and f.sensor_id == "imu_thigh_r"]
    assert abs(np.linalg.norm(imu[0].accel_m_s2) - 9.81) < 0.5


def test_centre_depth_is_the_ray_cast_distance(office_with_camera):
    sc, rig, ep = office_with_camera
    scene, motion = plan_office_walk(sc, rig)
    model = scene.model
    data = mujoco.MjData(model)
    frames = [f for f in ep.frames if isinstance(f, RgbdFrame)]
    T_cam = ep.truth.extra["camera_T_world"]
    t_cam = ep.truth.extra["camera_stamps_s"]
    checked = 0
    for f in frames:
        k = int(np.flatnonzero(np.isclose(t_cam, f.stamp_s))[0])
        data.qpos[:] = motion.sample(model, f.stamp_s).qpos[0]
        mujoco.mj_kinematics(model, data)
        T = T_cam[k]
        gid = np.zeros(1, dtype=np.int32)
        groups = np.array([1, 1, 1, 0, 0, 0], dtype=np.uint8)
        r = mujoco.mj_ray(model, data, T[:3, 3].copy(), T[:3, 2].copy(), groups, 1, -1, gid)
        d = float(f.depth_m[12, 16])
        if r > 0 and d > 0:
            assert abs(d - r) < 5e-3 * max(1.0, r)
            checked += 1
    assert checked >= 2


def test_lidar_points_land_on_the_true_surfaces(office_with_camera):
    sc, rig, ep = office_with_camera
    scans = [f for f in ep.frames if isinstance(f, LidarScan)]
    assert len(scans) == len(ep.truth.lidar) > 0
    for scan, lt in zip(scans, ep.truth.lidar):
        direct = lt.kind == int(ReturnKind.GENUINE)
        rng = np.linalg.norm(scan.points_xyz, axis=1)
        p_w = lt.origin_w + lt.dir_w * rng[:, None]
        assert np.all(np.linalg.norm(p_w[direct] - lt.hit_w[direct], axis=1) < 1e-6)
        for sid in np.unique(lt.surface_id[direct & (lt.surface_id >= 0)])[:5]:
            s = ep.truth.scene.surface(int(sid))
            sel = direct & (lt.surface_id == sid)
            assert np.all(np.abs((p_w[sel] - s.point_w) @ s.normal_w) < 1e-3)


def test_extra_sensor_presets_extend_the_rig():
    ids = [s.sensor_id for s in OfficeScenario(extra_sensors="rgbd_thigh").rig()]
    assert ids[-2:] == ["imu_thigh_r", "rgbd_thigh_r"] and ids[0] == "encoders"
    with pytest.raises(Exception, match="lidar_trunk"):
        OfficeScenario(extra_sensors="lidar_trunk").rig()
    with pytest.raises(Exception, match="extra sensor preset"):
        OfficeScenario(extra_sensors="sonar")


@pytest.fixture(scope="module")
def course_with_lidar():
    from exobench.envs.sensors import LidarConfig
    from exobench.envs.sensors.adapter import MountedSensor
    from exobench.envs.sim import LocomotionScenario, simulate_locomotion

    sc = LocomotionScenario(width_px=32, height_px=24, rate_hz=5.0, duration_cap_s=2.0)
    rig = (*sc.rig(), MountedSensor("lidar_trunk", "lidar", LidarConfig(range_noise_m=0.0, resolution_m=0.0)))
    return sc, simulate_locomotion(sc, 5, rig=rig)


def test_course_carries_a_lidar_whose_points_land_on_the_true_surfaces(course_with_lidar):
    sc, ep = course_with_lidar
    scans = [f for f in ep.frames if isinstance(f, LidarScan)]
    assert len(scans) == len(ep.truth.lidar) >= 10
    assert {"rgbd_head", "imu_head", "odom_head", "lidar_trunk"} <= {f.sensor_id for f in ep.frames}
    assert "lidar_trunk" in {m.sensor_id for m in ep.calibration.mounts}
    assert ep.calibration.extra["camera"] == "rgbd_head"
    kinds = set()
    for scan, lt in zip(scans, ep.truth.lidar):
        direct = lt.kind == int(ReturnKind.GENUINE)
        assert direct.mean() > 0.5
        p_w = lt.origin_w + lt.dir_w * np.linalg.norm(scan.points_xyz, axis=1)[:, None]
        assert np.all(np.linalg.norm(p_w[direct] - lt.hit_w[direct], axis=1) < 1e-6)
        for sid in np.unique(lt.surface_id[direct & (lt.surface_id >= 0)]):
            s = ep.truth.scene.surface(int(sid))
            kinds.add(s.kind)
            sel = direct & (lt.surface_id == sid)
            assert np.all(np.abs((p_w[sel] - s.point_w) @ s.normal_w) < 1e-3)
    assert len(kinds) >= 2  # the floor and the course's walls or steps


def test_course_lidar_preset_extends_the_default_rig():
    from exobench.envs.sim import LocomotionScenario

    ids = [s.sensor_id for s in LocomotionScenario(extra_sensors="lidar_trunk").rig()]
    assert ids[0] == "imu_head" and ids[-1] == "lidar_trunk"
