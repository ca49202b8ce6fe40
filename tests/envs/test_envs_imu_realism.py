"""What a worn D455's IMU meets beyond the kinematic motion: its extrinsics and clock offset to the
camera (against the kalibr calibration they come from and a rigid-body computation), and
heel-strike transients (against Light et al. 1980's tibia and skull peaks)."""

import dataclasses

import mujoco
import numpy as np
import pytest

from exobench.core import ConfigError, ImuSample
from exobench.envs.motion import climb_step
from exobench.envs.sensors import ImuConfig, RgbdConfig
from exobench.envs.sensors.adapter import MountedSensor
from exobench.envs.sensors.imu import impact
from exobench.envs.sim import StairScenario
from exobench.envs.sim.calibration import build_calibration
from exobench.envs.sim.compose import attached_sites
from exobench.envs.sim.rig import camera_rig
from exobench.envs.sim.scenarios.course import LocomotionScenario
from exobench.envs.sim.scenarios.stairs import compiled_staircase, record_climb

QUIET = dict(noise_scale=0.0, orientation_rms_deg=0.0)
# OpenVINS config/rs_d455/kalibr_imucam_chain.yaml, colour camera (848x480): T_cam_imu, timeshift_cam_imu
KALIBR_T_CAM_IMU = np.array([
    [0.9999654398038452, 0.007342326779113337, -0.003899927610975742, -0.027534314618518095],
    [-0.0073452195116216765, 0.9999727585590525, -0.0007279355223411334, -0.0030587146933711722],
    [0.0038944766308488753, 0.0007565561891287445, 0.9999921303062861, -0.023605118842939803],
    [0.0, 0.0, 0.0, 1.0],
])  # fmt: skip
KALIBR_TIMESHIFT_S = 0.002524377913673846


def _climb(sites=()):
    sc = StairScenario.paper_case("B")
    exo = sc.exo_spec()
    scene = compiled_staircase(sc.staircase_params(exo), exo, sites)
    motion = climb_step(exo, scene.truth, distance_m=sc.distance_m, yaw_deg=sc.yaw_deg)
    return exo, scene, motion


def _head_imu(**kw):
    return MountedSensor("imu_head", "imu", ImuConfig(rate_hz=1000.0, **QUIET, **kw), attached_to="rgbd_head")


def _record(rig, seed=0):
    exo, scene, motion = _climb(attached_sites(rig))
    rec = record_climb(scene, exo, motion, rig, seed)
    return exo, scene, motion, [f for f in rec.frames if isinstance(f, ImuSample)]


def test_d455_extrinsics_are_the_kalibr_calibration_and_reach_the_calibration():
    cfg = ImuConfig(extrinsics="d455")
    T = cfg.T_camera_imu()
    np.testing.assert_allclose(T, KALIBR_T_CAM_IMU, atol=1e-12)
    R = T[:3, :3]
    np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-9)
    assert np.linalg.det(R) == pytest.approx(1.0, abs=1e-9)
    # the BMI055 is left of (x right), above (y down) and behind (z forward) the colour camera
    assert T[0, 3] < -0.02 and T[1, 3] < 0.0 and T[2, 3] < -0.02
    exo = StairScenario.paper_case("B").exo_spec()
    rig = camera_rig("head", RgbdConfig(width_px=64, height_px=48), ImuConfig(extrinsics="d455"))
    cal = build_calibration(exo, rig)
    np.testing.assert_allclose(cal.extra["T_camera_imu"], KALIBR_T_CAM_IMU, atol=1e-12)
    mounts = {m.sensor_id: m for m in cal.mounts}
    parent, T_cam = exo.rgbd_mount("rgbd_head")
    assert mounts["imu_head"].parent_link == parent
    np.testing.assert_allclose(mounts["imu_head"].T_parent_sensor, T_cam @ KALIBR_T_CAM_IMU, atol=1e-12)
    # the default is the identity of before, and no time shift entry
    cal0 = build_calibration(exo, camera_rig("head", RgbdConfig(width_px=64, height_px=48)))
    np.testing.assert_array_equal(cal0.extra["T_camera_imu"], np.eye(4))
    assert "timeshift_cam_imu_s" not in cal0.extra


