"""LiDAR model: pattern, ranges, intensity, glass and mirrors, motion distortion, seeds, errors.

Every scene is built here with MjSpec and its truth by hand; expected values come from the
VLP-16 manual (angles, firing order, timing) and from analytic ray/plane geometry, not from the
model's own output.
"""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from exobench.core import ConfigError, PlanarSurface, SceneTruth
from exobench.core.transforms import rot_z
from exobench.envs.sensors.lidar import LidarConfig, LidarPattern, LidarSensor, ReturnKind
from exobench.envs.sim.pose import site_pose
from exobench.models.materials import LidarMaterial

H = 1.0  # sensor height above the floor, m
WALL_X = 6.0  # front wall face, m
FIRING_S, SLOT_S = 55.296e-6, 2.304e-6
LASER_ID_ANGLES = [-15, 1, -13, 3, -11, 5, -9, 7, -7, 9, -5, 11, -3, 13, -1, 15]  # VLP-16 manual

EXACT = dict(range_noise_m=0.0, resolution_m=0.0, detection_threshold=0.0)


def _face(center, R, half, axis: int, sign: float):
    """(normal, point, polygon) of one face of a box (center, rotation R, half sizes)."""
    c, h = np.asarray(center, float), np.asarray(half, float)
    a, b = [k for k in range(3) if k != axis]
    n = sign * R[:, axis]
    fc = c + n * h[axis]
    ea, eb = R[:, a] * h[a], R[:, b] * h[b]
    return n, fc, np.array([fc - ea - eb, fc + ea - eb, fc + ea + eb, fc - ea + eb])


def build(boxes, materials):
    """Floor plane z=0 plus boxes (name, center, half, yaw_deg, (axis, sign) of the face to label).

    Returns model, data, truth, {name: surface id}; the floor is surface 0.
    """
    spec = mujoco.MjSpec()
    w = spec.worldbody
    w.add_geom(name="floor", type=mujoco.mjtGeom.mjGEOM_PLANE, size=[300, 300, 0.1])
    big = 300.0
    surfaces = [
        PlanarSurface(0, "ground", np.array([0, 0, 1.0]), np.zeros(3),
                      np.array([[-big, -big, 0], [big, -big, 0], [big, big, 0], [-big, big, 0.0]]), ("floor",))
    ]  # fmt: skip
    geom_surfaces = {"floor": (0,)}
    ids = {"floor": 0}
    for name, center, half, yaw_deg, (axis, sign) in boxes:
        yaw = np.radians(yaw_deg)
        w.add_geom(name=name, type=mujoco.mjtGeom.mjGEOM_BOX, pos=list(center), size=list(half),
                   quat=[np.cos(yaw / 2), 0, 0, np.sin(yaw / 2)])  # fmt: skip
        n, p, poly = _face(center, rot_z(yaw), half, axis, sign)
        sid = len(surfaces)
        surfaces.append(PlanarSurface(sid, "wall", n, p, poly, (name,)))
        geom_surfaces[name] = (sid,)
        ids[name] = sid
    model = spec.compile()
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    truth = SceneTruth(tuple(surfaces), geom_surfaces, kind="level", geom_materials=dict(materials))
    return model, data, truth, ids


def front_wall_scene(floor="carpet", wall="plaster"):
    return build([("wall", (WALL_X + 0.1, 0, 0), (0.1, 20, 10), 0.0, (0, -1.0))], {"floor": floor, "wall": wall})


def sensor_pose(x=0.0, y=0.0, yaw=0.0):
    T = np.eye(4)
    T[:3, :3] = rot_z(yaw)
    T[:3, 3] = (x, y, H)
    return T


def vlp16_dirs(ring, time_offset_s):
    """Sensor-frame beam directions from the manual: ring -> elevation, azimuth from the firing
    time (0.2 deg per 55.296 us, clockwise from behind)."""
    el = np.radians(-15.0 + 2.0 * ring)
    az = np.radians(180.0 - 0.2 * time_offset_s / FIRING_S)
    return np.column_stack([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)])


def front_wall_range(u, origin):
    """Analytic first hit of rays (origin, u) on the floor z=0 or the wall face x=WALL_X
    (|y| <= 20, |z| <= 10); inf if none. Also returns 0 floor / 1 wall / -1."""
    r = np.full(len(u), np.inf)
    what = np.full(len(u), -1)
    with np.errstate(divide="ignore", invalid="ignore"):
        rf = np.where(u[:, 2] < 0, -origin[2] / u[:, 2], np.inf)
        rw = np.where(u[:, 0] > 0, (WALL_X - origin[0]) / u[:, 0], np.inf)
    pw = origin + np.where(np.isfinite(rw), rw, 0.0)[:, None] * u
    rw = np.where((np.abs(pw[:, 1]) <= 20) & (np.abs(pw[:, 2]) <= 10), rw, np.inf)
    r = np.minimum(rf, rw)
    what = np.where(np.isinf(r), -1, np.where(rf < rw, 0, 1))
    return r, what


