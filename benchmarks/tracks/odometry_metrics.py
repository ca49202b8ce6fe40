"""Scoring of a :class:`TrajectoryEstimate` against the true LiDAR trajectory (odometry track).

The reference is the true LiDAR pose at each estimate stamp, interpolated (linear position,
slerp rotation) in the truth's LiDAR track: ``EpisodeTruth.trajectory_w`` (pose at each sweep
start) merged with ``body_tracks["lidar_trunk"]`` (50 Hz) when present. A pipeline may stamp its
poses at the sweep start (the contract) or at the time its pose refers to (kiss-icp: the end of
the sweep); both are scored against the right true pose. Stamps outside the truth's time span
are left out.

Metrics (:mod:`exobench.benchmarks.trajectory`, as evo computes them):

- ``ate_m``: RMSE of the APE translation part after SE(3) Umeyama alignment (thesis eq. 5.1);
- ``rpe_m``: RMSE of the RPE translation part between consecutive poses (eq. 5.2);
- ``rpe_1m_m``: the same over pose pairs 1 m of travelled path apart;
- ``drift_per_m``: end-point error per metre of true path after aligning the first poses (m/m);
- loop errors (seeds/003 Sec. 5.2.2, Table 5.4) when the true trajectory ends where it started
  (within :data:`LOOP_TOL_M`): the relative pose error between the first and the last pose,
  ``E = (Q_0^-1 Q_N)^-1 (P_0^-1 P_N)``; ``te_m = |t_E|``, ``oe_rad`` its rotation angle,
  ``tve_{x,y,z}_m`` its translation in the first pose's axes. On an exact loop ``Q_0^-1 Q_N = I``
  and this is the thesis' TE/OE/TVE of the estimate alone;
- ``time_per_scan_ms`` (median), ``failures`` (poses whose status is not ``"ok"``),
  ``n_poses``, ``path_m`` (true path length), ``loop_edges``.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from exobench.core.episode import Episode
from exobench.core.estimates import TrajectoryEstimate

from .. import trajectory as tj

LOOP_TOL_M = 0.5
LIDAR_TRACK = "lidar_trunk"
METRIC_KEYS = ("ate_m", "rpe_m", "rpe_1m_m", "drift_per_m", "te_m", "oe_rad", "tve_x_m", "tve_y_m", "tve_z_m",
               "time_per_scan_ms", "failures", "n_poses", "path_m", "loop_edges")  # fmt: skip


def failure_metrics(episode: Episode | None, reason: str) -> dict[str, Any]:
    out: dict[str, Any] = {k: math.nan for k in METRIC_KEYS}
    out.update(failed=True, failed_reason=reason)
    return out


def true_track(episode: Episode) -> np.ndarray:
    """Rows ``[t, x, y, z, qw, qx, qy, qz]`` of the true LiDAR pose, time-sorted, unique stamps."""
    rows = [np.asarray(episode.truth.trajectory_w, dtype=float).reshape(-1, 8)]
    extra = episode.truth.body_tracks.get(LIDAR_TRACK) if episode.truth.body_tracks else None
    if extra is not None:
        rows.append(np.asarray(extra, dtype=float).reshape(-1, 8))
    allr = np.concatenate(rows)
    allr = allr[np.argsort(allr[:, 0], kind="stable")]
    _, idx = np.unique(allr[:, 0], return_index=True)
    return allr[idx]


def interpolate_poses(track: np.ndarray, stamps_s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(mask of stamps inside the track's span, poses (M, 4, 4) at those stamps)."""
    from scipy.spatial.transform import Rotation, Slerp

    t = track[:, 0]
    s = np.asarray(stamps_s, dtype=float)
    inside = np.isfinite(s) & (s >= t[0] - 1e-9) & (s <= t[-1] + 1e-9)
    si = np.clip(s[inside], t[0], t[-1])
    T = np.tile(np.eye(4), (len(si), 1, 1))
    if len(si) == 0:
        return inside, T
    for k in range(3):
        T[:, k, 3] = np.interp(si, t, track[:, 1 + k])
    rot = Rotation.from_quat(track[:, [5, 6, 7, 4]])  # xyzw
    T[:, :3, :3] = (Slerp(t, rot)(si) if len(t) > 1 else rot[np.zeros(len(si), dtype=int)]).as_matrix()
    return inside, T


def loop_metrics(P: np.ndarray, Q: np.ndarray) -> dict[str, float]:
    """TE/OE/TVE of the estimate's loop, relative to the true loop (module docstring)."""
    Q_rel = np.linalg.inv(Q[0]) @ Q[-1]
    P_rel = np.linalg.inv(P[0]) @ P[-1]
    E = np.linalg.inv(Q_rel) @ P_rel
    two = tj.Trajectory.from_poses(np.array([0.0, 1.0]), np.stack([np.eye(4), E]))
    return tj.loop_errors(two)


def score_trajectory(episode: Episode, est: TrajectoryEstimate) -> dict[str, Any]:
    """The metrics of the module docstring (never raises on a bad estimate)."""
    try:
        stamps = np.asarray(est.stamps_s, dtype=float).reshape(-1)
        P = np.asarray(est.T_world_sensor, dtype=float).reshape(-1, 4, 4)
        if len(P) != len(stamps):
            return failure_metrics(episode, f"{len(stamps)} stamps but {len(P)} poses")
        track = true_track(episode)
        inside, Q = interpolate_poses(track, stamps)
        finite = np.all(np.isfinite(P.reshape(len(P), -1)), axis=1)
        use = inside & finite
        P_use, Q_use = P[use], Q[finite[inside]]
        out: dict[str, Any] = {k: math.nan for k in METRIC_KEYS}
        status = tuple(est.status)
        out.update(
            failed=False, failed_reason="",
            time_per_scan_ms=tj.time_per_scan_ms(est.time_per_scan_s),
            failures=int(sum(s != "ok" for s in status)),
            n_poses=int(len(P)),
            loop_edges=int(len(est.loop_edges)),
        )  # fmt: skip
        if len(P_use) < 3:
            out.update(failed=True, failed_reason=f"{len(P_use)} finite poses inside the true trajectory")
            return out
        t_use = stamps[use]
        e_traj = tj.Trajectory.from_poses(t_use, P_use)
        r_traj = tj.Trajectory.from_poses(t_use, Q_use)
        out["ate_m"] = tj.ate(e_traj, r_traj)["rmse"]
        out["rpe_m"] = tj.rpe(e_traj, r_traj, 1, "frames")["rmse"]
        try:
            out["rpe_1m_m"] = tj.rpe(e_traj, r_traj, 1.0, "m")["rmse"]
        except Exception:  # shorter than 1 m of path
            out["rpe_1m_m"] = math.nan
        out["drift_per_m"] = tj.drift_per_metre(e_traj, r_traj)
        out["path_m"] = r_traj.path_length_m()
        if np.linalg.norm(track[-1, 1:4] - track[0, 1:4]) < LOOP_TOL_M and out["path_m"] > 4 * LOOP_TOL_M:
            out.update(loop_metrics(P_use, Q_use))
        return out
    except Exception as e:  # a scorer never raises on an estimate
        return failure_metrics(episode, f"scoring raised {type(e).__name__}: {e}")
