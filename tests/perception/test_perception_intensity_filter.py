"""Ground-aware intensity filters (seeds/003 eq. 4.15-4.19) on constructed clouds.

The scene is built in the footprint frame ``f`` (ground z = 0, z up) and seen by a LiDAR 1.4 m
above it, pitched nose-down and rolled like a leaning trunk. Ground returns follow a Lambertian
law, intensity = 100 * 0.35 * cos(incidence) = 35 * 1.4 / range, so every ground point farther
than 35 * 1.4 / 16 = 3.06 m is below psi*_min = 16: the plain band loses most of the ground by
eq. (4.15) alone. The glass pane and its mirrored ghost return 110-255 (above psi*_max = 100)
from above the footprint, on vertical surfaces; genuine walls return 20-90.
"""

import math

import numpy as np
import pytest

from exobench.core.errors import ConfigError, UnknownNameError
from exobench.perception.lidar_filter import (
    FILTERS,
    FilterReason,
    FloorGroundConfig,
    FloorGroundFilter,
    IntensityBandConfig,
    IntensityThresholdFilter,
    NaiveGroundConfig,
    NaiveGroundFilter,
    NoFilter,
    NormalGroundConfig,
    NormalGroundFilter,
    make_filter,
)
from exobench.perception.lidar_filter.ground import fit_floor_plane
from exobench.perception.lidar_filter.normals import (
    estimate_normals,
    estimate_range_image_normals,
    range_image_index,
    range_image_normal_candidates,
)

H = 1.4  # sensor height above the footprint, m


def _rot(roll: float, pitch: float) -> np.ndarray:
    cr, sr, cp, sp = math.cos(roll), math.sin(roll), math.cos(pitch), math.sin(pitch)
    Rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    Ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    return Ry @ Rx


def _T(R: np.ndarray, t) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = t
    return T


def _to_sensor(p_f: np.ndarray, T_fs: np.ndarray) -> np.ndarray:
    return (p_f - T_fs[:3, 3]) @ T_fs[:3, :3]  # R^T (p - t), row-wise


def _grid(a, b, step):
    return np.arange(a, b + 1e-9, step)


@pytest.fixture(scope="module")
def scene():
    rng = np.random.default_rng(7)
    T_fs = _T(_rot(math.radians(3.0), math.radians(8.0)), [0.0, 0.0, H])
    gx, gy = np.meshgrid(_grid(-8, 8, 0.1), _grid(-3.9, 3.9, 0.1), indexing="ij")
    ground = np.column_stack([gx.ravel(), gy.ravel(), rng.normal(0.0, 0.005, gx.size)])
    ground = ground[np.hypot(ground[:, 0], ground[:, 1]) > 1.0]
    rng_m = np.linalg.norm(ground - T_fs[:3, 3], axis=1)
    psi_ground = np.round(100 * 0.35 * H / rng_m)
    py, pz = np.meshgrid(_grid(-1, 1, 0.05), _grid(0.2, 2.4, 0.05), indexing="ij")
    pane = np.column_stack([np.full(py.size, 3.0), py.ravel(), pz.ravel()])
    gy2, gz2 = np.meshgrid(_grid(-1.5, 1.5, 0.1), _grid(0.2, 2.4, 0.1), indexing="ij")
    ghost = np.column_stack([np.full(gy2.size, 6.0), gy2.ravel(), gz2.ravel()])
    spurious = np.concatenate([pane, ghost])
    psi_spurious = rng.integers(110, 256, len(spurious)).astype(float)
    wx, wz = np.meshgrid(_grid(-8, 8, 0.1), _grid(0.1, 2.5, 0.1), indexing="ij")
    walls = np.concatenate([np.column_stack([wx.ravel(), np.full(wx.size, s * 4.0), wz.ravel()]) for s in (-1, 1)])
    psi_walls = rng.integers(20, 91, len(walls)).astype(float)
    p_f = np.concatenate([ground, spurious, walls])
    labels = np.concatenate([np.zeros(len(ground)), np.ones(len(spurious)), np.full(len(walls), 2)]).astype(int)
    psi = np.concatenate([psi_ground, psi_spurious, psi_walls])
    return _to_sensor(p_f, T_fs), psi, labels, T_fs, p_f


