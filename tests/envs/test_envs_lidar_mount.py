"""The office scenario's LiDAR mounts: the backpack mast above the head, or the front of the pelvis
at a chosen height (the height of the thesis' VLP-16 on a Unitree B1)."""

import numpy as np
import pytest

from exobench.core import ConfigError, LidarScan
from exobench.core.truth import ReturnKind
from exobench.envs.sim import OfficeScenario, simulate_office
from exobench.models.exo_spec import ExoSpec

LOWEST_BEAM_DEG = 15.0  # VLP-16: -15..+15 deg


def _first_scan_floor(mount: str, height_m: float) -> tuple[float, float, float]:
    """(ray origin height, nearest horizontal range of a floor return, range of the lowest
    beam's floor returns) in the first sweep, while the walker still stands upright."""
    sc = OfficeScenario(route="corridor", max_distance_m=0.5, lidar_noise_m=0.0, lidar_resolution_m=0.0,
                        lidar_mount=mount, lidar_height_m=height_m)  # fmt: skip
    ep = simulate_office(sc, 0)
    scan = next(f for f in ep.frames if isinstance(f, LidarScan))
    lt = ep.truth.lidar[0]
    floor_ids = [s.surface_id for s in ep.truth.scene.surfaces if s.kind == "ground"]
    on_floor = (lt.kind == int(ReturnKind.GENUINE)) & np.isin(lt.surface_id, floor_ids)
    assert on_floor.sum() > 50
    origin_z = float(np.median(lt.origin_w[:, 2]))
    horizontal = np.linalg.norm(lt.hit_w[on_floor, :2] - lt.origin_w[on_floor, :2], axis=1)
    elevation = np.degrees(np.arcsin(scan.points_xyz[on_floor, 2] / np.linalg.norm(scan.points_xyz[on_floor], axis=1)))
    lowest = np.abs(elevation + LOWEST_BEAM_DEG) < 0.5
    return origin_z, float(horizontal.min()), float(np.median(horizontal[lowest]))


@pytest.mark.parametrize("mount, height_m", [("pelvis", 0.68), ("pelvis", 1.0), ("mast", 0.68)])
def test_lidar_sits_where_mounted_and_its_lowest_beam_meets_the_floor_there(mount, height_m):
    origin_z, nearest_m, lowest_m = _first_scan_floor(mount, height_m)
    exo = ExoSpec()
    expected = height_m if mount == "pelvis" else exo.trunk_m + exo.head_m + 0.10 + exo.leg_m
    # the walker stands with slightly bent knees, a little below the straight-legged height
    assert expected - 0.04 < origin_z < expected + 0.005
    # the lowest beam meets a level floor at h / tan(15 deg), the nearest floor return of the sweep
    assert lowest_m == pytest.approx(origin_z / np.tan(np.radians(LOWEST_BEAM_DEG)), rel=0.03)
    assert nearest_m == pytest.approx(lowest_m, rel=0.05)


def test_lidar_mount_parameters_are_checked():
    assert ExoSpec(lidar_height_m=0.68).lidar_mount()[1][2, 3] == pytest.approx(0.68 - ExoSpec().leg_m)
    with pytest.raises(ConfigError, match="exo.lidar_height_m"):
        ExoSpec(lidar_height_m=0.3)
    with pytest.raises(ConfigError, match="lidar_height_m"):
        OfficeScenario(lidar_mount="pelvis", lidar_height_m=1.5)
    with pytest.raises(Exception, match="lidar_mount"):
        OfficeScenario(lidar_mount="head")
    assert OfficeScenario(lidar_height_m=0.5).exo_spec().lidar_height_m is None  # the mast ignores the height