def test_imu_at_the_d455_offset_measures_the_lever_arm_of_a_rigid_body():
    # on the swinging thigh, where the lever arm matters most
    def thigh_imu(**kw):
        return MountedSensor("imu_thigh_r", "imu", ImuConfig(rate_hz=1000.0, **QUIET, **kw), attached_to="rgbd_thigh_r")

    _, scene, motion, at_cam = _record((thigh_imu(),))
    _, scene_d, _, at_imu = _record((thigh_imu(extrinsics="d455"),))
    # the site is where the calibration says: the camera's pose times T_camera_imu
    data = mujoco.MjData(scene_d.model)
    data.qpos[:] = motion.sample(scene_d.model, 1.0).qpos[0]
    mujoco.mj_forward(scene_d.model, data)
    cam = data.cam("rgbd_thigh_r")
    from exobench.models.exo import R_OPTICAL_MJCAMERA

    T_w_cam = np.eye(4)
    T_w_cam[:3, :3] = cam.xmat.reshape(3, 3) @ R_OPTICAL_MJCAMERA.T
    T_w_cam[:3, 3] = cam.xpos
    T_w_imu = T_w_cam @ KALIBR_T_CAM_IMU
    np.testing.assert_allclose(data.site("imu_thigh_r").xpos, T_w_imu[:3, 3], atol=1e-9)
    np.testing.assert_allclose(data.site("imu_thigh_r").xmat.reshape(3, 3), T_w_imu[:3, :3], atol=1e-9)
    # rigid body: f_imu = R^T (f_cam + alpha x r + omega x (omega x r)), gyro_imu = R^T omega
    R, r = KALIBR_T_CAM_IMU[:3, :3], KALIBR_T_CAM_IMU[:3, 3]
    t = np.array([f.stamp_s for f in at_cam])
    w = np.array([f.gyro_rad_s for f in at_cam])
    f_cam = np.array([f.accel_m_s2 for f in at_cam])
    f_imu = np.array([f.accel_m_s2 for f in at_imu])
    alpha = np.gradient(w, t, axis=0)
    expected = (f_cam + np.cross(alpha, r) + np.cross(w, np.cross(w, r))) @ R
    k = slice(5, -5)
    np.testing.assert_allclose(np.array([f.gyro_rad_s for f in at_imu])[k], (w @ R)[k], atol=1e-9)
    lever = np.abs(np.cross(alpha, r) + np.cross(w, np.cross(w, r)))[k].max()
    assert lever > 0.05  # the swing turns the thigh: the check below would see a missing lever arm
    np.testing.assert_allclose(f_imu[k], expected[k], atol=0.1 * lever)


def test_time_offset_shifts_the_imu_stamps_and_nothing_else():
    *_, base = _record((_head_imu(),))
    *_, shifted = _record((_head_imu(time_offset_s=KALIBR_TIMESHIFT_S),))
    assert len(base) == len(shifted)
    np.testing.assert_allclose([b.stamp_s + KALIBR_TIMESHIFT_S for b in base], [s.stamp_s for s in shifted], atol=1e-12)
    np.testing.assert_array_equal([b.accel_m_s2 for b in base], [s.accel_m_s2 for s in shifted])
    exo = StairScenario.paper_case("B").exo_spec()
    cal = build_calibration(exo, camera_rig("head", RgbdConfig(width_px=64, height_px=48),
                                            ImuConfig(time_offset_s=KALIBR_TIMESHIFT_S)))  # fmt: skip
    assert cal.extra["timeshift_cam_imu_s"] == KALIBR_TIMESHIFT_S
    assert {m.sensor_id: m for m in cal.mounts}["imu_head"].params["time_offset_s"] == KALIBR_TIMESHIFT_S


