"""Visual and depth factors of D-VIO on the inverse-depth landmark (seeds/002 eq. 8, 11-14).

A landmark ``l`` lives in its host keyframe ``i`` (the first that observed it) as an inverse
depth ``xi`` along the host's normalised bearing ``(u_i, 1)``. With the IMU-camera extrinsics
``T_IC = (R_IC, p_IC)`` (the camera's pose in the IMU frame) and the IMU poses ``T_GI`` of the
keyframes in the gravity-aligned frame G, the landmark in the camera of a co-visible keyframe j is

    P_cj = R_IC^T (R_Gj^T (R_Gi (R_IC (u_i, 1) / xi + p_IC) + p_Gi - p_Gj) - p_IC)

and the residuals are

- :func:`reprojection_factor`, eq. (8): ``P_cj[:2] / P_cj[2] - u_j`` (2-vector, normalised plane),
  sigma ``pixel_sigma / f`` (VINS-Mono: 1.5 px at its 460 px virtual focal length);
- :func:`projection_depth_factor`, eq. (12): ``P_cj[2] - d_j`` (metres);
- :func:`host_depth_factor`, eq. (11): ``1 / xi - d_i`` (metres).

Both depth factors are weighted by the depth noise of a stereo depth camera (docs/sensor-reference.md "RGB-D",
the RMS error of a disparity error of ``subpixel`` pixels): ``sigma(z) = z^2 s / (f B)``,
evaluated at the measured depth (:class:`DepthNoise`); all factors take a robust kernel (the
``rho`` of eq. 10, 13, 14; VINS-Mono's estimator uses a Cauchy loss of scale 1 on whitened units).

Jacobians are analytic for gtsam's right perturbation of ``Pose3`` (``T exp(d)``, ``d`` =
(rotation, translation)), checked against finite differences in the tests. A measurement the
camera cannot make (a depth that is NaN, not positive or outside the camera's range; a
non-finite bearing) gives no factor: the builders return None and the caller counts it.

The window evaluates the same residuals grouped per host keyframe (:mod:`.grouped`: one Python
callback instead of one per observation); these per-observation factors are what that is tested
against.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import gtsam
import numpy as np

from exobench.core.errors import ConfigError, check_range

__all__ = [
    "DepthNoise",
    "Extrinsics",
    "host_depth_factor",
    "landmark_in_camera",
    "projection_depth_factor",
    "reprojection_factor",
    "robust",
]

KERNELS = ("none", "huber", "cauchy")

# Smallest depth (m) and inverse depth (1/m) the residuals divide by. An iterate can put a
# landmark behind a camera or drive xi through zero; the residual is then evaluated at the bound
# (large, finite, with a zero derivative past it) so the optimiser backs off instead of failing
# on inf or NaN.
_MIN_Z_M = 1e-3
_MIN_XI = 1e-3
_EMPTY = np.zeros((0, 0))


@dataclass(frozen=True)
class DepthNoise:
    """Depth noise of a stereo depth camera (docs/sensor-reference.md, D455 at 848x480 defaults).

    Attributes:
        focal_px: focal length of the depth image, px.
        baseline_m: stereo baseline, m.
        subpixel: RMS disparity error, px (0.08 typical, 0.032 well calibrated).
        min_depth_m / max_depth_m: range of valid depth; outside it no factor is built.
        floor_m: lower bound of sigma, m: keeps a near landmark from dominating the window
            through a millimetre sigma the quantised depth image cannot deliver [A].
    """

    focal_px: float = 424.0
    baseline_m: float = 0.095
    subpixel: float = 0.08
    min_depth_m: float = 0.4
    max_depth_m: float = 6.0
    floor_m: float = 0.002

    def __post_init__(self) -> None:
        check_range("depth_noise.focal_px", self.focal_px, 1.0, 1e5)
        check_range("depth_noise.baseline_m", self.baseline_m, 0.0, 1.0, low_open=True)
        check_range("depth_noise.subpixel", self.subpixel, 0.0, 10.0, low_open=True)
        check_range("depth_noise.min_depth_m", self.min_depth_m, 0.0, 100.0)
        check_range("depth_noise.max_depth_m", self.max_depth_m, self.min_depth_m, 100.0, low_open=True)
        check_range("depth_noise.floor_m", self.floor_m, 0.0, 1.0, low_open=True)

    def valid(self, depth_m: float) -> bool:
        return math.isfinite(depth_m) and self.min_depth_m <= depth_m <= self.max_depth_m

    def sigma_m(self, depth_m: float) -> float:
        """RMS depth error at ``depth_m``: ``z^2 s / (f B)``, at least :attr:`floor_m`."""
        return max(depth_m * depth_m * self.subpixel / (self.focal_px * self.baseline_m), self.floor_m)


@dataclass(frozen=True, eq=False)
class Extrinsics:
    """The camera's pose in the IMU frame: ``R_IC`` (3x3) and ``p_IC`` (3,), m."""

    R_IC: np.ndarray
    p_IC: np.ndarray

    @classmethod
    def from_T_imu_camera(cls, T_imu_camera: np.ndarray) -> Extrinsics:
        T = np.asarray(T_imu_camera, dtype=float)
        if T.shape != (4, 4) or not np.all(np.isfinite(T)):
            raise ConfigError("T_imu_camera", T.shape, "a finite 4x4 rigid transform")
        return cls(T[:3, :3].copy(), T[:3, 3].copy())

    @classmethod
    def identity(cls) -> Extrinsics:
        return cls(np.eye(3), np.zeros(3))