def _fractions(result, labels):
    keep = result.keep
    return (keep[labels == 0].mean(), 1.0 - keep[labels == 1].mean(), keep[labels == 2].mean())


def test_plain_threshold_loses_most_ground_as_eq_4_15_says(scene):
    pts, psi, labels, T_fs, p_f = scene
    res = IntensityThresholdFilter().apply(pts, psi)
    ground_kept, spurious_removed, walls_kept = _fractions(res, labels)
    # independent: a ground point survives iff 35 * H / range >= 16, i.e. range <= 3.0625 m
    rng_m = np.linalg.norm(p_f[labels == 0] - [0, 0, H], axis=1)
    expected = np.mean(np.round(35 * H / rng_m) >= 16)
    assert ground_kept == pytest.approx(expected)
    assert ground_kept < 0.2
    assert spurious_removed == 1.0 and walls_kept == 1.0


@pytest.mark.parametrize("filt", [NaiveGroundFilter(), NormalGroundFilter()], ids=lambda f: f.name)
def test_ground_aware_filters_keep_ground_and_remove_spurious(scene, filt):
    pts, psi, labels, T_fs, _ = scene
    res = filt.apply(pts, psi, T_fs)
    ground_kept, spurious_removed, walls_kept = _fractions(res, labels)
    assert ground_kept > 0.95
    assert spurious_removed > 0.9
    assert walls_kept == 1.0
    assert res.status == "ok"
    # rescued points are exactly the out-of-band kept ones
    out = (psi < 16) | (psi > 100)
    assert np.array_equal(res.reason == FilterReason.KEPT_GROUND, out & res.keep)
    assert sum(res.counts().values()) == len(pts)


def test_naive_filter_decisions_on_hand_computed_points():
    # level LiDAR 1.4 m above the footprint: ^l z_f = -1.4, margin 0.05 -> ground iff z < -1.35
    T_fs = _T(np.eye(3), [0.0, 0.0, H])
    pts = np.array([
        [5.0, 0.0, -1.39],  # psi 5: out of band, ground -> kept (eq. 4.16 rescue)
        [5.0, 0.0, -1.30],  # psi 5: out of band, 0.10 m above the footprint -> dropped low
        [3.0, 1.0, 0.20],  # psi 200: too strong, high -> dropped high
        [3.0, 1.0, 0.20],  # psi 50: in band -> kept
        [2.0, 0.0, -1.42],  # psi 250: a ghost below the footprint is kept, as the thesis warns
        [4.0, 0.0, 0.0],  # psi 16: band edge, inclusive
        [4.0, 0.0, 0.0],  # psi 100: band edge, inclusive
        [4.0, 0.0, 0.0],  # psi 101
        [np.nan, 0.0, 0.0],  # invalid
    ])
    psi = np.array([5, 5, 200, 50, 250, 16, 100, 101, 50], dtype=float)
    res = NaiveGroundFilter().apply(pts, psi, T_fs)
    R = FilterReason
    assert res.reason.tolist() == [R.KEPT_GROUND, R.DROPPED_LOW_INTENSITY, R.DROPPED_HIGH_INTENSITY, R.KEPT_IN_BAND,
                                   R.KEPT_GROUND, R.KEPT_IN_BAND, R.KEPT_IN_BAND, R.DROPPED_HIGH_INTENSITY,
                                   R.DROPPED_INVALID]
    assert res.keep.tolist() == [True, False, False, True, True, True, True, False, False]
    # with the strict inequality of eq. (4.16) the point 1 cm above the footprint plane is lost
    strict = NaiveGroundFilter(NaiveGroundConfig(ground_margin_m=0.0)).apply(pts[:1], psi[:1], T_fs)
    assert not strict.keep[0]


