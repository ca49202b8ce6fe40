"""`bench_lidar`: exobench's VLP-16 sweep of the office, and the mujoco-lidar comparison."""

from __future__ import annotations

import numpy as np
import pytest

from exobench.benchmarks.bench import bench_lidar
from exobench.envs.sensors.lidar import LidarPattern


@pytest.fixture(scope="module")
def result() -> dict:
    return bench_lidar(seed=0, repeats=1)


def test_exobench_sweep_returns_points(result: dict) -> None:
    n_rays = len(LidarPattern.vlp16().rays(0.0).dirs_s)
    assert result["rays_per_sweep"] == n_rays
    for name in ("static", "walking"):
        fig = result["exobench"][name]
        # indoors nearly every beam returns; some are below the 0.9 m minimum range
        assert n_rays // 2 < fig["returns"] <= n_rays
        assert fig["ms_per_sweep"] > 0.0
        assert np.isclose(fig["rays_per_s"], n_rays / (fig["ms_per_sweep"] * 1e-3))
        assert np.isclose(fig["returns_per_s"], fig["returns"] / (fig["ms_per_sweep"] * 1e-3))
    assert isinstance(result["meets_50ms_target"], bool)


def test_comparison_with_mujoco_lidar(result: dict) -> None:
    pytest.importorskip("mujoco_lidar.core_cpu", reason="mujoco-lidar (the `bench` extra) is not installed")
    mjl = result["mujoco_lidar"]
    assert isinstance(mjl, dict), mjl
    assert np.isclose(result["ratio_static"], mjl["ms_per_sweep"] / result["exobench"]["static"]["ms_per_sweep"])
    # same rays, pose and geoms: within the range limits the two see the same surfaces; exobench
    # differs only by glass (transmission/reflection) and returns below its detection threshold
    exo = result["exobench"]["static"]["returns"]
    assert abs(exo - mjl["returns_within_range_limits"]) <= 0.01 * result["rays_per_sweep"]


def test_missing_mujoco_lidar_is_reported(monkeypatch: pytest.MonkeyPatch) -> None:
    import sys

    monkeypatch.setitem(sys.modules, "mujoco_lidar", None)
    monkeypatch.setitem(sys.modules, "mujoco_lidar.core_cpu", None)
    r = bench_lidar(seed=0, repeats=1)
    assert r["mujoco_lidar"].startswith("not installed")
    assert "ratio_static" not in r and r["exobench"]["static"]["returns"] > 0