def robust(base: gtsam.noiseModel.Base, kernel: str, k: float) -> gtsam.noiseModel.Base:
    """``base`` wrapped in the robust kernel ``kernel`` ("none", "huber", "cauchy") of scale k."""
    if kernel == "none":
        return base
    check_range("kernel_k", k, 0.0, None, low_open=True)
    if kernel == "huber":
        return gtsam.noiseModel.Robust.Create(gtsam.noiseModel.mEstimator.Huber.Create(k), base)
    if kernel == "cauchy":
        return gtsam.noiseModel.Robust.Create(gtsam.noiseModel.mEstimator.Cauchy.Create(k), base)
    raise ConfigError("kernel", kernel, "one of " + ", ".join(KERNELS))


def _skew(v: np.ndarray) -> np.ndarray:
    x, y, z = float(v[0]), float(v[1]), float(v[2])
    return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])


def landmark_in_camera(T_Gi: gtsam.Pose3, T_Gj: gtsam.Pose3, xi: float, u_i: np.ndarray, ext: Extrinsics,
                       jacobians: bool = True) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``P_cj`` and its Jacobians with respect to T_Gi (3x6), T_Gj (3x6) and xi (3x1) (empty
    arrays when ``jacobians`` is False: the optimiser's trial steps need the residual only)."""
    # Called once per observation and optimiser step from gtsam's Python callback: written with
    # preallocated blocks (no hstack, eye or skew helper), which halves its cost.
    R_i, p_i = T_Gi.rotation().matrix(), T_Gi.translation()
    R_j, p_j = T_Gj.rotation().matrix(), T_Gj.translation()
    bearing = np.array([u_i[0], u_i[1], 1.0])
    R_CI = ext.R_IC.T
    P_Ii = ext.R_IC @ bearing / xi + ext.p_IC
    P_G = R_i @ P_Ii + p_i
    P_Ij = R_j.T @ (P_G - p_j)
    P_cj = R_CI @ (P_Ij - ext.p_IC)
    if not jacobians:
        return P_cj, _EMPTY, _EMPTY, _EMPTY
    A = R_CI @ R_j.T  # d P_cj / d P_G
    AR = A @ R_i
    J_i = np.empty((3, 6))
    J_i[:, :3] = -AR @ _skew(P_Ii)
    J_i[:, 3:] = AR
    J_j = np.empty((3, 6))
    J_j[:, :3] = R_CI @ _skew(P_Ij)
    J_j[:, 3:] = -R_CI
    J_xi = (AR @ (ext.R_IC @ bearing) * (-1.0 / (xi * xi))).reshape(3, 1)
    return P_cj, J_i, J_j, J_xi


Jacobians = list[np.ndarray] | None


def _visual(key_i: int, key_j: int, key_xi: int, u_i: np.ndarray, ext: Extrinsics, model: gtsam.noiseModel.Base,
            residual: Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]]) -> gtsam.CustomFactor:
    u_i = np.asarray(u_i, dtype=float).reshape(2).copy()

    def error(this: gtsam.CustomFactor, values: gtsam.Values, H: Jacobians) -> np.ndarray:
        xi = max(float(values.atVector(key_xi)[0]), _MIN_XI)
        P, J_i, J_j, J_xi = landmark_in_camera(values.atPose3(key_i), values.atPose3(key_j), xi, u_i, ext,
                                               H is not None)
        r, dr_dP = residual(P)
        if H is not None:
            H[0], H[1] = dr_dP @ J_i, dr_dP @ J_j
            H[2] = dr_dP @ J_xi if float(values.atVector(key_xi)[0]) > _MIN_XI else np.zeros((len(r), 1))
        return r

    return gtsam.CustomFactor(model, gtsam.KeyVector([key_i, key_j, key_xi]), error)