def test_tilt_changes_the_naive_ground_classification_as_the_equation_says():
    pitch = math.radians(10.0)  # nose-down: sensor x axis = (cos, 0, -sin) in f
    c, s = math.cos(pitch), math.sin(pitch)
    T_fs = _T(_rot(0.0, pitch), [0.0, 0.0, H])
    p_f = np.array([[6.0, 0.0, 0.0],  # floor ahead, weak return
                    [-6.0, 0.0, 0.5]])  # a spurious strong return 0.5 m above the floor behind
    psi = np.array([5.0, 200.0])
    # by hand: p_l = R^T (p_f - t) with R = R_y(pitch): z_l = s * x + c * (z - H)
    z_l = s * p_f[:, 0] + c * (p_f[:, 2] - H)
    assert z_l[0] == pytest.approx(-0.3368, abs=1e-4) and z_l[1] == pytest.approx(-1.9282, abs=1e-4)
    pts = np.column_stack([c * p_f[:, 0] - s * (p_f[:, 2] - H), p_f[:, 1], z_l])
    np.testing.assert_allclose(pts, _to_sensor(p_f, T_fs), atol=1e-12)
    l_z_f = -c * H  # footprint origin in l: R^T (0 - t), z part
    level_cfg = NaiveGroundConfig(ground_test="below", use_full_transform=False)  # eq. (4.16) as written
    level = NaiveGroundFilter(level_cfg).apply(pts, psi, T_fs)
    full = NaiveGroundFilter(NaiveGroundConfig(ground_test="below")).apply(pts, psi, T_fs)
    # eq. (4.16) with the level assumption: ground iff z_l < ^l z_f + margin
    assert level.keep.tolist() == (z_l < l_z_f + 0.05).tolist() == [False, True]
    # full transform: ground iff the footprint height < margin (0.0 and 0.5 m)
    assert full.keep.tolist() == [True, False]
    # the level form with the band: the point 0.55 m below the level footprint is not ground either
    band = NaiveGroundFilter(NaiveGroundConfig(ground_test="band", use_full_transform=False)).apply(pts, psi, T_fs)
    assert band.keep.tolist() == [False, False]
    # level LiDAR: both forms agree
    T_level = _T(np.eye(3), [0.0, 0.0, H])
    pts_level = _to_sensor(p_f, T_level)
    a = NaiveGroundFilter(level_cfg).apply(pts_level, psi, T_level)
    b = NaiveGroundFilter().apply(pts_level, psi, T_level)
    assert a.keep.tolist() == b.keep.tolist() == [True, False]


@pytest.mark.parametrize("slope_deg, ground", [(0.0, True), (10.0, True), (20.0, False)])
def test_normal_filter_threshold_on_known_slopes(slope_deg, ground):
    # a planar patch of the given slope in f: theta_eta = cos(slope) (eq. 4.18), ground iff > 0.97
    T_fs = _T(_rot(math.radians(-4.0), math.radians(6.0)), [0.0, 0.0, H])
    u, v = np.meshgrid(_grid(0, 1, 0.05), _grid(-0.5, 0.5, 0.05), indexing="ij")
    a = math.radians(slope_deg)
    p_f = np.column_stack([3.0 + u.ravel() * math.cos(a), v.ravel(), u.ravel() * math.sin(a)])
    pts = _to_sensor(p_f, T_fs)
    filt = NormalGroundFilter()
    theta = filt.cosines(pts, T_fs)
    np.testing.assert_allclose(theta, math.cos(a), atol=1e-9)
    res = filt.apply(pts, np.full(len(pts), 5.0), T_fs)
    assert bool(res.keep.all()) is ground and bool(res.keep.any()) is ground


def test_normals_face_the_sensor_and_are_undefined_on_a_line():
    p = np.column_stack([np.linspace(2, 3, 20), np.zeros(20), np.full(20, -1.0)])  # one ring segment
    assert np.isnan(estimate_normals(p)).all()
    gx, gy = np.meshgrid(np.linspace(2, 3, 6), np.linspace(-0.5, 0.5, 6))
    ceiling = np.column_stack([gx.ravel(), gy.ravel(), np.full(36, 1.0)])
    floor = ceiling * [1, 1, -1]
    np.testing.assert_allclose(estimate_normals(ceiling), np.tile([0, 0, -1.0], (36, 1)), atol=1e-9)
    np.testing.assert_allclose(estimate_normals(floor), np.tile([0, 0, 1.0], (36, 1)), atol=1e-9)
    # a ceiling is not ground: theta = -1
    assert not NormalGroundFilter().apply(ceiling, np.full(36, 5.0), np.eye(4)).keep.any()


