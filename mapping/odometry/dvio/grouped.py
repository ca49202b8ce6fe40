"""The window's visual and depth factors of one host keyframe as one gtsam factor (seeds/002
eq. 8, 11-14), evaluated with numpy over all their observations at once.

:mod:`.factors` writes eq. (8), (11) and (12) as one gtsam ``CustomFactor`` per observation, each
a Python callback: a window of 10 keyframes holds about a thousand, and every Levenberg-Marquardt
step crosses into Python for each of them (to linearise, and again for each trial's cost), which
made a keyframe's window update cost 0.5-3 s. :func:`host_group_factor` holds the same residuals
of every landmark hosted in one keyframe (its host depths, and the reprojection and projection
depth of each observation in the other keyframes) in one ``CustomFactor`` on the host's pose, the
observing poses and the landmarks' inverse depths, so a step makes one callback per host keyframe.

It is the same cost, not an approximation of it: the residuals and Jacobians are
:func:`.factors.landmark_in_camera`'s, the bounds on depth and inverse depth are the same, and the
robust kernel acts on each observation's residual block on its own, as gtsam's ``Robust`` noise
model does on each of the per-observation factors: the factor's noise model is the unit one and
the callback whitens each block and applies the kernel itself. gtsam's ``Robust`` model linearises
to the block's whitened Jacobian and residual scaled by ``sqrt(w(|r|))`` and costs ``rho(|r|)``;
the callback returns the former when gtsam asks for Jacobians (a linearisation) and, when it asks
for the residual alone (a trial step's cost), a vector whose half squared norm is the sum of the
blocks' ``rho`` (``sqrt(2 rho)`` in each block's first row). The tests hold the factor's cost and
linear system against the sum of the per-observation factors'.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import gtsam
import numpy as np

from exobench.core.errors import ConfigError, check_range

from .factors import _MIN_XI, _MIN_Z_M, KERNELS, DepthNoise, Extrinsics

__all__ = ["HostedLandmark", "host_group_factor", "kernel_loss_weight", "sfm_landmark_factor"]


@dataclass(frozen=True, eq=False)
class HostedLandmark:
    """A landmark hosted in the group's keyframe: its inverse-depth key, the host's normalised
    bearing ``u_host`` (2,) and depth ``d_host`` (m, NaN when none), and its observations in other
    keyframes as (pose key, normalised point (2,), depth m or NaN)."""

    key: int
    u_host: np.ndarray
    d_host: float
    observations: tuple[tuple[int, np.ndarray, float], ...]


def kernel_loss_weight(kernel: str, k: float, r: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``rho(|r|)`` and the weight ``w(|r|)`` of gtsam's m-estimators ("none", "huber", "cauchy")
    of scale k at the whitened residual norms ``r``."""
    a = np.abs(r)
    if kernel == "none":
        return 0.5 * a * a, np.ones_like(a)
    if kernel == "huber":
        inside = a <= k
        return (np.where(inside, 0.5 * a * a, k * a - 0.5 * k * k),
                np.where(inside, 1.0, k / np.maximum(a, k)))
    if kernel == "cauchy":
        q = a * a / (k * k)
        return 0.5 * k * k * np.log1p(q), 1.0 / (1.0 + q)
    raise ConfigError("kernel", kernel, "one of " + ", ".join(KERNELS))


def _cross_rows(M: np.ndarray, p: np.ndarray) -> np.ndarray:
    """``M @ skew(p)`` for stacks of 3x3 ``M`` (m, 3, 3) and 3-vectors ``p`` (m, 3): row r is
    ``M[r] x p`` (written out: ``np.cross`` costs more than the arithmetic at these sizes)."""
    a0, a1, a2 = M[..., 0], M[..., 1], M[..., 2]
    p0, p1, p2 = p[:, None, 0], p[:, None, 1], p[:, None, 2]
    out = np.empty(np.broadcast_shapes(M.shape, (len(p), 3, 3)))
    out[..., 0] = a1 * p2 - a2 * p1
    out[..., 1] = a2 * p0 - a0 * p2
    out[..., 2] = a0 * p1 - a1 * p0
    return out


