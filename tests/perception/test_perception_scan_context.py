"""Scan Context++ (eq. 4.20-4.25) and Gaussian Scan Context (eq. 4.26-4.33) of seeds/003 4.2.3.

Cells, keys and similarities are recomputed here from the equations on tiny clouds; retrieval,
rotation and robustness are checked on synthetic places (ground near the sensor, random boxes).
"""

import math

import numpy as np
import pytest

from exobench.core.errors import ConfigError
from exobench.perception.lidar_filter.filters import NaiveGroundFilter
from exobench.perception.place_recognition.gaussian_scan_context import (
    GaussianScanContext,
    GaussianScanContextConfig,
    bin_gaussians,
)
from exobench.perception.place_recognition.recognizer import ScanContextPP
from exobench.perception.place_recognition.scan_context import (
    ScanContextConfig,
    accumulate_submap,
    level_frame,
    shift_similarities,
)


def _polar(r, theta_deg, z):
    t = np.radians(theta_deg)
    return np.column_stack([np.multiply(r, np.cos(t)), np.multiply(r, np.sin(t)), z])


def _rot_z(p, yaw):
    c, s = math.cos(yaw), math.sin(yaw)
    return p @ np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]]).T


def _place(rng, n_boxes=25, extent=30.0):
    """Ground within 8 m of the sensor (1.5 m below it) and boxes of random size and height."""
    r = 8 * np.sqrt(rng.random(1500))
    a = rng.uniform(0, 2 * np.pi, 1500)
    parts = [np.column_stack([r * np.cos(a), r * np.sin(a), np.full(1500, -1.5)])]
    for _ in range(n_boxes):
        c = rng.uniform(-extent, extent, 2)
        s = rng.uniform(0.5, 4, 2)
        h = rng.uniform(0.3, 5)
        m = int(100 * s.sum())
        parts.append(np.column_stack([c + rng.uniform(-s / 2, s / 2, (m, 2)), rng.uniform(-1.5, -1.5 + h, m)]))
    return np.concatenate(parts)


def _revisit(rng, p):
    """The same place seen again: random yaw, 0.3 m offset, 2 cm noise, 20 % of the points lost."""
    q = p + rng.normal(0, 0.02, p.shape) + [0.3, 0.2, 0.0]
    q = _rot_z(q, rng.uniform(-np.pi, np.pi))
    return q[rng.random(len(q)) < 0.8]


TINY = dict(n_rings=4, n_sectors=8, max_radius_m=8.0, height_offset_m=0.0, min_points=1)


# ------------------------------------------------------------------------------------ SC++


def test_sc_cells_and_keys_match_hand_computation():
    # rings of 2 m, sectors of 45 deg; (ring, sector) by eq. (4.20)-(4.21), 1-based in comments
    pts = np.concatenate([
        _polar([1.0, 1.5], [10.0, 20.0], [0.5, 0.8]),  # ring 1, sector 1: max 0.8
        _polar([3.0], [100.0], [1.2]),  # ring 2, sector ceil(100/45) = 3
        _polar([7.0], [350.0], [2.0]),  # ring 4, sector 8
        _polar([7.0], [200.0], [-0.5]),  # ring 4, sector 5 (negative height is non-zero)
        _polar([12.0], [30.0], [0.3]),  # beyond max_r: clamped into ring 4, sector 1
    ])
    expected = np.zeros((4, 8))
    expected[0, 0], expected[1, 2], expected[3, 7], expected[3, 4], expected[3, 0] = 0.8, 1.2, 2.0, -0.5, 0.3
    d = ScanContextPP(ScanContextConfig(**TINY)).describe(pts)
    np.testing.assert_allclose(d.matrix, expected)
    np.testing.assert_array_equal(d.ring_key, [1, 1, 0, 3])  # eq. (4.23): non-zero cells per ring
    np.testing.assert_array_equal(d.sector_key, [2, 0, 1, 0, 1, 0, 0, 1])
    mean = ScanContextPP(ScanContextConfig(**TINY, ring_key_mode="mean")).describe(pts)
    np.testing.assert_allclose(mean.ring_key, [0.8 / 8, 1.2 / 8, 0.0, (2.0 - 0.5 + 0.3) / 8])
    dropped = ScanContextPP(ScanContextConfig(**TINY, beyond_max_radius="drop")).describe(pts)
    assert dropped.matrix[3, 0] == 0.0 and dropped.n_points == 5
    # the height offset shifts every occupied cell
    lifted = ScanContextPP(ScanContextConfig(**{**TINY, "height_offset_m": 2.0})).describe(pts)
    np.testing.assert_allclose(lifted.matrix[expected != 0], expected[expected != 0] + 2.0)


