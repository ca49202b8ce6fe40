"""RGB-D depth through glass: a D455's active IR stereo sees through clear glass, so with
``depth_through_glass`` (the default) a depth pixel looking through a pane gives the surface
behind it, found here by mj_ray with the pane's geom group left out; with False, the pane, as
before. The colour image is the same bit for bit either way. The office's glass is what the
renderer leaves out (its transparent geoms, the office_glass look), and nothing else."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from exobench.core.transforms import make_T, matrix_to_quat_wxyz, rot_z
from exobench.envs.sensors.rgbd import RgbdCamera, RgbdConfig
from exobench.envs.sim.scenarios.office_camera import CameraOfficeScenario
from exobench.models.exo import R_OPTICAL_MJCAMERA
from exobench.models.materials import material
from exobench.models.office import build_office
from exobench.models.office_look import add_office_materials

NOISE_FREE = {"subpixel": 0.0, "edge_threshold_rel": 0.0, "resolution_m": 0.0, "min_depth_m": 0.0, "max_depth_m": 100.0}
# optical frame looking along world +x, level: z_opt = +x, x_opt = -y, y_opt = -z
R_FORWARD = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
PANE_GROUP = 2  # rendered (groups 0-2), and left out of the rays that find the surface behind
BEHIND = np.array([1, 1, 0, 0, 0, 0], dtype=np.uint8)
ALL = np.array([1, 1, 1, 0, 0, 0], dtype=np.uint8)


@pytest.fixture(scope="module")
def pane_scene():
    """A camera 1 m up looking along +x, turned 20 degrees, at an office glass pane (turned 30
    degrees, 1.5 m ahead, 1.2 m wide: the wall shows beside it) before a plaster wall at 4 m."""
    T = make_T(rot_z(np.radians(20.0)) @ R_FORWARD, [0.0, 0.0, 1.0])
    spec = mujoco.MjSpec()
    add_office_materials(spec)
    wb = spec.worldbody
    wb.add_light(pos=[0, 0, 6], dir=[0, 0, -1])
    wb.add_camera(name="cam", pos=list(T[:3, 3]), quat=list(matrix_to_quat_wxyz(T[:3, :3] @ R_OPTICAL_MJCAMERA)))
    wb.add_geom(name="wall", type=mujoco.mjtGeom.mjGEOM_BOX, size=[0.05, 20, 20], pos=[4.05, 0, 0], material="office_carpet")
    wb.add_geom(name="pane", type=mujoco.mjtGeom.mjGEOM_BOX, size=[0.005, 0.6, 1.2], pos=[1.5, 0.4, 1.0],
                quat=list(matrix_to_quat_wxyz(rot_z(np.radians(30.0)))), material="office_glass", group=PANE_GROUP)
    model = spec.compile()
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    return model, data, T


def _capture(model, data, through: bool):
    config = RgbdConfig(width_px=96, height_px=72, depth_through_glass=through, **NOISE_FREE)
    with RgbdCamera("cam", config, model, seed=0, segmentation=True) as cam:
        return cam.capture(model, data, 0.0)


def _ray(model, data, T, K, u, v, groups):
    """z-depth and geom id of the ray through pixel (u, v) (-1, -1 when it misses)."""
    d_opt = np.linalg.solve(K, [u, v, 1.0])  # z component 1: the ray parameter is the z-depth
    gid = np.zeros(1, dtype=np.int32)
    x = mujoco.mj_ray(model, data, T[:3, 3], T[:3, :3] @ d_opt, groups, 1, -1, gid)
    return (x, int(gid[0])) if x >= 0 else (-1.0, -1)


@pytest.mark.parametrize("through", [True, False])
def test_depth_through_a_pane_is_the_wall_behind_or_the_pane(pane_scene, through):
    model, data, T = pane_scene
    frame, truth = _capture(model, data, through)
    wall, pane = (mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, n) for n in ("wall", "pane"))
    K, z, gid = frame.K, truth["depth_m"], truth["geom_id"]
    through_pane = 0
    for v in range(2, 70, 3):
        for u in range(2, 94, 3):
            x_all, g_all = _ray(model, data, T, K, u, v, ALL)
            x_behind, g_behind = _ray(model, data, T, K, u, v, BEHIND)
            assert g_behind == wall  # the wall fills the view
            inside = all(_ray(model, data, T, K, u + du, v + dv, ALL)[1] == pane for du, dv in ((-1, 0), (1, 0), (0, -1), (0, 1)))
            if g_all == pane and inside:
                through_pane += 1  # inside the pane, not on its edge
                expected, expected_id = (x_behind, wall) if through else (x_all, pane)
            elif g_all == wall and not any(
                _ray(model, data, T, K, u + du, v + dv, ALL)[1] == pane for du, dv in ((-1, 0), (1, 0), (0, -1), (0, 1))
            ):
                expected, expected_id = x_all, wall
            else:
                continue  # the pane's edge: the rasterised pixel may belong to either side
            assert gid[v, u] == expected_id
            assert abs(z[v, u] - expected) < 1e-3  # float32 depth buffer: micrometres here
            assert abs(frame.depth_m[v, u] - expected) < 1e-3
    assert through_pane > 100  # the pane covers a good part of the view


def test_colour_is_the_same_bit_for_bit(pane_scene):
    """Only the depth pass changes: the colour shows the wall through the tinted pane either way."""
    model, data, _ = pane_scene
    (f_on, t_on), (f_off, t_off) = _capture(model, data, True), _capture(model, data, False)
    np.testing.assert_array_equal(f_on.rgb, f_off.rgb)
    on_pane = t_off["geom_id"] == mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, "pane")
    assert on_pane.mean() > 0.1 and not (t_on["geom_id"] == t_off["geom_id"][on_pane][0]).any()
    assert (f_on.depth_m[on_pane] > 2.5).all() and (f_off.depth_m[on_pane] < 2.0).all()


def test_the_office_glass_is_what_the_depth_looks_through():
    """The renderer leaves out the transparent geoms; in an office these are exactly the geoms of
    a glass LiDAR material (partitions, glass doors, windows)."""
    world = build_office()
    model = world.spec.compile()
    transparent = set()
    for g in range(model.ngeom):
        m = model.geom_matid[g]
        alpha = model.mat_rgba[m, 3] if m >= 0 else model.geom_rgba[g, 3]
        if alpha < 1.0:
            transparent.add(model.geom(g).name)
    glass = {n for n, mat in world.truth.geom_materials.items() if material(mat).kind == "glass"}
    assert glass and transparent == glass


def test_the_camera_row_reaches_the_config():
    assert CameraOfficeScenario().rgbd_config().depth_through_glass is True
    assert CameraOfficeScenario.from_dict({"depth_through_glass": False}).rgbd_config().depth_through_glass is False
