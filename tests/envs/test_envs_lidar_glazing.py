"""Glazing against a dark outside: Fresnel pane reflectance, the strongest echo, ghosts beside a façade.

Expected values come from Fresnel's equations for float glass (n = 1.51), the stated material
table (:mod:`exobench.models.materials`) and the Lambertian return strength of
:mod:`exobench.envs.sensors.lidar.optics`, worked out by hand here, not from the model's output.
"""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from exobench.core import ConfigError, ReturnKind, SceneTruth
from exobench.envs.sensors.lidar import LidarConfig
from exobench.envs.sensors.lidar.optics import (
    EchoChoice,
    cast_rays,
    follow_beams,
    geom_optics,
    pane_reflectance,
)

SENSOR = np.array([0.0, 0.0, 1.0])
PANE_X = 2.0  # pane face towards the sensor (a window: nothing beyond it, a dark outside)


def _scene(pane_material: str):
    """A 10 mm pane at x = 2, plaster walls behind the sensor (x = -3) and to the left (y = 15)."""
    spec = mujoco.MjSpec()
    w = spec.worldbody
    boxes = {
        "pane": ((PANE_X + 0.005, 0.0, 1.5), (0.005, 40.0, 1.5)),
        "back": ((-3.1, 0.0, 1.5), (0.1, 40.0, 1.5)),
        "left": ((0.0, 15.1, 1.5), (2.0, 0.1, 1.5)),
    }
    for name, (pos, half) in boxes.items():
        w.add_geom(name=name, type=mujoco.mjtGeom.mjGEOM_BOX, pos=list(pos), size=list(half))
    model = spec.compile()
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    truth = SceneTruth(surfaces=(), geom_surfaces={}, geom_materials={"pane": pane_material, "back": "plaster",
                                                                       "left": "plaster"})  # fmt: skip
    return model, data, truth


def _fire(mode: str, incidence_deg: float, pane_material: str = "float_glass"):
    model, data, truth = _scene(pane_material)
    names = [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, g) or "" for g in range(model.ngeom)]
    a = np.radians(incidence_deg)
    d = np.array([[np.cos(a), np.sin(a), 0.0]])
    o = SENSOR[None].copy()
    group = np.ones(6, dtype=np.uint8)
    r, g, n = cast_rays(model, data, group, o, d)
    assert names[int(g[0])] == "pane"
    cfg = LidarConfig()
    echo = EchoChoice(mode, cfg.ref_reflectivity, cfg.ref_range_m, cfg.detection_threshold, 0.9, 100.0)
    res = follow_beams(model, data, group, o, d, g, r, n, geom_optics(names, truth, {}), np.full((1, 3), 0.5),
                       glass=True, mirrors=True, echo=echo)  # fmt: skip
    return res, names, float(r[0])


def test_fresnel_pane_reflectance_of_float_glass():
    # per surface ((n - 1) / (n + 1))^2 = 4.13 %, the pane 2R / (1 + R) = 7.93 %
    assert pane_reflectance(1.51, 1.0) == pytest.approx(0.0793, abs=5e-4)
    # unpolarised Fresnel at 80 deg: Rs = 0.543, Rp = 0.236, R = 0.389, pane 0.560
    assert pane_reflectance(1.51, np.cos(np.radians(80.0))) == pytest.approx(0.560, abs=2e-3)
    r = pane_reflectance(1.51, np.cos(np.radians(np.arange(0, 90, 5))))
    assert np.all(np.diff(r) > -1e-12)


def test_normal_incidence_on_a_window_returns_the_pane():
    # pane echo 100 (0.001 / 0.8) (10 / 2)^2 = 3.1; ghost of the back wall (path 2 + 5 m)
    # 100 * 0.0793^2 * (0.6 / 0.8) * (10 / 7)^2 = 0.96, under the detection threshold 1
    res, names, _ = _fire("strongest", 0.0)
    assert names[int(res.geom[0])] == "pane" and res.kind[0] == ReturnKind.GLASS
    assert res.path_m[0] == pytest.approx(PANE_X - 0.0, abs=6e-3) and res.gain[0] == 1.0