# --------------------------------------------------------------------------- pattern


def test_vlp16_pattern_matches_the_manual():
    p = LidarPattern.vlp16()
    assert p.n_channels == 16 and p.rate_hz == 10.0 and p.azimuth_step_deg == pytest.approx(0.2)
    assert sorted(p.vertical_angles_deg) == list(range(-15, 16, 2))
    fired = [p.vertical_angles_deg[c] for c in p.firing_order]
    assert fired == LASER_ID_ANGLES
    assert (p.min_range_m, p.max_range_m) == (0.9, 100.0)
    rays = p.rays()
    assert len(rays) == 16 * 1800
    k = np.arange(len(rays)) // 16
    slot = np.arange(len(rays)) % 16
    np.testing.assert_allclose(rays.time_offset_s, k * FIRING_S + slot * SLOT_S, rtol=0, atol=1e-15)
    assert rays.time_offset_s[-1] < 0.1  # the whole turn fits in one 10 Hz sweep
    np.testing.assert_allclose(rays.dirs_s, vlp16_dirs(rays.channel, rays.time_offset_s), atol=1e-12)


def test_other_patterns():
    v32 = LidarPattern.vlp32()
    assert v32.n_channels == 32 and min(v32.vertical_angles_deg) == -25 and max(v32.vertical_angles_deg) == 15
    assert list(v32.vertical_angles_deg) == sorted(v32.vertical_angles_deg)
    r = v32.rays()
    # lasers fire in pairs: laser ids 2i and 2i+1 at i * 2.304 us
    np.testing.assert_allclose(r.time_offset_s[:32], (np.arange(32) // 2) * SLOT_S, atol=1e-15)
    os64 = LidarPattern.ouster(channels=64)
    r = os64.rays()
    assert len(r) == 64 * 1024
    np.testing.assert_allclose(r.time_offset_s[64], 1.0 / (10 * 1024), rtol=1e-12)
    assert np.all(r.time_offset_s[:64] == 0.0)
    liv = LidarPattern.livox_like()
    a, b, a2 = liv.rays(0.0), liv.rays(0.1), liv.rays(0.0)
    assert len(a) == 10_000
    np.testing.assert_array_equal(a.dirs_s, a2.dirs_s)  # deterministic
    assert np.max(np.abs(a.dirs_s - b.dirs_s)) > 0.05  # non-repetitive from sweep to sweep
    off_axis = np.degrees(np.arccos(np.clip(a.dirs_s[:, 0], -1, 1)))
    assert off_axis.max() <= 19.2 + 1e-9 and off_axis.max() > 15.0
    g = LidarPattern.grid([-10.0, 0.0, 10.0], 1.0, fov_deg=90.0)
    r = g.rays()
    az = np.degrees(np.arctan2(r.dirs_s[:, 1], r.dirs_s[:, 0]))
    assert len(r) == 3 * 91 and az.max() == pytest.approx(45.0) and az.min() == pytest.approx(-45.0)


@pytest.mark.parametrize(
    "make, field",
    [
        (lambda: LidarPattern.grid([], 0.2), "vertical_angles_deg"),
        (lambda: LidarPattern.grid([0.0, 95.0], 0.2), "vertical_angles_deg"),
        (lambda: LidarPattern.grid([0.0, -90.5], 0.2), "vertical_angles_deg"),
        (lambda: LidarPattern.grid([0.0], 0.2, rate_hz=0.0), "rate_hz"),
        (lambda: LidarPattern("x", (0.0, 1.0), (0, 1), 0.2, -10.0, 1e-5), "rate_hz"),
        (lambda: LidarPattern("x", (0.0, 1.0), (0, 0), 0.2, 10.0, 1e-5), "firing_order"),
        (lambda: LidarPattern("x", (0.0,), (0,), 0.2, 10.0, 1e-3), "firing_period_s"),
        (lambda: LidarPattern("x", (0.0,), (0,), 0.2, 10.0, 1e-5, min_range_m=5, max_range_m=1), "max_range_m"),
        (lambda: LidarPattern.ouster(channels=48), "channels"),
        (lambda: LidarConfig(range_noise_m=-0.01), "range_noise_m"),
        (lambda: LidarConfig(intensity_mode="raw"), "intensity_mode"),
        (lambda: LidarConfig(pose_blocks=-1), "pose_blocks"),
        (lambda: LidarConfig(materials=(LidarMaterial("g", 0.1, "glass", 0.8, 0.5),)), "specular"),
    ],
)
def test_invalid_patterns_name_the_field(make, field):
    with pytest.raises(ConfigError) as e:
        make()
    assert e.value.field.endswith(field)


# --------------------------------------------------------------------------- ranges and intensity


def test_noise_free_ranges_equal_the_analytic_planes():
    model, data, truth, ids = front_wall_scene()
    s = LidarSensor("lidar", LidarConfig(**EXACT), model, seed=1)
    scan, tr = s.scan(model, data, sensor_pose(), 0.0, truth)
    pts = scan.points_xyz
    u = vlp16_dirs(scan.ring.astype(float), scan.time_offset_s)
    rng = np.linalg.norm(pts, axis=1)
    np.testing.assert_allclose(pts, rng[:, None] * u, atol=1e-9)  # on the documented beams
    r_exp, what = front_wall_range(u, np.array([0, 0, H]))
    np.testing.assert_allclose(rng, r_exp, rtol=0, atol=1e-9)
    np.testing.assert_array_equal(tr.surface_id, np.where(what == 1, ids["wall"], 0))
    np.testing.assert_allclose(tr.true_range_m, rng, atol=1e-12)
    # every beam with an analytic hit inside 0.9..100 m is there, and nothing else
    all_rays = s.rays(0.0)
    r_all, _ = front_wall_range(all_rays.dirs_s, np.array([0, 0, H]))
    assert len(scan.points_xyz) == int(np.sum((r_all >= 0.9) & (r_all <= 100.0)))
    assert np.all(tr.kind == ReturnKind.GENUINE)
    assert set(tr.material) == {"carpet", "plaster"}
    assert np.all(np.diff(scan.time_offset_s) >= 0)
    assert scan.stamp_s == pytest.approx(0.1) and scan.sweep_start_s == 0.0


def test_intensity_follows_reflectivity_incidence_and_range():
    model, data, truth, _ = front_wall_scene(floor="carpet", wall="plaster")
    cfg = LidarConfig(range_noise_m=0.0, resolution_m=0.0, intensity_mode="signal")  # default detection threshold 1.0
    scan, tr = LidarSensor("lidar", cfg, model, 1).scan(model, data, sensor_pose(), 0.0, truth)
    u = vlp16_dirs(scan.ring.astype(float), scan.time_offset_s)
    r, what = front_wall_range(u, np.array([0, 0, H]))
    cos = np.where(what == 0, np.abs(u[:, 2]), np.abs(u[:, 0]))
    rho = np.where(what == 0, 0.15, 0.6)
    expected = 100.0 * (rho / 0.8) * cos * (10.0 / r) ** 2
    np.testing.assert_allclose(tr.signal, expected, rtol=1e-9)
    np.testing.assert_array_equal(scan.intensity, np.rint(np.minimum(expected, 100.0)).astype(np.uint8))
    # two floor beams at the same azimuth: the grazing, farther one is weaker by cos * r^-2
    floor = np.flatnonzero(what == 0)
    k = floor[np.argmin(np.abs(scan.time_offset_s[floor] - 0.05))]  # pointing forward
    t_fire = scan.time_offset_s[k] - (scan.time_offset_s[k] % FIRING_S)
    same = floor[np.abs(scan.time_offset_s[floor] - t_fire) < FIRING_S * 0.99]
    lo, hi = same[np.argmin(scan.ring[same])], same[np.argmax(scan.ring[same])]
    el_lo, el_hi = np.radians(-15.0 + 2 * scan.ring[lo]), np.radians(-15.0 + 2 * scan.ring[hi])
    r_lo, r_hi = H / np.sin(-el_lo), H / np.sin(-el_hi)
    ratio = (np.sin(-el_hi) / r_hi**2) / (np.sin(-el_lo) / r_lo**2)
    assert tr.signal[hi] < tr.signal[lo]
    assert tr.signal[hi] / tr.signal[lo] == pytest.approx(ratio, rel=1e-9)
    # the detection threshold drops exactly the weak returns (grazing floor far away)
    rays = LidarSensor("lidar", cfg, model, 1).rays(0.0)
    r_all, w_all = front_wall_range(rays.dirs_s, np.array([0, 0, H]))
    ok = np.isfinite(r_all)
    c_all = np.where(w_all == 0, np.abs(rays.dirs_s[:, 2]), np.abs(rays.dirs_s[:, 0]))
    sig = np.full(len(rays), -1.0)
    sig[ok] = 100.0 * (np.where(w_all == 0, 0.15, 0.6)[ok] / 0.8) * c_all[ok] * (10.0 / r_all[ok]) ** 2
    keep = ok & (r_all >= 0.9) & (r_all <= 100.0) & (sig >= 1.0)
    assert len(scan.points_xyz) == int(keep.sum()) < int((ok & (r_all <= 100.0)).sum())
    assert scan.intensity[what == 0].mean() < 50 < scan.intensity[what == 1].mean()


def test_range_compensated_intensity_mode():
    model, data, truth, _ = front_wall_scene(floor="carpet", wall="plaster")
    cfg = LidarConfig(intensity_mode="reflectivity", **EXACT)
    scan, tr = LidarSensor("lidar", cfg, model, 1).scan(model, data, sensor_pose(), 0.0, truth)
    u = vlp16_dirs(scan.ring.astype(float), scan.time_offset_s)
    _, what = front_wall_range(u, np.array([0, 0, H]))
    level = 100.0 * np.where(what == 0, 0.15 * np.abs(u[:, 2]), 0.6 * np.abs(u[:, 0]))
    np.testing.assert_array_equal(scan.intensity, np.rint(level).astype(np.uint8))


def test_retroreflectors_report_above_100():
    model, data, truth, _ = front_wall_scene(wall="retroreflector")
    scan, tr = LidarSensor("lidar", LidarConfig(**EXACT), model, 1).scan(model, data, sensor_pose(), 0.0, truth)
    on_wall = tr.material == "retroreflector"
    assert on_wall.any() and np.all(scan.intensity[on_wall] > 100)
    assert np.all(scan.intensity[~on_wall] <= 100)


# --------------------------------------------------------------------------- glass and mirrors

PANE = ("pane", (2.0, 0.0, 1.25), (0.005, 1.0, 1.25), 0.0, (0, -1.0))  # faces at x = 1.995 / 2.005


def _crosses_pane(origin, u):
    """Slab test of rays against the pane box (axis-aligned), before the wall."""
    lo = np.array([1.995, -1.0, 0.0])
    hi = np.array([2.005, 1.0, 2.5])
    with np.errstate(divide="ignore", invalid="ignore"):
        t1, t2 = (lo - origin) / u, (hi - origin) / u
    tmin = np.nanmax(np.minimum(t1, t2), axis=1)
    tmax = np.nanmin(np.maximum(t1, t2), axis=1)
    return (tmax >= tmin) & (tmax > 0)


def test_clear_glass_lets_the_beam_through():
    clear = LidarMaterial("clear_glass", 0.05, "glass", transmission=1.0, specular=0.0)
    wall = ("wall", (WALL_X + 0.1, 0, 0), (0.1, 20, 10), 0.0, (0, -1.0))
    model, data, truth, ids = build([wall, PANE], {"pane": "clear_glass", "wall": "plaster"})
    cfg = LidarConfig(materials=(clear,), **EXACT)
    scan, tr = LidarSensor("lidar", cfg, model, 3).scan(model, data, sensor_pose(), 0.0, truth)
    origin = np.array([0, 0, H])
    u = vlp16_dirs(scan.ring.astype(float), scan.time_offset_s)
    r_exp, _ = front_wall_range(u, origin)  # the pane is not there for the beams
    np.testing.assert_allclose(np.linalg.norm(scan.points_xyz, axis=1), r_exp, atol=1e-9)
    crossed = _crosses_pane(origin, u)
    assert crossed.sum() > 100
    assert not np.any(tr.kind == ReturnKind.GLASS)
    np.testing.assert_array_equal(tr.kind == ReturnKind.THROUGH_GLASS, crossed)
    assert np.all(tr.genuine)
    assert np.all(tr.via_geom_id[crossed] == mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, "pane"))
    assert not np.any(tr.surface_id == ids["pane"])


def test_opaque_pane_gives_weak_pane_returns():
    pane = LidarMaterial("dull_glass", 0.05, "glass", transmission=0.0, specular=0.0)
    wall = ("wall", (WALL_X + 0.1, 0, 0), (0.1, 20, 10), 0.0, (0, -1.0))
    model, data, truth, ids = build([wall, PANE], {"pane": "dull_glass", "wall": "plaster"})
    cfg = LidarConfig(materials=(pane,), **EXACT)
    scan, tr = LidarSensor("lidar", cfg, model, 3).scan(model, data, sensor_pose(), 0.0, truth)
    g = tr.kind == ReturnKind.GLASS
    on_face = tr.surface_id == ids["pane"]
    assert on_face.sum() > 100 and np.all(g[on_face])
    np.testing.assert_allclose(scan.points_xyz[on_face, 0], 1.995, atol=1e-9)
    u = scan.points_xyz[on_face] / np.linalg.norm(scan.points_xyz[on_face], axis=1)[:, None]
    r = np.linalg.norm(scan.points_xyz[on_face], axis=1)
    np.testing.assert_allclose(tr.signal[on_face], 100 * (0.05 / 0.8) * u[:, 0] * (10 / r) ** 2, rtol=1e-9)
    assert not np.any(tr.genuine[g])


def _mirror_scene(mat: LidarMaterial):
    """A mirror (or pane) turned 30 deg, facing the sensor; walls behind and beside the sensor."""
    yaw = -30.0
    mirror = ("mirror", (3.0, 0.0, 1.26), (0.01, 1.5, 1.25), yaw, (0, -1.0))
    back = ("back", (-4.1, 0, 0), (0.1, 20, 10), 0.0, (0, 1.0))
    side = ("side", (0, 8.1, 0), (20, 0.1, 10), 0.0, (1, -1.0))
    model, data, truth, ids = build([mirror, back, side], {"mirror": mat.name, "back": "plaster", "side": "wood"})
    s = truth.surface(ids["mirror"])
    return model, data, truth, ids, s.normal_w, s.point_w


@pytest.mark.parametrize(
    "mat",
    [
        LidarMaterial("perfect_mirror", 0.05, "mirror", specular=1.0),
        LidarMaterial("reflective_pane", 0.05, "glass", transmission=0.0, specular=1.0),
    ],
)
def test_specular_surfaces_make_ghosts_at_the_mirrored_geometry(mat):
    model, data, truth, ids, n_m, q_m = _mirror_scene(mat)
    cfg = LidarConfig(materials=(mat,), **EXACT)
    scan, tr = LidarSensor("lidar", cfg, model, 5).scan(model, data, sensor_pose(), 0.0, truth)
    ghost = tr.kind == ReturnKind.GHOST
    assert ghost.sum() > 200
    assert not np.any(tr.surface_id == ids["mirror"])  # the mirror itself returns nothing
    gw = scan.points_xyz[ghost] + np.array([0, 0, H])  # static pose: sensor frame + offset
    real = tr.hit_w[ghost]
    mirrored = real - 2.0 * ((real - q_m) @ n_m)[:, None] * n_m  # the real point seen in the mirror
    np.testing.assert_allclose(gw, mirrored, atol=1e-9)
    # the ghost lies along the original ray at the reflected path length
    u = scan.points_xyz[ghost] / np.linalg.norm(scan.points_xyz[ghost], axis=1)[:, None]
    s1 = ((q_m - np.array([0, 0, H])) @ n_m) / (u @ n_m)  # distance to the mirror plane
    p1 = np.array([0, 0, H]) + s1[:, None] * u
    np.testing.assert_allclose(tr.true_range_m[ghost], s1 + np.linalg.norm(real - p1, axis=1), atol=1e-9)
    assert set(tr.surface_id[ghost]) <= {0, ids["back"], ids["side"]}
    assert ids["back"] in set(tr.surface_id[ghost])
    assert np.all(tr.via_geom_id[ghost] == mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, "mirror"))
    assert not np.any(tr.genuine[ghost])


