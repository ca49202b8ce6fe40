"""The drifting odometry of the locomotion track, computed from the true camera motion.

:func:`drift_odometry`: increments of the true camera position, rotated by a heading error
growing at ``yaw_deg_per_m`` per metre of horizontal travel, plus a translation error of ``pct``
% of the distance travelled along a seeded unit direction; orientation = heading error @ true
orientation. All in the gravity-aligned odometry frame of the true camera at t = 0.
"""

from __future__ import annotations

import numpy as np

from exobench.core.transforms import invert_T, make_T, rot_z


def gravity_aligned(T_world_cam: np.ndarray) -> np.ndarray:
    """``T_world_odom``: origin at the camera, z up, x along the optical axis's horizontal heading."""
    z_opt = T_world_cam[:3, 2]
    yaw = float(np.arctan2(z_opt[1], z_opt[0]))
    return make_T(rot_z(yaw), T_world_cam[:3, 3].copy())


def drift_odometry(t: np.ndarray, T_world_cam: np.ndarray, pct: float, yaw_deg_per_m: float,
                   rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:  # fmt: skip
    """(T_world_odom, T_odom_cam (N, 4, 4), v_odom (N, 3), distance travelled (N,)) of the drift model.

    ``T_world_cam`` are true optical-frame poses at times ``t``. Distance = cumulative horizontal
    path length of the camera. Translation error e(s) = pct/100 * s * u (u a seeded unit vector,
    its vertical part a third of the horizontal); heading error psi(s) = +-yaw_deg_per_m * s.
    """
    T_world_odom = gravity_aligned(T_world_cam[0])
    T_odom_w = invert_T(T_world_odom)
    T_true = np.einsum("ij,njk->nik", T_odom_w, T_world_cam)
    p = T_true[:, :3, 3]
    step = np.linalg.norm(np.diff(p[:, :2], axis=0), axis=1)
    s = np.concatenate([[0.0], np.cumsum(step)])
    u = rng.standard_normal(3)
    u[2] /= 3.0
    u /= np.linalg.norm(u)
    sign = 1.0 if rng.random() < 0.5 else -1.0
    psi = sign * np.radians(yaw_deg_per_m) * s
    e = (pct / 100.0) * s[:, None] * u[None, :]
    Rz = np.array([rot_z(a) for a in psi]).reshape(-1, 3, 3)
    dp = np.diff(p, axis=0)
    p_o = np.empty_like(p)
    p_o[0] = p[0]
    if len(p) > 1:
        p_o[1:] = p[0] + np.cumsum(np.einsum("nij,nj->ni", Rz[1:], dp), axis=0)
    p_o += e
    T = np.repeat(np.eye(4)[None], len(t), axis=0)
    T[:, :3, :3] = np.einsum("nij,njk->nik", Rz, T_true[:, :3, :3])
    T[:, :3, 3] = p_o
    v = np.gradient(p_o, t, axis=0) if len(t) > 1 else np.zeros((len(t), 3))
    return T_world_odom, T, v, s