def test_grazing_incidence_on_a_window_returns_a_bright_ghost():
    # at 80 deg the pane echo is 100 (0.001 / 0.8) cos 80 (10 / 11.5)^2 = 0.016; the pane mirrors
    # 56 % and the left wall's ghost keeps 0.560^2 = 0.314 of the energy: path 11.52 + 3.71 m
    res, names, _ = _fire("strongest", 80.0)
    assert res.kind[0] == ReturnKind.GHOST and names[int(res.geom[0])] == "left"
    assert names[int(res.via_geom[0])] == "pane"
    r0, r80 = pane_reflectance(1.51, 1.0), pane_reflectance(1.51, np.cos(np.radians(80.0)))
    s80 = 0.079 + (1 - 0.079) * (r80 - r0) / (1 - r0)  # the table's 0.079 at normal incidence, raised as Fresnel
    assert res.gain[0] == pytest.approx(s80**2, rel=1e-9)
    assert res.gain[0] == pytest.approx(0.314, abs=3e-3)
    t_pane = (PANE_X - 0.0) / np.cos(np.radians(80.0))
    t_wall = (15.0 - t_pane * np.sin(np.radians(80.0))) / np.sin(np.radians(80.0))
    assert res.path_m[0] == pytest.approx(t_pane + t_wall, abs=1e-3)
    signal = 100 * res.gain[0] * (0.6 / 0.8) * np.sin(np.radians(80.0)) * (10 / res.path_m[0]) ** 2
    assert signal == pytest.approx(9.98, abs=0.05)  # detected (threshold 1)
    # low-e glazing (30 % at normal incidence) mirrors more: 0.30 + 0.70 * (0.560 - 0.079) / 0.921 = 0.666
    res_l, _, _ = _fire("strongest", 80.0, "lowe_glass")
    assert res_l.gain[0] == pytest.approx(0.666**2, abs=3e-3)


def test_sampled_mode_draws_one_path_and_loses_the_crossing_beam():
    # at 80 deg T = 0.84 (1 - 0.560) / (1 - 0.079) = 0.40 <= u = 0.5 < T + S = 0.96: the draw mirrors
    # the beam; at normal incidence u < T = 0.84: it crosses into the dark, no return
    res, _, _ = _fire("sampled", 80.0)
    assert res.kind[0] == ReturnKind.GHOST
    res0, _, _ = _fire("sampled", 0.0)
    assert res0.geom[0] == -1


def test_return_mode_is_validated():
    with pytest.raises(ConfigError, match="return_mode"):
        LidarConfig(return_mode="dual")


def test_sweep_beside_a_window_facade_has_ghosts_in_the_tens_of_percent():
    """One VLP-16 sweep in the south corridor of a small office: plain walls give well under 1 % of
    returns involving glass; a float-glass façade, glass partitions and the strongest echo give
    some 10-50 % (glass pane returns and ghosts; about 30 % in the 24 m office)."""
    from exobench.envs.sensors.lidar import LidarSensor
    from exobench.models.exo_spec import ExoSpec
    from exobench.models.office import OfficeParams, build_office
    from exobench.models.worlds import compose

    def fraction(params: OfficeParams, mode: str) -> tuple[float, float]:
        scene = compose(build_office(params), ExoSpec())
        model, truth = scene.model, scene.truth
        data = mujoco.MjData(model)
        mujoco.mj_forward(model, data)
        T = np.eye(4)
        T[:3, 3] = (6.0, 0.5 * params.corridor_width_m, 1.3)
        scan, lt = LidarSensor("lidar", LidarConfig(return_mode=mode), model, 0).scan(model, data, T, 0.0, truth)
        k = np.asarray(lt.kind)
        involved = np.isin(k, [ReturnKind.GLASS, ReturnKind.GHOST, ReturnKind.THROUGH_GLASS])
        return float(np.mean(involved)), float(np.mean(k == ReturnKind.GHOST))

    base = dict(n_offices=2, corridor_length_m=14.0, meeting_room_m=4.0)
    plain, _ = fraction(OfficeParams(**base, glass_fraction=0.0), "strongest")
    assert plain < 0.01
    windows = OfficeParams(**base, glass_fraction=1.0, facade="windows", facade_glass="lowe_glass",
                           partition_glass="float_glass")  # fmt: skip
    inv, ghost = fraction(windows, "strongest")
    assert 0.1 < inv < 0.6
    assert 0.05 < ghost < 0.5
