"""RGB-D camera: rendered depth against MuJoCo ray casts, intrinsics against drawn points, the
stereo noise model, range and edge invalidation, configs, determinism and GL back-end choice."""

import os
import subprocess
import sys
from pathlib import Path

import mujoco
import numpy as np
import pytest

from exobench.core import ConfigError, UnknownNameError
from exobench.core.transforms import make_T, matrix_to_quat_wxyz, rot_x, rot_y
from exobench.envs.sensors.rgbd import RgbdCamera, RgbdConfig, edge_mask, intrinsics
from exobench.models import worlds
from exobench.models.exo import R_OPTICAL_MJCAMERA
from exobench.models.exo_spec import ExoSpec

pytestmark = pytest.mark.long(seconds=6)  # the workers take it first (tests/conftest.py); 6: the file at -n 0 in one run at load 12-15, scaled to that run's CPU

VISIBLE_GROUPS = np.array([1, 1, 1, 0, 0, 0], dtype=np.uint8)  # MuJoCo's default rendered groups
NOISE_FREE = {"subpixel": 0.0, "edge_threshold_rel": 0.0, "resolution_m": 0.0}
# optical frame looking along world +x, level: z_opt = +x, x_opt = -y, y_opt = -z
R_FORWARD = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])


@pytest.fixture(scope="module")
def stairs():
    scene = worlds.compose(worlds.build_staircase(worlds.StaircaseParams(position_m=(1.0, 0.0))), ExoSpec())
    data = mujoco.MjData(scene.model)
    mujoco.mj_forward(scene.model, data)
    return scene.model, data


def _camera_scene(T_world_opt, geoms=(), wall_x_m=None):
    """A world with one camera 'cam' at T_world_opt, optional spheres ((pos, r)) and a wall."""
    spec = mujoco.MjSpec()
    wb = spec.worldbody
    wb.add_light(pos=[0, 0, 6], dir=[0, 0, -1])
    wb.add_camera(name="cam", pos=list(T_world_opt[:3, 3]),
                  quat=list(matrix_to_quat_wxyz(T_world_opt[:3, :3] @ R_OPTICAL_MJCAMERA)))
    for pos, r in geoms:
        wb.add_geom(type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[r, 0, 0], pos=list(pos), rgba=[1, 0, 0, 1])
    if wall_x_m is not None:
        wb.add_geom(type=mujoco.mjtGeom.mjGEOM_BOX, size=[0.05, 20, 20], pos=[wall_x_m + 0.05, 0, 0])
    model = spec.compile()
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    return model, data


def _ray_depth(model, data, T_world_opt, K, u, v):
    """z-depth and geom id of the ray through pixel (u, v) by mj_ray (-1, -1 when it misses)."""
    d_opt = np.linalg.solve(K, [u, v, 1.0])  # z component 1: the ray parameter is the z-depth
    gid = np.zeros(1, dtype=np.int32)
    x = mujoco.mj_ray(model, data, T_world_opt[:3, 3], T_world_opt[:3, :3] @ d_opt, VISIBLE_GROUPS, 1, -1, gid)
    return (x, int(gid[0])) if x >= 0 else (-1.0, -1)


@pytest.mark.parametrize("size", [(640, 480), (848, 480)])
def test_depth_equals_ray_cast_z_depth_on_stairs(stairs, size):
    model, data = stairs
    config = RgbdConfig(width_px=size[0], height_px=size[1], min_depth_m=0.0, max_depth_m=100.0, **NOISE_FREE)
    with RgbdCamera("rgbd_chest", config, model, seed=0, segmentation=True) as cam:
        frame, truth = cam.capture(model, data, 0.0)
    T, K = truth["T_world_sensor"], frame.K
    z, gid = truth["depth_m"], truth["geom_id"]
    checked, misses = 0, 0
    for v in range(4, size[1] - 4, 9):
        for u in range(4, size[0] - 4, 9):
            if np.unique(gid[v - 1 : v + 2, u - 1 : u + 2]).size > 1:
                continue  # a surface edge: the rasterised pixel may belong to either side
            x, g = _ray_depth(model, data, T, K, u, v)
            assert g == gid[v, u]
            if g < 0:
                assert z[v, u] == 0 and frame.depth_m[v, u] == 0
                misses += 1
                continue
            # float32 depth buffer: relative precision ~1e-7, so micrometres at a few metres
            assert abs(z[v, u] - x) < 1e-3
            assert abs(frame.depth_m[v, u] - x) < 1e-3
            checked += 1
    assert checked > 1500 and misses > 100  # stairs, floor and sky all sampled


