"""Trajectory metrics of the odometry track, computed as evo computes them, and TUM/KITTI files.

A :class:`Trajectory` holds time-stamped poses ``T_world_body`` as positions and ``wxyz``
quaternions (evo's ``PoseTrajectory3D`` layout). Definitions:

- ``associate``: evo's ``sync.associate_trajectories(ref, est, max_diff)`` (nearest stamp within
  ``max_diff_s``, starting from the trajectory with fewer poses).
- ``umeyama_alignment`` / ``align``: least-squares SE(3) (Sim(3) with ``correct_scale``) fit of
  the estimated positions onto the reference ones (Umeyama 1991), as ``PosePath3D.align``.
- ``ate``: evo's APE with ``PoseRelation.translation_part``: per pose ``|p_est - p_ref|`` after
  alignment, m; statistics rmse, mean, median, std, min, max, sse (sse in m^2).
- ``rpe``: evo's RPE with ``PoseRelation.translation_part``: for pose pairs (i, j) ``delta``
  apart (in frames, or in metres of travelled path of the estimate), the translation norm of
  ``E = (Q_i^-1 Q_j)^-1 (P_i^-1 P_j)`` (Q reference, P estimate), m. A rigid alignment does not
  change it, so none is applied.
- ``drift_per_metre``: after moving the estimate so that its first pose equals the reference's,
  the end-point position error divided by the reference path length, m/m (x100 for %).
- ``loop_errors``: for a sequence that starts and ends at the same true pose (thesis seeds/003
  Sec. 5.2.2, Table 5.4): TVE = t_f - t_i (x, y, z, m), TE = |TVE| (m), OE = rotation angle of
  ``q_i^-1 * q_f`` (rad). ``loop_errors_rmse`` gives the table's RMSE over runs.
- ``time_per_scan_ms``: median compute time per scan (or frame), ms.

Files: TUM ``timestamp tx ty tz qx qy qz qw`` (quaternion xyzw in the file, as the TUM RGB-D
tools and evo expect), KITTI 12 numbers of the 3x4 matrix ``[R | t]`` per line (no stamps).
Floats are written with ``repr`` so they read back exactly.
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from exobench.core.errors import ConfigError
from exobench.core.transforms import matrix_to_quat_wxyz, quat_multiply

STAT_KEYS = ("rmse", "mean", "median", "std", "min", "max", "sse")


@dataclass(frozen=True)
class Trajectory:
    """Time-stamped poses ``T_world_body``: stamps (N,) s, positions (N, 3) m, quaternions (N, 4) wxyz."""

    stamps_s: np.ndarray
    positions_xyz: np.ndarray
    orientations_quat_wxyz: np.ndarray

    def __post_init__(self) -> None:
        stamps = np.asarray(self.stamps_s, dtype=float).reshape(-1)
        pos = np.asarray(self.positions_xyz, dtype=float)
        quat = np.asarray(self.orientations_quat_wxyz, dtype=float)
        n = len(stamps)
        if pos.shape != (n, 3):
            raise ConfigError("trajectory.positions_xyz", pos.shape, f"shape ({n}, 3) for {n} stamps")
        if quat.shape != (n, 4):
            raise ConfigError("trajectory.orientations_quat_wxyz", quat.shape, f"shape ({n}, 4) for {n} stamps")
        if n and not np.all(np.linalg.norm(quat, axis=1) > 0):
            raise ConfigError("trajectory.orientations_quat_wxyz", "a zero quaternion", "non-zero quaternions")
        object.__setattr__(self, "stamps_s", stamps)
        object.__setattr__(self, "positions_xyz", pos)
        object.__setattr__(self, "orientations_quat_wxyz", quat)

    def __len__(self) -> int:
        return len(self.stamps_s)

    @classmethod
    def from_poses(cls, stamps_s: np.ndarray, poses_se3: np.ndarray | Sequence[np.ndarray]) -> Trajectory:
        """A trajectory from 4x4 poses ``T_world_body`` (N, 4, 4)."""
        T = np.asarray(poses_se3, dtype=float).reshape(-1, 4, 4)
        quats = np.array([matrix_to_quat_wxyz(Ti[:3, :3]) for Ti in T]).reshape(-1, 4)
        return cls(np.asarray(stamps_s, dtype=float), T[:, :3, 3].copy(), quats)

    def rotations(self) -> np.ndarray:
        """Rotation matrices ``R_world_body`` (N, 3, 3) of the (normalised) quaternions."""
        q = self.orientations_quat_wxyz / np.linalg.norm(self.orientations_quat_wxyz, axis=1, keepdims=True)
        w, x, y, z = q.T
        R = np.empty((len(q), 3, 3))
        R[:, 0, 0], R[:, 0, 1], R[:, 0, 2] = 1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)
        R[:, 1, 0], R[:, 1, 1], R[:, 1, 2] = 2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)
        R[:, 2, 0], R[:, 2, 1], R[:, 2, 2] = 2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)
        return R

    def poses_se3(self) -> np.ndarray:
        """Poses ``T_world_body`` as an (N, 4, 4) array."""
        T = np.zeros((len(self), 4, 4))
        T[:, :3, :3] = self.rotations()
        T[:, :3, 3] = self.positions_xyz
        T[:, 3, 3] = 1.0
        return T

    def path_length_m(self) -> float:
        """Arc length of the positions, m."""
        return float(np.linalg.norm(np.diff(self.positions_xyz, axis=0), axis=1).sum()) if len(self) > 1 else 0.0

    def subset(self, ids: Sequence[int] | np.ndarray) -> Trajectory:
        """The poses at ``ids`` (in that order, repeats allowed)."""
        ids = np.asarray(ids, dtype=int)
        return Trajectory(self.stamps_s[ids], self.positions_xyz[ids], self.orientations_quat_wxyz[ids])

    def transformed(self, R: np.ndarray, t: np.ndarray, scale: float = 1.0) -> Trajectory:
        """The trajectory mapped by ``p -> R (scale p) + t``, orientations ``R R_world_body``."""
        R = np.asarray(R, dtype=float)
        q_R = matrix_to_quat_wxyz(R)
        q = quat_multiply(q_R, self.orientations_quat_wxyz)
        return Trajectory(self.stamps_s.copy(), (scale * self.positions_xyz) @ R.T + np.asarray(t, dtype=float), q)


def umeyama_alignment(src: np.ndarray, dst: np.ndarray, with_scale: bool = False,
                      allow_collinear: bool = False) -> tuple[np.ndarray, np.ndarray, float]:
    """``(R, t, s)`` minimising ``sum |dst_i - (s R src_i + t)|^2`` for points (N, 3) (Umeyama 1991).

    ``s`` is 1 unless ``with_scale``. Raises :class:`ConfigError` when the points are collinear
    (the rotation about their line is not determined), as evo does; with ``allow_collinear`` it
    returns one of the minimisers instead (for drawing: every one moves the points alike).
    """
    x, y = np.asarray(src, dtype=float), np.asarray(dst, dtype=float)
    if x.shape != y.shape or x.ndim != 2:
        raise ConfigError("umeyama.dst", y.shape, f"the shape of src {x.shape}, (N, dim)")
    n, m = x.shape
    mean_x, mean_y = x.mean(axis=0), y.mean(axis=0)
    xc, yc = x - mean_x, y - mean_y
    sigma_x = float(np.sum(xc * xc)) / n
    cov = yc.T @ xc / n
    u, d, vt = np.linalg.svd(cov)
    if np.count_nonzero(d > np.finfo(d.dtype).eps) < m - 1 and not allow_collinear:
        raise ConfigError("umeyama.src", f"{n} points of rank {np.count_nonzero(d > np.finfo(d.dtype).eps)}",
                          f"points spanning at least {m - 1} dimensions (not collinear)")
    S = np.eye(m)
    if np.linalg.det(u) * np.linalg.det(vt) < 0.0:
        S[m - 1, m - 1] = -1.0  # a rotation, not a reflection
    R = u @ S @ vt
    s = float(np.trace(np.diag(d) @ S) / sigma_x) if with_scale else 1.0
    t = mean_y - s * (R @ mean_x)
    return R, t, s


def align(est: Trajectory, ref: Trajectory, correct_scale: bool = False) -> Trajectory:
    """``est`` moved by the Umeyama fit of its positions onto ``ref``'s (same length, associated)."""
    if len(est) != len(ref):
        raise ConfigError("align.est", f"{len(est)} poses", f"as many poses as ref ({len(ref)}); associate first")
    R, t, s = umeyama_alignment(est.positions_xyz, ref.positions_xyz, with_scale=correct_scale)
    return est.transformed(R, t, s)


