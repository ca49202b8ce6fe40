"""Panes that are not flat: overall bow and roller wave bend the normal a mirrored beam sees.

Expected values are worked out here from the surface of :mod:`exobench.envs.sensors.lidar.pane_shape`
(``w = delta cos(pi u / 2a) cos(pi v / 2b) + A sin(2 pi t / lam + phi)``), differentiated
numerically, and from the law of reflection, not from the model's output.
"""

from __future__ import annotations

import hashlib
from dataclasses import replace

import mujoco
import numpy as np
import pytest

from exobench.core import ConfigError, ReturnKind, SceneTruth
from exobench.envs.sensors.lidar import LidarConfig
from exobench.envs.sensors.lidar.optics import KIND_CODE, cast_rays, follow_beams, geom_optics
from exobench.envs.sensors.lidar.pane_shape import PaneShapes

PANE_X, HALF_U, HALF_V, Z_C = 2.0, 0.6, 0.65, 1.5  # a 1.2 m x 1.3 m pane facing the sensor at x = 2
BACK_X = -3.0  # face of the plaster wall behind the sensor


def _scene():
    spec = mujoco.MjSpec()
    w = spec.worldbody
    boxes = {
        "pane": ((PANE_X + 0.005, 0.0, Z_C), (0.005, HALF_U, HALF_V)),
        "back": ((BACK_X - 0.1, 0.0, 1.5), (0.1, 40.0, 1.5)),
    }
    for name, (pos, half) in boxes.items():
        w.add_geom(name=name, type=mujoco.mjtGeom.mjGEOM_BOX, pos=list(pos), size=list(half))
    model = spec.compile()
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    truth = SceneTruth(surfaces=(), geom_surfaces={}, geom_materials={"pane": "lowe_glass", "back": "plaster"})
    names = [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, g) or "" for g in range(model.ngeom)]
    return model, data, truth, names


def _shapes(model, names, optics, bow: float, wave_pv: float, lam: float = 0.35) -> PaneShapes:
    return PaneShapes(model, names, optics.kind == KIND_CODE["glass"], bow, wave_pv, lam, seed=7)


def _numeric_slopes(w, u: float, v: float, h: float = 1e-6) -> tuple[float, float]:
    return (w(u + h, v) - w(u - h, v)) / (2 * h), (w(u, v + h) - w(u, v - h)) / (2 * h)


@pytest.mark.parametrize("bow, wave", [(3e-3, 0.0), (0.0, 0.3e-3), (3e-3, 0.3e-3)])
def test_local_normal_of_a_bowed_wavy_pane(bow: float, wave: float):
    model, data, truth, names = _scene()
    optics = geom_optics(names, truth, {})
    s = _shapes(model, names, optics, bow, wave)
    # the pane's thin axis is x: u = y (half 0.6), v = z (half 0.65)
    assert s.normal_axis[0] == 0 and tuple(s.half[0]) == (HALF_U, HALF_V)
    delta = s.delta[0, 0]
    assert abs(delta) == pytest.approx(bow * 2 * np.hypot(HALF_U, HALF_V))  # 5.3 mm at 3 mm/m on a 1.77 m diagonal
    A, k, phi, on_v = 0.5 * wave, 2 * np.pi / 0.35, s.phase[0, 0], bool(s.wave_on_v[0, 0])

    def w(u, v):
        t = v if on_v else u
        return delta * np.cos(np.pi * u / (2 * HALF_U)) * np.cos(np.pi * v / (2 * HALF_V)) + A * np.sin(k * t + phi)

    u, v = 0.3, 0.2
    wu, wv = _numeric_slopes(w, u, v)
    # the face at x = 2 faces -x: its normal is -(e_n - grad w)
    expect = np.array([-1.0, wu, wv]) / np.sqrt(1 + wu * wu + wv * wv)
    hit = np.array([[PANE_X, u, Z_C + v]])
    got = s.normals(data, np.array([0]), hit, np.array([[-1.0, 0.0, 0.0]]))
    np.testing.assert_allclose(got[0], expect, atol=1e-9)
    # a hit on another geom keeps its normal; the pane's far face bends the same way
    np.testing.assert_array_equal(s.normals(data, np.array([1]), hit, np.array([[1.0, 0.0, 0.0]])), [[1.0, 0.0, 0.0]])
    far = s.normals(data, np.array([0]), hit + [0.01, 0, 0], np.array([[1.0, 0.0, 0.0]]))
    np.testing.assert_allclose(far[0], -expect, atol=1e-9)