def host_group_factor(host_key: int, landmarks: Sequence[HostedLandmark], ext: Extrinsics, sigma: float,
                      depth: DepthNoise | None, kernel: str = "cauchy", kernel_k: float = 1.0
                      ) -> gtsam.CustomFactor | None:
    """One factor for the landmarks hosted in ``host_key``'s keyframe (module docstring): eq. (8)
    with ``sigma`` on the normalised plane for every observation, and with ``depth`` (None: the
    ``dvio-no-depth`` ablation) eq. (11) for every host depth and eq. (12) for every observed
    depth the camera can measure. None when there is no observation."""
    check_range("reprojection sigma", sigma, 0.0, None, low_open=True)
    if kernel not in KERNELS:
        raise ConfigError("kernel", kernel, "one of " + ", ".join(KERNELS))
    check_range("kernel_k", kernel_k, 0.0, None, low_open=True)
    obs_keys: list[int] = []
    where: dict[int, int] = {}
    lm_i, ob_i, u_obs, d_obs = [], [], [], []
    for i, lm in enumerate(landmarks):
        for key, uu, d in lm.observations:
            if key == host_key:
                raise ConfigError("observation key", key, "a keyframe other than the host")
            if key not in where:
                where[key] = len(obs_keys)
                obs_keys.append(key)
            lm_i.append(i)
            ob_i.append(where[key])
            u_obs.append(np.asarray(uu, dtype=float).reshape(2))
            d_obs.append(float(d))
    if not lm_i:
        return None
    n_l, n_o, M = len(landmarks), len(obs_keys), len(lm_i)
    lm_i, ob_i = np.array(lm_i), np.array(ob_i)
    u_obs = np.array(u_obs)
    d_obs = np.array(d_obs)
    bearing = np.array([[*np.asarray(lm.u_host, dtype=float).reshape(2), 1.0] for lm in landmarks])
    d_host = np.array([lm.d_host for lm in landmarks], dtype=float)
    if not (np.all(np.isfinite(bearing)) and np.all(np.isfinite(u_obs))):
        raise ConfigError("landmark bearing", "non-finite", "finite normalised points")
    use_host = np.array([depth is not None and depth.valid(d) for d in d_host], dtype=bool)
    use_depth = np.array([depth is not None and depth.valid(d) for d in d_obs], dtype=bool)
    host_l = np.flatnonzero(use_host)
    dep_m = np.flatnonzero(use_depth)
    inv_s_host = np.array([1.0 / depth.sigma_m(d) for d in d_host[host_l]]) if len(host_l) else np.zeros(0)
    inv_s_dep = np.array([1.0 / depth.sigma_m(d) for d in d_obs[dep_m]]) if len(dep_m) else np.zeros(0)
    inv_s_rep = 1.0 / sigma
    R_IC, p_IC = ext.R_IC, ext.p_IC
    R_CI = R_IC.T
    RB = bearing @ R_IC.T  # R_IC (u, 1) of each landmark
    n_h, n_d = len(host_l), len(dep_m)
    n = n_h + 2 * M + n_d
    # Rows: host depths, then each observation's reprojection pair, then observed depths.
    r0_rep = n_h + 2 * np.arange(M)
    row_dep = n_h + 2 * M + np.arange(n_d)
    # Columns of the stacked Jacobian: host pose, observing poses, inverse depths.
    c_obs = 6 + 6 * ob_i
    c_lm = 6 + 6 * n_o + lm_i
    six = np.arange(6)
    keys = gtsam.KeyVector([host_key, *obs_keys, *(lm.key for lm in landmarks)])
    first_row = np.concatenate([np.arange(n_h), r0_rep, row_dep]).astype(int)

    def error(this: gtsam.CustomFactor, values: gtsam.Values, H: list[np.ndarray] | None) -> np.ndarray:
        T_h = values.atPose3(host_key).matrix()
        R_h, p_h = T_h[:3, :3], T_h[:3, 3]
        T_o = np.array([values.atPose3(key).matrix() for key in obs_keys])
        R_o, p_o = T_o[:, :3, :3], T_o[:, :3, 3]
        raw = np.array([values.atVector(lm.key)[0] for lm in landmarks])
        xi = np.maximum(raw, _MIN_XI)
        # landmark_in_camera, for every observation at once
        P_Ih = RB / xi[:, None] + p_IC
        P_G = P_Ih @ R_h.T + p_h
        P_Ij = np.einsum("mji,mj->mi", R_o[ob_i], P_G[lm_i] - p_o[ob_i])
        P = (P_Ij - p_IC) @ R_IC
        z = np.maximum(P[:, 2], _MIN_Z_M)
        r_rep = (P[:, :2] / z[:, None] - u_obs) * inv_s_rep
        r_dep = (P[dep_m, 2] - d_obs[dep_m]) * inv_s_dep
        r_host = (1.0 / xi[host_l] - d_host[host_l]) * inv_s_host
        rho_h, w_h = kernel_loss_weight(kernel, kernel_k, r_host)
        rho_r, w_r = kernel_loss_weight(kernel, kernel_k, np.linalg.norm(r_rep, axis=1))
        rho_d, w_d = kernel_loss_weight(kernel, kernel_k, r_dep)
        if H is None:  # a trial step's cost: 0.5 |e|^2 is the sum of the blocks' rho
            e = np.zeros(n)
            e[first_row] = np.sqrt(2.0 * np.concatenate([rho_h, rho_r, rho_d]))
            return e
        sw_h, sw_r, sw_d = np.sqrt(w_h), np.sqrt(w_r), np.sqrt(w_d)
        AR = np.matmul(R_CI @ R_o.transpose(0, 2, 1), R_h)[ob_i]  # d P / d P_G, times R_h
        J_h = np.concatenate([-_cross_rows(AR, P_Ih[lm_i]), AR], axis=2)  # (M, 3, 6)
        J_j = np.concatenate([_cross_rows(R_CI, P_Ij), np.broadcast_to(-R_CI, (M, 3, 3))], axis=2)
        gate = raw > _MIN_XI
        J_x = np.einsum("mij,mj->mi", AR, RB[lm_i]) * (-(gate / (xi * xi)))[lm_i, None]
        dz = P[:, 2] > _MIN_Z_M
        D = np.zeros((M, 2, 3))
        D[:, 0, 0] = D[:, 1, 1] = 1.0 / z
        D[:, 0, 2] = -P[:, 0] / z**2 * dz
        D[:, 1, 2] = -P[:, 1] / z**2 * dz
        s = (sw_r * inv_s_rep)[:, None, None]
        A = np.zeros((n, 6 + 6 * n_o + n_l), order="F")  # column blocks are gtsam's (column-major) blocks
        rows = (r0_rep[:, None] + np.arange(2))[:, :, None]  # (M, 2, 1)
        A[n_h:n_h + 2 * M, :6] = (np.matmul(D, J_h) * s).reshape(2 * M, 6)
        A[rows, (c_obs[:, None] + six)[:, None, :]] = np.matmul(D, J_j) * s
        A[rows[:, :, 0], c_lm[:, None]] = np.einsum("mij,mj->mi", D, J_x) * s[:, :, 0]
        if n_d:
            s_d = (sw_d * inv_s_dep)[:, None]
            A[row_dep, :6] = J_h[dep_m, 2] * s_d
            A[row_dep[:, None], c_obs[dep_m, None] + six] = J_j[dep_m, 2] * s_d
            A[row_dep, c_lm[dep_m]] = J_x[dep_m, 2] * s_d[:, 0]
        if n_h:
            A[np.arange(n_h), 6 + 6 * n_o + host_l] = -(gate / (xi * xi))[host_l] * inv_s_host * sw_h
        H[0] = A[:, :6]
        for k in range(n_o):
            H[1 + k] = A[:, 6 + 6 * k:12 + 6 * k]
        c0 = 6 + 6 * n_o
        for i in range(n_l):
            H[1 + n_o + i] = A[:, c0 + i:c0 + i + 1]
        return np.concatenate([r_host * sw_h, (r_rep * sw_r[:, None]).reshape(-1), r_dep * sw_d])

    return gtsam.CustomFactor(gtsam.noiseModel.Unit.Create(n), keys, error)