def test_shift_similarity_is_eq_4_24_at_every_shift():
    rng = np.random.default_rng(3)
    Cq, Cc = rng.random((5, 12)), rng.random((5, 12))
    sims = shift_similarities(Cq, Cc)
    for t in range(12):
        Ct = np.roll(Cc, t, axis=1)
        assert sims[t] == pytest.approx(np.sum(Cq * Ct) / (np.linalg.norm(Cq, "fro") * np.linalg.norm(Ct, "fro")))


def _bin_interior_cloud(rng, cfg, n=400):
    """Points strictly inside bins (away from sector edges), so a rotation by k sectors is exact."""
    ring = rng.integers(0, cfg.n_rings, n)
    sector = rng.integers(0, cfg.n_sectors, n)
    r = (ring + rng.uniform(0.1, 0.9, n)) * cfg.max_radius_m / cfg.n_rings
    th = (sector + rng.uniform(0.1, 0.9, n)) * 360.0 / cfg.n_sectors
    return _polar(r, th, rng.uniform(-1.5, 3.0, n)), rng.uniform(0, 255, n)


RECOGNISERS = [
    lambda **kw: ScanContextPP(ScanContextConfig(**kw)),
    lambda **kw: GaussianScanContext(GaussianScanContextConfig(variant="height", **kw)),
    lambda **kw: GaussianScanContext(GaussianScanContextConfig(variant="huber", **kw)),
    lambda **kw: GaussianScanContext(GaussianScanContextConfig(variant="intensity", **kw)),
]


@pytest.mark.parametrize("make", RECOGNISERS, ids=["sc++", "gsc-height", "gsc-huber", "gsc-intensity"])
@pytest.mark.parametrize("k", [0, 7, 45])
def test_rotation_by_k_sectors_is_matched_with_shift_k(make, k):
    rng = np.random.default_rng(11 + k)
    rec = make(max_radius_m=20.0)
    cfg = rec.config
    pts, psi = _bin_interior_cloud(rng, cfg)
    for _ in range(5):  # unrelated places
        other, other_psi = _bin_interior_cloud(rng, cfg)
        rec.add(rec.describe(other, other_psi))
    target = rec.add(rec.describe(pts, psi))
    yaw = 2 * math.pi * k / cfg.n_sectors
    query = rec.describe(_rot_z(pts, yaw), psi)
    distance, shift = rec.distance(query, rec.database.descriptors[target])
    assert shift == k and abs(distance) < 1e-12
    match = rec.query(query)
    assert (match.index, match.yaw_shift, match.accepted, match.status) == (target, k, True, "match")
    assert match.distance == pytest.approx(0.0, abs=1e-12)
    assert match.yaw_rad == pytest.approx(math.remainder(yaw, 2 * math.pi))
    # the sector-key window finds the same shift
    rec_sk = make(max_radius_m=20.0, shift_search="sector_key")
    assert rec_sk.distance(query, rec_sk.describe(pts, psi))[1] == k


@pytest.mark.parametrize("make", RECOGNISERS[:3], ids=["sc++", "gsc-height", "gsc-huber"])
def test_retrieval_finds_the_revisited_place_among_others(make):
    rng = np.random.default_rng(5)
    rec = make(max_radius_m=40.0)
    places = [_place(rng) for _ in range(20)]
    for p in places:
        rec.add(rec.describe(p))
    for target in (2, 9, 13, 17):
        q = rec.describe(_revisit(rng, places[target]))
        match = rec.query(q)
        assert match.index == target and match.accepted, match
        others = [1 - rec.distance(q, d)[0] for i, d in enumerate(rec.database.descriptors) if i != target]
        assert match.similarity > max(others)
    # the most recent entries are excluded on request
    rec.add(rec.describe(places[0]))  # index 20 duplicates place 0
    assert rec.query(rec.describe(places[0])).index == 20
    assert rec.query(rec.describe(places[0]), exclude_recent=1).index == 0
    assert rec.query(rec.describe(places[0]), exclude_recent=21).status == "no_candidates"


def test_lateral_virtual_descriptors_match_a_sideways_viewpoint():
    rng = np.random.default_rng(8)
    place = _place(rng)
    seen_from_the_side = place - [0.0, 1.0, 0.0]  # the sensor moved 1 m to its left
    plain = ScanContextPP(ScanContextConfig(max_radius_m=40.0))
    virtual = ScanContextPP(ScanContextConfig(max_radius_m=40.0, lateral_offsets_m=(-1.0, 1.0)))
    for rec in (plain, virtual):
        rec.add(rec.describe(place))
    with_aug = virtual.query(virtual.describe(seen_from_the_side))
    without = plain.query(plain.describe(seen_from_the_side))
    assert with_aug.similarity == pytest.approx(1.0) and with_aug.yaw_shift == 0
    assert without.similarity < with_aug.similarity - 0.01