def _ghost(bow: float) -> tuple[np.ndarray, PaneShapes | None]:
    """A beam along +x at y = 0.3 onto a low-e pane, mirrored (sampled draw 0.7: T = 0.6 <= u < T + S
    = 0.9) back onto the wall behind: the true surface point of the ghost."""
    model, data, truth, names = _scene()
    optics = geom_optics(names, truth, {})
    shapes = _shapes(model, names, optics, bow, 0.0) if bow > 0 else None
    optics = replace(optics, shape=shapes)
    o, d = np.array([[0.0, 0.3, Z_C]]), np.array([[1.0, 0.0, 0.0]])
    group = np.ones(6, dtype=np.uint8)
    r, g, n = cast_rays(model, data, group, o, d)
    res = follow_beams(model, data, group, o, d, g, r, n, optics, np.full((1, 3), 0.7), glass=True, mirrors=True)
    assert res.kind[0] == ReturnKind.GHOST and names[int(res.geom[0])] == "back"
    return res.hit_w[0], shapes


def test_ghost_in_a_bowed_pane_moves_by_twice_the_slope():
    flat, _ = _ghost(0.0)
    assert flat[1] == pytest.approx(0.3, abs=1e-9)  # a flat pane sends the beam straight back
    bowed, s = _ghost(3e-3)
    # slope at u = 0.3, v = 0: dw/du = -delta pi / 1.2 sin(pi 0.3 / 1.2) = -/+ 9.8 mrad; the beam is turned
    # by twice the slope: back over 5 m to the wall, tan(2 theta) = 2 tan / (1 - tan^2)
    wu = -s.delta[0, 0] * np.pi / (2 * HALF_U) * np.sin(np.pi * 0.3 / (2 * HALF_U))
    expect_dy = (PANE_X - BACK_X) * 2 * wu / (1 - wu * wu)
    assert abs(expect_dy) == pytest.approx(0.098, abs=1e-3)
    assert bowed[1] - flat[1] == pytest.approx(expect_dy, abs=1e-6)
    assert bowed[0] == pytest.approx(BACK_X) and bowed[2] == pytest.approx(Z_C, abs=1e-9)


def test_defaults_leave_a_sweep_bit_identical():
    """A VLP-16 sweep beside a float-glass window façade with the default (flat) panes, hashed; the
    hash is that of main at a096fa2, before panes could bend. The same sweep with bowed panes differs."""
    from exobench.envs.sensors.lidar import LidarSensor
    from exobench.models.exo_spec import ExoSpec
    from exobench.models.office import OfficeParams, build_office
    from exobench.models.worlds import compose

    params = OfficeParams(n_offices=2, corridor_length_m=14.0, meeting_room_m=4.0, glass_fraction=1.0,
                          facade="windows", facade_glass="float_glass", partition_glass="float_glass")  # fmt: skip
    scene = compose(build_office(params), ExoSpec())
    data = mujoco.MjData(scene.model)
    mujoco.mj_forward(scene.model, data)
    T = np.eye(4)
    T[:3, 3] = (6.0, 0.5 * params.corridor_width_m, 1.3)

    def sweep(**kw):
        scan, lt = LidarSensor("lidar", LidarConfig(return_mode="strongest", **kw), scene.model, 0).scan(
            scene.model, data, T, 0.0, scene.truth)
        raw = np.ascontiguousarray(scan.points_xyz).tobytes() + np.ascontiguousarray(scan.intensity).tobytes()
        return hashlib.sha256(raw).hexdigest()[:16], lt

    h, _ = sweep()
    assert h == "70ae7fc6496446c6"
    h2, lt = sweep(glass_bow_mm_per_m=3.0, glass_roller_wave_mm=0.3)
    assert h2 != h and np.mean(np.asarray(lt.kind) == ReturnKind.GHOST) > 0.02