@pytest.mark.parametrize(
    "kw",
    [{}, {"width_px": 848, "height_px": 480},
     {"width_px": 640, "height_px": 480, "fx_px": 500.0, "fy_px": 450.0, "cx_px": 300.2, "cy_px": 250.7}],
)
def test_intrinsics_project_points_where_the_renderer_draws_them(kw):
    config = RgbdConfig(**kw, **NOISE_FREE)
    K = intrinsics(config)
    W, H = config.width_px, config.height_px
    T = make_T(R_FORWARD @ rot_x(np.radians(-20.0)) @ rot_y(np.radians(10.0)), np.array([0.3, -0.2, 1.4]))
    targets = [(W / 2, H / 2), (40, 35), (W - 45, 38), (42, H - 40), (W - 40, H - 44), (W / 3, 2 * H / 3)]
    spheres = []
    for i, (u, v) in enumerate(targets):
        z = 1.2 + 0.2 * i
        spheres.append((T[:3, :3] @ (z * np.linalg.solve(K, [u, v, 1.0])) + T[:3, 3], 0.012 * z))
    model, data = _camera_scene(T, spheres)
    with RgbdCamera("cam", config, model, seed=0, segmentation=True) as cam:
        _, truth = cam.capture(model, data, 0.0)
    np.testing.assert_allclose(truth["T_world_sensor"], T, atol=1e-9)
    for gid, (u, v) in enumerate(targets):
        vv, uu = np.nonzero(truth["geom_id"] == gid)
        assert len(uu) > 10
        assert abs(uu.mean() - u) < 1.0 and abs(vv.mean() - v) < 1.0


def test_default_intrinsics_follow_the_d455():
    K = intrinsics(RgbdConfig())
    np.testing.assert_allclose(K, [[384.0, 0, 319.5], [0, 384.0, 236.4], [0, 0, 1]])
    c = RgbdConfig(width_px=848, height_px=480)
    assert (c.fx_px, c.fy_px, c.cx_px, c.cy_px, c.min_depth_m) == (424.0, 424.0, 423.5, 239.5, 0.34)
    assert RgbdConfig().min_depth_m == 0.4 and RgbdConfig().max_depth_m == 6.0 and RgbdConfig().rate_hz == 30.0


@pytest.mark.parametrize("distance_m", [2.0, 4.0])
def test_noise_std_matches_the_stereo_model_on_a_wall(distance_m):
    config = RgbdConfig(resolution_m=0.0)
    model, data = _camera_scene(make_T(R_FORWARD, np.zeros(3)), wall_x_m=distance_m)
    with RgbdCamera("cam", config, model, seed=3) as cam:
        frame, truth = cam.capture(model, data, 0.0)
    np.testing.assert_allclose(truth["depth_m"], distance_m, atol=1e-4)
    valid = frame.depth_m > 0
    assert valid.mean() > 0.999
    err = frame.depth_m[valid].astype(float) - distance_m
    sigma = distance_m**2 * 0.08 / (384.0 * 0.095)  # z^2 s / (f B), docs/sensor-reference.md
    assert abs(err.std() / sigma - 1.0) < 0.10
    assert abs(err.mean()) < 0.02 * sigma


def test_depth_outside_the_range_is_zero(stairs):
    model, data = stairs
    config = RgbdConfig(min_depth_m=1.6, max_depth_m=3.0, **NOISE_FREE)
    with RgbdCamera("rgbd_chest", config, model, seed=0) as cam:
        frame, truth = cam.capture(model, data, 0.0)
    z, d = truth["depth_m"], frame.depth_m
    inside = (z >= 1.6) & (z <= 3.0)
    assert inside.sum() > 10000 and ((z > 0) & (z < 1.6)).sum() > 10000 and (z > 3.0).sum() > 10000
    assert np.all(d[~inside] == 0)
    np.testing.assert_array_equal(d[inside], z[inside])