@pytest.mark.parametrize("mode", ["reflectivity", "signal"])
def test_ghost_strength_carries_the_specular_fraction_there_and_back(mode):
    # a half-silvered mirror: a ghost's light is mirrored on the way out and on the way back
    spec = 0.5
    mat = LidarMaterial("half_mirror", 0.05, "mirror", specular=spec)
    model, data, truth, ids, n_m, q_m = _mirror_scene(mat)
    cfg = LidarConfig(materials=(mat,), intensity_mode=mode, range_noise_m=0.0, resolution_m=0.0, detection_threshold=0.0)
    scan, tr = LidarSensor("lidar", cfg, model, 5).scan(model, data, sensor_pose(), 0.0, truth)
    ghost = tr.kind == ReturnKind.GHOST
    assert ghost.sum() > 100
    o = np.array([0, 0, H])
    u = scan.points_xyz[ghost] / np.linalg.norm(scan.points_xyz[ghost], axis=1)[:, None]
    # hand computation: reflect the ray on the mirror plane, intersect the labelled real plane
    s1 = ((q_m - o) @ n_m) / (u @ n_m)
    p1 = o + s1[:, None] * u
    d = u - 2.0 * (u @ n_m)[:, None] * n_m
    rho_of = {0: 0.35, ids["back"]: 0.6, ids["side"]: 0.45}  # concrete (default) floor, plaster, wood
    sids = tr.surface_id[ghost]
    normals = np.array([truth.surface(int(k)).normal_w for k in sids])
    points = np.array([truth.surface(int(k)).point_w for k in sids])
    s2 = np.einsum("ij,ij->i", points - p1, normals) / np.einsum("ij,ij->i", d, normals)
    cos = np.abs(np.einsum("ij,ij->i", d, normals))
    rho = np.array([rho_of[int(k)] for k in sids])
    signal = 100.0 * spec**2 * (rho / 0.8) * cos * (10.0 / (s1 + s2)) ** 2
    np.testing.assert_allclose(tr.signal[ghost], signal, rtol=1e-9)
    level = signal if mode == "signal" else 100.0 * spec**2 * rho * cos
    np.testing.assert_array_equal(scan.intensity[ghost], np.rint(np.minimum(level, 100.0)).astype(np.uint8))


