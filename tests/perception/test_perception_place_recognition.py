"""Place-recognition pipelines (seeds/003 4.2.3): keys, column-shift yaw, Huber weights, faulty scans.

Scans are built here as LidarScan frames of synthetic places (ground ring, boxes of random size
and height, a place-dependent intensity); the expected values come from the construction (a
known yaw, a known ceiling) or from the equations written out here.
"""

import math

import numpy as np
import pytest

from exobench.core.calibration import Calibration, SensorMount
from exobench.core.errors import ConfigError
from exobench.core.frames import ImuSample, LidarScan
from exobench.perception.place_recognition import (
    GaussianPlaceRecognitionConfig,
    GscHeightPipeline,
    GscHuberPipeline,
    GscIntensityPipeline,
    PlaceRecognitionConfig,
    ScanContextPPPipeline,
    remove_ceiling,
)
from exobench.perception.place_recognition.gaussian_scan_context import (
    GaussianScanContext,
    GaussianScanContextConfig,
    huber_weights,
)
from exobench.perception.place_recognition.recognizer import ScanContextPP
from exobench.perception.place_recognition.scan_context import ScanContextConfig, ring_key

PIPELINES = (ScanContextPPPipeline, GscHeightPipeline, GscHuberPipeline, GscIntensityPipeline)
SECTOR = 2 * math.pi / 60


def _rot_z(p, yaw):
    c, s = math.cos(yaw), math.sin(yaw)
    return p @ np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]]).T


def _place(seed, n_boxes=30, extent=15.0):
    """(points (N, 3), intensity (N,)): ground 1.7 m below the sensor and boxes around it."""
    rng = np.random.default_rng(seed)
    r = 12 * np.sqrt(rng.random(3000))
    a = rng.uniform(0, 2 * np.pi, 3000)
    parts = [np.column_stack([r * np.cos(a), r * np.sin(a), np.full(3000, -1.7)])]
    inten = [np.full(3000, 10.0)]
    for _ in range(n_boxes):
        c = rng.uniform(-extent, extent, 2)
        s = rng.uniform(0.5, 3, 2)
        h = rng.uniform(0.3, 2.2)
        m = int(150 * s.sum())
        parts.append(np.column_stack([c + rng.uniform(-s / 2, s / 2, (m, 2)), rng.uniform(-1.7, -1.7 + h, m)]))
        inten.append(np.full(m, rng.uniform(20, 90)))
    return np.concatenate(parts), np.concatenate(inten)


def _scan(points, intensity, t):
    n = len(points)
    return LidarScan(stamp_s=t + 0.1, sensor_id="lidar", points_xyz=np.asarray(points, dtype=float),
                     intensity=np.asarray(intensity), ring=np.zeros(n, dtype=np.int16),
                     time_offset_s=np.zeros(n), sweep_start_s=t)  # fmt: skip


def _calibration():
    mounts = (
        SensorMount("lidar", "lidar", "pelvis", np.eye(4), {"rate_hz": 10.0}),
        SensorMount("imu", "imu", "pelvis", np.eye(4), {}),
    )
    return Calibration("<robot/>", "pelvis", (), mounts, 0.1, 0.25, 0.05)


def _run(cls, scans, imu=(), **cfg):
    pipe = cls(cls.Config(keyframe_every=1, exclude_recent=0, **cfg))
    pipe.reset(_calibration())
    frames = sorted([*imu, *scans], key=lambda f: f.stamp_s)
    for f in frames:
        pipe.process(f)
    return pipe, pipe.finalize()


@pytest.mark.parametrize("cls", PIPELINES)
def test_rotated_scan_is_matched_with_its_yaw(cls):
    p0, i0 = _place(1)
    p1, i1 = _place(2)
    yaw = 1.3  # not a multiple of the 6 deg sector
    scans = [_scan(p0, i0, 0.0), _scan(p1, i1, 1.0), _scan(_rot_z(p0, yaw), i0, 2.0)]
    _, est = _run(cls, scans)
    assert est.match_index.tolist()[2] == 0
    # the query is the match rotated by +yaw (PlaceMatch's convention); within one sector
    assert abs((est.yaw_rad[2] - yaw + math.pi) % (2 * math.pi) - math.pi) <= SECTOR
    assert est.distance[2] < est.distance[1]
    assert est.match_index[0] == -1 and math.isinf(est.distance[0])
    assert est.time_per_keyframe_s.shape == (3,) and np.all(est.time_per_keyframe_s > 0)