def _finite(*xs: object) -> bool:
    return all(bool(np.all(np.isfinite(np.asarray(x, dtype=float)))) for x in xs)


def reprojection_factor(key_i: int, key_j: int, key_xi: int, u_i: np.ndarray, u_j: np.ndarray, ext: Extrinsics,
                        sigma: float, kernel: str = "cauchy", kernel_k: float = 1.0) -> gtsam.CustomFactor | None:
    """Eq. (8): landmark hosted in i (bearing u_i) observed at u_j in j; ``sigma`` on the
    normalised plane (pixel sigma / focal length)."""
    if not _finite(u_i, u_j):
        return None
    check_range("reprojection sigma", sigma, 0.0, None, low_open=True)
    u_j = np.asarray(u_j, dtype=float).reshape(2).copy()

    def residual(P: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        z = max(P[2], _MIN_Z_M)
        dz = P[2] > _MIN_Z_M
        J = np.array([[1.0 / z, 0.0, -P[0] / z**2 * dz], [0.0, 1.0 / z, -P[1] / z**2 * dz]])
        return P[:2] / z - u_j, J

    model = robust(gtsam.noiseModel.Isotropic.Sigma(2, sigma), kernel, kernel_k)
    return _visual(key_i, key_j, key_xi, u_i, ext, model, residual)


def projection_depth_factor(key_i: int, key_j: int, key_xi: int, u_i: np.ndarray, depth_j_m: float,
                            ext: Extrinsics, noise: DepthNoise, kernel: str = "cauchy",
                            kernel_k: float = 1.0) -> gtsam.CustomFactor | None:
    """Eq. (12): depth ``d_j`` measured in j of the landmark hosted in i, sigma ``noise`` at d_j."""
    if not (_finite(u_i) and noise.valid(depth_j_m)):
        return None
    d = float(depth_j_m)
    dz = np.array([[0.0, 0.0, 1.0]])

    def residual(P: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return np.array([P[2] - d]), dz

    model = robust(gtsam.noiseModel.Isotropic.Sigma(1, noise.sigma_m(d)), kernel, kernel_k)
    return _visual(key_i, key_j, key_xi, u_i, ext, model, residual)


def host_depth_factor(key_xi: int, depth_i_m: float, noise: DepthNoise, kernel: str = "cauchy",
                      kernel_k: float = 1.0) -> gtsam.CustomFactor | None:
    """Eq. (11): ``1 / xi - d_i``, the host's own depth measurement of its landmark."""
    if not noise.valid(depth_i_m):
        return None
    d = float(depth_i_m)

    def error(this: gtsam.CustomFactor, values: gtsam.Values, H: Jacobians) -> np.ndarray:
        raw = float(values.atVector(key_xi)[0])
        xi = max(raw, _MIN_XI)
        if H is not None:
            H[0] = np.array([[-1.0 / xi**2 if raw > _MIN_XI else 0.0]])
        return np.array([1.0 / xi - d])

    model = robust(gtsam.noiseModel.Isotropic.Sigma(1, noise.sigma_m(d)), kernel, kernel_k)
    return gtsam.CustomFactor(model, gtsam.KeyVector([key_xi]), error)