def test_through_glass_returns_lose_the_transmission_twice():
    wall = ("wall", (WALL_X + 0.1, 0, 0), (0.1, 20, 10), 0.0, (0, -1.0))
    model, data, truth, _ = build([wall, PANE], {"pane": "tinted", "wall": "plaster"})
    origin = np.array([0, 0, H])
    ref = None
    for t in (1.0, 0.7):
        mat = LidarMaterial("tinted", 0.05, "glass", transmission=t, specular=0.0)
        cfg = LidarConfig(materials=(mat,), intensity_mode="reflectivity", **EXACT)
        scan, tr = LidarSensor("lidar", cfg, model, 3).scan(model, data, sensor_pose(), 0.0, truth)
        through = tr.kind == ReturnKind.THROUGH_GLASS
        u = scan.points_xyz[through] / np.linalg.norm(scan.points_xyz[through], axis=1)[:, None]
        _, what = front_wall_range(u, origin)
        cos = np.where(what == 0, np.abs(u[:, 2]), np.abs(u[:, 0]))
        rho = np.where(what == 0, 0.35, 0.6)  # concrete (default) floor, plaster wall
        np.testing.assert_array_equal(scan.intensity[through], np.rint(100.0 * t**2 * rho * cos).astype(np.uint8))
        ref = through.sum() if ref is None else ref
    assert 0 < through.sum() < ref  # the rest of the beams return from the pane itself