def test_heel_strike_peaks_are_light_1980s_and_attenuate_up_the_body():
    g = impact.G_M_S2
    s = np.linspace(0.0, 0.2, 200001)
    peak = {lv: (impact.PEAK_G[lv] * g * impact.waveform(s)).max() for lv in impact.PEAK_G}
    # Light, McLellan & Klenerman (1980): about 5 g at the tibia and 0.5 g at the skull, hard heels
    assert peak["shank"] == pytest.approx(5.0 * g, rel=1e-4)
    assert peak["head"] == pytest.approx(0.5 * g, rel=1e-4)
    assert peak["shank"] > peak["thigh"] > peak["trunk"] > peak["head"]
    # equal attenuation per joint (knee, hip, neck) between the two measured ends
    assert peak["thigh"] / peak["shank"] == pytest.approx(peak["trunk"] / peak["thigh"], rel=1e-9)
    assert peak["head"] / peak["trunk"] == pytest.approx(peak["trunk"] / peak["thigh"], rel=1e-9)
    # the transient starts at the touchdown and is over within 0.1 s
    assert impact.waveform(np.array([-1e-3, 0.0]))[0] == 0.0
    assert np.abs(impact.waveform(np.linspace(0.1, 0.5, 100))).max() == 0.0
    # a sensor on the other leg gets the trunk's figure; resilient heels (scale 0.5) halve it
    a = impact.impact_accel_world(s, [(0.0, "r")], "shank_l", 0.5)
    assert np.abs(a).max() == pytest.approx(0.5 * peak["trunk"], rel=1e-3)


@pytest.mark.parametrize("sid,body", [("imu_trunk", "pelvis"), ("imu_head", "head")])
def test_heel_strike_transients_appear_in_the_imu_at_the_touchdown(sid, body):
    def imu(scale):
        if sid == "imu_head":
            return _head_imu(heel_strike_scale=scale)
        return MountedSensor(sid, "imu", ImuConfig(rate_hz=1000.0, heel_strike_scale=scale, **QUIET))

    _, _, motion, calm = _record((imu(0.0),))
    _, _, _, shaken = _record((imu(1.0),))
    (step,) = motion.footsteps
    t = np.array([f.stamp_s for f in calm])
    diff = np.array([b.accel_m_s2 for b in shaken]) - np.array([a.accel_m_s2 for a in calm])
    # world vertical: rotate back with the true orientation (noiseless here)
    R = np.array([_R(f.quat_wxyz) for f in calm])
    vertical = np.einsum("nij,nj->ni", R, diff)
    level = "trunk" if body == "pelvis" else "head"
    expected = impact.PEAK_G[level] * impact.G_M_S2 * impact.waveform(t - step.touchdown_s)
    np.testing.assert_allclose(vertical[:, 2], expected, atol=1e-9)
    np.testing.assert_allclose(vertical[:, :2], 0.0, atol=1e-9)
    assert np.abs(diff[t < step.touchdown_s]).max() == 0.0
    assert np.abs(vertical[:, 2]).max() == pytest.approx(impact.PEAK_G[level] * impact.G_M_S2, rel=0.02)


def _R(q):
    w, x, y, z = q
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])  # fmt: skip


@pytest.mark.parametrize("make,field", [
    (lambda: ImuConfig(extrinsics="d435"), "imu.extrinsics"),
    (lambda: ImuConfig(time_offset_s=0.5), "imu.time_offset_s"),
    (lambda: ImuConfig(time_offset_s=float("nan")), "imu.time_offset_s"),
    (lambda: ImuConfig(heel_strike_scale=-1.0), "imu.heel_strike_scale"),
    (lambda: LocomotionScenario(imu_extrinsics="d435"), "imu_extrinsics"),
    (lambda: LocomotionScenario(imu_time_offset_s=0.2), "imu_time_offset_s"),
    (lambda: LocomotionScenario(heel_strike_scale=9.0), "heel_strike_scale"),
])  # fmt: skip
def test_bad_imu_realism_values_are_refused_naming_the_field(make, field):
    with pytest.raises(ConfigError) as err:
        make()
    assert err.value.field == field


def test_locomotion_parameters_feed_the_camera_imu():
    sc = LocomotionScenario(imu_extrinsics="d455", imu_time_offset_s=0.0025, heel_strike_scale=1.0)
    imu = next(s for s in sc.rig() if s.kind == "imu")
    assert dataclasses.astuple(imu.config)[-3:] == ("d455", 0.0025, 1.0)
    assert next(s for s in LocomotionScenario().rig() if s.kind == "imu").config == ImuConfig()