def _matching_time_indices(stamps_1: np.ndarray, stamps_2: np.ndarray, max_diff: float) -> tuple[list[int], list[int]]:
    """For each stamp of ``stamps_1`` the nearest of ``stamps_2`` within ``max_diff`` (evo's rule)."""
    ids_1: list[int] = []
    ids_2: list[int] = []
    if not np.all(np.diff(stamps_2) >= 0):
        for i, s1 in enumerate(stamps_1):
            diffs = np.abs(stamps_2 - s1)
            j = int(np.argmin(diffs))
            if diffs[j] <= max_diff:
                ids_1.append(i)
                ids_2.append(j)
        return ids_1, ids_2
    for i, s1 in enumerate(stamps_1):
        if s1 < stamps_2[0] - max_diff or s1 > stamps_2[-1] + max_diff:
            continue
        j = min(int(np.searchsorted(stamps_2, s1, side="right")), len(stamps_2) - 1)
        diff_ub = stamps_2[j] - s1
        diff_lb = s1 - stamps_2[j - 1] if j > 0 else math.inf
        if diff_ub <= max_diff and diff_ub < diff_lb:
            ids_1.append(i)
            ids_2.append(j)
        elif diff_lb <= max_diff and diff_lb <= diff_ub:
            ids_1.append(i)
            ids_2.append(j - 1)
    return ids_1, ids_2


