"""Surfaces a visual tracker can hold and lose, light level and motion blur: textures drawn from the
world's seed, corners on a textured wall against a white one (OpenCV's Shi-Tomasi detector), the
blur's image motion against projecting the moved points, and refusals of bad values."""

import cv2
import mujoco
import numpy as np
import pytest

from exobench.core import ConfigError, RgbdFrame
from exobench.core.transforms import matrix_to_quat_wxyz
from exobench.envs.sensors.rgbd import RgbdCamera, RgbdConfig, intrinsics
from exobench.envs.sensors.rgbd.blur import blur_flow, motion_blur
from exobench.envs.sim.scenarios.course import LocomotionScenario, simulate_locomotion
from exobench.envs.sim.scenarios.office import OfficeScenario
from exobench.models.exo import R_OPTICAL_MJCAMERA
from exobench.models.vision_look import WorldLook, apply_look, texture_images
from exobench.models.world_look import add_lights, add_materials, set_visual

pytestmark = pytest.mark.long(seconds=10)  # the workers take it first (tests/conftest.py); 10: the file at -n 0 in one run at load 12-15, scaled to that run's CPU

CFG = RgbdConfig(width_px=160, height_px=120)


def _wall_images(look: WorldLook | None, seed: int = 0) -> list[np.ndarray]:
    """Three views, 2.5 m apart, of a 3 m tall, 10 m long plaster wall 2 m in front of a camera at
    1.5 m (each view sees only the wall), lit as the worlds are."""
    spec = mujoco.MjSpec()
    add_materials(spec)
    set_visual(spec)
    add_lights(spec, np.array([-1.0, 0.0, 0.0]), np.array([1.0, 0.0, 0.0]), 0.0)
    spec.worldbody.add_geom(type=mujoco.mjtGeom.mjGEOM_BOX, size=[0.05, 5.0, 1.5], pos=[2.05, 0.0, 1.5],
                            material="world_plaster")  # fmt: skip
    R_opt = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])  # looking along +x, level
    for k, y in enumerate((-2.5, 0.0, 2.5)):
        spec.worldbody.add_camera(name=f"cam{k}", pos=[0.0, y, 1.5], fovy=58.0,
                                  quat=list(matrix_to_quat_wxyz(R_opt @ R_OPTICAL_MJCAMERA)))  # fmt: skip
    if look is not None:
        apply_look(spec, look, seed)
    model = spec.compile()
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    out = []
    for k in range(3):
        with RgbdCamera(f"cam{k}", CFG, model, 0) as cam:
            out.append(cam.render(data)[0])
    return out


def _corners(rgb: np.ndarray) -> int:
    gray = cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY)
    pts = cv2.goodFeaturesToTrack(gray, maxCorners=500, qualityLevel=0.01, minDistance=4)
    strong = cv2.cornerMinEigenVal(gray, 3).max()
    # a corner detector ranks relative to the strongest response: count none on an image without any
    return 0 if pts is None or strong < 1e-3 else len(pts)


def test_textures_are_drawn_from_the_seed():
    a, b, c = texture_images(7, "textured"), texture_images(7, "textured"), texture_images(8, "textured")
    assert set(a) == {"world_wood", "office_wood", "office_carpet"}
    for mat in a:
        np.testing.assert_array_equal(a[mat][0], b[mat][0])
        assert np.mean(a[mat][0] != c[mat][0]) > 0.2, mat
    assert texture_images(7, "default") == {}

    def posters(seed):
        from exobench.models.office import build_office
        from exobench.models.office_params import OfficeParams

        spec = build_office(OfficeParams(seed=seed)).spec.copy()
        apply_look(spec, WorldLook("textured"), seed)
        return {t.name: t.data for t in spec.textures if t.name.startswith("look_poster")}

    p7, p7b, p8 = posters(7), posters(7), posters(8)
    assert len(p7) >= 40  # about 100 m of walls, both faces
    assert p7 == p7b
    assert p7 != p8


def test_a_textured_wall_has_many_more_corners_than_a_white_one():
    def corners(images):
        return sum(_corners(im) for im in images)

    textured = [_wall_images(WorldLook("textured"), seed=s) for s in (0, 1, 2)]
    n_tex = [corners(ims) for ims in textured]
    n_white = corners(_wall_images(WorldLook("featureless")))
    default = _wall_images(None)
    n_default = corners(default)
    # a white wall gives a corner detector nothing; posters and notice boards give it plenty
    assert n_white == 0 and min(n_tex) >= 30, (n_tex, n_white)
    # the default plaster is faint: far fewer corners than the posters give
    assert n_default < min(n_tex) / 2, (n_default, n_tex)
    # different seeds hang different posters
    assert np.mean(textured[0][1] != textured[1][1]) > 0.02
    # default look: the same images as no look at all
    for a, b in zip(_wall_images(WorldLook()), default):
        np.testing.assert_array_equal(a, b)