def test_glass_decisions_follow_the_material_fractions():
    mat = LidarMaterial("glass", 0.05, "glass", transmission=0.85, specular=0.1)  # the table's glass
    wall = ("wall", (WALL_X + 0.1, 0, 0), (0.1, 20, 10), 0.0, (0, -1.0))
    model, data, truth, _ = build([wall, PANE], {"pane": "glass", "wall": "plaster"})
    s = LidarSensor("lidar", LidarConfig(**EXACT), model, 11)
    scan, tr = s.scan(model, data, sensor_pose(), 0.0, truth)
    pane = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, "pane")
    n = int(_crosses_pane(np.array([0, 0, H]), s.rays(0.0).dirs_s).sum())  # beams that meet the pane
    counts = {k: int(np.sum(tr.kind == k)) for k in ReturnKind}
    sigma = np.sqrt(0.85 * 0.15 / n)
    # every crossing beam reaches the wall; every pane reflection is strong enough at 2 m
    assert counts[ReturnKind.THROUGH_GLASS] / n == pytest.approx(mat.transmission, abs=4 * sigma)
    assert counts[ReturnKind.GLASS] / n == pytest.approx(1 - mat.transmission - mat.specular, abs=4 * sigma)
    # mirrored beams going up leave the scene without a return: ghosts <= the specular share
    assert 0 < counts[ReturnKind.GHOST] / n <= mat.specular + 4 * sigma
    assert np.all(tr.via_geom_id[tr.kind == ReturnKind.THROUGH_GLASS] == pane)
    off = LidarConfig(glass=False, **EXACT)
    _, tr_off = LidarSensor("lidar", off, model, 11).scan(model, data, sensor_pose(), 0.0, truth)
    assert not np.any(tr_off.kind == ReturnKind.THROUGH_GLASS) and not np.any(tr_off.kind == ReturnKind.GHOST)


