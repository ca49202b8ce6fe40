"""The ``dvio`` and ``dvio-no-depth`` pipelines on a short simulated course walk (chest camera at
424x240 and 30 Hz, its IMU at 200 Hz with a D455's extrinsics and clock offset, textured walls),
scored against the episode's true camera poses; faulty input; bad parameters."""

import dataclasses

import numpy as np
import pytest

from exobench.benchmarks.trajectory import umeyama_alignment
from exobench.core.errors import ConfigError, PipelineStateError
from exobench.core.frames import ImuSample, RgbdFrame
from exobench.envs.sim.scenarios.course import LocomotionScenario, simulate_locomotion
from exobench.mapping.odometry.dvio.pipeline import DvioConfig, DvioNoDepthPipeline, DvioPipeline

pytestmark = pytest.mark.long(seconds=10)  # the workers take it first (tests/conftest.py); 10: the file at -n 0 in one run at load 12-15, scaled to that run's CPU

FAST = {"window": 6, "init_keyframes": 6}  # a shorter window keeps the test's run short


@pytest.fixture(scope="module")
def walk():
    sc = LocomotionScenario(terrain="stairs", mount="chest", surfaces="textured", duration_cap_s=5.0,
                            imu_extrinsics="d455", imu_time_offset_s=0.0025)
    return simulate_locomotion(sc, 0)


def run(cls, episode, frames=None, imu_rate=None, **config):
    """The pipeline's estimate; the IMU-rate poses it returned are appended to ``imu_rate``."""
    p = cls(cls.Config(**{**FAST, **config}))
    p.reset(episode.calibration)
    for f in episode.frames if frames is None else frames:
        out = p.process(f)
        if out is not None and imu_rate is not None:
            imu_rate.append(out)
    return p.finalize()


def ate(est, episode):
    t_cam = np.asarray(episode.truth.extra["camera_stamps_s"])
    T_cam = np.asarray(episode.truth.extra["camera_T_world"])
    ok = np.array([s == "ok" for s in est.status])
    idx = [int(np.argmin(np.abs(t_cam - t))) for t in est.stamps_s[ok]]
    P, Q = est.T_world_sensor[ok][:, :3, 3], T_cam[idx][:, :3, 3]
    R, t, _ = umeyama_alignment(P, Q)
    return float(np.sqrt(np.mean(np.sum((P @ R.T + t - Q) ** 2, axis=1))))


def test_dvio_tracks_a_simulated_course_walk(walk):
    imu_rate = []
    est = run(DvioPipeline, walk, imu_rate=imu_rate)
    n_rgbd = sum(isinstance(f, RgbdFrame) for f in walk.frames)
    assert len(est.stamps_s) == n_rgbd == est.counts["rgbd"].used
    assert est.counts["imu"].used == sum(isinstance(f, ImuSample) for f in walk.frames)
    assert est.status[0] == "initialising" and est.status[-1] == "ok"
    ok = np.array([s == "ok" for s in est.status])
    assert ok.mean() > 0.6  # initialised within the first 2 s of 5
    assert np.all(np.isnan(est.T_world_sensor[~ok])) and np.all(np.isfinite(est.T_world_sensor[ok]))
    assert est.stats["reinitialisations"] == 0 and est.stats["keyframes"] >= 10
    assert 0.0 < est.stats["init_s"] < 2.5
    # Gravity-aligned: the estimate's z axis is the world's up to the yaw-only alignment.
    T_cam = np.asarray(walk.truth.extra["camera_T_world"])
    t_cam = np.asarray(walk.truth.extra["camera_stamps_s"])
    k = int(np.argmin(np.abs(t_cam - est.stamps_s[-1])))
    assert np.allclose(est.T_world_sensor[-1][2, :3], T_cam[k][2, :3], atol=0.05)
    # About 3 m of walk: the paper's D-VIO reaches 0.05-0.19 m over 35-90 m of EuRoC.
    assert ate(est, walk) < 0.05
    # The IMU-rate pose (200 Hz) in the same frame: the camera it implies lies near the frame
    # poses around it (linear motion between two frames 33 ms apart). It propagates the newest
    # keyframe's state, the frames are PnP-refined: measured median 5 mm, largest 2.5 cm.
    assert len(imu_rate) > 5 * ok.sum()
    T_ci = np.asarray(walk.calibration.extra["T_camera_imu"])
    t_ok, P_ok = est.stamps_s[ok], est.T_world_sensor[ok][:, :3, 3]
    gaps = []
    for r in imu_rate[::20]:
        k = np.searchsorted(t_ok, r.stamp_s)
        if 0 < k < len(t_ok) and t_ok[k] - t_ok[k - 1] < 0.05:
            a = (r.stamp_s - t_ok[k - 1]) / (t_ok[k] - t_ok[k - 1])
            cam = (r.T_world_imu @ np.linalg.inv(T_ci))[:3, 3]
            gaps.append(np.linalg.norm(cam - ((1 - a) * P_ok[k - 1] + a * P_ok[k])))
    assert len(gaps) > 10 and np.median(gaps) < 0.01 and max(gaps) < 0.04