def test_ring_key_is_invariant_and_matrix_shifts_by_whole_sectors():
    pts, _ = _place(3)
    sc = ScanContextPP(ScanContextConfig(max_radius_m=20.0))
    k = 7
    a = sc.describe(pts)
    b = sc.describe(_rot_z(pts, k * SECTOR + 1e-9))  # by exactly k sectors (off the bin edges)
    np.testing.assert_array_equal(a.ring_key, b.ring_key)
    np.testing.assert_allclose(b.matrix, np.roll(a.matrix, k, axis=1))
    np.testing.assert_array_equal(ring_key(a.matrix), np.count_nonzero(a.matrix, axis=1))  # eq. (4.23)


def test_huber_weights_and_bin_statistics_follow_eq_4_31_to_4_33():
    np.testing.assert_allclose(huber_weights(np.array([0.0, 0.5, 1.0, 2.0, -4.0]), 1.0), [1, 1, 1, 0.5, 0.25])
    # one bin (a 1x1 grid): three points at z = 0, 0.2, 0.4 and an outlier 3 m above
    z = np.array([0.0, 0.2, 0.4, 3.4])
    pts = np.column_stack([np.full(4, 1.0), np.zeros(4), z])
    cfg = dict(n_rings=1, n_sectors=1, max_radius_m=5.0, height_offset_m=0.0, min_points=1, alpha=2.0, delta_m=1.0)
    mu = z.mean()  # eq. (4.26) over x, y, z (x, y equal): residual = |z - mu|, eq. (4.29)
    w = np.where(np.abs(z - mu) <= 1.0, 1.0, 1.0 / np.abs(z - mu))  # eq. (4.31)
    mu_h = np.sum(w * z) / w.sum()  # eq. (4.32)
    var_h = np.sum(w * (z - mu_h) ** 2) / w.sum()  # eq. (4.33)
    huber = GaussianScanContext(GaussianScanContextConfig(variant="huber", **cfg)).describe(pts)
    assert huber.matrix[0, 0] == pytest.approx(mu_h + 2.0 * var_h)  # eq. (4.28)
    plain = GaussianScanContext(GaussianScanContextConfig(variant="height", **cfg)).describe(pts)
    assert plain.matrix[0, 0] == pytest.approx(mu + 2.0 * z.var(ddof=1))  # eq. (4.26)-(4.28)
    assert huber.matrix[0, 0] < plain.matrix[0, 0]  # the outlier weighs less


@pytest.mark.parametrize("cls", PIPELINES)
def test_faulty_scans_give_invalid_keyframes_and_never_raise(cls):
    p0, i0 = _place(4)
    glass = np.column_stack([np.full(400, 1.2), np.linspace(-0.4, 0.4, 400), np.tile(np.linspace(-0.5, 0.5, 20), 20)])
    nan_scan = np.full((300, 3), np.nan)
    partly = p0.copy()
    partly[:50] = np.nan
    scans = [
        _scan(p0, i0, 0.0),
        _scan(np.zeros((0, 3)), np.zeros(0), 1.0),  # empty
        _scan(glass, np.full(400, 150.0), 2.0),  # only a glass pane next to the sensor
        _scan(nan_scan, np.full(300, 10.0), 3.0),  # all NaN
        _scan(partly, i0, 4.0),  # some NaN: still a valid keyframe, matching the first
    ]
    _, est = _run(cls, scans)
    assert est.match_index.tolist()[1:4] == [-1, -1, -1]
    assert np.all(np.isinf(est.distance[1:4]))
    assert est.match_index[4] == 0
    assert est.stats["invalid_keyframes"] == 3
    assert est.stats["descriptor_status"].get("too_few_cells") == 1
    lidar = est.counts["lidar"]
    assert (lidar.nan, lidar.nan_values, lidar.absurd, lidar.used) == (2, 300 + 50, 0, 5)