# --------------------------------------------------------------------------- motion, seeds, dropout


def test_motion_during_the_sweep_distorts_and_deskews():
    model, data, truth, ids = front_wall_scene()
    v, t0 = 2.0, 0.5

    def pose_at(times):
        T = np.repeat(np.eye(4)[None], len(times), axis=0)
        T[:, 0, 3] = v * (np.asarray(times) - t0)
        T[:, 2, 3] = H
        return T

    scan, tr = LidarSensor("lidar", LidarConfig(**EXACT), model, 2).scan(model, data, pose_at, t0, truth)
    wall = tr.surface_id == ids["wall"]
    x_s = scan.points_xyz[wall, 0]
    # in the sensor frame each wall point is nearer by the distance travelled at its firing time;
    # the lasers of one firing block share the block's pose (they fire within 37 us)
    t_fire = np.floor(scan.time_offset_s / FIRING_S + 1e-9) * FIRING_S
    np.testing.assert_allclose(x_s, WALL_X - v * t_fire[wall], rtol=0, atol=1e-9)
    np.testing.assert_allclose(x_s, WALL_X - v * scan.time_offset_s[wall], atol=v * 16 * SLOT_S)
    np.testing.assert_allclose(scan.points_xyz[~wall, 2], -H, atol=1e-9)  # the floor stays at -H
    assert np.ptp(x_s) > 0.05
    # casting every firing from its own origin gives the same cloud (no silhouette in between)
    slow, _ = LidarSensor("lidar", LidarConfig(cast_period_s=0.0, **EXACT), model, 2).scan(model, data, pose_at, t0, truth)
    assert len(slow.points_xyz) == len(scan.points_xyz)
    np.testing.assert_allclose(slow.points_xyz, scan.points_xyz, rtol=0, atol=1e-9)
    # deskewing with the reported time offsets puts every point back on the wall
    T = pose_at(t0 + scan.time_offset_s)
    world = np.einsum("nij,nj->ni", T[:, :3, :3], scan.points_xyz) + T[:, :3, 3]
    np.testing.assert_allclose(world[wall, 0], WALL_X, atol=v * 16 * SLOT_S + 1e-9)
    np.testing.assert_allclose(world[~wall, 2], 0.0, atol=1e-6)
    # a static pose gives the undistorted wall
    scan0, tr0 = LidarSensor("lidar", LidarConfig(**EXACT), model, 2).scan(model, data, sensor_pose(), t0, truth)
    np.testing.assert_allclose(scan0.points_xyz[tr0.surface_id == ids["wall"], 0], WALL_X, atol=1e-9)


