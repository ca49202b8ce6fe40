"""LEO-SLAM point cloud preprocessing (seeds/003 section 4.2.1, "Point cloud preprocessing").

One LiDAR sweep becomes the cloud ``P_p`` used by scan matching and the cloud ``P_f`` added to
the map:

1. invalid points (NaN, infinite, zero range) are dropped;
2. optional constant-velocity deskew: each point, given in the sensor frame at its firing time
   ``tau`` (``LidarScan.time_offset_s``), is moved into the sensor frame at the sweep start with
   the motion ``T_start_tau = exp(tau * xi)`` of a constant twist ``xi`` (per second);
3. the crop boxes: points inside the robot's own box are removed, points outside the outer box
   (too far to be useful) are removed;
4. voxel downsampling (the small-GICP leaf, 0.25 m in section 5.2.1) for ``P_p`` and a finer
   voxel for the map cloud ``P_f``;
5. the statistical outlier-rejection filter (mean distance to ``k`` neighbours beyond
   ``mean + std_ratio * std`` of all points). It runs on the voxelised registration cloud,
   where it removes the same isolated returns at a fraction of the cost of the raw sweep; the
   map cloud loses its points within one registration voxel of a rejected one.

The ground-aware intensity filter of section 4.2.2 lives in
:mod:`exobench.perception.lidar_filter.filters`; it is not applied here.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import open3d as o3d
from scipy.spatial import cKDTree
from scipy.spatial.transform import Rotation

from exobench.core.errors import ConfigError, check_int, check_range

__all__ = ["PreprocessConfig", "clean_points", "deskew", "preprocess", "voxel_downsample"]


def _check_box(name: str, lo: tuple[float, ...], hi: tuple[float, ...]) -> None:
    lo_a, hi_a = np.asarray(lo, dtype=float), np.asarray(hi, dtype=float)
    if lo_a.shape != (3,) or hi_a.shape != (3,) or not np.all(np.isfinite(lo_a)) or not np.all(lo_a < hi_a):
        raise ConfigError(name, (lo, hi), "two finite 3-vectors with min < max on every axis")


@dataclass(frozen=True)
class PreprocessConfig:
    """Crop boxes, outlier filter and voxel sizes.

    Attributes:
        self_box_min_m / self_box_max_m: corners of the box around the robot (wearer) in the
            sensor frame; points inside are removed, m.
        outer_box_min_m / outer_box_max_m: corners of the box that keeps the useful range, m.
        sor_neighbors: ``k`` neighbours of the statistical outlier filter; 0 disables it.
        sor_std_ratio: points whose mean neighbour distance exceeds ``mean + ratio * std`` go.
        voxel_m: voxel leaf of the registration cloud ``P_p`` (small-GICP leaf, section 5.2.1).
        map_voxel_m: voxel leaf of the map cloud ``P_f``.
        deskew: apply the constant-velocity deskew.
    """

    self_box_min_m: tuple[float, float, float] = (-0.5, -0.5, -1.6)
    self_box_max_m: tuple[float, float, float] = (0.5, 0.5, 0.3)
    outer_box_min_m: tuple[float, float, float] = (-50.0, -50.0, -10.0)
    outer_box_max_m: tuple[float, float, float] = (50.0, 50.0, 10.0)
    sor_neighbors: int = 20
    sor_std_ratio: float = 2.0
    voxel_m: float = 0.25
    map_voxel_m: float = 0.1
    deskew: bool = True

    def __post_init__(self) -> None:
        _check_box("self_box_m", self.self_box_min_m, self.self_box_max_m)
        _check_box("outer_box_m", self.outer_box_min_m, self.outer_box_max_m)
        object.__setattr__(self, "sor_neighbors", check_int("sor_neighbors", self.sor_neighbors, 0, 1000))
        check_range("sor_std_ratio", self.sor_std_ratio, 0.0, None, low_open=True)
        check_range("voxel_m", self.voxel_m, 0.0, 10.0, low_open=True)
        check_range("map_voxel_m", self.map_voxel_m, 0.0, 10.0, low_open=True)


def clean_points(points_xyz: np.ndarray) -> np.ndarray:
    """Boolean mask of the finite, non-zero points of an (N, 3) array."""
    p = np.asarray(points_xyz, dtype=float).reshape(-1, 3)
    return np.all(np.isfinite(p), axis=1) & (np.einsum("ij,ij->i", p, p) > 1e-12)


def deskew(points_xyz: np.ndarray, time_offset_s: np.ndarray, twist_per_s: np.ndarray) -> np.ndarray:
    """Points moved into the sweep-start frame: ``p_start = R(w tau) p + v tau``.

    ``twist_per_s = (v, w)``: linear (m/s) and angular (rad/s) velocity of the sensor expressed
    in its own frame (a constant-velocity model over the sweep; first order in translation).
    """
    p = np.asarray(points_xyz, dtype=float).reshape(-1, 3)
    tau = np.asarray(time_offset_s, dtype=float).reshape(-1)
    xi = np.asarray(twist_per_s, dtype=float).reshape(6)
    if len(p) == 0 or not np.any(xi):
        return p.copy()
    R = Rotation.from_rotvec(tau[:, None] * xi[None, 3:]).as_matrix()
    return np.einsum("nij,nj->ni", R, p) + tau[:, None] * xi[None, :3]


def voxel_downsample(points_xyz: np.ndarray, voxel_m: float) -> np.ndarray:
    """Voxel-grid centroids (Open3D ``voxel_down_sample``), (M, 3)."""
    p = np.asarray(points_xyz, dtype=float).reshape(-1, 3)
    if len(p) == 0:
        return p.copy()
    pcd = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(p))
    return np.asarray(pcd.voxel_down_sample(float(voxel_m)).points)


def _statistical_outliers(points_xyz: np.ndarray, k: int, std_ratio: float) -> np.ndarray:
    """Keep mask of the statistical outlier-rejection filter (Open3D's, as in PCL)."""
    n = len(points_xyz)
    if k == 0 or n <= k:
        return np.ones(n, dtype=bool)
    pcd = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points_xyz))
    _, kept = pcd.remove_statistical_outlier(nb_neighbors=k, std_ratio=float(std_ratio))
    mask = np.zeros(n, dtype=bool)
    mask[np.asarray(kept, dtype=np.int64)] = True
    return mask


