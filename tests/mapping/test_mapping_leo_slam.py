"""LEO-SLAM (seeds/003 4.2.1) on synthetic VLP-16-like sweeps of a box world.

The scans are ray-cast analytically here (numpy only): a 16 x 12 m room, a 7 x 3 m block in
the middle that makes a loop corridor, pillars and furniture boxes. A sensor moving along a
rounded-rectangle loop (with pitch, roll and height oscillations) fires 16 rings x 180 azimuths;
every column is cast from the pose at its own firing time, so the sweeps carry the motion
distortion the pipeline must remove. Ground truth is the sensor pose at sweep start.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from exobench.core.errors import ConfigError
from exobench.core.estimates import TrajectoryEstimate
from exobench.core.frames import ImuSample, LidarScan
from exobench.mapping.odometry.gicp import GicpCloud, GicpConfig, align
from exobench.mapping.odometry.leo_slam import LeoSlamPipeline
from exobench.mapping.odometry.loop_closure import in_search_ellipsoid
from exobench.mapping.odometry.pose_graph import PoseGraph, PoseGraphConfig
from exobench.mapping.odometry.preprocess import PreprocessConfig, deskew, preprocess

pytestmark = pytest.mark.long(seconds=9)  # the workers take it first (tests/conftest.py); 9: the file at -n 0 in one run at load 12-15, scaled to that run's CPU

ROOM_MIN = np.array([-2.0, -2.0, 0.0])
ROOM_MAX = np.array([14.0, 10.0, 2.8])
BOXES = [  # (min corner, max corner)
    ((2.5, 2.5, 0.0), (9.5, 5.5, 2.8)),  # inner block: the loop corridor around it
    ((-1.0, 6.8, 0.0), (-0.6, 7.2, 2.8)),  # pillars
    ((11.0, 0.0, 0.0), (11.4, 0.4, 2.8)),
    ((12.2, 7.5, 0.0), (13.0, 8.5, 0.9)),  # furniture
    ((5.0, -1.8, 0.0), (6.2, -1.2, 0.75)),
    ((0.2, 8.5, 0.0), (1.0, 9.6, 1.6)),
    ((7.0, 8.8, 0.0), (7.6, 9.6, 2.0)),
    ((-1.8, 2.0, 0.0), (-1.2, 3.5, 1.1)),
    ((12.8, 2.5, 0.0), (13.8, 3.1, 1.9)),
]
SWEEP_S = 0.1
STEP_M = 0.35  # path length per sweep


def ray_cast(origins: np.ndarray, dirs: np.ndarray) -> np.ndarray:
    """Range of each ray to the first surface: the room from inside, the boxes from outside."""
    inv = 1.0 / np.where(np.abs(dirs) < 1e-12, 1e-12, dirs)
    r = np.min(np.maximum((ROOM_MIN - origins) * inv, (ROOM_MAX - origins) * inv), axis=1)
    for lo, hi in BOXES:
        a, b = (np.asarray(lo) - origins) * inv, (np.asarray(hi) - origins) * inv
        t_near, t_far = np.max(np.minimum(a, b), axis=1), np.min(np.maximum(a, b), axis=1)
        r = np.where((t_near <= t_far) & (t_near > 0) & (t_near < r), t_near, r)
    return r


def _rotations(yaw, pitch, roll):
    cy, sy, cp, sp, cr, sr = np.cos(yaw), np.sin(yaw), np.cos(pitch), np.sin(pitch), np.cos(roll), np.sin(roll)
    return np.stack([np.stack([cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr], -1),
                     np.stack([sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr], -1),
                     np.stack([-sp, cp * sr, cp * cr], -1)], axis=-2)


_TH = np.linspace(0.0, 2 * np.pi, 4000, endpoint=False)
_XY = np.column_stack([6.0 + 5.75 * np.sign(np.cos(_TH)) * np.abs(np.cos(_TH)) ** 0.5,
                       4.0 + 3.75 * np.sign(np.sin(_TH)) * np.abs(np.sin(_TH)) ** 0.5])  # superellipse n=4
_XY = np.vstack([_XY, _XY[:1]])
_ARC = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(_XY, axis=0), axis=1))])
PERIMETER = float(_ARC[-1])


def poses_at(s: np.ndarray) -> np.ndarray:
    """(K, 4, 4) true sensor poses at path lengths ``s``."""
    s = np.atleast_1d(np.asarray(s, dtype=float))
    u, u2 = s % PERIMETER, (s + 0.05) % PERIMETER
    x, y = np.interp(u, _ARC, _XY[:, 0]), np.interp(u, _ARC, _XY[:, 1])
    yaw = np.arctan2(np.interp(u2, _ARC, _XY[:, 1]) - y, np.interp(u2, _ARC, _XY[:, 0]) - x)
    T = np.tile(np.eye(4), (len(s), 1, 1))
    T[:, :3, :3] = _rotations(yaw, 0.03 * np.sin(2.1 * s), 0.02 * np.sin(1.3 * s))
    T[:, :3, 3] = np.column_stack([x, y, 1.2 + 0.02 * np.sin(3.0 * s)])
    return T


def make_scan(s0: float, moved_m: float, rng: np.random.Generator, n_az: int = 180, noise_m: float = 0.01):
    """``(points, time_offset_s, ring, T_world_sensor at sweep start)``; the sensor moves
    ``moved_m`` along the path during the sweep."""
    elev = np.deg2rad(np.linspace(-15.0, 15.0, 16))
    frac = np.arange(n_az) / n_az
    T = poses_at(s0 + frac * moved_m)
    A, E = np.meshgrid(2 * np.pi * frac, elev, indexing="ij")
    d = np.stack([np.cos(E) * np.cos(A), np.cos(E) * np.sin(A), np.sin(E)], axis=-1)  # (n_az, 16, 3)
    dw = np.einsum("kij,kmj->kmi", T[:, :3, :3], d).reshape(-1, 3)
    r = ray_cast(np.repeat(T[:, :3, 3], 16, axis=0), dw) + rng.normal(0.0, noise_m, n_az * 16)
    return d.reshape(-1, 3) * r[:, None], np.repeat(frac * SWEEP_S, 16), np.tile(np.arange(16), n_az), poses_at(s0)[0]


def loop_episode(seed: int = 7):
    """Sweeps around the loop and a bit beyond its start, with their true poses."""
    rng = np.random.default_rng(seed)
    scans, truth = [], []
    for k in range(int(np.ceil(PERIMETER / STEP_M)) + 3):
        p, tau, ring, T = make_scan(k * STEP_M, STEP_M, rng)
        scans.append(LidarScan(k * SWEEP_S + SWEEP_S, "lidar_trunk", p, np.full(len(p), 40.0), ring, tau,
                               k * SWEEP_S))
        truth.append(T)
    T0 = np.linalg.inv(truth[0])
    return scans, np.array([T0 @ T for T in truth])


def run(scans, **config) -> TrajectoryEstimate:
    pipe = LeoSlamPipeline(LeoSlamPipeline.Config(**config))
    pipe.reset(None)
    for frame in scans:
        assert pipe.process(frame) is None
    return pipe.finalize()


def rot_err_deg(R: np.ndarray) -> float:
    return float(np.degrees(np.arccos(np.clip((np.trace(R) - 1.0) / 2.0, -1.0, 1.0))))


@pytest.fixture(scope="module")
def episode():
    return loop_episode()


@pytest.fixture(scope="module")
def with_loops(episode):
    return run(episode[0])


# ------------------------------------------------------------------------------------ pieces


def test_gicp_recovers_a_known_relative_pose():
    rng = np.random.default_rng(3)
    pa, ta, _, Ta = make_scan(2.0, 0.0, rng, n_az=360, noise_m=0.005)  # no motion during the sweeps
    pb, tb, _, Tb = make_scan(2.3, 0.0, rng, n_az=360, noise_m=0.005)
    cfg = PreprocessConfig(deskew=False)
    A, B = GicpCloud(preprocess(pa, ta, cfg)[0]), GicpCloud(preprocess(pb, tb, cfg)[0])
    res = align(B, A, np.eye(4), GicpConfig())
    T_true = np.linalg.inv(Ta) @ Tb
    E = np.linalg.inv(T_true) @ res.T_target_source
    assert res.converged and res.status == "ok"
    assert np.linalg.norm(T_true[:3, 3]) > 0.25 and rot_err_deg(T_true[:3, :3]) > 5.0  # through a bend
    assert np.linalg.norm(E[:3, 3]) < 0.01
    assert rot_err_deg(E[:3, :3]) < 0.2


def test_gicp_reports_failure_instead_of_raising():
    few = GicpCloud(np.random.default_rng(0).normal(size=(5, 3)))
    res = align(few, few, np.eye(4), GicpConfig())
    assert not res.converged and res.status == "too_few_points"
    assert np.array_equal(res.T_target_source, np.eye(4))


def test_deskew_moves_points_to_the_sweep_start_frame():
    # a sensor moving at v along x and turning at w about z sees a fixed world point p_w
    v, w = 2.0, 0.8
    tau = np.linspace(0.0, 0.1, 11)
    p_w = np.array([3.0, 1.0, 0.5])
    R = np.array([[[np.cos(w * t), -np.sin(w * t), 0], [np.sin(w * t), np.cos(w * t), 0], [0, 0, 1]] for t in tau])
    # exact pose at tau under constant body twist: t(tau) = integral of R v dt
    t = np.column_stack([v * np.sin(w * tau) / w, v * (1 - np.cos(w * tau)) / w, np.zeros_like(tau)])
    p_tau = np.einsum("nji,nj->ni", R, p_w - t)  # the point in the sensor frame at tau
    out = deskew(p_tau, tau, np.array([v, 0, 0, 0, 0, w]))
    assert np.max(np.linalg.norm(out - p_w, axis=1)) < 0.01  # first order in translation
    assert np.max(np.linalg.norm(p_tau - p_w, axis=1)) > 0.15  # the distortion was real


def test_search_ellipsoid_is_eq_4_12():
    d = np.array([[2.0, 0.0, 0.0], [0.0, 2.9, 0.0], [1.5, 1.5, 0.5], [2.5, 2.0, 0.0], [0.0, 0.0, 1.2]])
    # (d_x / 3)^2 + (d_y / 3)^2 + (d_z / 1)^2: 0.44, 0.93, 0.75, 1.14, 1.44
    assert in_search_ellipsoid(d, np.array([3.0, 3.0, 1.0])).tolist() == [True, True, True, False, False]


def test_pose_graph_loop_factor_pulls_a_drifted_chain_back():
    # a 4 x 4 m square walked in 1 m steps; odometry has 3 deg of yaw error per corner
    def T(yaw, x, y):
        c, s_ = np.cos(yaw), np.sin(yaw)
        return np.array([[c, -s_, 0, x], [s_, c, 0, y], [0, 0, 1, 0], [0, 0, 0, 1.0]])

    true = []
    for side in range(4):
        for k in range(4):
            yaw = side * np.pi / 2
            start = [(0, 0), (4, 0), (4, 4), (0, 4)][side]
            true.append(T(yaw, start[0] + k * np.cos(yaw), start[1] + k * np.sin(yaw)))
    true.append(T(2 * np.pi, 0.0, 0.0))  # back at the start
    graph = PoseGraph(PoseGraphConfig())
    est = [true[0]]
    graph.add_node(0, true[0])
    for i in range(1, len(true)):
        rel = np.linalg.inv(true[i - 1]) @ true[i]
        if i % 4 == 0:
            rel = rel @ T(np.radians(3.0), 0, 0)
        est.append(est[-1] @ rel)
        graph.add_node(i, est[-1], rel)
    drift = np.linalg.norm(est[-1][:3, 3] - true[-1][:3, 3])
    graph.add_loop(len(true) - 1, 0, np.linalg.inv(true[-1]) @ true[0])  # eq. (4.14)
    closed = graph.pose(len(true) - 1)
    assert drift > 0.3
    assert np.linalg.norm(closed[:3, 3] - true[-1][:3, 3]) < 0.1 * drift
    assert np.allclose(graph.pose(0), true[0], atol=1e-3) and graph.n_loops == 1


def test_bad_config_raises_config_error():
    with pytest.raises(ConfigError):
        LeoSlamPipeline.Config(keyframe_distance_m=0.0)
    with pytest.raises(ConfigError):
        LeoSlamPipeline.Config(voxel_m=-1.0)
    with pytest.raises(ConfigError):
        LeoSlamPipeline.Config(sc_tau=1.5)


def test_registered_under_leo_slam():
    from exobench.benchmarks.registry import build_registry

    reg = build_registry(entry_points=False)
    cls = reg.load("leo-slam")
    assert cls is LeoSlamPipeline and cls.track == "odometry" and cls.name == "leo-slam"
    assert reg.make_config("leo-slam", {"loop_closure": "false"}).loop_closure is False


# ------------------------------------------------------------------------------------ pipeline


def test_loop_trajectory_is_tracked_and_closed(episode, with_loops):
    scans, gt = episode
    est = with_loops
    n = len(scans)
    assert est.T_world_sensor.shape == (n, 4, 4) and len(est.status) == n and len(est.time_per_scan_s) == n
    assert np.allclose(est.stamps_s, [s.sweep_start_s for s in scans])
    assert np.allclose(est.T_world_sensor[0], np.eye(4), atol=1e-9)
    assert set(est.status) == {"ok"}
    err = np.linalg.norm(est.T_world_sensor[:, :3, 3] - gt[:, :3, 3], axis=1)
    assert err.max() < 0.15 and np.sqrt(np.mean(err**2)) < 0.08
    rot = [rot_err_deg(gt[i][:3, :3].T @ est.T_world_sensor[i][:3, :3]) for i in range(n)]
    assert max(rot) < 2.0
    # a loop edge joins the end of the loop to its start: the true poses are close there
    assert est.loop_edges and est.stats["n_loops"] == len(est.loop_edges) >= 1
    for i, j in est.loop_edges:
        assert j - i > 60
        assert np.linalg.norm(gt[i][:3, 3] - gt[j][:3, 3]) < 3.0
    assert est.stats["n_keyframes"] >= 20 and est.stats["n_submaps"] == est.stats["n_keyframes"]
    # the corrected map lies on the true surfaces (the map frame is the first sensor pose)
    T_scene_map = poses_at(0.0)[0]
    m = est.map_points @ T_scene_map[:3, :3].T + T_scene_map[:3, 3]
    assert len(m) > 1000
    dist = _dist_to_scene(m)
    assert np.median(dist) < 0.05 and np.mean(dist < 0.2) > 0.95


def _dist_to_scene(p: np.ndarray) -> np.ndarray:
    """Distance of world points to the nearest room wall or box face (independent of SLAM)."""
    d = np.min(np.abs(np.concatenate([p - ROOM_MIN, ROOM_MAX - p], axis=1)), axis=1)
    for lo, hi in BOXES:
        lo, hi = np.asarray(lo), np.asarray(hi)
        outside = np.linalg.norm(np.maximum(np.maximum(lo - p, p - hi), 0.0), axis=1)
        inside = np.min(np.concatenate([p - lo, hi - p], axis=1), axis=1)
        d = np.minimum(d, np.where(outside > 0, outside, inside))
    return d


def test_loop_closure_reduces_the_end_point_error(episode, with_loops):
    scans, gt = episode
    without = run(scans, loop_closure=False)
    assert without.loop_edges == () and without.stats["n_loops"] == 0
    end_with = np.linalg.norm(with_loops.T_world_sensor[-1, :3, 3] - gt[-1, :3, 3])
    end_without = np.linalg.norm(without.T_world_sensor[-1, :3, 3] - gt[-1, :3, 3])
    assert end_with < end_without
    assert end_with < 0.05


def test_same_input_gives_bit_identical_output(episode, with_loops):
    again = run(episode[0])
    assert np.array_equal(again.T_world_sensor, with_loops.T_world_sensor)
    assert again.loop_edges == with_loops.loop_edges and again.status == with_loops.status
    assert np.array_equal(again.map_points, with_loops.map_points)


def test_faulty_scans_are_reported_and_tracking_continues(episode):
    scans, gt = episode
    n = 30
    s = list(scans[:n])
    nan_pts = s[8].points_xyz.copy()
    nan_pts[::3] = np.nan
    s[8] = dataclasses.replace(s[8], points_xyz=nan_pts)  # a third of the points NaN: still usable
    empty = np.zeros((0, 3))
    s[12] = dataclasses.replace(s[12], points_xyz=empty, intensity=np.zeros(0), ring=np.zeros(0, int),
                                time_offset_s=np.zeros(0))
    s[16] = dataclasses.replace(s[16], points_xyz=np.full_like(s[16].points_xyz, np.nan))
    s[20] = dataclasses.replace(s[20], points_xyz=s[20].points_xyz[:20], intensity=s[20].intensity[:20],
                                ring=s[20].ring[:20], time_offset_s=s[20].time_offset_s[:20])
    junk = np.random.default_rng(5).uniform(-20.0, 20.0, size=s[24].points_xyz.shape)
    s[24] = dataclasses.replace(s[24], points_xyz=junk)  # nothing to align with: tracking is lost
    imu = ImuSample(0.45, "imu", np.array([1.0, 0, 0, 0]), np.zeros(3), np.zeros(3))
    frames = [*s[:5], imu, *s[5:], s[-1]]  # an IMU sample (ignored) and a repeated sweep
    est = run(frames)
    # the repeated sweep is counted and not processed: no pose of its own
    assert len(est.status) == n and est.T_world_sensor.shape == (n, 4, 4)
    lidar = est.counts["lidar"]
    assert (lidar.seen, lidar.repeated, lidar.used, est.counts["imu"].ignored) == (n + 1, 1, n, 1)
    n_nan = int(np.count_nonzero(np.isnan(nan_pts[:, 0]))) + len(s[16].points_xyz)
    assert est.status[8] == "ok" and (lidar.nan, lidar.nan_values) == (2, n_nan)
    assert est.status[12] == "empty_scan" and est.status[16] == "empty_scan" and est.stats["n_empty"] == 2
    assert est.status[20] == "too_few_points" and est.stats["n_too_few_points"] == 1
    assert est.status[24] == "lost" and est.stats["n_lost"] == 1
    assert np.all(np.isfinite(est.T_world_sensor))
    err = np.linalg.norm(est.T_world_sensor[:n, :3, 3] - gt[:n, :3, 3], axis=1)
    good = [i for i in range(n) if est.status[i] == "ok"]
    assert err[good].max() < 0.15  # tracking resumed after every gap
    # a dropped sweep is bridged by the constant-velocity motion (0.35 m per sweep)
    assert err[12] < 0.2