def test_submap_descriptor_equals_the_descriptor_of_the_whole_cloud():
    rng = np.random.default_rng(4)
    cloud_level = _place(rng)  # points in the level frame of the keyframe
    T_world_key = np.eye(4)
    T_world_key[:3, :3] = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])  # yaw 90 deg
    T_world_key[:3, 3] = [5.0, -2.0, 1.5]
    assert np.allclose(level_frame(T_world_key), T_world_key)
    world = cloud_level @ T_world_key[:3, :3].T + T_world_key[:3, 3]
    # two scans from two tilted sensor poses, each holding half of the world points
    scans = []
    for half, (roll, pitch, pos) in zip(np.array_split(np.arange(len(world)), 2),
                                        [(0.05, -0.1, [5.2, -2.0, 1.4]), (-0.08, 0.12, [4.6, -1.7, 1.6])]):
        cr, sr, cp, sp = math.cos(roll), math.sin(roll), math.cos(pitch), math.sin(pitch)
        T = np.eye(4)
        T[:3, :3] = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]]) @ np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
        T[:3, 3] = pos
        scans.append(((world[half] - T[:3, 3]) @ T[:3, :3], T))
    submap = accumulate_submap(scans, T_world_key)
    np.testing.assert_allclose(np.sort(submap, axis=0), np.sort(cloud_level, axis=0), atol=1e-9)
    rec = ScanContextPP(ScanContextConfig(max_radius_m=40.0))
    assert rec.distance(rec.describe(submap), rec.describe(cloud_level))[0] == pytest.approx(0.0, abs=1e-12)
    # a tilted keyframe sensor: the level frame keeps its heading and position, drops roll/pitch
    T_tilt = scans[1][1]
    L = level_frame(T_tilt)
    assert np.allclose(L[:3, 2], [0, 0, 1]) and np.allclose(L[:3, 3], T_tilt[:3, 3])
    heading = T_tilt[:3, 0] * [1, 1, 0]
    assert np.allclose(L[:3, 0], heading / np.linalg.norm(heading))


# ------------------------------------------------------------------------------------- GSC


def _tiny_gsc_cloud():
    # bin A (ring 1, sector 1): 5 points, one of them 2.5 m above the rest (Huber: r > delta)
    a = _polar([0.8, 1.0, 1.2, 1.5, 1.1], [5, 10, 15, 20, 30], [0.2, 0.3, 0.25, 0.35, 2.8])
    b = _polar([3.0], [100.0], [1.0])  # bin B (ring 2, sector 2): one point
    c = _polar([3.5, 3.9], [200.0, 210.0], [0.4, 1.6])  # bin C (ring 2, sector 3): two points
    psi = np.array([10, 20, 30, 40, 250, 80, 60, 90], dtype=float)
    return np.concatenate([a, b, c]), psi, {(0, 0): slice(0, 5), (1, 1): slice(5, 6), (1, 2): slice(6, 8)}


def _huber_by_hand(P, delta):
    mu = P.mean(axis=0)  # eq. (4.26)
    w = []
    for p in P:
        r = math.sqrt(sum((p[c] - mu[c]) ** 2 for c in range(3)))  # eq. (4.29), over x, y, z
        w.append(1.0 if abs(r) <= delta else delta / abs(r))  # eq. (4.31)
    w = np.array(w)
    mu_h = (w[:, None] * P).sum(axis=0) / w.sum()  # eq. (4.32)
    D = P - mu_h
    sigma_h = sum(wk * np.outer(d, d) for wk, d in zip(w, D)) / w.sum()  # eq. (4.33)
    return mu_h, sigma_h, w


@pytest.mark.parametrize("variant", ["height", "huber", "intensity"])
def test_gsc_cells_match_eq_4_26_to_4_33(variant):
    pts, psi, bins = _tiny_gsc_cloud()
    cfg = GaussianScanContextConfig(variant=variant, n_rings=2, n_sectors=4, max_radius_m=4.0,
                                    height_offset_m=0.0, min_points=1)
    assert cfg.alpha == 2.0 and cfg.delta_m == 1.0
    d = GaussianScanContext(cfg).describe(pts, psi)
    expected = np.zeros((2, 4))
    P4 = np.column_stack([pts, psi / 255.0])
    for (i, j), sl in bins.items():
        P = P4[sl]
        if variant == "huber":
            mu, sigma, w = _huber_by_hand(P, 1.0)
            if (i, j) == (0, 0):
                assert (w < 1).sum() == 1 and w[4] < 1  # the high point is down-weighted
        else:
            mu = P.mean(axis=0)
            sigma = np.cov(P.T, ddof=1) if len(P) > 1 else np.zeros((4, 4))
        c = 3 if variant == "intensity" else 2
        expected[i, j] = mu[c] + 2.0 * sigma[c, c]  # eq. (4.28)
    np.testing.assert_allclose(d.matrix, expected, rtol=1e-12, atol=1e-12)
    assert d.ring_key.tolist() == [1, 2]


