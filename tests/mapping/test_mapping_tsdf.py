"""TSDF map (seeds/002 II-E eq. 19-22) and its ray-cast smoothed depth image (II-F) on depth
images of a staircase computed analytically (tests/analytic_staircase.py), and the AHC
planes of that image (perception/plane_extraction.py)."""

import numpy as np
import pytest
from analytic_staircase import WIDTH, H, K, W, camera, faces, render
from scipy.ndimage import maximum_filter, minimum_filter

from exobench.core import ConfigError
from exobench.mapping.tsdf import Tsdf, TsdfConfig
from exobench.perception.terrain.plane_extraction import AhcConfig, extract_planes

VOXEL = TsdfConfig().voxel_size_m


def interior(fid, margin=4, border=10):
    """Pixels whose (2 margin + 1)^2 neighbourhood sees one face, away from the image border."""
    m = (minimum_filter(fid, 2 * margin + 1) == maximum_filter(fid, 2 * margin + 1)) & (fid >= 0)
    m[:border] = m[-border:] = False
    m[:, :border] = m[:, -border:] = False
    return m


POSES = [camera(0.0, 40.0), camera(0.3, 50.0, y=0.1), camera(-0.2, 35.0, y=-0.1), camera(0.6, 45.0, yaw_deg=10.0)]


@pytest.mark.parametrize("pose", range(len(POSES)))
def test_raycast_of_one_frame_matches_the_analytic_depth(pose):
    T = POSES[pose]
    depth, fid = render(T)
    tsdf = Tsdf()
    tsdf.integrate(depth, K, T)
    out = tsdf.raycast_depth(K, T, W, H)
    assert out.shape == (H, W) and out.dtype == np.float32
    m = interior(fid)
    hit = m & (out > 0)
    assert hit.sum() > 0.97 * m.sum()
    err = np.abs(out[hit] - depth[hit])
    assert np.median(err) < 0.002
    assert np.percentile(err, 99) < VOXEL
    assert err.max() < 2 * VOXEL
    assert np.all(out[maximum_filter(fid, 9) < 0] == 0)  # nothing where there is nothing near


