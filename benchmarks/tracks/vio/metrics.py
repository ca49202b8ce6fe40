"""The vio track's scorer: a camera trajectory against the camera's true pose (pure functions).

The estimate (:class:`~exobench.core.estimates.TrajectoryEstimate`) holds the camera optical
frame's pose at each RGB-D frame stamp in the estimator's gravity-aligned world, a status per
frame (``"ok"`` or why not) and the processing time per frame. The reference is the true
optical-frame pose at the frame's measurement time (its stamp minus the camera's latency,
``calibration`` ``latency_s``), interpolated in ``body_tracks[<camera>]`` (one row per rendered
frame, so the interpolation only bridges rounding).

A pose is *scored* when its status is ``"ok"``, it is finite and its stamp lies in the truth's
span; every other frame is lost. Metrics (names and definitions of :mod:`..lidar_trajectory`,
:mod:`exobench.benchmarks.trajectory`, as evo computes them):

- ``ate_m``: APE translation RMSE after SE(3) Umeyama alignment, over the scored poses;
- ``rpe_1m_m``: RPE translation RMSE over pose pairs 1 m of true path apart;
- ``drift_per_m``: end-point error per metre of true path after aligning the first poses;
- loop errors when the true camera ends where it started (within :data:`LOOP_TOL_M`, after
  more than 4 of it of path): ``te_m`` and ``oe_rad`` of the relative pose error between the first
  and the last scored pose (:func:`..lidar_trajectory.loop_metrics`): the end point's error after
  putting the first poses on each other; ``tve_{x,y,z}_m`` that error in the estimate's own
  gravity-aligned axes as seeds/002 Table V gives its drift x/y/z (:func:`loop_drift_g`);
- ``lost_frac``: frames without a scored pose over the frames the pipeline received (the
  estimate's entries, or the RGB-D frames its counters say it used, if more: a frame the
  estimate left out is lost too);
- ``init_s``: simulated time from the camera's first frame (its first measurement, delivered or
  not, plus the latency) to the first scored pose;
- ``time_per_frame_ms`` (median) and ``time_per_frame_ms_p95`` of ``time_per_scan_s``;
- ``n_frames``, ``n_poses`` (scored), ``path_m`` (true path of the camera).

A run with fewer than 3 scored poses is failed (its ATE NaN, never 0), with ``lost_frac`` and
the timings kept.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from exobench.core.episode import Episode
from exobench.core.estimates import TrajectoryEstimate

from ... import trajectory as tj
from ..lidar_trajectory import aligned_positions, estimate_arrays, interpolate_poses, path_metrics

METRIC_KEYS = ("ate_m", "rpe_1m_m", "drift_per_m", "te_m", "oe_rad", "tve_x_m", "tve_y_m", "tve_z_m", "lost_frac",
               "init_s", "time_per_frame_ms", "time_per_frame_ms_p95", "n_frames", "n_poses", "path_m")  # fmt: skip


def failure_metrics(episode: Episode | None, reason: str) -> dict[str, Any]:
    out: dict[str, Any] = {k: math.nan for k in METRIC_KEYS}
    out.update(failed=True, failed_reason=reason)
    return out


def camera_id(episode: Episode) -> str:
    """The id of the rig's camera (``calibration.extra["camera"]``; the calibration's mounts list
    every camera position of the device, the rig's or not)."""
    return str(episode.calibration.extra["camera"])


def camera_latency_s(episode: Episode) -> float:
    mount = next(m for m in episode.calibration.mounts if m.sensor_id == camera_id(episode))
    return float(mount.params.get("latency_s", 0.0))


def camera_truth(episode: Episode) -> np.ndarray:
    """Rows ``[t, x, y, z, qw, qx, qy, qz]`` of the true optical-frame pose at each frame's
    measurement time."""
    return np.asarray(episode.truth.body_tracks[camera_id(episode)], dtype=float).reshape(-1, 8)


def imu_truth(episode: Episode) -> np.ndarray:
    """Rows of the true IMU pose at each IMU sample's measurement time."""
    imu = str(episode.calibration.extra["camera_imu"])
    return np.asarray(episode.truth.body_tracks[imu], dtype=float).reshape(-1, 8)


def timing_ms(seconds: Any) -> tuple[float, float]:
    """(median, 95th percentile) of per-frame times in ms; NaN when there are none."""
    t = np.asarray(seconds, dtype=float).reshape(-1)
    t = t[np.isfinite(t)]
    if not len(t):
        return math.nan, math.nan
    return float(np.median(t) * 1e3), float(np.percentile(t, 95) * 1e3)


def ate_rmse(p_est: np.ndarray, p_true: np.ndarray, e_traj: tj.Trajectory, r_traj: tj.Trajectory) -> float:
    """:func:`exobench.benchmarks.trajectory.ate`'s RMSE; for an estimate that stays at one point
    (Umeyama's rotation is then undetermined, and evo refuses it) the RMSE every rigid alignment
    gives it: the true positions' spread about their mean."""
    if np.ptp(p_est, axis=0).max() <= 1e-12:
        return float(np.sqrt(np.mean(np.sum((p_true - p_true.mean(axis=0)) ** 2, axis=1))))
    xc, yc = p_est - p_est.mean(axis=0), p_true - p_true.mean(axis=0)
    d = np.linalg.svd(yc.T @ xc / len(xc), compute_uv=False)
    if np.count_nonzero(d > np.finfo(float).eps) < 2:
        # collinear estimate or truth (a straight walk): evo refuses Umeyama (the rotation about the line is
        # free), but every minimising rotation moves the points alike, so the minimum is Umeyama's
        # closed form var_true + var_est - 2 d_1 (d_2 = d_3 = 0 here, so no reflection sign enters)
        var = float(np.mean(np.sum(xc * xc, axis=1)) + np.mean(np.sum(yc * yc, axis=1)))
        return float(np.sqrt(max(var - 2.0 * d[0], 0.0)))
    return float(tj.ate(e_traj, r_traj)["rmse"])