def test_bin_gaussians_are_the_full_multivariate_estimates():
    pts, psi, bins = _tiny_gsc_cloud()
    P4 = np.column_stack([pts, psi])
    flat = np.array([0] * 5 + [5] + [6] * 2)
    ids, counts, mu, sigma = bin_gaussians(P4, flat, 8)
    assert ids.tolist() == [0, 5, 6] and counts.tolist() == [5, 1, 2]
    np.testing.assert_allclose(mu[0], P4[:5].mean(axis=0))
    np.testing.assert_allclose(sigma[0], np.cov(P4[:5].T, ddof=1))
    np.testing.assert_allclose(sigma[1], 0.0)
    _, _, mu_h, sigma_h = bin_gaussians(P4, flat, 8, huber_delta=1.0)
    mu_ref, sigma_ref, _ = _huber_by_hand(P4[:5], 1.0)
    np.testing.assert_allclose(mu_h[0], mu_ref)
    np.testing.assert_allclose(sigma_h[0], sigma_ref)


def test_sparse_high_outliers_move_gsc_huber_less_than_sc():
    rng = np.random.default_rng(21)
    sc = ScanContextPP(ScanContextConfig(max_radius_m=40.0))
    gsc = GaussianScanContext(GaussianScanContextConfig(max_radius_m=40.0))
    for _ in range(3):
        place = _place(rng)
        noisy = place.copy()
        hit = rng.choice(len(place), size=len(place) // 100, replace=False)  # 1 % spurious high points
        noisy[hit, 2] += rng.uniform(2.0, 4.0, len(hit))
        d_sc = sc.distance(sc.describe(place), sc.describe(noisy))[0]
        d_gsc = gsc.distance(gsc.describe(place), gsc.describe(noisy))[0]
        assert d_gsc < 0.5 * d_sc


# ------------------------------------------------------------------------- failure handling


@pytest.mark.parametrize("make", RECOGNISERS, ids=["sc++", "gsc-height", "gsc-huber", "gsc-intensity"])
def test_empty_tiny_and_glass_only_scans_do_not_crash(make):
    rec = make()
    empty = rec.describe(np.zeros((0, 3)), np.zeros(0))
    assert not empty.valid and empty.status == "empty" and empty.matrix.shape == (20, 60)
    assert rec.query(empty).status == "no_descriptor"
    assert rec.query(rec.describe(np.ones((20, 3)), np.ones(20))).status == "no_candidates"
    tiny = rec.describe(np.ones((3, 3)), np.ones(3))
    assert tiny.status == "too_few_points" and tiny.n_points == 3
    nan = rec.describe(np.full((50, 3), np.nan), np.ones(50))
    assert nan.status == "empty"
    assert rec.add(empty) == 0 and rec.add(tiny) == 1 and len(rec) == 2  # indices still follow keyframes
    assert rec.query(rec.describe(np.ones((20, 3)), np.ones(20))).status == "no_candidates"
    assert math.isnan(rec.distance(empty, tiny)[0])
    # a scan with only glass: the filter removes everything, the descriptor reports it
    py, pz = np.meshgrid(np.linspace(-1, 1, 21), np.linspace(-1, 1, 21))
    glass = np.column_stack([np.full(py.size, 3.0), py.ravel(), pz.ravel()])
    T_fs = np.eye(4)
    T_fs[2, 3] = 1.4
    kept = NaiveGroundFilter().apply(glass, np.full(len(glass), 240.0), T_fs)
    assert kept.status == "all_removed"
    d = rec.describe(glass[kept.keep], np.full(kept.n_kept, 240.0))
    assert d.status == "empty" and rec.query(d).status == "no_descriptor"


def test_intensity_variant_without_intensity_reports_it():
    rec = GaussianScanContext(GaussianScanContextConfig(variant="intensity"))
    assert rec.describe(np.ones((20, 3))).status == "no_intensity"
    assert rec.describe(np.ones((20, 3)), np.ones(5)).status == "no_intensity"


@pytest.mark.parametrize("bad", [dict(n_rings=0), dict(n_sectors=2.5), dict(max_radius_m=0.0), dict(tau=1.5),
                                 dict(ring_key_mode="l1"), dict(beyond_max_radius="wrap"),
                                 dict(shift_search="fft"), dict(lateral_offsets_m=(math.nan,)),
                                 dict(min_points=0)])
def test_invalid_sc_configs_raise(bad):
    with pytest.raises(ConfigError):
        ScanContextConfig(**bad)


@pytest.mark.parametrize("bad", [dict(variant="max"), dict(alpha=0.0), dict(delta_m=-1.0),
                                 dict(intensity_scale=0.0)])
def test_invalid_gsc_configs_raise(bad):
    with pytest.raises(ConfigError):
        GaussianScanContextConfig(**bad)
