"""`bench_lidar` on a small office and a coarse pattern: the figures it returns and the scene it
hands mujoco-lidar.

Timings are the bench's output, not its behaviour: nothing here asserts a duration or a ratio.
mujoco-lidar (the ``bench`` extra) is replaced by a stand-in with its interface that records
what the bench gives it and casts those rays with MuJoCo itself, so the comparison is checked
whether the extra is installed or not.
"""

from __future__ import annotations

import dataclasses
import sys
import types

import mujoco
import numpy as np
import pytest

from exobench.benchmarks.bench import bench_lidar
from exobench.envs.sensors.lidar import LidarConfig
from exobench.models.office_params import OfficeParams

OFFICE = OfficeParams(n_offices=1, corridor_length_m=8.0, meeting_room_m=2.5)
_PAT = LidarConfig().pattern
COARSE = LidarConfig(pattern=dataclasses.replace(_PAT, azimuth_step_deg=2.0, firing_period_s=_PAT.firing_period_s * 10))
EXO_KEYS = {"ms_per_sweep", "rays_per_s", "returns_per_s", "returns", "returns_genuine", "returns_via_glass_or_mirror"}


class StandInLidar:
    """``mujoco_lidar.core_cpu.MjLidarCPU`` as the bench uses it: it keeps what it is given and
    casts each ray (sensor-frame azimuth ``theta``, elevation ``phi``) with ``mj_multiRay``."""

    made: list[StandInLidar] = []

    def __init__(self, model, cutoff_dist, geomgroup, bodyexclude):
        self.model, self.cutoff, self.group, self.exclude = model, float(cutoff_dist), np.array(geomgroup), int(bodyexclude)
        self.traced: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []
        StandInLidar.made.append(self)

    def update(self, data):
        self.data = data

    def trace_rays(self, T, theta, phi):
        T = np.array(T, dtype=float)
        self.traced.append((T, np.array(theta), np.array(phi)))
        d_s = np.column_stack([np.cos(phi) * np.cos(theta), np.cos(phi) * np.sin(theta), np.sin(phi)])
        n = len(d_s)
        gid, dist = np.zeros(n, dtype=np.int32), np.zeros(n)
        mujoco.mj_multiRay(self.model, self.data, T[:3, 3].copy(), (d_s @ T[:3, :3].T).ravel(), self.group.astype(np.uint8),
                           1, self.exclude, gid, dist, np.zeros(3 * n), n, self.cutoff)  # fmt: skip
        self._dist = np.where(gid >= 0, dist, 0.0)

    def get_distances(self):
        return self._dist


@pytest.fixture(scope="module")
def compared():
    """The bench's result with the stand-in installed as mujoco-lidar, and the stand-in."""
    import importlib.metadata

    package, core = types.ModuleType("mujoco_lidar"), types.ModuleType("mujoco_lidar.core_cpu")
    core.MjLidarCPU = StandInLidar
    real_version = importlib.metadata.version
    StandInLidar.made.clear()
    with pytest.MonkeyPatch.context() as mp:
        mp.setitem(sys.modules, "mujoco_lidar", package)
        mp.setitem(sys.modules, "mujoco_lidar.core_cpu", core)
        mp.setattr(importlib.metadata, "version", lambda name: "stand-in" if name == "mujoco-lidar" else real_version(name))
        result = bench_lidar(seed=0, repeats=1, office=OFFICE, config=COARSE)
    (lidar,) = StandInLidar.made
    return result, lidar


def test_the_figures_of_each_sweep_are_all_there(compared):
    result, _ = compared
    n_rays = len(COARSE.pattern.rays(0.0).dirs_s)
    assert result["rays_per_sweep"] == n_rays and result["pattern"] == COARSE.pattern.name
    assert set(result["exobench"]) == {"static", "walking", "static_one_thread", "static_mujoco_caster",
                                       "walking_mujoco_caster"}
    # the BVH caster and MuJoCo's (the reference) see the same returns
    for pose in ("static", "walking"):
        assert result["exobench"][pose]["returns"] == result["exobench"][f"{pose}_mujoco_caster"]["returns"]
    for name, fig in result["exobench"].items():
        assert set(fig) == EXO_KEYS, name
        # indoors nearly every beam returns; some fall below the minimum range
        assert n_rays // 2 < fig["returns"] <= n_rays, (name, fig["returns"])
        assert fig["returns_genuine"] + fig["returns_via_glass_or_mirror"] >= fig["returns"] // 2
    # the static sweep gives the same points on one thread as on all of them
    assert result["exobench"]["static"]["returns"] == result["exobench"]["static_one_thread"]["returns"]
    mjl = result["mujoco_lidar"]
    assert mjl["version"] == "stand-in" and {"ms_per_sweep", "returns", "returns_within_range_limits"} <= set(mjl)
    assert {"ratio_static", "ratio_walking", "ratio_static_one_thread", "meets_ratio_target"} <= set(result)


def test_mujoco_lidar_is_given_the_same_scene_rays_and_pose(compared):
    result, lidar = compared
    # the bench's own scene: the same office and exoskeleton, the LiDAR site's pose
    from exobench.models.exo_spec import ExoSpec
    from exobench.models.office import build_office
    from exobench.models.worlds import compose

    scene = compose(build_office(OFFICE), ExoSpec())
    data = mujoco.MjData(scene.model)
    mujoco.mj_forward(scene.model, data)
    site = mujoco.mj_name2id(scene.model, mujoco.mjtObj.mjOBJ_SITE, "lidar_trunk")
    assert lidar.model.ngeom == scene.model.ngeom and lidar.exclude == scene.model.site_bodyid[site]
    T, theta, phi = lidar.traced[-1]
    assert all(np.array_equal(T, t) for t, _, _ in lidar.traced)  # every timed sweep from one pose
    np.testing.assert_allclose(T[:3, 3], data.site_xpos[site], atol=1e-12)
    np.testing.assert_allclose(T[:3, :3], data.site_xmat[site].reshape(3, 3), atol=1e-12)
    dirs = np.column_stack([np.cos(phi) * np.cos(theta), np.cos(phi) * np.sin(theta), np.sin(phi)])
    np.testing.assert_allclose(dirs, COARSE.pattern.rays(0.0).dirs_s, atol=1e-12)
    # same rays in the same scene: within the range limits both see the same surfaces; exobench
    # differs only by glass (transmission, reflection) and returns below its detection threshold
    exo = result["exobench"]["static"]["returns"]
    assert abs(exo - result["mujoco_lidar"]["returns_within_range_limits"]) <= 0.01 * result["rays_per_sweep"]


def test_without_mujoco_lidar_the_exobench_figures_stand_alone(monkeypatch):
    monkeypatch.setitem(sys.modules, "mujoco_lidar", None)
    monkeypatch.setitem(sys.modules, "mujoco_lidar.core_cpu", None)
    r = bench_lidar(seed=0, repeats=1, office=OFFICE, config=COARSE)
    assert r["mujoco_lidar"].startswith("not installed")
    assert not {k for k in r if k.startswith("ratio_")} and r["exobench"]["static"]["returns"] > 0