def test_submap_levels_scans_with_the_imu_and_removes_the_ceiling():
    # a ground plane and a ceiling seen by a sensor pitched by 10 deg (z up after levelling)
    rng = np.random.default_rng(5)
    xy = rng.uniform(-8, 8, (4000, 2))
    world = np.concatenate([np.column_stack([xy, np.full(4000, -1.7)]), np.column_stack([xy, np.full(4000, 1.0)])])
    pitch = math.radians(10)
    R = np.array([[math.cos(pitch), 0, math.sin(pitch)], [0, 1, 0], [-math.sin(pitch), 0, math.cos(pitch)]])
    sensor = world @ R  # p_sensor = R^T p_world
    q = [math.cos(pitch / 2), 0.0, math.sin(pitch / 2), 0.0]
    imu = [ImuSample(0.05 * k, "imu", np.array(q), np.zeros(3), np.zeros(3)) for k in range(40)]
    scans = [_scan(sensor, np.full(len(sensor), 20.0), 0.1 * k) for k in range(3)]
    pipe, _ = _run(ScanContextPPPipeline, scans, imu, on="submap", submap_scans=3, ceiling="none")
    pts, _ = pipe.cloud()
    assert len(pts) == 3 * len(world)
    np.testing.assert_allclose(np.sort(np.unique(np.round(pts[:, 2], 6))), [-1.7, 1.0], atol=1e-6)
    cfg = PlaceRecognitionConfig(ceiling="auto")
    keep, cut = remove_ceiling(pts, cfg)
    assert cut == pytest.approx(1.0 - cfg.ceiling_margin_m, abs=cfg.ceiling_bin_m)
    assert not np.any(keep & (pts[:, 2] > 0.5)) and np.all(keep[pts[:, 2] < 0])
    keep, cut = remove_ceiling(pts, PlaceRecognitionConfig(ceiling="fixed", ceiling_above_sensor_m=0.6))
    assert cut == 0.6 and np.array_equal(keep, pts[:, 2] <= 0.6)


def test_exclude_recent_and_bad_configs():
    p0, i0 = _place(6)
    scans = [_scan(p0, i0, float(k)) for k in range(4)]
    _, est = _run(ScanContextPPPipeline, scans)
    assert est.match_index[0] == -1 and all(0 <= m < k for k, m in enumerate(est.match_index.tolist()) if k)
    pipe = ScanContextPPPipeline(PlaceRecognitionConfig(keyframe_every=1, exclude_recent=2))
    pipe.reset(_calibration())
    for s in scans:
        pipe.process(s)
    est = pipe.finalize()
    assert est.match_index.tolist()[:3] == [-1, -1, -1] and est.match_index[3] == 0
    with pytest.raises(ConfigError):
        PlaceRecognitionConfig(on="map")
    with pytest.raises(ConfigError):
        PlaceRecognitionConfig(ceiling="attic")
    with pytest.raises(ConfigError):
        GaussianPlaceRecognitionConfig(alpha=0.0)
    with pytest.raises(ConfigError):
        PlaceRecognitionConfig(n_sectors=0)
    with pytest.raises(ConfigError):
        GscHuberPipeline(PlaceRecognitionConfig())


@pytest.mark.parametrize("variant", ("height", "huber", "intensity"))
def test_component_cells_equal_the_full_gaussian_reference(variant):
    from exobench.perception.place_recognition.component_gsc import ComponentGaussianScanContext

    pts, inten = _place(7)
    rng = np.random.default_rng(8)
    outliers = rng.uniform(-15, 15, (300, 3))  # spurious points (ghosts) inside the boxes' bins
    pts = np.concatenate([pts, outliers])
    inten = np.concatenate([inten, rng.uniform(0, 255, 300)])
    cfg = GaussianScanContextConfig(variant=variant, max_radius_m=20.0)
    ref = GaussianScanContext(cfg).describe(pts, inten)
    fast = ComponentGaussianScanContext(cfg).describe(pts, inten)
    np.testing.assert_allclose(fast.matrix, ref.matrix, rtol=1e-12, atol=1e-12)
    np.testing.assert_array_equal(fast.ring_key, ref.ring_key)


def test_scan_with_a_broken_intensity_channel_keeps_its_geometry():
    p0, i0 = _place(9)
    scans = [_scan(p0, i0, 0.0), _scan(_rot_z(p0, 0.5), i0[:10], 1.0)]
    _, est = _run(ScanContextPPPipeline, scans)
    assert est.match_index.tolist() == [-1, 0] and est.stats["bad_intensity_scans"] == 1
    _, est = _run(GscIntensityPipeline, scans)
    assert est.match_index.tolist() == [-1, -1] and est.stats["invalid_keyframes"] == 1
