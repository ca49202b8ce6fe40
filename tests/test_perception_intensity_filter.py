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
from exobench.perception.intensity_filter import (
    FILTERS,
    FilterReason,
    IntensityBandConfig,
    IntensityThresholdFilter,
    NaiveGroundConfig,
    NaiveGroundFilter,
    NoFilter,
    NormalGroundConfig,
    NormalGroundFilter,
    estimate_normals,
    make_filter,
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
    level = NaiveGroundFilter(NaiveGroundConfig(use_full_transform=False)).apply(pts, psi, T_fs)
    full = NaiveGroundFilter().apply(pts, psi, T_fs)
    # eq. (4.16) with the level assumption: ground iff z_l < ^l z_f + margin
    assert level.keep.tolist() == (z_l < l_z_f + 0.05).tolist() == [False, True]
    # full transform: ground iff the footprint height < margin (0.0 and 0.5 m)
    assert full.keep.tolist() == [True, False]
    # level LiDAR: both forms agree
    T_level = _T(np.eye(3), [0.0, 0.0, H])
    pts_level = _to_sensor(p_f, T_level)
    a = NaiveGroundFilter(NaiveGroundConfig(use_full_transform=False)).apply(pts_level, psi, T_level)
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
        make_filter("intensity", bogus=1)
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