def test_edges_invalidate_pixels_at_depth_jumps_only():
    # a box face at 2 m covers the image left of the optical axis, a wall at 4 m the rest
    T = make_T(R_FORWARD, np.zeros(3))
    spec = mujoco.MjSpec()
    spec.worldbody.add_camera(name="cam", quat=list(matrix_to_quat_wxyz(R_FORWARD @ R_OPTICAL_MJCAMERA)))
    spec.worldbody.add_geom(type=mujoco.mjtGeom.mjGEOM_BOX, size=[0.05, 10, 10], pos=[4.05, 0, 0])
    spec.worldbody.add_geom(type=mujoco.mjtGeom.mjGEOM_BOX, size=[0.05, 5, 10], pos=[2.05, 5.0, 0])  # y > 0
    model = spec.compile()
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    frames = {}
    for thr in (0.05, 1.5, 0.0):
        config = RgbdConfig(subpixel=0.0, edge_threshold_rel=thr, resolution_m=0.0)
        with RgbdCamera("cam", config, model, seed=0) as cam:
            frames[thr], truth = cam.capture(model, data, 0.0)
    np.testing.assert_allclose(truth["T_world_sensor"], T, atol=1e-12)
    # optical x < 0 (world y > 0) <=> u < cx = 319.5: columns 0..319 see the box at 2 m
    z = truth["depth_m"]
    np.testing.assert_allclose(z[:, :320], 2.0, atol=1e-4)
    np.testing.assert_allclose(z[:, 320:], 4.0, atol=1e-4)
    d = frames[0.05].depth_m
    assert np.all(d[:, 319:321] == 0)  # the jump of 2 m is 100 % of the nearer depth
    assert np.all(d[:, :319] > 0) and np.all(d[:, 321:] > 0)
    for thr in (1.5, 0.0):  # above the relative jump, or off: nothing invalid
        assert np.all(frames[thr].depth_m > 0)


def test_smooth_surfaces_keep_their_pixels(stairs):
    model, data = stairs
    with RgbdCamera("rgbd_chest", RgbdConfig(subpixel=0.0, segmentation=True), model, seed=0) as cam:
        frame, truth = cam.capture(model, data, 0.0)
    gid, z = truth["geom_id"], truth["depth_m"]
    same = np.ones_like(gid, dtype=bool)
    for dv, du in ((-1, 0), (1, 0), (0, -1), (0, 1)):
        same[1:-1, 1:-1] &= gid[1 + dv : gid.shape[0] - 1 + dv, 1 + du : gid.shape[1] - 1 + du] == gid[1:-1, 1:-1]
    inner = same & (gid >= 0) & (z > 0.45) & (z < 5.9)
    inner[[0, -1], :] = inner[:, [0, -1]] = False
    assert inner.sum() > 50000
    assert np.all(frame.depth_m[inner] > 0)


def test_edge_mask_marks_both_sides_of_a_jump():
    z = np.full((4, 5), 2.0)
    z[:, 3:] = 3.0
    m = edge_mask(z, 0.2)
    assert m[:, 2:4].all() and not m[:, :2].any() and not m[:, 4].any()
    assert not edge_mask(z, 0.6).any() and not edge_mask(z, 0.0).any()


@pytest.mark.parametrize(
    "kw, field",
    [({"width_px": 0}, "rgbd.width_px"), ({"height_px": 0}, "rgbd.height_px"),
     ({"width_px": 640.5}, "rgbd.width_px"), ({"fx_px": 0.0}, "rgbd.fx_px"),
     ({"fx_px": -384.0}, "rgbd.fx_px"), ({"fy_px": 0.0}, "rgbd.fy_px"),
     ({"cx_px": 700.0}, "rgbd.cx_px"), ({"min_depth_m": 6.0}, "rgbd.min_depth_m"),
     ({"min_depth_m": 7.0, "max_depth_m": 6.0}, "rgbd.min_depth_m"), ({"max_depth_m": 0.0}, "rgbd.max_depth_m"),
     ({"subpixel": -0.1}, "rgbd.subpixel"), ({"baseline_m": 0.0}, "rgbd.baseline_m"),
     ({"rate_hz": 0.0}, "rgbd.rate_hz"), ({"edge_threshold_rel": -1.0}, "rgbd.edge_threshold_rel"),
     ({"dropout_prob": 1.0}, "rgbd.dropout_prob"), ({"shadows": "yes"}, "rgbd.shadows")],
)
def test_bad_config_names_the_field(kw, field):
    with pytest.raises(ConfigError) as err:
        RgbdConfig(**kw)
    assert err.value.field == field


def test_same_seed_gives_identical_frames(stairs):
    model, data = stairs
    out = []
    for seed in (7, 7, 8):
        with RgbdCamera("rgbd_chest", RgbdConfig(), model, seed=seed) as cam:
            out.append([cam.capture(model, data, k / 30.0)[0] for k in range(2)])
    for a, b in zip(out[0], out[1]):
        np.testing.assert_array_equal(a.depth_m, b.depth_m)
        np.testing.assert_array_equal(a.rgb, b.rgb)
        assert a.stamp_s == b.stamp_s
    assert not np.array_equal(out[0][0].depth_m, out[0][1].depth_m)  # fresh noise each frame
    assert not np.array_equal(out[0][0].depth_m, out[2][0].depth_m)  # another seed


