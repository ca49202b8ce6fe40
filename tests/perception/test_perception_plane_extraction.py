"""AHC plane extraction (seeds/002 II-F, ref. [34]) on depth images of a staircase computed
analytically (tests/analytic_staircase.py), checked against the true treads and risers."""

import numpy as np
import pytest
from analytic_staircase import H, K, W, camera, face_planes, faces, render

from exobench.core import ConfigError
from exobench.perception.terrain.plane_extraction import AhcConfig, extract_planes, segment_depth
from exobench.perception.terrain.plane_tracking import DetectedPlane, voxel_centers


def match(plane: DetectedPlane):
    """(face index, normal angle deg, offset error m) of the true face closest to the plane."""
    errs = []
    for k, (n, off) in enumerate(face_planes()):
        ang = np.degrees(np.arccos(min(1.0, abs(float(n @ plane.normal)))))
        errs.append((ang + 100.0 * abs(float(n @ plane.center_m) - off), k, ang, abs(float(n @ plane.center_m) - off)))
    _, k, ang, off = min(errs)
    return k, ang, off


POSES = [camera(0.0, 40.0), camera(-0.3, 35.0), camera(0.3, 50.0, y=0.1), camera(0.1, 45.0, y=-0.1, yaw_deg=8.0)]


@pytest.mark.parametrize("pose", range(len(POSES)))
def test_planes_match_the_true_treads_and_risers(pose):
    T = POSES[pose]
    depth, fid = render(T)
    planes = extract_planes(depth, K, T, AhcConfig(), cell_m=0.05)
    px = np.bincount(fid[fid >= 0], minlength=len(faces()))
    # every face seen by >= 4000 px (well above min support) is found once; no face is in between
    assert not np.any((px > 800) & (px < 4000))
    found = [match(p) for p in planes]
    assert sorted(k for k, _, _ in found) == sorted(np.flatnonzero(px >= 4000).tolist())
    for k, ang, off in found:
        assert ang < 3.0, (k, ang)
        assert off < 0.01, (k, off)


def test_plane_attributes_are_consistent_with_the_face():
    T = POSES[0]
    depth, fid = render(T)
    seg = segment_depth(depth, K)
    planes = extract_planes(depth, K, T, cell_m=0.05)
    assert len(planes) == len(seg.planes) == int(seg.labels_px.max()) + 1
    cam = T[:3, 3]
    for i, p in enumerate(planes):
        k, _, _ = match(p)
        n, off = face_planes()[k]
        assert abs(np.linalg.norm(p.normal) - 1.0) < 1e-9
        assert p.normal @ (cam - p.center_m) > 0  # towards the camera
        # label i covers pixels of face k (up to cells straddling an edge that the fit accepted)
        assert np.mean(fid[seg.labels_px == i] == k) > 0.9
        # support voxels lie on the face; area close to the seen area of the face
        centres = voxel_centers(p.cells, 0.05)
        assert np.all(np.abs(centres @ n - off) < 0.05)
        assert np.all(np.diff(p.cells) > 0)
        v, u = np.nonzero(seg.labels_px == i)
        z = depth[v, u]
        pts = np.column_stack([(u - K[0, 2]) / K[0, 0] * z, (v - K[1, 2]) / K[1, 1] * z, z]) @ T[:3, :3].T + T[:3, 3]
        e1 = np.cross(n, [0.0, 1.0, 0.0]) if abs(n[1]) < 0.9 else np.array([1.0, 0.0, 0.0])
        e2 = np.cross(n, e1)
        extent = np.ptp(pts @ e1) * np.ptp(pts @ e2)  # the labelled region is a rectangle here
        assert 0.7 * extent < p.area_m2 < 1.6 * extent + 0.05


def test_small_depth_noise_keeps_planes():
    """Depth noise of 2 mm (about what the TSDF ray cast leaves) does not change the result."""
    T = POSES[0]
    depth, fid = render(T)
    rng = np.random.default_rng(7)
    noisy = (depth + rng.normal(0.0, 0.002, depth.shape) * (depth > 0)).astype(np.float32)
    found = [match(p) for p in extract_planes(noisy, K, T)]
    px = np.bincount(fid[fid >= 0], minlength=len(faces()))
    assert sorted(k for k, _, _ in found) == sorted(np.flatnonzero(px >= 4000).tolist())
    assert all(ang < 3.0 and off < 0.01 for _, ang, off in found)