def test_dvio_no_depth_tracks_the_same_walk(walk):
    est = run(DvioNoDepthPipeline, walk)
    assert est.stats["depth_factors"] is False
    # Measured 7.6 mm (dvio: 8.9 mm with this 6-keyframe window; 6.9 mm against 8.3 mm over 6 s
    # with the default 10): on walks this short the depth factors do not lower the ATE reliably.
    assert ate(est, walk) < 0.05


def test_feature_depth_is_bilinear_on_a_surface_and_none_on_a_depth_edge(walk):
    p = DvioPipeline()
    p.reset(walk.calibration)
    # A plane tilted along x (depth 1 m + 1 mm per pixel) with a step to 3 m from column 40 on.
    depth = 1.0 + 0.001 * np.tile(np.arange(60, dtype=float), (40, 1))
    depth[:, 40:] = 3.0
    depth[5, 5] = 0.0  # no measurement
    pts = np.array([[10.25, 20.5], [39.5, 10.0], [5.5, 5.0], [50.0, 30.0]])
    d = p._depth_at(depth, pts)
    assert d[0] == pytest.approx(1.01025, abs=1e-9)  # between pixels 10 and 11
    assert np.isnan(d[1])  # straddles the step
    assert np.isnan(d[2])  # touches the hole
    assert d[3] == pytest.approx(3.0)


def test_faulty_input_is_counted_and_survived(walk):
    rng = np.random.default_rng(0)
    frames = list(walk.frames)
    out = []
    rgbd_seen = 0
    for f in frames:
        if isinstance(f, ImuSample) and rng.uniform() < 0.1:
            continue  # a dropped IMU sample
        if isinstance(f, RgbdFrame):
            rgbd_seen += 1
            if rgbd_seen in (50, 51):
                continue  # two dropped frames
            if rgbd_seen == 70:
                f = dataclasses.replace(f, depth_m=np.zeros_like(f.depth_m))  # no depth
            if rgbd_seen == 80:
                f = dataclasses.replace(f, depth_m=np.full_like(f.depth_m, np.nan))
            if rgbd_seen == 90:
                out.append(f)  # repeated
        out.append(f)
    # Two frames swapped: the later one arrives first, the earlier is then out of order.
    i = [k for k, f in enumerate(out) if isinstance(f, RgbdFrame)][100:102]
    out[i[0]], out[i[1]] = out[i[1]], out[i[0]]
    est = run(DvioPipeline, walk, frames=out)
    c = est.counts["rgbd"]
    assert c.repeated == 1 and c.out_of_order == 1 and c.dropped >= 2 and c.nan == 1
    assert est.counts["imu"].dropped > 0
    assert est.stats["frames_without_depth"] >= 2
    assert est.status[-1] == "ok"
    assert ate(est, walk) < 0.08


def test_process_before_reset_and_bad_parameters_are_refused(walk):
    with pytest.raises(PipelineStateError):
        DvioPipeline().process(walk.frames[0])
    with pytest.raises(ConfigError, match="window"):
        DvioConfig(window=2)
    with pytest.raises(ConfigError, match="kernel"):
        DvioConfig(kernel="tukey")
    with pytest.raises(ConfigError, match="max_features"):
        DvioConfig(max_features=0)
    with pytest.raises(ConfigError, match="update_slack_m"):
        DvioConfig(update_slack_m=-0.1)
    with pytest.raises(ConfigError, match="max_gyro_bias"):
        DvioConfig(max_gyro_bias=0.0)
    with pytest.raises(ConfigError, match="max_depth_misfit"):  # the pipeline's field reaches the window's check
        DvioConfig(max_depth_misfit=-1.0)
    with pytest.raises(ConfigError, match="max_init_tilt_deg"):
        DvioConfig(max_init_tilt_deg=181.0)
    with pytest.raises(ConfigError, match="max_init_gyro_bias"):
        DvioConfig(max_init_gyro_bias=float("nan"))
    with pytest.raises(ConfigError, match="linear_solver"):
        DvioConfig(linear_solver="lu")
    cal = walk.calibration
    bent = dataclasses.replace(cal, extra={**cal.extra, "T_camera_imu": (2.0 * np.eye(4)).tolist()})
    with pytest.raises(ConfigError, match="T_camera_imu"):
        DvioPipeline().reset(bent)
    cam = cal.mount(cal.extra["camera"])
    blind = dataclasses.replace(cam, params={**cam.params, "fx_px": 0.0})
    broken = dataclasses.replace(cal, mounts=tuple(blind if m is cam else m for m in cal.mounts))
    with pytest.raises(ConfigError, match="fx_px"):
        DvioPipeline().reset(broken)
    shifted = dataclasses.replace(cal, extra={**cal.extra, "timeshift_cam_imu_s": 0.5})
    with pytest.raises(ConfigError, match="timeshift"):
        DvioPipeline().reset(shifted)