def test_without_segmentation_the_images_are_the_same(stairs):
    """``segmentation=False`` skips the geom-id pass only: colour and depth are unchanged."""
    model, data = stairs
    caps = []
    for seg in (True, False):
        with RgbdCamera("rgbd_chest", RgbdConfig(segmentation=seg), model, seed=3) as cam:
            caps.append(cam.capture(model, data, 0.0))
    (f_on, t_on), (f_off, t_off) = caps
    np.testing.assert_array_equal(f_on.rgb, f_off.rgb)
    np.testing.assert_array_equal(f_on.depth_m, f_off.depth_m)
    assert (t_on["geom_id"] >= 0).any() and (t_off["geom_id"] == -1).all()
    with pytest.raises(ConfigError, match="rgbd.segmentation"):
        RgbdConfig(segmentation="yes")


def test_dropout_latency_and_unknown_camera():
    model, data = _camera_scene(make_T(R_FORWARD, np.zeros(3)), wall_x_m=2.0)
    config = RgbdConfig(width_px=160, height_px=120, dropout_prob=0.5, pixel_dropout_prob=0.2, latency_s=0.05)
    with RgbdCamera("cam", config, model, seed=1) as cam:
        caps = [cam.capture(model, data, k / 30.0) for k in range(12)]
    kept = [(f, t) for f, t in caps if f is not None]
    assert 0 < len(kept) < len(caps)
    invalid = np.mean([np.mean(f.depth_m == 0) for f, _ in kept])
    assert abs(invalid - 0.2) < 0.02
    for f, t in kept:
        assert f.stamp_s == pytest.approx(t["t_s"] + 0.05) and t["stamp_s"] == f.stamp_s
        assert f.rgb.shape == (120, 160, 3) and f.rgb.dtype == np.uint8 and f.depth_m.dtype == np.float32
    with pytest.raises(UnknownNameError):
        RgbdCamera("rgbd_nowhere", config, model, seed=1)


def _run(script, env):
    root = Path(__file__).resolve().parents[2]
    return subprocess.run([sys.executable, "-c", script], env=env, cwd=root, capture_output=True, text=True, timeout=120)


def _clean_env():
    return {k: v for k, v in os.environ.items() if k not in ("MUJOCO_GL", "PYOPENGL_PLATFORM")}


def test_backend_is_chosen_when_mujoco_gl_is_unset():
    script = (
        "import os, sys\n"
        "import exobench.envs.sensors.rgbd as rgbd\n"
        "assert 'mujoco' not in sys.modules\n"
        "backend = rgbd.select_gl_backend()\n"
        "import mujoco\n"
        "m = mujoco.MjModel.from_xml_string('<mujoco><worldbody><camera name=\"c\" pos=\"0 0 2\"/>"
        "<geom type=\"plane\" size=\"5 5 1\"/></worldbody></mujoco>')\n"
        "d = mujoco.MjData(m); mujoco.mj_forward(m, d)\n"
        "cam = rgbd.RgbdCamera('c', rgbd.RgbdConfig(width_px=64, height_px=48, subpixel=0.0), m, 0)\n"
        "f, t = cam.capture(m, d, 0.0)\n"
        "print(backend, os.environ['MUJOCO_GL'], float(f.depth_m[24, 32]))\n"
    )
    res = _run(script, _clean_env())
    assert res.returncode == 0, res.stderr
    backend, env_value, depth = res.stdout.split()
    assert backend in ("egl", "osmesa") and env_value == backend
    assert float(depth) == pytest.approx(2.0, abs=1e-3)


def test_render_error_when_no_backend_works():
    script = (
        "import exobench.envs.gl_platform as gp\n"
        "gp._probe = lambda backend: False\n"
        "import exobench.envs.sensors.rgbd.render as rr\n"
        "from exobench.core import RenderError\n"
        "try:\n"
        "    rr.select_gl_backend()\n"
        "except RenderError as e:\n"
        "    print('RenderError:', e)\n"
    )
    res = _run(script, _clean_env())
    assert "RenderError:" in res.stdout and "EGL and OSMesa" in res.stdout, res.stderr
    # an explicit back-end that cannot load: OSMesa while PyOpenGL is bound to EGL
    script = (
        "import mujoco\n"
        "from exobench.core import RenderError\n"
        "from exobench.envs.sensors.rgbd import RgbdConfig, make_renderer\n"
        "m = mujoco.MjModel.from_xml_string('<mujoco/>')\n"
        "try:\n"
        "    make_renderer(m, RgbdConfig(width_px=32, height_px=24))\n"
        "except RenderError as e:\n"
        "    print('RenderError:', e)\n"
    )
    res = _run(script, dict(_clean_env(), MUJOCO_GL="osmesa", PYOPENGL_PLATFORM="egl"))
    assert "RenderError:" in res.stdout and "MUJOCO_GL=osmesa" in res.stdout, res.stderr