@pytest.mark.parametrize("name", sorted(FILTERS))
def test_empty_and_glass_only_scans_are_reported_not_raised(name):
    filt = make_filter(name)
    T_fs = _T(np.eye(3), [0.0, 0.0, H])
    empty = filt.apply(np.zeros((0, 3)), np.zeros(0), T_fs)
    assert empty.status == "empty_input" and empty.keep.shape == (0,)
    py, pz = np.meshgrid(_grid(-1, 1, 0.1), _grid(-1.0, 1.0, 0.1))
    glass = np.column_stack([np.full(py.size, 3.0), py.ravel(), pz.ravel()])
    res = filt.apply(glass, np.full(len(glass), 230.0), T_fs)
    if name == "none":
        assert res.status == "ok" and res.keep.all()
    else:
        assert res.status == "all_removed" and not res.keep.any()


def test_missing_transform_falls_back_to_the_band_and_says_so():
    pts = np.array([[5.0, 0.0, -1.39], [3.0, 0.0, 0.0]])
    psi = np.array([5.0, 50.0])
    for filt in (NaiveGroundFilter(), NormalGroundFilter()):
        for T in (None, np.full((4, 4), np.nan)):
            res = filt.apply(pts, psi, T)
            assert res.status == "no_transform" and res.keep.tolist() == [False, True]


def test_registry_and_config_errors():
    assert isinstance(make_filter("none"), NoFilter)
    assert make_filter("naive-ground", ground_margin_m=0.1).config.ground_margin_m == 0.1
    with pytest.raises(UnknownNameError):
        make_filter("median")
    with pytest.raises(ConfigError):
        make_filter("threshold", bogus=1)
    with pytest.raises(ConfigError):
        IntensityBandConfig(intensity_min=120, intensity_max=100)
    with pytest.raises(ConfigError):
        NormalGroundConfig(epsilon_eta=0.0)
    with pytest.raises(ConfigError):
        NormalGroundConfig(normal_k=2)
    with pytest.raises(ConfigError):
        NaiveGroundConfig(ground_margin_m=-0.1)
    with pytest.raises(ConfigError):
        NaiveGroundFilter().apply(np.zeros((2, 3)), np.zeros(2), np.eye(3))


# ------------------------------------------------------------------ range-image normals (VLP-16-like rings)

ELEV_DEG = np.arange(-15.0, 16.0, 2.0)  # 16 rings, 2 deg apart (ring 0 lowest)
AZ_STEP_DEG = 0.2


def _ring_scan(T_fs: np.ndarray, half_x_m: float = 6.0, half_y_m: float = 5.0, noise_m: float = 0.0, seed: int = 0,
               shuffle: bool = True, max_range_m: float = 40.0):  # fmt: skip
    """A VLP-16-like sweep cast analytically inside a room: floor z_f = 0, walls x_f = +-half_x_m,
    y_f = +-half_y_m (no ceiling: upward rays that leave over the walls are no return).

    Rays in the sensor frame (ring r at ELEV_DEG[r], azimuth steps of 0.2 deg, ring-dependent
    phase as interleaved lasers have), rotated into f; each ray hits the nearest plane in front
    of it. Returns points (sensor frame), ring, the true unit normal of the hit plane facing the
    sensor (sensor frame) and whether the hit is on the floor."""
    rng = np.random.default_rng(seed)
    az = np.radians(np.arange(0.0, 360.0, AZ_STEP_DEG))
    rows = []
    for r, e in enumerate(np.radians(ELEV_DEG)):
        a = az + np.radians(AZ_STEP_DEG) * r / 16.0
        rows.append(np.column_stack([np.cos(e) * np.cos(a), np.cos(e) * np.sin(a), np.full(len(a), np.sin(e)),
                                     np.full(len(a), r)]))  # fmt: skip
    rays = np.concatenate(rows)
    d_l, ring = rays[:, :3], rays[:, 3].astype(np.uint16)
    R, o = T_fs[:3, :3], T_fs[:3, 3]
    d_f = d_l @ R.T
    planes = [(2, 0.0, [0.0, 0.0, 1.0]), (0, half_x_m, [-1.0, 0.0, 0.0]), (0, -half_x_m, [1.0, 0.0, 0.0]),
              (1, half_y_m, [0.0, -1.0, 0.0]), (1, -half_y_m, [0.0, 1.0, 0.0])]  # fmt: skip
    ts = []
    with np.errstate(divide="ignore", invalid="ignore"):
        for axis, value, _ in planes:
            t = (value - o[axis]) / d_f[:, axis]
            ts.append(np.where(t > 0, t, np.inf))
    ts = np.array(ts)
    which = np.argmin(ts, axis=0)
    t = ts[which, np.arange(len(which))]
    z_hit = o[2] + t * d_f[:, 2]
    hit = np.isfinite(t) & (t < max_range_m) & (z_hit < 3.0)
    n_f = np.array([pl[2] for pl in planes])[which]
    on_floor = which == 0
    rng_m = t + rng.normal(0.0, noise_m, len(t)) if noise_m else t
    pts = d_l * rng_m[:, None]
    n_l = n_f @ R  # R^T n, row-wise
    pts, ring, n_l, on_floor = pts[hit], ring[hit], n_l[hit], on_floor[hit]
    if shuffle:  # the organisation must not depend on the point order
        perm = rng.permutation(len(pts))
        pts, ring, n_l, on_floor = pts[perm], ring[perm], n_l[perm], on_floor[perm]
    return pts, ring, n_l, on_floor