def test_raycast_from_a_new_pose_and_at_half_resolution():
    tsdf = Tsdf()
    for T in POSES:
        tsdf.integrate(render(T)[0], K, T)
    T = camera(0.15, 42.0, y=0.05)  # a pose not integrated
    Kh = K.copy()
    Kh[:2] /= 2.0
    Kh[:2, 2] = (K[:2, 2] - 0.5) / 2.0  # pixel centres of the half-resolution image
    depth, fid = render(T, Kh, W // 2, H // 2)
    out = tsdf.raycast_depth(Kh, T, W // 2, H // 2)
    m = interior(fid, margin=2, border=5)
    hit = m & (out > 0)
    assert hit.sum() > 0.95 * m.sum()
    err = np.abs(out[hit] - depth[hit])
    assert np.median(err) < 0.002 and np.percentile(err, 99) < VOXEL


def test_raycast_of_an_image_not_a_multiple_of_8_pixels():
    """Open3D's range map is 1/8 of the image; a size that is not a multiple of 8 (212 x 122, as
    a 424 x 240 camera at half resolution gives 212 x 120) is padded, cast and cropped: the
    right and bottom pixels are hit like the others, and the result equals the padded cast's
    crop."""
    T = POSES[0]
    tsdf = Tsdf()
    tsdf.integrate(render(T)[0], K, T)
    w, h = 212, 122
    Ks = K.copy()
    Ks[:2] *= w / W
    depth, fid = render(T, Ks, w, h)
    out = tsdf.raycast_depth(Ks, T, w, h)
    assert out.shape == (h, w)
    m = interior(fid, margin=1, border=1)
    hit = m & (out > 0)
    part = m.copy()
    part[:120, :208] = False  # the pixels of the last, partial range-map cells
    assert hit.sum() > 0.95 * m.sum() and part.sum() > 0 and hit[part].sum() > 0.9 * part.sum()
    err = np.abs(out[hit] - depth[hit])
    assert np.median(err) < 0.002 and np.percentile(err, 99) < VOXEL
    np.testing.assert_array_equal(out, tsdf.raycast_depth(Ks, T, 216, 128)[:h, :w])


def test_fusing_noisy_frames_from_several_poses_reduces_the_error():
    rng = np.random.default_rng(3)
    poses = [camera(0.05 * i - 0.1, 38.0 + i, y=0.03 * (i % 3) - 0.03) for i in range(6)]
    T_ref = poses[0]
    truth, fid = render(T_ref)
    m = interior(fid)

    def rms_after(n):
        tsdf = Tsdf()
        for T in poses[:n]:
            d, _ = render(T)
            tsdf.integrate((d + rng.normal(0.0, 0.01, d.shape) * (d > 0)).astype(np.float32), K, T)
        out = tsdf.raycast_depth(K, T_ref, W, H)
        hit = m & (out > 0)
        return float(np.sqrt(np.mean((out[hit] - truth[hit]) ** 2)))

    one, six = rms_after(1), rms_after(6)
    assert six < 0.6 * one
    assert six < 0.005


def test_planes_of_the_smoothed_depth_image_match_the_staircase():
    """II-F end to end: AHC planes of the ray cast of 6 noisy frames (sigma 1 cm)."""
    rng = np.random.default_rng(4)
    poses = [camera(0.05 * i - 0.1, 38.0 + i, y=0.03 * (i % 3) - 0.03) for i in range(6)]
    tsdf = Tsdf()
    for T in poses:
        d, _ = render(T)
        tsdf.integrate((d + rng.normal(0.0, 0.01, d.shape) * (d > 0)).astype(np.float32), K, T)
    T = poses[0]
    planes = extract_planes(tsdf.raycast_depth(K, T, W, H), K, T, AhcConfig(), cell_m=0.05)
    _, fid = render(T)
    px = np.bincount(fid[fid >= 0], minlength=len(faces()))
    found = []
    for p in planes:
        errs = []
        for k, (kind, lvl, _) in enumerate(faces()):
            n, off = (np.array([0.0, 0.0, 1.0]), lvl) if kind == "flat" else (np.array([-1.0, 0.0, 0.0]), -lvl)
            ang = np.degrees(np.arccos(min(1.0, abs(float(n @ p.normal)))))
            errs.append((ang + 100.0 * abs(float(n @ p.center_m) - off), k, ang, abs(float(n @ p.center_m) - off)))
        _, k, ang, off = min(errs)
        assert ang < 3.0 and off < 0.01, (k, ang, off)
        found.append(k)
    assert sorted(found) == sorted(np.flatnonzero(px >= 4000).tolist())


def _wall(d):
    return np.full((H, W), d, np.float32)


def test_eq19_22_update_matches_a_hand_computation():
    """Fronto-parallel walls at known depths; voxels on the optical axis follow eq. 19-22 with
    w = 2, W_max = 5, t_delta = 0.06 (voxels more than t_delta behind the surface: no update)."""
    cfg = TsdfConfig(voxel_size_m=0.02, truncation_m=0.06, obs_weight=2.0, max_weight=5.0)
    tsdf = Tsdf(cfg)
    walls = [1.005, 1.013, 1.031, 0.993, 1.022]  # no voxel exactly t_delta from a wall
    # voxels of the block z in [0.96, 1.12), allocated by the first wall already
    zs = np.round(np.arange(0.96, 1.11, 0.02), 2)
    lam = {z: 0.0 for z in zs}
    Wt = {z: 0.0 for z in zs}
    for d in walls:
        tsdf.integrate(_wall(d), K, np.eye(4))
        for z in zs:
            sdf = z - d  # eq. 19: voxel depth - measured depth
            if sdf > cfg.truncation_m:
                continue  # occluded
            lam_new = max(-1.0, min(1.0, sdf / cfg.truncation_m))  # eq. 20
            lam[z] = (Wt[z] * lam[z] + cfg.obs_weight * lam_new) / (Wt[z] + cfg.obs_weight)  # eq. 21
            Wt[z] = min(Wt[z] + cfg.obs_weight, cfg.max_weight)  # eq. 22
    p, lam_map, W_map = tsdf.voxel_values()
    on_axis = (np.abs(p[:, 0]) < 1e-6) & (np.abs(p[:, 1]) < 1e-6)
    got = {round(float(z), 2): (lv, wv) for z, lv, wv in zip(p[on_axis, 2], lam_map[on_axis], W_map[on_axis])}
    for z in zs:
        assert got[z][0] == pytest.approx(lam[z], abs=2e-6), z
        assert got[z][1] == pytest.approx(Wt[z], abs=1e-6), z
    assert Wt[1.1] == 0.0 and Wt[1.08] > 0.0  # 1.10 was always > t_delta behind a wall
    assert max(Wt.values()) == 5.0  # the cap was reached
    # the ray cast finds the zero of eq. 21's running average: between the last walls
    out = tsdf.raycast_depth(K, np.eye(4), W, H)
    assert 0.99 < out[H // 2, W // 2] < 1.03


def test_faulty_frames_leave_the_map_unchanged():
    T = POSES[0]
    depth, _ = render(T)
    tsdf = Tsdf()
    tsdf.integrate(depth, K, T)
    before = tsdf.voxel_values()
    ray_before = tsdf.raycast_depth(K, T, W, H)
    bad_frames = [(None, K, T), (np.zeros_like(depth), K, T), (np.full_like(depth, np.nan), K, T),
                  (np.full_like(depth, np.inf), K, T), (-depth, K, T), (depth[0], K, T), (depth[:1, :1], K, T),
                  (np.full((H, W), 99.0, np.float32), K, T), (depth, np.full((3, 3), np.nan), T),
                  (depth, K, np.full((4, 4), np.nan)), (depth, K, np.zeros((4, 4))), (depth, np.eye(2), T),
                  (np.ones((3, 3), np.float32), K, T)]
    for d, Kb, Tb in bad_frames:
        tsdf.integrate(d, Kb, Tb)
    assert tsdf.stats.frames_integrated == 1
    assert tsdf.stats.frames_skipped == len(bad_frames)
    after = tsdf.voxel_values()
    assert all(np.array_equal(a, b) for a, b in zip(before, after))
    assert np.array_equal(tsdf.raycast_depth(K, T, W, H), ray_before)
    assert not tsdf.raycast_depth(K, np.full((4, 4), np.nan), W, H).any()
    assert tsdf.raycast_depth(K, T, 0, 0).shape == (0, 0)
    assert not tsdf.raycast_depth(K, T, 5, 5).any()


def test_nan_pixels_count_as_invalid():
    T = POSES[1]
    depth, _ = render(T)
    holed = depth.copy()
    holed[100:200, 200:300] = np.nan
    zeroed = depth.copy()
    zeroed[100:200, 200:300] = 0.0
    a, b = Tsdf(), Tsdf()
    a.integrate(holed, K, T)
    b.integrate(zeroed, K, T)
    assert all(np.array_equal(x, y) for x, y in zip(a.voxel_values(), b.voxel_values()))


def test_deterministic_and_reset():
    def run():
        rng = np.random.default_rng(11)
        tsdf = Tsdf(TsdfConfig(block_count=64))  # forces the hash map to grow
        for T in POSES[:3]:
            d, _ = render(T)
            tsdf.integrate((d + rng.normal(0.0, 0.005, d.shape) * (d > 0)).astype(np.float32), K, T)
        return tsdf, tsdf.raycast_depth(K, POSES[0], W, H), tsdf.surface_points()

    (ta, ra, pa), (_, rb, pb) = run(), run()
    assert np.array_equal(ra, rb) and np.array_equal(pa, pb)
    assert ta.stats.active_blocks > 64
    ta.reset()
    assert ta.stats.frames_integrated == 0 and ta.surface_points().shape == (0, 3)
    assert not ta.raycast_depth(K, POSES[0], W, H).any()


def test_surface_points_lie_on_the_staircase():
    tsdf = Tsdf()
    for T in POSES[:2]:
        tsdf.integrate(render(T)[0], K, T)
    pts = tsdf.surface_points()
    assert len(pts) > 1000
    dist = np.full(len(pts), np.inf)
    for kind, lvl, (lo, hi) in faces():
        a, b = (2, 0) if kind == "flat" else (0, 2)
        # distance to the face rectangle (clamped to its extent)
        q = pts.copy()
        q[:, a] = lvl
        q[:, b] = np.clip(q[:, b], lo, hi)
        q[:, 1] = np.clip(q[:, 1], -WIDTH / 2, WIDTH / 2)
        dist = np.minimum(dist, np.linalg.norm(pts - q, axis=1))
    assert np.percentile(dist, 99) < VOXEL
    assert np.all(np.diff(pts[:, 0]) >= 0)  # sorted


def test_strided_integration_stays_within_a_voxel():
    T = POSES[0]
    depth, fid = render(T)
    tsdf = Tsdf(TsdfConfig(integrate_stride_px=2))
    tsdf.integrate(depth, K, T)
    out = tsdf.raycast_depth(K, T, W, H)
    m = interior(fid) & (out > 0)
    assert m.sum() > 0.9 * interior(fid).sum()
    assert np.percentile(np.abs(out[m] - depth[m]), 99) < VOXEL


def test_config_validation():
    with pytest.raises(ConfigError):
        TsdfConfig(voxel_size_m=0.0)
    with pytest.raises(ConfigError):
        TsdfConfig(truncation_m=0.01)  # below one voxel
    with pytest.raises(ConfigError):
        TsdfConfig(max_weight=0.5)  # below obs_weight
    with pytest.raises(ConfigError):
        TsdfConfig(depth_min_m=2.0, depth_max_m=1.0)
    with pytest.raises(ConfigError):
        TsdfConfig(block_count=0)
