"""Generalized ICP for LEO-SLAM's three alignment levels (seeds/003 section 4.2.1).

The thesis aligns with small-GICP [58] (GICP of Segal et al. [121]): plane-to-plane
covariances from 20 nearest neighbours, correspondences within ``max_correspondence_m``,
Gauss-Newton on SE(3). Here Open3D's ``registration_generalized_icp`` does the iterations; the
clouds are prepared once (:class:`GicpCloud`: normals from ``k`` neighbours, from which Open3D
builds the regularised covariances ``R diag(eps, 1, 1) R^T``) so a scan prepared as a source is
reused as the next target.

Open3D merges the correspondences of its OpenMP threads in arrival order, which makes the
result depend on thread timing; :func:`align` therefore runs Open3D single-threaded
(deterministic, and the clouds here are small).

:func:`align` never raises on data: too few points, a non-finite result or too few inliers give
``GicpResult.converged = False`` with a status.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np
import open3d as o3d

from exobench.core.errors import check_int, check_range

__all__ = ["GicpCloud", "GicpConfig", "GicpResult", "align", "single_threaded"]

_REG = o3d.pipelines.registration


@dataclass(frozen=True)
class GicpConfig:
    """GICP parameters (small-GICP defaults where the thesis gives none).

    Attributes:
        max_correspondence_m: correspondence distance (small-GICP default 1.0 m).
        max_iterations: Gauss-Newton iterations (small-GICP default 20).
        covariance_neighbors: neighbours of each point's covariance (small-GICP default 20).
        epsilon: the smallest eigenvalue of the plane-like covariances (GICP, 1e-3).
        relative_change: stop when the fitness and the RMSE (m) change less than this between
            iterations (Open3D criterion; 1e-4 stops after 3-5 iterations at sub-mm RMSE change).
        min_fitness: fraction of source points with a correspondence needed to accept.
        max_rmse_m: largest accepted inlier RMSE, m.
        min_points: fewer points than this in either cloud -> not attempted.
    """

    max_correspondence_m: float = 1.0
    max_iterations: int = 20
    covariance_neighbors: int = 20
    epsilon: float = 1e-3
    relative_change: float = 1e-4
    min_fitness: float = 0.3
    max_rmse_m: float = 0.5
    min_points: int = 30

    def __post_init__(self) -> None:
        check_range("max_correspondence_m", self.max_correspondence_m, 0.0, 100.0, low_open=True)
        for name, value, high in (("max_iterations", self.max_iterations, 1000),
                                  ("covariance_neighbors", self.covariance_neighbors, 200),
                                  ("min_points", self.min_points, 10**7)):
            object.__setattr__(self, name, check_int(name, value, 3, high))
        check_range("epsilon", self.epsilon, 0.0, 1.0, low_open=True)
        check_range("relative_change", self.relative_change, 0.0, 1.0)
        check_range("min_fitness", self.min_fitness, 0.0, 1.0)
        check_range("max_rmse_m", self.max_rmse_m, 0.0, None, low_open=True)


@dataclass(frozen=True, eq=False)
class GicpResult:
    """One alignment.

    Attributes:
        T_target_source: pose of the source frame in the target frame (4x4); the initial guess
            when not converged.
        fitness: fraction of source points with a correspondence.
        rmse_m: inlier RMSE (Euclidean), m.
        converged: accepted (finite, enough inliers, small RMSE).
        status: ``"ok"``, ``"too_few_points"``, ``"not_finite"``, ``"low_fitness"``, ``"high_rmse"``.
    """

    T_target_source: np.ndarray
    fitness: float
    rmse_m: float
    converged: bool
    status: str


@contextlib.contextmanager
def single_threaded() -> Iterator[None]:
    """Run Open3D with one thread inside the block (restores the previous limit)."""
    previous = o3d.utility.get_max_threads()
    if previous == 1:
        yield
        return
    o3d.utility.set_max_threads(1)
    try:
        yield
    finally:
        o3d.utility.set_max_threads(previous)


class GicpCloud:
    """A cloud ready for GICP: points and plane-like covariances (via normals)."""

    def __init__(self, points_xyz: np.ndarray, covariance_neighbors: int = 20) -> None:
        p = np.asarray(points_xyz, dtype=float).reshape(-1, 3)
        self.points = p[np.all(np.isfinite(p), axis=1)]
        self.pcd = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(self.points))
        if len(self.points) >= 3:
            with single_threaded():
                self.pcd.estimate_normals(o3d.geometry.KDTreeSearchParamKNN(int(covariance_neighbors)))

    def __len__(self) -> int:
        return len(self.points)


def align(source: GicpCloud, target: GicpCloud, T_init: np.ndarray, config: GicpConfig) -> GicpResult:
    """GICP of ``source`` onto ``target`` from ``T_init`` (source pose in the target frame)."""
    T0 = np.asarray(T_init, dtype=float)
    if len(source) < config.min_points or len(target) < config.min_points:
        return GicpResult(T0.copy(), 0.0, float("nan"), False, "too_few_points")
    if not np.all(np.isfinite(T0)):
        return GicpResult(np.eye(4), 0.0, float("nan"), False, "not_finite")
    criteria = _REG.ICPConvergenceCriteria(
        relative_fitness=config.relative_change, relative_rmse=config.relative_change,
        max_iteration=config.max_iterations)
    with single_threaded():
        res = _REG.registration_generalized_icp(
            source.pcd, target.pcd, config.max_correspondence_m, T0,
            _REG.TransformationEstimationForGeneralizedICP(epsilon=config.epsilon), criteria)
    T = np.asarray(res.transformation, dtype=float).copy()
    fitness, rmse = float(res.fitness), float(res.inlier_rmse)
    if not np.all(np.isfinite(T)):
        return GicpResult(T0.copy(), fitness, rmse, False, "not_finite")
    if fitness < config.min_fitness:
        return GicpResult(T, fitness, rmse, False, "low_fitness")
    if rmse > config.max_rmse_m:
        return GicpResult(T, fitness, rmse, False, "high_rmse")
    return GicpResult(T, fitness, rmse, True, "ok")
