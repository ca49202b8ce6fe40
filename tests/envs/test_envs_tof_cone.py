"""ToF cone model against an independent computation on level ground."""

import mujoco
import numpy as np

from exobench.core import TofStatus
from exobench.envs.sensors.tof import ToFConfig, ToFSensor, cone_directions
from exobench.models.exo_spec import ExoSpec
from exobench.models.worlds import build_level, compose


def _standing(exo):
    scene = compose(build_level(), exo)
    data = mujoco.MjData(scene.model)
    mujoco.mj_resetData(scene.model, data)
    mujoco.mj_kinematics(scene.model, data)
    return scene, data


def _expected_mixture(data, model, site, n, fov_deg):
    """Return-weighted mean over the cone on the plane z = 0, computed analytically."""
    sid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, site)
    p = data.site_xpos[sid]
    R = data.site_xmat[sid].reshape(3, 3)
    d = cone_directions(n, fov_deg) @ R.T
    down = d[:, 2] < 0
    r = -p[2] / d[down, 2]  # distance to the floor along each sub-ray
    w = np.abs(d[down, 2]) / r**2  # cos(incidence) / r^2 on a horizontal floor
    mixed = np.sum(w * r) / np.sum(w)
    spread = np.sqrt(np.sum(w * (r - mixed) ** 2) / np.sum(w))
    return mixed, spread, -p[2] / d[0, 2]


def test_cone_reading_is_the_return_weighted_mean_of_the_sub_rays():
    exo = ExoSpec()
    scene, data = _standing(exo)
    cfg = ToFConfig(noise_m=0.0, resolution_m=0.0, n_cone_rays=32, sigma_limit_m=1.0)
    s = ToFSensor("tof_r_lat", cfg, scene.model, seed=0)
    s.observe(scene.model, data, 0.0)
    (fr, tt), = s.frames(scene.model, scene.truth)
    mixed, spread, central = _expected_mixture(data, scene.model, "tof_r_lat", 32, 27.0)
    assert fr.status == TofStatus.VALID
    np.testing.assert_allclose(fr.range_m, mixed, rtol=0, atol=1e-9)
    np.testing.assert_allclose(tt.true_range_m, central, rtol=0, atol=1e-9)
    # on a floor seen at an angle the near half of the cone weighs more: the mixture reads short
    assert fr.range_m < central and spread > 0.01


def test_wide_spread_is_flagged_sigma_fail():
    exo = ExoSpec()
    scene, data = _standing(exo)
    _, spread, _ = _expected_mixture(data, scene.model, "tof_r_lat", 32, 27.0)
    cfg = ToFConfig(noise_m=0.0, resolution_m=0.0, n_cone_rays=32, sigma_limit_m=0.5 * spread)
    s = ToFSensor("tof_r_lat", cfg, scene.model, seed=0)
    s.observe(scene.model, data, 0.0)
    (fr, _), = s.frames(scene.model, scene.truth)
    assert fr.status == TofStatus.SIGMA_FAIL and not fr.valid
