"""A LiDAR trajectory of an office walk against the truth: its metrics, figure data and report section.

Shared by the odometry track (which scores its pipelines' :class:`TrajectoryEstimate` with
:func:`score_trajectory`) and the lidar-filter track (which scores KISS-ICP on each filter's kept
points the same way).

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

For the report: :func:`trajectory_figure_data` (the arrays the runner saves per figure case),
:func:`alignment` (the SE(3) fit the ATE uses) and :func:`trajectory_sections` (top views and
TUM/KITTI files).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path
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


def estimate_arrays(est: TrajectoryEstimate) -> tuple[np.ndarray, np.ndarray, str]:
    """(stamps, poses (N, 4, 4), why the estimate cannot be scored or ""): one pose per stamp, and
    at least one."""
    stamps = np.asarray(est.stamps_s, dtype=float).reshape(-1)
    P = np.asarray(est.T_world_sensor, dtype=float).reshape(-1, 4, 4)
    if len(P) != len(stamps):
        return stamps, P, f"{len(stamps)} stamps but {len(P)} poses"
    return stamps, P, "" if len(P) else "no poses"


def path_metrics(e_traj: tj.Trajectory, r_traj: tj.Trajectory, P: np.ndarray, Q: np.ndarray,
                 truth: np.ndarray) -> dict[str, float]:
    """``rpe_1m_m``, ``drift_per_m``, ``path_m`` of the estimate ``e_traj`` (poses ``P``) against
    ``r_traj`` (``Q``) and, when the truth (rows ``[t, x, y, z, ...]``) ends where it started after
    more than 4 :data:`LOOP_TOL_M` of path, the loop errors (:func:`loop_metrics`)."""
    out: dict[str, float] = {}
    try:
        out["rpe_1m_m"] = tj.rpe(e_traj, r_traj, 1.0, "m")["rmse"]
    except Exception:  # shorter than 1 m of path
        out["rpe_1m_m"] = math.nan
    out["drift_per_m"] = tj.drift_per_metre(e_traj, r_traj)
    out["path_m"] = r_traj.path_length_m()
    if np.linalg.norm(truth[-1, 1:4] - truth[0, 1:4]) < LOOP_TOL_M and out["path_m"] > 4 * LOOP_TOL_M:
        out.update(loop_metrics(P, Q))
    return out


def score_trajectory(episode: Episode, est: TrajectoryEstimate) -> dict[str, Any]:
    """The metrics of the module docstring (never raises on a bad estimate)."""
    try:
        stamps, P, reason = estimate_arrays(est)
        if reason:
            return failure_metrics(episode, reason)
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
        out.update(path_metrics(e_traj, r_traj, P_use, Q_use, track))
        return out
    except Exception as e:  # a scorer never raises on an estimate
        return failure_metrics(episode, f"scoring raised {type(e).__name__}: {e}")


# ------------------------------------------------------------------ figures and files


def trajectory_figure_data(episode: Episode, estimates: Mapping[str, Any]) -> dict[str, Any]:
    """Arrays of the top-view figure and the trajectory files: truth and each estimate."""
    track = true_track(episode)
    data: dict[str, Any] = {"truth": track}
    for name, est in estimates.items():
        if isinstance(est, TrajectoryEstimate) and len(est.stamps_s):
            data[f"est_stamps__{name}"] = np.asarray(est.stamps_s, dtype=float)
            data[f"est_poses__{name}"] = np.asarray(est.T_world_sensor, dtype=float).reshape(-1, 4, 4)
    return data


def alignment(truth: np.ndarray, stamps: np.ndarray, poses: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(R, t) of the SE(3) Umeyama fit of the estimated positions onto the true ones (as the ATE);
    identity when fewer than 3 poses fall inside the truth. For the figures: on a collinear estimate
    (a straight walk) one of the fits that all give the ATE's minimum."""
    inside, Q = interpolate_poses(truth, stamps)
    P = poses[inside]
    ok = np.all(np.isfinite(P.reshape(len(P), -1)), axis=1)
    if ok.sum() < 3:
        return np.eye(3), np.zeros(3)
    R, t, _ = tj.umeyama_alignment(P[ok, :3, 3], Q[ok, :3, 3], allow_collinear=True)
    return R, t


def aligned_positions(truth: np.ndarray, stamps: np.ndarray, poses: np.ndarray) -> np.ndarray:
    """Estimated positions moved onto the truth by :func:`alignment`, (N, 3)."""
    R, t = alignment(truth, stamps, poses)
    return poses[:, :3, 3] @ R.T + t


def trajectory_sections(out: Path) -> list[str]:
    """Top views (estimate aligned as for the ATE, vs truth) and TUM/KITTI files per case."""
    from ..plots import pyplot

    folder = out / "figures"
    files = []
    for f in sorted(folder.glob("*.npz")) if folder.exists() else []:
        with np.load(f) as z:
            if "truth" in z.files and any(k.startswith("est_poses__") for k in z.files):
                files.append(f)
    if not files:
        return []
    traj_dir = out / "trajectories"
    traj_dir.mkdir(exist_ok=True)
    lines = ["## Trajectories (top view, estimates SE(3)-aligned to the truth)", "",
             "TUM (`t x y z qx qy qz qw`) and KITTI (3x4 per line) files of every estimate and of the truth are in "
             "`trajectories/`.", ""]  # fmt: skip
    plt = pyplot()
    for f in files:
        key = f.stem
        with np.load(f) as z:
            data = dict(z)
        truth = data["truth"]
        ref = tj.Trajectory(truth[:, 0], truth[:, 1:4], truth[:, 4:8])
        tj.write_tum(ref, traj_dir / f"{key}__truth.tum")
        tj.write_kitti(ref, traj_dir / f"{key}__truth.kitti")
        fig, ax = plt.subplots(figsize=(7, 5))
        ax.plot(truth[:, 1], truth[:, 2], "k-", lw=2, label="truth")
        for name in sorted(k.split("__", 1)[1] for k in data if k.startswith("est_poses__")):
            stamps, poses = data[f"est_stamps__{name}"], data[f"est_poses__{name}"]
            est = tj.Trajectory.from_poses(stamps, poses)
            tj.write_tum(est, traj_dir / f"{key}__{name}.tum")
            tj.write_kitti(est, traj_dir / f"{key}__{name}.kitti")
            p = aligned_positions(truth, stamps, poses)
            ax.plot(p[:, 0], p[:, 1], "-", lw=1.2, label=name)
        ax.set_aspect("equal", adjustable="datalim")
        ax.set_xlabel("x (m)")
        ax.set_ylabel("y (m)")
        ax.legend(fontsize=8)
        ax.set_title(key.replace("__", "/"))
        png = folder / f"{key}_top.png"
        fig.savefig(png, dpi=110, bbox_inches="tight")
        plt.close(fig)
        lines += [f"### {key.replace('__', '/')}", "", f"![{key}](figures/{png.name})", ""]
    return lines
