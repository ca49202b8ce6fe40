"""Relative pose of two keyframes by SIFT matches and PnP in RANSAC (seeds/000 III-B.2).

For a candidate keyframe ``p`` (from place recognition) and a query keyframe ``q``: SIFT
features of both images are matched (Lowe's ratio test), the matched keypoints of ``p`` are
lifted to 3-D with ``p``'s depth image, and ``cv2.solvePnPRansac`` finds the pose of those
points in ``q``'s camera; the inliers are then refined by Levenberg-Marquardt
(``cv2.solvePnPRefineLM``). Among several candidates the one with most inliers is kept
(:func:`best_candidate`).

Covariance (the ``Sigma`` of eq. 1), :func:`pnp_covariance`: the relative pose ``T_p_q`` is
perturbed on the right, ``T_p_q * Exp(xi)`` with ``xi = (omega, v)`` in gtsam's tangent order
(rotation, translation), which is how gtsam's ``BetweenFactorPose3`` reads a covariance. The
Jacobian ``J`` (2n x 6) of the inliers' reprojection residuals in ``q`` with respect to ``xi``
is taken by central differences at the solution, ``sigma^2`` is the residuals' variance
``|r|^2 / (2n - 6)`` (floored at ``pixel_sigma_floor_px``, since a near-perfect fit would
claim an impossible certainty), and ``Sigma = sigma^2 (J^T J)^-1``: the Gauss-Newton covariance
of the least-squares fit. The test checks it against the scatter of PnP solutions under pixel
noise.

Frames: cameras in OpenCV's convention (x right, y down, z forward); ``T_p_q`` maps points of
camera ``q`` into camera ``p``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import gtsam
import numpy as np

from exobench.core.errors import ConfigError, check_int, check_range

from .place_recognition import to_grey

__all__ = ["PnpConfig", "RelativePose", "best_candidate", "depth_at", "pnp_covariance", "relative_pose",
           "sift_features"]


@dataclass(frozen=True)
class PnpConfig:
    """SIFT, matching and PnP-RANSAC settings.

    Attributes:
        n_sift_features: SIFT keypoints kept per image (OpenCV ``SIFT_create(nfeatures)``;
            Lowe's other parameters at his defaults: 3 layers per octave, contrast 0.04, edge 10).
        ratio: Lowe's ratio test (his paper: 0.8 rejects 90 % of false matches, 5 % of true).
        min_depth_m / max_depth_m: depth readings used to lift keypoints (the D435 range).
        ransac_reprojection_px: RANSAC inlier threshold.
        ransac_iterations / ransac_confidence: RANSAC stopping rule.
        min_inliers: fewer inliers than this is no relative pose (a wrong place).
        pixel_sigma_floor_px: lower bound of the reprojection sigma of the covariance.
        ransac_seed: seed of OpenCV's generator before each RANSAC (repeatable runs).
    """

    n_sift_features: int = 1000
    ratio: float = 0.8
    min_depth_m: float = 0.2
    max_depth_m: float = 6.0
    ransac_reprojection_px: float = 3.0
    ransac_iterations: int = 500
    ransac_confidence: float = 0.999
    min_inliers: int = 30
    pixel_sigma_floor_px: float = 0.3
    ransac_seed: int = 0

    def __post_init__(self) -> None:
        check_int("pnp.n_sift_features", self.n_sift_features, 10, 100_000)
        check_range("pnp.ratio", self.ratio, 0.0, 1.0, low_open=True)
        check_range("pnp.min_depth_m", self.min_depth_m, 0.0, None)
        check_range("pnp.max_depth_m", self.max_depth_m, self.min_depth_m, None, low_open=True)
        check_range("pnp.ransac_reprojection_px", self.ransac_reprojection_px, 0.0, None, low_open=True)
        check_int("pnp.ransac_iterations", self.ransac_iterations, 1, 1_000_000)
        check_range("pnp.ransac_confidence", self.ransac_confidence, 0.0, 1.0, low_open=True, high_open=True)
        check_int("pnp.min_inliers", self.min_inliers, 6, None)
        check_range("pnp.pixel_sigma_floor_px", self.pixel_sigma_floor_px, 0.0, None, low_open=True)
        check_int("pnp.ransac_seed", self.ransac_seed, 0, 2**31 - 1)


@dataclass(frozen=True)
class RelativePose:
    """A verified relative pose between keyframes ``p`` and ``q``.

    Attributes:
        T_p_q: 4x4 pose of camera ``q`` in camera ``p``.
        covariance: 6x6 covariance of ``T_p_q`` in gtsam's tangent (rotation rad, translation m),
            right perturbation.
        n_inliers / n_matches: PnP-RANSAC inliers among the ratio-test matches with depth.
        reprojection_rms_px: RMS reprojection error of the inliers at the solution.
    """

    T_p_q: np.ndarray
    covariance: np.ndarray
    n_inliers: int
    n_matches: int
    reprojection_rms_px: float


def sift_features(image: np.ndarray, config: PnpConfig | None = None) -> tuple[np.ndarray, np.ndarray]:
    """SIFT keypoints ``(N, 2)`` pixel (u, v) and descriptors ``(N, 128)`` float32 of a uint8 image."""
    cfg = config or PnpConfig()
    kps, desc = cv2.SIFT_create(nfeatures=cfg.n_sift_features).detectAndCompute(to_grey(image), None)
    if desc is None or not kps:
        return np.zeros((0, 2)), np.zeros((0, 128), dtype=np.float32)
    return np.array([k.pt for k in kps], dtype=float), desc


def _project(K: np.ndarray, points_cam: np.ndarray) -> np.ndarray:
    uvw = points_cam @ K.T
    return uvw[:, :2] / uvw[:, 2:3]


def _residuals(T_p_q: np.ndarray, points_p: np.ndarray, uv_q: np.ndarray, K: np.ndarray) -> np.ndarray:
    T_q_p = np.linalg.inv(T_p_q)
    return (_project(K, points_p @ T_q_p[:3, :3].T + T_q_p[:3, 3]) - uv_q).ravel()


def pnp_covariance(T_p_q: np.ndarray, points_p: np.ndarray, uv_q: np.ndarray, K: np.ndarray,
                   pixel_sigma_floor_px: float = 0.3) -> tuple[np.ndarray, float]:
    """Covariance of ``T_p_q`` from the PnP fit of ``points_p`` (n, 3, camera ``p``) seen at
    ``uv_q`` (n, 2) in camera ``q``: ``sigma^2 (J^T J)^-1`` (module docstring) and the RMS
    reprojection error (px)."""
    n = len(points_p)
    if n < 4:
        raise ConfigError("pnp_covariance.points", n, "at least 4 points (2n > 6 residuals)")
    r0 = _residuals(T_p_q, points_p, uv_q, K)
    J = np.empty((2 * n, 6))
    eps = 1e-6
    for i in range(6):
        d = np.zeros(6)
        d[i] = eps
        plus = T_p_q @ gtsam.Pose3.Expmap(d).matrix()
        minus = T_p_q @ gtsam.Pose3.Expmap(-d).matrix()
        J[:, i] = (_residuals(plus, points_p, uv_q, K) - _residuals(minus, points_p, uv_q, K)) / (2 * eps)
    sigma2 = max(float(r0 @ r0) / (2 * n - 6), pixel_sigma_floor_px**2)
    return sigma2 * np.linalg.inv(J.T @ J), float(np.sqrt(np.mean(r0.reshape(-1, 2) ** 2) * 2))


def _match(desc_p: np.ndarray, desc_q: np.ndarray, ratio: float) -> list[tuple[int, int]]:
    if len(desc_p) < 2 or len(desc_q) < 2:
        return []
    knn = cv2.BFMatcher(cv2.NORM_L2).knnMatch(desc_q, desc_p, k=2)
    return [(m.trainIdx, m.queryIdx) for m, n in (pair for pair in knn if len(pair) == 2)
            if m.distance < ratio * n.distance]


def depth_at(depth: np.ndarray, uv: np.ndarray, max_spread: float = 0.02) -> np.ndarray:
    """Depth (m) at sub-pixel keypoints ``uv`` (n, 2): bilinear between the four pixels around
    each when they agree within ``max_spread`` of their mean (a smooth surface: the nearest
    pixel alone would put a slanted wall's point up to half a pixel's depth change off), else
    the nearest pixel (an edge, where blending would invent a point between two surfaces)."""
    d = np.asarray(depth, dtype=float)
    h, w = d.shape
    u = np.clip(uv[:, 0], 0, w - 1)
    v = np.clip(uv[:, 1], 0, h - 1)
    u0 = np.clip(np.floor(u).astype(int), 0, w - 2)
    v0 = np.clip(np.floor(v).astype(int), 0, h - 2)
    fu, fv = u - u0, v - v0
    quad = np.stack([d[v0, u0], d[v0, u0 + 1], d[v0 + 1, u0], d[v0 + 1, u0 + 1]], axis=1)
    bilinear = (quad[:, 0] * (1 - fu) * (1 - fv) + quad[:, 1] * fu * (1 - fv)
                + quad[:, 2] * (1 - fu) * fv + quad[:, 3] * fu * fv)
    nearest = d[np.rint(v).astype(int), np.rint(u).astype(int)]
    with np.errstate(invalid="ignore"):
        smooth = np.all(np.isfinite(quad), axis=1) & (np.ptp(quad, axis=1) <= max_spread * np.abs(quad.mean(axis=1)))
    return np.where(smooth, bilinear, nearest)


def relative_pose(features_p: tuple[np.ndarray, np.ndarray], depth_p: np.ndarray,
                  features_q: tuple[np.ndarray, np.ndarray], K: np.ndarray,
                  config: PnpConfig | None = None) -> RelativePose | None:
    """``T_p_q`` from SIFT features of both keyframes (:func:`sift_features`) and the depth image
    (m, same size as ``p``'s image; 0 or non-finite = no reading) of ``p``; None when fewer than
    ``config.min_inliers`` inliers support it."""
    cfg = config or PnpConfig()
    K = np.asarray(K, dtype=float)
    uv_p, desc_p = features_p
    uv_q, desc_q = features_q
    pairs = _match(desc_p, desc_q, cfg.ratio)
    if len(pairs) < cfg.min_inliers:
        return None
    ip, iq = np.array(pairs).T
    z = depth_at(depth_p, uv_p[ip])
    ok = np.isfinite(z) & (z >= cfg.min_depth_m) & (z <= cfg.max_depth_m)
    if ok.sum() < cfg.min_inliers:
        return None
    uv1 = np.column_stack([uv_p[ip[ok]], np.ones(ok.sum())])
    points_p = (uv1 @ np.linalg.inv(K).T) * z[ok, None]
    image_q = uv_q[iq[ok]]
    # RANSAC draws from OpenCV's global generator: seeding it makes a run repeat to the bit
    cv2.setRNGSeed(cfg.ransac_seed)
    found, rvec, tvec, inliers = cv2.solvePnPRansac(
        points_p, image_q, K, None, iterationsCount=cfg.ransac_iterations,
        reprojectionError=cfg.ransac_reprojection_px, confidence=cfg.ransac_confidence,
        flags=cv2.SOLVEPNP_EPNP)
    if not found or inliers is None or len(inliers) < cfg.min_inliers:
        return None
    inl = inliers.ravel()
    rvec, tvec = cv2.solvePnPRefineLM(points_p[inl], image_q[inl], K, None, rvec, tvec)
    T_q_p = np.eye(4)
    T_q_p[:3, :3] = cv2.Rodrigues(rvec)[0]
    T_q_p[:3, 3] = tvec.ravel()
    T_p_q = np.linalg.inv(T_q_p)
    cov, rms = pnp_covariance(T_p_q, points_p[inl], image_q[inl], K, cfg.pixel_sigma_floor_px)
    return RelativePose(T_p_q, cov, len(inl), int(ok.sum()), rms)


def best_candidate(poses: Sequence[RelativePose | None]) -> int | None:
    """Index of the candidate with most inliers (seeds/000 III-B.2); None if none was verified.
    Ties keep the earlier (better ranked) candidate."""
    best = None
    for i, pose in enumerate(poses):
        if pose is not None and (best is None or pose.n_inliers > poses[best].n_inliers):
            best = i
    return best