def associate(est: Trajectory, ref: Trajectory, max_diff_s: float = 0.01) -> tuple[Trajectory, Trajectory]:
    """``(est, ref)`` reduced to pairs of poses with stamps within ``max_diff_s`` (evo's association).

    Every pose of the trajectory with fewer poses is matched to the nearest stamp of the other;
    a pose of the longer one may be used twice, as in evo.
    """
    if not max_diff_s >= 0:
        raise ConfigError("associate.max_diff_s", max_diff_s, "max_diff_s >= 0")
    est_longer = len(est) > len(ref)  # evo's traj_1 is ref, traj_2 est
    short, long = (ref, est) if est_longer else (est, ref)
    ids_short, ids_long = _matching_time_indices(short.stamps_s, long.stamps_s, float(max_diff_s))
    if not ids_short:
        raise ConfigError("associate.max_diff_s", max_diff_s, "a time tolerance that matches at least one pair of stamps")
    short_sync, long_sync = short.subset(ids_short), long.subset(ids_long)
    return (long_sync, short_sync) if est_longer else (short_sync, long_sync)


def error_statistics(errors: np.ndarray) -> dict[str, float]:
    """rmse, mean, median, std, min, max and sse of per-pair errors (evo's ``get_all_statistics``)."""
    e = np.asarray(errors, dtype=float)
    if e.size == 0:
        return {k: math.nan for k in STAT_KEYS}
    sq = e * e
    return {
        "rmse": math.sqrt(float(np.mean(sq))),
        "mean": float(np.mean(e)),
        "median": float(np.median(e)),
        "std": float(np.std(e)),
        "min": float(np.min(e)),
        "max": float(np.max(e)),
        "sse": float(np.sum(sq)),
    }


def ate_errors(est: Trajectory, ref: Trajectory, align: bool = True, correct_scale: bool = False,
               max_diff_s: float = 0.01) -> np.ndarray:
    """Per associated pose ``|p_est - p_ref|`` after (optional) Umeyama alignment, m."""
    est_s, ref_s = associate(est, ref, max_diff_s)
    if align or correct_scale:
        R, t, s = umeyama_alignment(est_s.positions_xyz, ref_s.positions_xyz, with_scale=correct_scale)
        p_est = (s * est_s.positions_xyz) @ R.T + t
    else:
        p_est = est_s.positions_xyz
    return np.linalg.norm(p_est - ref_s.positions_xyz, axis=1)


def ate(est: Trajectory, ref: Trajectory, align: bool = True, correct_scale: bool = False,
        max_diff_s: float = 0.01) -> dict[str, float]:
    """Absolute trajectory error statistics (evo APE, translation part), m (sse m^2)."""
    return error_statistics(ate_errors(est, ref, align, correct_scale, max_diff_s))


def _pairs_by_frames(n: int, delta: int, all_pairs: bool) -> list[tuple[int, int]]:
    if all_pairs:
        return [(i, i + delta) for i in range(n - delta)]
    ids = list(range(0, n, delta))
    return list(zip(ids, ids[1:]))


def _pairs_by_path(positions: np.ndarray, delta_m: float, tol_m: float, all_pairs: bool) -> list[tuple[int, int]]:
    steps = np.linalg.norm(np.diff(positions, axis=0), axis=1)
    if all_pairs:
        dist = np.concatenate(([0.0], np.cumsum(steps)))
        pairs = []
        for i in range(len(dist) - 1):
            ahead = dist[i + 1:] - dist[i]
            k = int(np.argmin(np.abs(ahead - delta_m)))
            if abs(ahead[k] - delta_m) <= tol_m:
                pairs.append((i, i + 1 + k))
        return pairs
    ids, travelled = [0], 0.0
    for i, step in enumerate(steps, start=1):
        travelled += float(step)
        if travelled >= delta_m:
            ids.append(i)
            travelled = 0.0
    return list(zip(ids, ids[1:]))