def _angle_deg(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.degrees(np.arccos(np.clip(np.einsum("ni,ni->n", a, b), -1.0, 1.0)))


@pytest.fixture(scope="module")
def tilted_sensor():
    return _T(_rot(math.radians(2.0), math.radians(5.0)), [0.0, 0.0, 1.2])


def test_range_image_organises_rings_and_azimuth(tilted_sensor):
    pts, ring, _, _ = _ring_scan(tilted_sensor)
    index, step = range_image_index(pts, ring)
    assert step == pytest.approx(math.radians(AZ_STEP_DEG), rel=1e-6)
    assert index.shape == (16, 1800) and len(pts) > 0.5 * index.size
    idx = index[index >= 0]
    assert len(idx) == len(np.unique(idx)) == len(pts)  # every return in its own cell
    rows, _ = np.nonzero(index >= 0)
    assert np.array_equal(ring[index[index >= 0]], rows)  # rows are the rings, lowest first
    # rows sorted by elevation, not by ring number: relabelled rings give the same image
    perm = np.array([3, 0, 15, 7, 1, 2, 4, 5, 6, 8, 9, 10, 11, 12, 13, 14], dtype=np.uint16)
    index2, _ = range_image_index(pts, perm[ring])
    assert np.array_equal(index2, index)


@pytest.mark.parametrize("noise_m", [0.0, 0.015])
def test_range_image_normals_of_floor_and_wall(tilted_sensor, noise_m):
    pts, ring, n_true, on_floor = _ring_scan(tilted_sensor, noise_m=noise_m, seed=3)
    normals = estimate_range_image_normals(pts, ring)
    defined = ~np.isnan(normals[:, 0])
    assert defined[on_floor].mean() > 0.85 and defined[~on_floor].mean() > 0.85  # NaN near creases
    err = _angle_deg(normals, n_true)
    floor, wall = defined & on_floor, defined & ~on_floor
    if noise_m == 0:  # exact but where a window reaches across a crease (room corners, wall bases)
        assert np.median(err[defined]) < 0.1 and np.percentile(err[defined], 90) < 2.0, np.percentile(err[defined], [50, 90])
    else:  # 1.5 cm range noise over 4-column (0.8 deg) azimuth windows: a few degrees
        assert np.median(err[floor]) < 3.5 and np.median(err[wall]) < 6.5, (np.median(err[floor]), np.median(err[wall]))
    # oriented towards the sensor: n . (0 - p) > 0
    assert (np.einsum("ni,ni->n", normals[defined], -pts[defined]) > 0).all()
    # the filter on weak returns: floor kept (eq. 4.19 via the one-sided normals), wall removed
    res = NormalGroundFilter().apply(pts, np.full(len(pts), 5.0), tilted_sensor, ring=ring)
    assert res.normal_method == "range-image"
    assert res.keep[on_floor].mean() > 0.97
    assert res.keep[~on_floor].mean() < 0.03


def test_range_image_undefined_at_depth_jumps_and_sparse_rings(tilted_sensor):
    pts, ring, _, on_floor = _ring_scan(tilted_sensor)
    # a lone return far behind its neighbours (a ghost behind glass) has no ring or azimuth side
    k = np.flatnonzero(~on_floor & (ring == 10))[50]
    pts2 = pts.copy()
    pts2[k] *= 2.0
    cand = range_image_normal_candidates(pts2, ring)
    assert np.isnan(cand[k]).all()
    # a ring with a single return: fewer azimuth neighbours than needed -> NaN, no crash
    one = np.flatnonzero(ring == 0)[:1]
    sel = np.concatenate([one, np.flatnonzero(ring == 1)])
    cand = range_image_normal_candidates(pts[sel], ring[sel])
    assert np.isnan(cand[0]).all()


def test_range_image_falls_back_to_knn_without_rings(tilted_sensor):
    pts, ring, _, _ = _ring_scan(tilted_sensor)
    assert range_image_index(pts, None) is None
    assert range_image_index(pts, np.zeros(len(pts), dtype=np.uint16)) is None  # one ring: not a spinning scan
    assert range_image_index(pts, ring[:-1]) is None  # mismatched length
    psi = np.full(len(pts), 5.0)
    filt = NormalGroundFilter()
    assert filt.apply(pts, psi, tilted_sensor).normal_method == "knn"
    assert filt.apply(pts, psi, tilted_sensor, ring=np.zeros(len(pts))).normal_method == "knn"
    knn = NormalGroundFilter(NormalGroundConfig(normal_method="knn"))
    res_knn = knn.apply(pts, psi, tilted_sensor, ring=ring)
    assert res_knn.normal_method == "knn"
    # the knn method is the thesis' PCL one, unchanged: same mask as the ring-less call
    assert np.array_equal(res_knn.keep, filt.apply(pts, psi, tilted_sensor).keep)


def test_range_image_nan_and_empty_inputs(tilted_sensor):
    pts, ring, _, on_floor = _ring_scan(tilted_sensor, shuffle=False)
    bad = pts.copy()
    bad[::97] = np.nan
    psi = np.full(len(pts), 5.0)
    psi[5] = np.nan
    res = NormalGroundFilter().apply(bad, psi, tilted_sensor, ring=ring)
    assert res.normal_method == "range-image"
    invalid = np.isnan(bad[:, 0]) | np.isnan(psi)
    assert (res.reason[invalid] == FilterReason.DROPPED_INVALID).all()
    assert res.keep[on_floor & ~invalid].mean() > 0.95
    normals = estimate_range_image_normals(bad, ring)
    assert np.isnan(normals[np.isnan(bad[:, 0])]).all()
    empty = NormalGroundFilter().apply(np.zeros((0, 3)), np.zeros(0), tilted_sensor, ring=np.zeros(0, dtype=np.uint16))
    assert empty.status == "empty_input" and empty.keep.shape == (0,)
    assert estimate_range_image_normals(np.zeros((0, 3)), np.zeros(0)) is None
    all_nan = NormalGroundFilter().apply(np.full((10, 3), np.nan), np.full(10, 5.0), tilted_sensor, ring=np.arange(10))
    assert not all_nan.keep.any() and all_nan.status == "all_removed"


def test_normal_method_config():
    assert NormalGroundConfig().normal_method == "range-image"
    assert make_filter("normal-ground", normal_method="knn").config.normal_method == "knn"
    for bad in ({"normal_method": "pca"}, {"ri_col_halfwidth": 0}, {"ri_max_ring_skip": 5},
                {"ri_ring_jump_rel": 0.0}, {"ri_azimuth_jump_rel": 1.5}):  # fmt: skip
        with pytest.raises(ConfigError):
            NormalGroundConfig(**bad)


def test_far_grazing_floor_reads_as_a_depth_jump_unless_allowed():
    """Adjacent rings on a level floor far away differ in range by more than ri_ring_jump_rel
    (seen from 1.2 m, the rings at -7 / -5 / -3 deg meet the floor at 9.8 / 13.7 / 22.9 m: range
    ratios 1.40 and 1.67 > 1.3): with the default 0.3 they count as depth jumps (no normal, not
    rescued); a looser gate keeps them. Nearer rings (-15..-9 deg: ratios <= 1.28) pass."""
    T_fs = _T(np.eye(3), [0.0, 0.0, 1.2])
    pts, ring, _, on_floor = _ring_scan(T_fs, half_x_m=100.0, half_y_m=100.0)
    far = on_floor & (ring >= 5)  # rings at -5 and -3 deg
    psi = np.full(len(pts), 5.0)
    strict = NormalGroundFilter().apply(pts, psi, T_fs, ring=ring)
    loose = NormalGroundFilter(NormalGroundConfig(ri_ring_jump_rel=1.0)).apply(pts, psi, T_fs, ring=ring)
    near = on_floor & (ring <= 3)  # -15..-9 deg
    assert strict.keep[near].all() and loose.keep[near].all()
    assert strict.keep[far].mean() < 0.05 and loose.keep[far].mean() > 0.95


def test_pipeline_config_passes_the_normal_method_through():
    from exobench.perception.lidar_filter.pipelines import FilterNormalGround

    assert FilterNormalGround().filter.config.normal_method == "range-image"
    pipe = FilterNormalGround(FilterNormalGround.Config(normal_method="knn", ri_col_halfwidth=6, ri_ring_jump_rel=0.4))
    cfg = pipe.filter.config
    assert (cfg.normal_method, cfg.ri_col_halfwidth, cfg.ri_ring_jump_rel) == ("knn", 6, 0.4)
    with pytest.raises(ConfigError):
        FilterNormalGround.Config(normal_method="bogus")


# ------------------------------------------------------------- naive filter: ground tests below the footprint


def _floor_and_mirror_ghosts(T_fs: np.ndarray, floor_z: float = 0.0, seed: int = 0):
    """A weak floor (psi 5) at height ``floor_z`` of the footprint frame, 1.5-12 m around the
    sensor, and the weak ghosts a polished floor mirrors under it (psi 3): a wall's foot 1-10 cm
    below the floor and furniture 0.3-1.5 m below. Returns points (sensor frame), psi, labels
    (0 floor, 1 ghost 1-10 cm under, 2 ghost deeper)."""
    rng = np.random.default_rng(seed)
    n = 4000
    r = rng.uniform(1.5, 12.0, n)
    a = rng.uniform(-math.pi, math.pi, n)
    floor = np.column_stack([r * np.cos(a), r * np.sin(a), floor_z + rng.normal(0.0, 0.004, n)])
    y = rng.uniform(-2.0, 2.0, 300)
    foot = np.column_stack([np.full(300, 7.0), y, floor_z - rng.uniform(0.01, 0.10, 300)])
    deep = np.column_stack([rng.uniform(4.0, 9.0, 300), rng.uniform(-3.0, 3.0, 300), floor_z - rng.uniform(0.3, 1.5, 300)])
    p_f = np.concatenate([floor, foot, deep])
    labels = np.repeat([0, 1, 2], [n, 300, 300])
    psi = np.where(labels == 0, 5.0, 3.0)
    return _to_sensor(p_f, T_fs), psi, labels


def test_ghosts_mirrored_below_the_floor_are_kept_by_eq_4_16_and_removed_by_the_band():
    T_fs = _T(_rot(math.radians(2.0), math.radians(6.0)), [0.0, 0.0, H])
    pts, psi, labels = _floor_and_mirror_ghosts(T_fs)
    below = NaiveGroundFilter(NaiveGroundConfig(ground_test="below")).apply(pts, psi, T_fs)
    band = NaiveGroundFilter(NaiveGroundConfig(ground_test="band")).apply(pts, psi, T_fs)
    plane = FloorGroundFilter().apply(pts, psi, T_fs)
    assert below.keep.all()  # eq. (4.16) as written: everything below the footprint is ground
    for res in (band, plane):
        assert res.keep[labels == 0].all()
        assert not res.keep[labels == 2].any()  # 0.3-1.5 m under the floor: not ground
    # the foot of the wall 1-10 cm under the floor: inside the kinematic band, outside +-3 cm of the floor plane
    assert band.keep[labels == 1].all()
    assert plane.ground_plane == "refined" and band.ground_plane == "footprint"
    # (the fitted plane is within a few mm of the floor: points within 1 cm of the band edge may go either way)
    foot_z = pts[labels == 1] @ T_fs[2, :3] + T_fs[2, 3]
    assert plane.keep[labels == 1][foot_z > -0.02].all() and not plane.keep[labels == 1][foot_z < -0.04].any()


def test_plane_band_follows_the_scans_floor_when_the_footprint_is_off():
    # the kinematic footprint 4 cm too low and 0.5 deg off: the floor lies at z_f = +0.04 tilted
    true_T = _T(_rot(math.radians(1.0), math.radians(4.0)), [0.0, 0.0, H])
    pts, psi, labels = _floor_and_mirror_ghosts(true_T)
    est_T = _T(_rot(math.radians(1.5), math.radians(4.0)), [0.0, 0.0, H + 0.04])
    below = NaiveGroundFilter(NaiveGroundConfig(ground_test="below")).apply(pts, psi, est_T)
    plane = FloorGroundFilter().apply(pts, psi, est_T)
    assert plane.ground_plane == "refined"
    assert plane.keep[labels == 0].all()  # the whole floor, out to 12 m
    assert below.keep[labels == 0].mean() < 0.9  # part of the floor is above +0.05 in the wrong footprint
    true_z = pts @ true_T[2, :3] + true_T[2, 3]
    ghost_z = true_z[labels > 0]
    assert plane.keep[labels > 0][ghost_z > -0.02].all() and not plane.keep[labels > 0][ghost_z < -0.04].any()


def test_fit_floor_plane_recovers_a_known_plane_and_refuses_a_bad_one():
    rng = np.random.default_rng(1)
    xy = rng.uniform(-10.0, 10.0, (3000, 2))
    a, b, c = 0.01, -0.02, 0.03  # 1.3 deg of tilt, 3 cm of offset
    z = a * xy[:, 0] + b * xy[:, 1] + c + rng.normal(0.0, 0.005, len(xy))
    z_ghost = z.copy()
    z_ghost[:300] -= rng.uniform(0.04, 0.09, 300)  # 10 % just under the floor
    for zz in (z, z_ghost):
        plane = fit_floor_plane(xy, zz)
        assert plane is not None
        np.testing.assert_allclose(plane, (a, b, c), atol=2e-3)
    assert fit_floor_plane(xy[:20], z[:20]) is None  # too few points
    steep = 0.1 * xy[:, 0]  # 5.7 deg
    assert fit_floor_plane(xy, steep, search_m=0.5) is None
    assert fit_floor_plane(xy, z + 0.3) is None  # nothing within plane_search_m of the footprint
    # a scan without a floor near the footprint falls back to the band and says so
    T = _T(np.eye(3), [0.0, 0.0, H])
    res = FloorGroundFilter().apply(_to_sensor(np.column_stack([xy[:20], z[:20]]), T), np.full(20, 5.0), T)
    assert res.ground_plane == "footprint"
    np.testing.assert_array_equal(res.keep, (z[:20] < 0.05) & (z[:20] > -0.1))


def test_naive_ground_test_config_and_pipeline():
    from exobench.perception.lidar_filter.pipelines import FilterFloorGround, FilterNaiveGround

    # the thesis's naive filter tests eq. (4.16) as written; the floor filter the band about the floor plane
    assert NaiveGroundConfig().ground_test == "below" and FilterNaiveGround().filter.config.ground_test == "below"
    assert FloorGroundConfig().ground_test == "plane-band" and FilterFloorGround().filter.config.ground_test == "plane-band"
    assert isinstance(FilterFloorGround().filter, FloorGroundFilter)
    for bad in ({"ground_test": "above"}, {"ground_depth_m": 0.0}, {"plane_margin_m": 0.5}, {"plane_search_m": -1.0}):
        with pytest.raises(ConfigError):
            NaiveGroundConfig(**bad)
    pipe = FilterNaiveGround(FilterNaiveGround.Config(ground_test="below", ground_depth_m=0.2, plane_margin_m=0.02))
    cfg = pipe.filter.config
    assert (cfg.ground_test, cfg.ground_depth_m, cfg.plane_margin_m) == ("below", 0.2, 0.02)
    with pytest.raises(ConfigError):
        FilterNaiveGround.Config(ground_test="bogus")