@pytest.mark.parametrize("field, value, allowed", [
    ("glass_bow_mm_per_m", -1.0, "0.0 <= glass_bow_mm_per_m <= 20.0"),
    ("glass_roller_wave_mm", 6.0, "0.0 <= glass_roller_wave_mm <= 5.0"),
    ("glass_roller_wave_length_m", 0.0, "0.0 < glass_roller_wave_length_m <= 10.0"),
])  # fmt: skip
def test_pane_shape_parameters_are_range_checked(field: str, value: float, allowed: str):
    with pytest.raises(ConfigError) as e:
        LidarConfig(**{field: value})
    msg = str(e.value)
    assert f"lidar.{field}" in msg and str(value) in msg and allowed in msg


def test_office_scenario_passes_the_pane_shape_to_the_lidar():
    from exobench.envs.sim.scenarios.office import OfficeScenario

    cfg = OfficeScenario(office_seed=5, glass_bow_mm_per_m=3.0, glass_roller_wave_mm=0.3).lidar_config()
    assert (cfg.glass_bow_mm_per_m, cfg.glass_roller_wave_mm, cfg.glass_shape_seed) == (3.0, 0.3, 5)
    assert not OfficeScenario().lidar_config().glass_shaped
    with pytest.raises(ConfigError, match=r"glass_bow_mm_per_m=25.0 is invalid; allowed: 0.0 <= glass_bow_mm_per_m"):
        OfficeScenario(glass_bow_mm_per_m=25.0)


def test_double_glazing_reflects_from_two_panes_bowed_apart():
    from exobench.models.materials import material

    # two float panes (R 0.079, T 0.84): R = 0.079 + 0.84^2 0.079 / (1 - 0.079^2) = 0.1351,
    # T = 0.84^2 / (1 - 0.079^2) = 0.7100, the front pane's share 0.079 / 0.1351 = 0.585
    igu = material("igu_float")
    assert (igu.specular, igu.transmission, igu.front_share) == pytest.approx((0.1351, 0.7100, 0.585), abs=5e-4)
    model, data, truth, names = _scene()
    truth = SceneTruth(surfaces=(), geom_surfaces={}, geom_materials={"pane": "igu_float", "back": "plaster"})
    optics = geom_optics(names, truth, {})
    shapes = PaneShapes(model, names, optics.kind == KIND_CODE["glass"], 3e-3, 0.0, 0.35, 7, optics.front_share)
    optics = replace(optics, shape=shapes)
    o, d = np.array([[0.0, 0.3, Z_C]]), np.array([[1.0, 0.0, 0.0]])
    group = np.ones(6, dtype=np.uint8)
    r, g, n = cast_rays(model, data, group, o, d)
    ys = []
    # sampled draws mirroring the beam (T = 0.710 <= u < T + S = 0.845); frac(1024 u) picks the pane:
    # 0 (front, share 0.585) or 0.9 (back)
    for u0 in (0.75, 0.75 + 0.9 / 1024):
        res = follow_beams(model, data, group, o, d, g, r, n, optics, np.full((1, 3), u0), glass=True, mirrors=True)
        assert res.kind[0] == ReturnKind.GHOST
        ys.append(res.hit_w[0, 1] - 0.3)
    assert abs(ys[0]) == pytest.approx(0.098, abs=1e-3)
    assert ys[1] == pytest.approx(-ys[0], abs=1e-9)