def sfm_landmark_factor(lm_key: int, observations: Sequence[tuple[int, np.ndarray, float]], ext: Extrinsics,
                        sigma: float, depth: DepthNoise, kernel: str = "cauchy", kernel_k: float = 1.0
                        ) -> gtsam.CustomFactor | None:
    """The initialisation's SfM cost of one world landmark (Point3 ``lm_key``), eq. (1) and (3):
    for each observation (IMU pose key, normalised point (2,), depth m or NaN) the reprojection
    ``P_c[:2] / P_c[2] - u`` (sigma ``sigma``) and, where the camera can measure it, the depth
    ``P_c[2] - d`` (sigma ``depth.sigma_m(d)``), each block under the robust kernel as in
    :func:`host_group_factor`; one callback for all of them. None without an observation."""
    check_range("reprojection sigma", sigma, 0.0, None, low_open=True)
    if kernel not in KERNELS:
        raise ConfigError("kernel", kernel, "one of " + ", ".join(KERNELS))
    if not observations:
        return None
    pose_keys = [key for key, _, _ in observations]
    if len(set(pose_keys)) != len(pose_keys):
        raise ConfigError("observation key", pose_keys, "one observation per pose")
    u = np.array([np.asarray(uu, dtype=float).reshape(2) for _, uu, _ in observations])
    if not np.all(np.isfinite(u)):
        raise ConfigError("observation", "non-finite", "finite normalised points")
    d = np.array([float(dd) for _, _, dd in observations])
    dep = np.flatnonzero([depth.valid(x) for x in d])
    inv_s_dep = np.array([1.0 / depth.sigma_m(x) for x in d[dep]]) if len(dep) else np.zeros(0)
    K, n_d = len(observations), len(dep)
    n = 2 * K + n_d
    R_CI, p_IC = ext.R_IC.T, ext.p_IC
    keys = gtsam.KeyVector([*pose_keys, lm_key])
    first_row = np.concatenate([2 * np.arange(K), 2 * K + np.arange(n_d)])
    rows = np.arange(2 * K).reshape(K, 2)

    def error(this: gtsam.CustomFactor, values: gtsam.Values, H: list[np.ndarray] | None) -> np.ndarray:
        T = np.array([values.atPose3(key).matrix() for key in pose_keys])
        R, t = T[:, :3, :3], T[:, :3, 3]
        lw = values.atPoint3(lm_key)
        P_I = np.einsum("kji,kj->ki", R, lw - t)  # R_k^T (l - t_k)
        P = (P_I - p_IC) @ ext.R_IC  # R_CI (P_I - p_IC)
        z = P[:, 2]
        r_rep = (P[:, :2] / z[:, None] - u) / sigma
        r_dep = (z[dep] - d[dep]) * inv_s_dep
        rho_r, w_r = kernel_loss_weight(kernel, kernel_k, np.linalg.norm(r_rep, axis=1))
        rho_d, w_d = kernel_loss_weight(kernel, kernel_k, r_dep)
        if H is None:
            e = np.zeros(n)
            e[first_row] = np.sqrt(2.0 * np.concatenate([rho_r, rho_d]))
            return e
        sw_r, sw_d = np.sqrt(w_r), np.sqrt(w_d)
        J_pose = np.concatenate([_cross_rows(R_CI, P_I), np.broadcast_to(-R_CI, (K, 3, 3))], axis=2)  # (K, 3, 6)
        J_l = R_CI @ R.transpose(0, 2, 1)  # (K, 3, 3)
        D = np.zeros((K, 2, 3))
        D[:, 0, 0] = D[:, 1, 1] = 1.0 / z
        D[:, 0, 2] = -P[:, 0] / z**2
        D[:, 1, 2] = -P[:, 1] / z**2
        s = (sw_r / sigma)[:, None, None]
        A_pose = np.zeros((n, K, 6))
        A_pose[rows, np.arange(K)[:, None]] = np.matmul(D, J_pose) * s
        A_l = np.empty((n, 3))
        A_l[:2 * K] = (np.matmul(D, J_l) * s).reshape(2 * K, 3)
        if n_d:
            s_d = (sw_d * inv_s_dep)[:, None]
            A_pose[2 * K + np.arange(n_d), dep] = J_pose[dep, 2] * s_d
            A_l[2 * K:] = J_l[dep, 2] * s_d
        for k in range(K):
            H[k] = A_pose[:, k]
        H[K] = A_l
        return np.concatenate([(r_rep * sw_r[:, None]).reshape(-1), r_dep * sw_d])

    return gtsam.CustomFactor(gtsam.noiseModel.Unit.Create(n), keys, error)