def rpe_errors(est: Trajectory, ref: Trajectory, delta: float = 1, delta_unit: str = "frames",
               all_pairs: bool = False, max_diff_s: float = 0.01, rel_delta_tol: float = 0.1) -> np.ndarray:
    """Per pose pair the translation norm of the relative pose error, m (see module docstring).

    Pairs are chosen on the estimate as evo does: ``delta`` frames apart, or (``delta_unit="m"``)
    each time the estimate has travelled ``delta`` metres (``all_pairs``: from every pose, the
    pose whose path distance is nearest ``delta``, within ``rel_delta_tol * delta``).
    """
    est_s, ref_s = associate(est, ref, max_diff_s)
    if delta_unit == "frames":
        if not (delta >= 1 and float(delta).is_integer()):
            raise ConfigError("rpe.delta", delta, "an integer >= 1 for delta_unit 'frames'")
        pairs = _pairs_by_frames(len(est_s), int(delta), all_pairs)
    elif delta_unit == "m":
        if not delta > 0:
            raise ConfigError("rpe.delta", delta, "delta > 0 for delta_unit 'm'")
        pairs = _pairs_by_path(est_s.positions_xyz, float(delta), float(delta) * rel_delta_tol, all_pairs)
    else:
        raise ConfigError("rpe.delta_unit", delta_unit, "'frames' or 'm'")
    if not pairs:
        raise ConfigError("rpe.delta", delta, f"a delta giving at least one pair among {len(est_s)} poses")
    i, j = np.array(pairs).T
    Q, P = ref_s.poses_se3(), est_s.poses_se3()
    Q_rel = _relative(Q[i], Q[j])
    P_rel = _relative(P[i], P[j])
    E = _relative(Q_rel, P_rel)
    return np.linalg.norm(E[:, :3, 3], axis=1)