def test_yawing_sensor_and_pose_blocks():
    model, data, truth, ids = front_wall_scene()
    w = 2.0  # rad/s yaw rate

    def pose_at(times):
        return np.array([sensor_pose(yaw=w * t) for t in np.asarray(times)])

    exact = LidarSensor("lidar", LidarConfig(**EXACT), model, 2).scan(model, data, pose_at, 0.0, truth)
    coarse = LidarSensor("lidar", LidarConfig(pose_blocks=20, **EXACT), model, 2).scan(model, data, pose_at, 0.0, truth)
    for (scan, tr), tol in ((exact, 16 * SLOT_S * w * 25), (coarse, 0.05 / 20 * w * 25)):
        T = pose_at(scan.time_offset_s)
        world = np.einsum("nij,nj->ni", T[:, :3, :3], scan.points_xyz) + T[:, :3, 3]
        wall = tr.surface_id == ids["wall"]
        assert wall.sum() > 1000
        np.testing.assert_allclose(world[wall, 0], WALL_X, atol=tol)
    # the pose grouping changes nothing for a static sensor
    a, _ = LidarSensor("lidar", LidarConfig(**EXACT), model, 2).scan(model, data, sensor_pose(), 0.0, truth)
    b, _ = LidarSensor("lidar", LidarConfig(pose_blocks=7, **EXACT), model, 2).scan(model, data, sensor_pose(), 0.0, truth)
    np.testing.assert_array_equal(a.points_xyz, b.points_xyz)


def test_same_seed_same_scan_and_noise_statistics():
    model, data, truth, ids = front_wall_scene()
    cfg = LidarConfig(resolution_m=0.0)
    runs = []
    for seed in (7, 7, 8):
        s = LidarSensor("lidar", cfg, model, seed)
        runs.append([s.scan(model, data, sensor_pose(), 0.1 * k, truth) for k in range(2)])
    for (sa, ta), (sb, tb) in zip(runs[0], runs[1]):
        np.testing.assert_array_equal(sa.points_xyz, sb.points_xyz)
        np.testing.assert_array_equal(sa.intensity, sb.intensity)
        np.testing.assert_array_equal(ta.kind, tb.kind)
    assert not np.array_equal(runs[0][0][0].points_xyz, runs[2][0][0].points_xyz)
    assert not np.array_equal(runs[0][0][0].points_xyz, runs[0][1][0].points_xyz)  # fresh noise per sweep
    scan, tr = runs[0][0]
    err = np.linalg.norm(scan.points_xyz, axis=1) - tr.true_range_m
    assert np.std(err) == pytest.approx(0.015, rel=0.05) and abs(np.mean(err)) < 1e-3


def test_dropout_and_resolution():
    model, data, truth, _ = front_wall_scene()
    full, _ = LidarSensor("lidar", LidarConfig(**EXACT), model, 4).scan(model, data, sensor_pose(), 0.0, truth)
    half, _ = LidarSensor("lidar", LidarConfig(point_dropout_prob=0.5, **EXACT), model, 4).scan(
        model, data, sensor_pose(), 0.0, truth
    )
    assert len(half.points_xyz) / len(full.points_xyz) == pytest.approx(0.5, abs=0.03)
    s = LidarSensor("lidar", LidarConfig(dropout_prob=0.5), model, 4)
    lost = sum(s.scan(model, data, sensor_pose(), 0.1 * k, truth) is None for k in range(20))
    assert 3 <= lost <= 17
    q, _ = LidarSensor("lidar", LidarConfig(range_noise_m=0.0), model, 4).scan(model, data, sensor_pose(), 0.0, truth)
    r = np.linalg.norm(q.points_xyz, axis=1) / 0.002
    np.testing.assert_allclose(r, np.round(r), atol=1e-6)


def test_the_mount_body_does_not_block_its_own_beams():
    spec = mujoco.MjSpec()
    spec.worldbody.add_geom(name="floor", type=mujoco.mjtGeom.mjGEOM_PLANE, size=[300, 300, 0.1])
    spec.worldbody.add_geom(name="wall", type=mujoco.mjtGeom.mjGEOM_BOX, pos=[WALL_X + 0.1, 0, 0], size=[0.1, 20, 10])
    trunk = spec.worldbody.add_body(name="trunk", pos=[0, 0, H])
    trunk.add_site(name="lidar_trunk")
    trunk.add_geom(name="torso", type=mujoco.mjtGeom.mjGEOM_BOX, size=[0.2, 0.2, 0.2], group=2)
    model = spec.compile()
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    truth = SceneTruth((), {}, geom_materials={"wall": "plaster"})
    scan, tr = LidarSensor("lidar_trunk", LidarConfig(**EXACT), model, 0).scan(model, data, sensor_pose(), 0.0, truth)
    u = vlp16_dirs(scan.ring.astype(float), scan.time_offset_s)
    r_exp, _ = front_wall_range(u, np.array([0, 0, H]))
    np.testing.assert_allclose(np.linalg.norm(scan.points_xyz, axis=1), r_exp, atol=1e-9)
    assert len(scan.points_xyz) > 10_000 and np.all(tr.surface_id == -1)  # no surfaces listed
    # another sensor id (no such site) sees the torso at 0.2 m, inside the minimum range
    other, _ = LidarSensor("lidar_x", LidarConfig(**EXACT), model, 0).scan(model, data, sensor_pose(), 0.0, truth)
    assert len(other.points_xyz) == 0