def test_fronto_parallel_wall_gives_one_plane_facing_the_camera():
    T = np.eye(4)
    depth = np.full((H, W), 2.0, np.float32)
    (plane,) = extract_planes(depth, K, T)
    assert np.allclose(plane.normal, [0.0, 0.0, -1.0], atol=1e-6)
    assert abs(plane.center_m[2] - 2.0) < 1e-6
    # the 64 x 48 cells cover 640 x 480 px: 2 m * 640 / 385 wide, 2 m * 480 / 385 high
    assert plane.area_m2 == pytest.approx((2 * 640 / 385) * (2 * 480 / 385), rel=0.1)


def test_holes_and_nan_only_drop_cells():
    T = POSES[0]
    depth, fid = render(T)
    holed = depth.copy()
    holed[200:230, 300:340] = np.nan
    holed[300:305, :] = 0.0
    holed[100:110, 100:110] = np.inf
    seg = segment_depth(holed, K)
    assert np.all(seg.labels_px[200:230, 300:340] == -1)
    for p in extract_planes(holed, K, T):
        k, ang, off = match(p)
        assert ang < 3.0 and off < 0.01


@pytest.mark.parametrize("bad", ["none", "zeros", "nan", "inf", "1d", "tiny", "k_nan", "pose_nan", "negative"])
def test_faulty_input_gives_no_planes_and_no_error(bad):
    T = POSES[0]
    depth, _ = render(T)
    Kb, Tb = K, T
    d = {"none": None, "zeros": np.zeros_like(depth), "nan": np.full_like(depth, np.nan),
         "inf": np.full_like(depth, np.inf), "1d": depth[0], "tiny": depth[:5, :5],
         "negative": -depth}.get(bad, depth)
    if bad == "k_nan":
        Kb = np.full((3, 3), np.nan)
    if bad == "pose_nan":
        Tb = np.full((4, 4), np.nan)
    assert extract_planes(d, Kb, Tb) == []
    seg = segment_depth(d, Kb)
    if bad != "pose_nan":
        assert seg.planes == []
        assert np.all(seg.labels_px == -1)


def test_deterministic():
    T = POSES[3]
    depth, _ = render(T)
    a, b = extract_planes(depth, K, T), extract_planes(depth.copy(), K.copy(), T.copy())
    assert len(a) == len(b) > 0
    for p, q in zip(a, b):
        assert np.array_equal(p.center_m, q.center_m) and np.array_equal(p.normal, q.normal)
        assert p.area_m2 == q.area_m2 and np.array_equal(p.cells, q.cells)
    assert np.array_equal(segment_depth(depth, K).labels_px, segment_depth(depth, K).labels_px)


def test_thresholds_reject_a_curved_surface():
    """A cylinder (r = 0.5 m) seen from 1.5 m is not one plane: with [34]'s MSE threshold the
    clusters stay small patches, each much flatter than the whole."""
    v, u = np.mgrid[0:H, 0:W].astype(float)
    x = (u - K[0, 2]) / K[0, 0]
    # cylinder axis along y at z = 2.0: (X)^2 + (Z - 2)^2 = 0.25, front surface
    a = x * x + 1.0
    b = -4.0
    c = 4.0 - 0.25
    disc = b * b - 4 * a * c
    z = np.where(disc > 0, (-b - np.sqrt(np.maximum(disc, 0))) / (2 * a), 0.0).astype(np.float32)
    seg = segment_depth(z, K)
    assert all(p.mse_m2 < AhcConfig().t_mse(np.array(p.center_cam_m[2]), AhcConfig().std_tol_merge_m)
               for p in seg.planes)
    assert len(seg.planes) >= 2


def test_config_validation():
    with pytest.raises(ConfigError):
        AhcConfig(cell_px=1)
    with pytest.raises(ConfigError):
        AhcConfig(merge_angle_deg=0.0)
    with pytest.raises(ConfigError):
        AhcConfig(z_far_m=0.1)
    with pytest.raises(ConfigError):
        extract_planes(np.ones((48, 64), np.float32), K, np.eye(4), cell_m=0.0)