def test_light_level_darkens_the_image():
    bright = _wall_images(None)[1].astype(float).mean()
    dim = _wall_images(WorldLook(light_level=0.3))[1].astype(float).mean()
    assert dim < 0.5 * bright


def test_blur_flow_is_the_image_motion_of_the_moved_points():
    K = intrinsics(CFG)
    h, w = CFG.height_px, CFG.width_px
    depth = np.full((h, w), 2.0)
    depth[:, : w // 2] = 0.0  # left half: nothing (points at infinity)
    v, om, tau = np.array([0.3, -0.1, 0.5]), np.array([0.2, -0.6, 0.15]), 1e-4  # short: first order is exact enough
    du, dv = blur_flow(depth, K, v, om, tau)
    # independent: move the camera by (v tau, om tau) and project each point again
    from scipy.spatial.transform import Rotation

    R = Rotation.from_rotvec(om * tau).as_matrix()  # camera at t+tau in the camera at t
    for (r, c) in [(10, 10), (60, 40), (100, 150), (30, 120), (119, 159)]:
        ray = np.linalg.solve(K, [c, r, 1.0])
        P = ray * depth[r, c] if depth[r, c] > 0 else ray * 1e9
        P2 = R.T @ (P - v * tau)
        uv = (K @ P2)[:2] / P2[2]
        exact = uv - [c, r]
        np.testing.assert_allclose([du[r, c], dv[r, c]], exact, atol=5e-3 * np.linalg.norm(exact))


def test_motion_blur_smears_an_edge_over_its_path():
    img = np.zeros((20, 60, 3), np.uint8)
    img[:, 30:] = 200
    du, dv = np.full((20, 60), 10.0), np.zeros((20, 60))
    out = motion_blur(img, du, dv)
    row = out[10, :, 0].astype(float)
    ramp = np.flatnonzero((row > 5) & (row < 195))
    assert 8 <= len(ramp) <= 11  # a 10-pixel path spreads the step over about 10 pixels
    assert row[:20].max() == 0 and row[41:].min() == 200
    np.testing.assert_array_equal(motion_blur(img, du * 0.0, dv), img)


def test_exposure_blurs_colour_not_depth_in_a_walk():
    base = dict(width_px=96, height_px=72, rate_hz=10.0, duration_cap_s=2.5, surfaces="textured")
    sharp = simulate_locomotion(LocomotionScenario(**base), 0)
    blurred = simulate_locomotion(LocomotionScenario(**base, exposure_s=0.03), 0)
    fs = [f for f in sharp.frames if isinstance(f, RgbdFrame)]
    fb = [f for f in blurred.frames if isinstance(f, RgbdFrame)]
    assert len(fs) == len(fb) > 10
    for a, b in zip(fs, fb):
        np.testing.assert_array_equal(a.depth_m, b.depth_m)

    def energy(frames):
        return np.mean([np.mean(np.abs(np.diff(f.rgb.astype(float), axis=1))) for f in frames])

    assert energy(fb) < 0.95 * energy(fs)
    plain = simulate_locomotion(LocomotionScenario(**{**base, "surfaces": "default"}), 0)
    fp = [f for f in plain.frames if isinstance(f, RgbdFrame)]
    assert np.mean([np.mean(a.rgb != p.rgb) for a, p in zip(fs, fp)]) > 0.05


@pytest.mark.parametrize("make,field", [
    (lambda: WorldLook(surfaces="glass"), "surfaces"),
    (lambda: WorldLook(light_level=0.0), "light_level"),
    (lambda: RgbdConfig(exposure_s=0.05), "rgbd.exposure_s"),
    (lambda: RgbdConfig(exposure_s=-0.001), "rgbd.exposure_s"),
    (lambda: LocomotionScenario(surfaces="mirror"), "surfaces"),
    (lambda: LocomotionScenario(light_level=3.0), "light_level"),
    (lambda: LocomotionScenario(exposure_s=0.05).rig(), "exposure_s"),
    (lambda: OfficeScenario(light_level=-1.0), "light_level"),
])  # fmt: skip
def test_bad_look_values_are_refused_naming_the_field(make, field):
    with pytest.raises(ConfigError) as err:
        make()
    assert err.value.field == field