def test_unknown_material_is_named():
    from exobench.core import UnknownNameError

    model, data, truth, _ = front_wall_scene(wall="unobtainium")
    with pytest.raises(UnknownNameError):
        LidarSensor("lidar", LidarConfig(), model, 0).scan(model, data, sensor_pose(), 0.0, truth)


def _office_scene():
    from exobench.models.exo_spec import ExoSpec
    from exobench.models.office import build_office
    from exobench.models.worlds import compose

    scene = compose(build_office(), ExoSpec())
    data = mujoco.MjData(scene.model)
    mujoco.mj_forward(scene.model, data)
    T0 = site_pose(scene.model, data, "lidar_trunk")
    return scene.model, data, scene.truth, T0


def test_threads_and_vectorised_labels_do_not_change_a_sweep():
    model, data, truth, T0 = _office_scene()

    def walking(t):
        T = np.repeat(T0[None], len(t), axis=0)
        T[:, :3, 3] += (0.5 * np.asarray(t))[:, None] * np.array([1.0, 0.0, 0.0])
        return T

    for pose in (T0, walking):
        out = [LidarSensor("lidar_trunk", LidarConfig(cast_threads=k), model, 3).scan(model, data, pose, 0.0, truth) for k in (1, 3)]
        (s1, t1), (s3, t3) = out
        np.testing.assert_array_equal(s1.points_xyz, s3.points_xyz)
        np.testing.assert_array_equal(t1.geom_id, t3.geom_id)
        np.testing.assert_array_equal(t1.surface_id, t3.surface_id)
    # the labels are SceneTruth.surface_of_hit's, point by point
    names = [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, int(g)) or "" for g in t1.geom_id]
    idx = np.arange(0, len(names), 7)
    expected = [truth.surface_of_hit(names[i], t1.hit_w[i]) for i in idx]
    np.testing.assert_array_equal(t1.surface_id[idx], expected)
    assert np.count_nonzero(t1.surface_id >= 0) > 0.9 * len(names)


def test_zoned_two_pass_cast_equals_one_cast_on_the_simulation_model():
    """The private zoned model and the near/far passes change the speed, not the hits.

    The reference is one plain ``mj_multiRay`` pass on the simulation's own model; the legs
    are bent and the pelvis moved after the first sweeps, so the zoned model must follow the
    moving geoms, which a sensor facing the user's legs sees.
    """
    model, data, truth, T0 = _office_scene()
    plain = LidarConfig(zoned_cast=False, cast_near_m=0.0, caster="mujoco")
    fast = LidarConfig(caster="mujoco")
    facing = T0.copy()  # 1.5 m in front of the user at knee height, level: its rings cross the legs
    facing[:3, 3] += T0[:3, :3] @ np.array([1.5, 0.0, 0.0])
    facing[2, 3] = 0.6
    sensors = {name: LidarSensor("lidar_trunk", cfg, model, 3) for name, cfg in (("plain", plain), ("fast", fast))}
    legs = {mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, g))
            for g in range(model.ngeom) if model.body_weldid[model.geom_bodyid[g]] != 0}  # fmt: skip
    for step in range(2):
        if step == 1:  # bend the knees and hips, move the pelvis: the moving geoms must follow
            for j, q in (("hip_l", 0.5), ("knee_l", -0.9), ("hip_r", -0.3), ("knee_r", -0.4)):
                data.qpos[model.jnt_qposadr[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, j)]] = q
            data.qpos[:3] += [0.3, -0.2, 0.0]
            mujoco.mj_forward(model, data)
        for pose in (T0, facing):
            (sp, tp), (sf, tf) = (sensors[k].scan(model, data, pose, 0.0, truth) for k in ("plain", "fast"))
            np.testing.assert_array_equal(sp.points_xyz, sf.points_xyz)
            np.testing.assert_array_equal(tp.geom_id, tf.geom_id)
            np.testing.assert_array_equal(tp.surface_id, tf.surface_id)
            np.testing.assert_array_equal(tp.kind, tf.kind)
        assert np.count_nonzero(np.isin(tp.geom_id, list(legs))) > 50  # the sweep does see the user's legs
    # returns beyond the near pass's 8 m come from the second pass
    assert np.count_nonzero(tp.true_range_m > 8.0) > 100