def preprocess(
    points_xyz: np.ndarray,
    time_offset_s: np.ndarray | None,
    config: PreprocessConfig,
    twist_per_s: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """``(P_p, P_f)``: the registration cloud and the map cloud of one sweep, sensor frame.

    Both are empty (0, 3) arrays when nothing survives. Never raises on data.
    """
    p = np.asarray(points_xyz, dtype=float).reshape(-1, 3)
    ok = clean_points(p)
    tau = None
    if time_offset_s is not None:
        tau = np.asarray(time_offset_s, dtype=float).reshape(-1)
        if len(tau) != len(p):
            tau = None
        else:
            ok &= np.isfinite(tau)
    p = p[ok]
    if config.deskew and twist_per_s is not None and tau is not None:
        p = deskew(p, tau[ok], twist_per_s)
    inside_self = np.all((p > np.asarray(config.self_box_min_m)) & (p < np.asarray(config.self_box_max_m)), axis=1)
    inside_outer = np.all((p >= np.asarray(config.outer_box_min_m)) & (p <= np.asarray(config.outer_box_max_m)), axis=1)
    p = p[inside_outer & ~inside_self]
    if len(p) == 0:
        return np.zeros((0, 3)), np.zeros((0, 3))
    p_reg = voxel_downsample(p, config.voxel_m)
    keep = _statistical_outliers(p_reg, config.sor_neighbors, config.sor_std_ratio)
    p_map = voxel_downsample(p, config.map_voxel_m)
    if not np.all(keep):  # the map loses the points around the rejected registration voxels
        near, _ = cKDTree(p_reg[~keep]).query(p_map, k=1, distance_upper_bound=config.voxel_m)
        p_map = p_map[~np.isfinite(near)]
    return p_reg[keep], p_map