def aligned_or_centred(truth: np.ndarray, stamps: np.ndarray, poses: np.ndarray) -> np.ndarray:
    """Estimated positions moved onto the truth as for the ATE; a one-point estimate is put at the
    true positions' mean (the figures' view of :func:`ate_rmse`)."""
    p = poses[:, :3, 3]
    if np.ptp(p, axis=0).max() <= 1e-12:
        _, Q = interpolate_poses(truth, stamps)
        return p - p.mean(axis=0) + Q[:, :3, 3].mean(axis=0)
    return aligned_positions(truth, stamps, poses)


def scored_mask(episode: Episode, est: TrajectoryEstimate) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(stamps, poses (N, 4, 4), mask of the scored ones) of an estimate (module docstring)."""
    stamps = np.asarray(est.stamps_s, dtype=float).reshape(-1)
    P = np.asarray(est.T_world_sensor, dtype=float).reshape(-1, 4, 4)
    status = np.array([str(s) for s in est.status], dtype=object)
    ok = np.zeros(len(stamps), dtype=bool) if len(status) != len(stamps) else status == "ok"
    finite = np.all(np.isfinite(P.reshape(len(P), -1)), axis=1) & np.isfinite(stamps)
    truth = camera_truth(episode)
    inside, _ = interpolate_poses(truth, stamps - camera_latency_s(episode))
    return stamps, P, ok & finite & inside


def loop_drift_g(P0: np.ndarray, PN: np.ndarray, Q0: np.ndarray, QN: np.ndarray) -> np.ndarray:
    """The loop's end-point error (first poses put on each other) in the axes seeds/002 Table V
    reports its drift in: D-VIO's state lives in a gravity-aligned frame G (seeds/002 II-C), which
    VINS-Mono, its base, turns so that the first frame's yaw (``R2ypr``: the heading of the body x
    axis, the camera's right for a D455) is zero. So z is up as the estimator sees it, x the first
    camera's right, y (z cross x) its forward. The pose-graph axes of the first camera (y down, z
    forward) would put the vertical drift in -y and the forward drift in z. The norm is ``te_m``."""
    d_est = PN[:3, 3] - P0[:3, 3]
    d_true_in_est = P0[:3, :3] @ Q0[:3, :3].T @ (QN[:3, 3] - Q0[:3, 3])
    yaw = math.atan2(P0[1, 0], P0[0, 0])
    c, s = math.cos(yaw), math.sin(yaw)
    return np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]]) @ (d_est - d_true_in_est)


def score_vio(episode: Episode, est: TrajectoryEstimate) -> dict[str, Any]:
    """The metrics of the module docstring (never raises on a bad estimate)."""
    try:
        stamps, P, reason = estimate_arrays(est)
        if len(P) == len(stamps) and len(tuple(est.status)) != len(stamps):
            reason = f"{len(stamps)} stamps but {len(tuple(est.status))} statuses"
        if reason:
            out = failure_metrics(episode, reason)
            if reason == "no poses":
                out["lost_frac"] = 1.0
            return out
        stamps, P, use = scored_mask(episode, est)
        counts = est.counts.get("rgbd") if isinstance(est.counts, dict) else None
        n_frames = max(len(stamps), int(getattr(counts, "used", 0) or 0))
        out: dict[str, Any] = {k: math.nan for k in METRIC_KEYS}
        med, p95 = timing_ms(est.time_per_scan_s)
        n_used = int(use.sum())
        out.update(failed=False, failed_reason="", time_per_frame_ms=med, time_per_frame_ms_p95=p95,
                   n_frames=int(n_frames), n_poses=n_used,
                   lost_frac=float(1.0 - n_used / n_frames) if n_frames else math.nan)  # fmt: skip
        if n_used < 3:
            out.update(failed=True, failed_reason=f"{n_used} scored poses (status ok, finite, inside the truth)")
            return out
        return _alignment_metrics(episode, out, stamps, P, use)
    except Exception as e:  # a scorer never raises on an estimate
        return failure_metrics(episode, f"scoring raised {type(e).__name__}: {e}")


def _alignment_metrics(episode: Episode, out: dict[str, Any], stamps: np.ndarray, P: np.ndarray,
                       use: np.ndarray) -> dict[str, Any]:
    """The metrics against the truth; should one raise, the record fails but keeps its counts
    (``lost_frac``, ``n_poses``): how much was tracked is known whatever the alignment does."""
    try:
        truth = camera_truth(episode)
        out["init_s"] = float(stamps[use][0] - (truth[0, 0] + camera_latency_s(episode)))
        _, Q = interpolate_poses(truth, stamps[use] - camera_latency_s(episode))
        t_use = stamps[use]
        e_traj = tj.Trajectory.from_poses(t_use, P[use])
        r_traj = tj.Trajectory.from_poses(t_use, Q)
        out["ate_m"] = ate_rmse(P[use][:, :3, 3], Q[:, :3, 3], e_traj, r_traj)
        out.update(path_metrics(e_traj, r_traj, P[use], Q, truth))
        if math.isfinite(out["te_m"]):
            Pu = P[use]
            out["tve_x_m"], out["tve_y_m"], out["tve_z_m"] = (float(v) for v in loop_drift_g(Pu[0], Pu[-1], Q[0], Q[-1]))
    except Exception as e:  # a scorer never raises on an estimate
        out.update({k: math.nan for k in ("ate_m", "rpe_1m_m", "drift_per_m")},
                   failed=True, failed_reason=f"scoring raised {type(e).__name__}: {e}")  # fmt: skip
    return out