def _relative(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """``A^-1 B`` for stacks of rigid 4x4 transforms."""
    RtA = np.transpose(A[:, :3, :3], (0, 2, 1))
    out = np.zeros_like(B)
    out[:, :3, :3] = RtA @ B[:, :3, :3]
    out[:, :3, 3] = np.einsum("nij,nj->ni", RtA, B[:, :3, 3] - A[:, :3, 3])
    out[:, 3, 3] = 1.0
    return out


def rpe(est: Trajectory, ref: Trajectory, delta: float = 1, delta_unit: str = "frames",
        all_pairs: bool = False, max_diff_s: float = 0.01) -> dict[str, float]:
    """Relative pose error statistics (evo RPE, translation part), m (sse m^2)."""
    return error_statistics(rpe_errors(est, ref, delta, delta_unit, all_pairs, max_diff_s))


def drift_per_metre(est: Trajectory, ref: Trajectory, max_diff_s: float = 0.01) -> float:
    """End-point position error per metre of reference path after aligning the first poses, m/m.

    NaN when the associated reference path has zero length.
    """
    est_s, ref_s = associate(est, ref, max_diff_s)
    T_ref0, T_est0 = ref_s.poses_se3()[0], est_s.poses_se3()[0]
    R = T_ref0[:3, :3] @ T_est0[:3, :3].T
    t = T_ref0[:3, 3] - R @ T_est0[:3, 3]
    end_err = float(np.linalg.norm(R @ est_s.positions_xyz[-1] + t - ref_s.positions_xyz[-1]))
    length = ref_s.path_length_m()
    return end_err / length if length > 0 else math.nan


LOOP_KEYS = ("te_m", "oe_rad", "tve_x_m", "tve_y_m", "tve_z_m")


def loop_errors(est: Trajectory, in_start_frame: bool = False) -> dict[str, float]:
    """TE (m), OE (rad) and TVE (x, y, z, m) between the last and the first pose of a loop.

    TVE = t_f - t_i in the trajectory's frame (as the thesis computes it), or in the axes of the
    first pose with ``in_start_frame``; TE = |TVE|; OE = angle of ``q_i^-1 * q_f`` in [0, pi].
    """
    if len(est) < 2:
        raise ConfigError("loop_errors.est", f"{len(est)} poses", "at least 2 poses")
    R = est.rotations()
    tve = est.positions_xyz[-1] - est.positions_xyz[0]
    if in_start_frame:
        tve = R[0].T @ tve
    q_i, q_f = (q / np.linalg.norm(q) for q in (est.orientations_quat_wxyz[0], est.orientations_quat_wxyz[-1]))
    q_i_inv = q_i * np.array([1.0, -1.0, -1.0, -1.0])
    q_r = quat_multiply(q_i_inv, q_f)
    oe = 2.0 * math.atan2(float(np.linalg.norm(q_r[1:])), abs(float(q_r[0])))
    return {"te_m": float(np.linalg.norm(tve)), "oe_rad": oe,
            "tve_x_m": float(tve[0]), "tve_y_m": float(tve[1]), "tve_z_m": float(tve[2])}


def loop_errors_rmse(runs: Sequence[dict[str, float]]) -> dict[str, float]:
    """RMSE over runs of each loop error (thesis Table 5.4: TE, OE, TVE x y z)."""
    if not runs:
        return {k: math.nan for k in LOOP_KEYS}
    return {k: math.sqrt(float(np.mean([float(r[k]) ** 2 for r in runs]))) for k in LOOP_KEYS}


def time_per_scan_ms(compute_time_s: Sequence[float] | np.ndarray) -> float:
    """Median compute time per scan (or frame), ms; NaN when there is none."""
    t = np.asarray(compute_time_s, dtype=float)
    t = t[np.isfinite(t)]
    return float(np.median(t) * 1e3) if t.size else math.nan


def _fmt(values: np.ndarray) -> str:
    return " ".join(repr(float(v)) for v in values)


def write_tum(traj: Trajectory, path: str | os.PathLike) -> None:
    """Write ``timestamp tx ty tz qx qy qz qw`` lines (quaternion xyzw in the file) after a header."""
    q_xyzw = np.roll(traj.orientations_quat_wxyz, -1, axis=1)
    rows = np.column_stack([traj.stamps_s, traj.positions_xyz, q_xyzw])
    lines = ["# timestamp tx ty tz qx qy qz qw"] + [_fmt(r) for r in rows]
    with open(path, "w", encoding="utf-8") as f:
        f.write("\n".join(lines) + "\n")


def read_tum(path: str | os.PathLike) -> Trajectory:
    """Read a TUM file (``#`` comments and blank lines skipped; separators spaces or commas)."""
    rows = []
    with open(path, encoding="utf-8") as f:
        for k, line in enumerate(f, start=1):
            line = line.strip()
            if not line or line.startswith("#"):
                continue
            fields = line.replace(",", " ").split()
            if len(fields) != 8:
                raise ConfigError(f"tum.line{k}", line, "8 numbers: timestamp tx ty tz qx qy qz qw")
            rows.append([float(v) for v in fields])
    mat = np.array(rows, dtype=float).reshape(-1, 8)
    return Trajectory(mat[:, 0], mat[:, 1:4], np.roll(mat[:, 4:8], 1, axis=1))


def write_kitti(traj: Trajectory, path: str | os.PathLike) -> None:
    """Write the first three rows of each pose matrix, 12 numbers per line (no stamps, no header)."""
    flat = traj.poses_se3()[:, :3, :].reshape(-1, 12)
    with open(path, "w", encoding="utf-8") as f:
        f.write("".join(_fmt(r) + "\n" for r in flat))


def read_kitti(path: str | os.PathLike, stamps_s: np.ndarray | None = None) -> Trajectory:
    """Read a KITTI pose file; stamps default to the line index (0, 1, 2, ...)."""
    rows = []
    with open(path, encoding="utf-8") as f:
        for k, line in enumerate(f, start=1):
            fields = line.split()
            if not fields or fields[0].startswith("#"):
                continue
            if len(fields) != 12:
                raise ConfigError(f"kitti.line{k}", line.strip(), "12 numbers of a 3x4 pose matrix")
            rows.append([float(v) for v in fields])
    mat = np.array(rows, dtype=float).reshape(-1, 12)
    T = np.tile(np.eye(4), (len(mat), 1, 1))
    T[:, :3, :] = mat.reshape(-1, 3, 4)
    stamps = np.arange(len(mat), dtype=float) if stamps_s is None else np.asarray(stamps_s, dtype=float)
    if len(stamps) != len(mat):
        raise ConfigError("read_kitti.stamps_s", f"{len(stamps)} stamps", f"{len(mat)} stamps, one per pose")
    return Trajectory.from_poses(stamps, T)
