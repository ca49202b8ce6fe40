"""The multisession track's scorer: a :class:`~exobench.core.estimates.MultiSessionEstimate`
against the episode's truth (:mod:`.episodes`), with the point-set metrics of :mod:`.metrics`.

- ``ate_m``: RMS of the keyframe camera positions of the sessions merged into the main map, in
  session 0's frame as the truth places it (``T_world_estimator``: no alignment, so session
  0's own drift counts too), against the true positions at the keyframes' stamps.
- ``ate_aligned_m``: the same positions after the rigid motion that fits them best onto the
  truth (SE(3), Umeyama; :func:`aligned_rmse`): Table I's "ATE ... of the aligned
  trajectories", as the vio track's ``ate_m``. What it leaves is the merged map's shape error;
  what ``ate_m`` adds is where the anchoring session's drift put the whole map, which no
  inter-session edge observes (docs/tracks/multisession.md, *Exo*).
- ``rpe_1m_m``: RMS over keyframe pairs of one session 1 m of true path apart (the first
  keyframe at least 1 m further) of the error of the second's position seen from the first.
- Changes (Table II): each change run (a session against the map updated by those before it)
  whose days differ is scored against the truth of the days between (the appeared and
  disappeared samples of days ``d_prior + 1 .. d`` on the changed objects, :func:`true_changes`;
  each point associated with its nearest true sample, :mod:`.metrics`); detected changed = removed and added points,
  detected static = the rest of the updated map (``static_masks``); true static = the surfaces of both days; the
  point counts are summed over the runs, Chamfer is the mean over runs of the Chamfer distance
  between the detected changes and the true changed samples that the sessions observed (a map
  point within 5 cm; the paper annotated changes in its recordings).
- Map error (Table III): the merged map against the last day's true surfaces; the same of the
  map without change detection (every session's points) and of the last session alone.
- ``n_separate_sessions``: sessions kept out of the main map (overlapping none of it, or joined
  to it by no two agreeing inter-session edges): out of the ATE and the map figures, in the RPE
  (within their own maps);
  ``merge_time_s``, ``peak_memory_mb``: the pipeline's own figures.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from exobench.core.episode import Episode
from exobench.core.estimates import MultiSessionEstimate

from .metrics import (
    ASSOCIATION_M,
    ChangeConfusion,
    change_chamfer_m,
    change_confusion,
    error_metrics,
    map_errors,
)

METRICS = (
    "ate_m", "ate_aligned_m", "rpe_1m_m", "change_precision", "change_recall", "change_f1", "change_chamfer_m",
    "change_precision_whole_map", "change_recall_whole_map", "map_error_mean_m", "map_error_median_m",
    "map_error_p90_m", "map_error_max_m", "map_error_mean_m_no_change_detection", "map_error_mean_m_single_session",
    "merge_time_s", "peak_memory_mb", "n_sessions", "n_separate_sessions", "n_inter_edges", "n_keyframes",
    "n_change_runs",
)  # fmt: skip
RPE_DISTANCE_M = 1.0


def failure_metrics(episode: Episode | None, reason: str) -> dict[str, Any]:
    """Every metric NaN, with the reason."""
    return {"failed": True, "failed_reason": reason, **{m: float("nan") for m in METRICS}}


def _near(points: np.ndarray, reference: np.ndarray, radius_m: float) -> np.ndarray:
    from scipy.spatial import cKDTree

    if not len(points) or not len(reference):
        return np.zeros(len(points), dtype=bool)
    return cKDTree(reference).query(points, k=1, distance_upper_bound=radius_m)[0] <= radius_m


def _to_world(T_we: np.ndarray, points: np.ndarray) -> np.ndarray:
    p = np.asarray(points, dtype=float).reshape(-1, 3)
    return p @ T_we[:3, :3].T + T_we[:3, 3]


def true_keyframe_poses(camera_w: np.ndarray, stamps: np.ndarray) -> np.ndarray:
    """True camera positions (N, 3) at the stamps: the nearest true camera instant."""
    t = camera_w[:, 0]
    idx = np.clip(np.searchsorted(t, stamps), 1, len(t) - 1)
    idx = np.where(np.abs(t[idx - 1] - stamps) <= np.abs(t[idx] - stamps), idx - 1, idx)
    return camera_w[idx, 1:4]


def aligned_rmse(p_est: np.ndarray, p_true: np.ndarray) -> float:
    """RMS of ``|R p_est + t - p_true|`` at the rigid motion ``(R, t)`` that minimises it.

    Umeyama's (1991) closed form of the minimum, ``var_true + var_est - 2 tr(D S)``: the value is
    the same for every minimising rotation, so it is defined where the rotation is not (a straight
    walk leaves the roll about its line free, and :func:`~exobench.benchmarks.trajectory.umeyama_alignment`
    refuses collinear points, as evo does)."""
    x, y = np.asarray(p_est, dtype=float).reshape(-1, 3), np.asarray(p_true, dtype=float).reshape(-1, 3)
    if not len(x):
        return float("nan")
    xc, yc = x - x.mean(axis=0), y - y.mean(axis=0)
    u, d, vt = np.linalg.svd(yc.T @ xc / len(x))
    sign = np.ones(3)
    if np.linalg.det(u) * np.linalg.det(vt) < 0.0:
        sign[2] = -1.0  # a rotation, not a reflection
    var = float(np.mean(np.sum(xc * xc, axis=1)) + np.mean(np.sum(yc * yc, axis=1)))
    return float(np.sqrt(max(var - 2.0 * float(np.sum(d * sign)), 0.0)))


def rpe_errors(est_T: np.ndarray, true_p: np.ndarray, true_T_rot: np.ndarray, distance_m: float = RPE_DISTANCE_M) -> np.ndarray:
    """Position error of keyframe j seen from keyframe i, for each i and the first j at least
    ``distance_m`` of true path further (:mod:`module docstring <.scoring>`)."""
    cum = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(true_p, axis=0), axis=1))])
    out = []
    for i in range(len(true_p)):
        j = int(np.searchsorted(cum, cum[i] + distance_m))
        if j >= len(true_p):
            break
        d_est = est_T[i][:3, :3].T @ (est_T[j][:3, 3] - est_T[i][:3, 3])
        d_true = true_T_rot[i].T @ (true_p[j] - true_p[i])
        out.append(float(np.linalg.norm(d_est - d_true)))
    return np.asarray(out)


def _quat_to_R(q: np.ndarray) -> np.ndarray:
    from exobench.core.transforms import quat_wxyz_to_matrix

    return np.stack([quat_wxyz_to_matrix(x) for x in q])


def score_multisession(episode: Episode, est: MultiSessionEstimate) -> dict[str, Any]:
    """Every metric of one estimate (module docstring); never raises on a bad estimate."""
    truth = episode.truth.extra
    T_we = np.asarray(episode.truth.T_world_estimator, dtype=float)
    sessions = {s["session"]: s for s in truth["sessions"]}
    n = len(est.sessions)
    if not n:
        return failure_metrics(episode, "no session with a keyframe")
    for name in ("days", "keyframe_stamps_s", "T_map_cam", "map_of_session"):
        if len(getattr(est, name)) != n:
            return failure_metrics(episode, f"estimate.{name} has {len(getattr(est, name))} entries for {n} sessions")
    if any(s not in sessions for s in est.sessions):
        return failure_metrics(episode, f"estimate sessions {list(est.sessions)} not of the episode {sorted(sessions)}")
    ate_sq, rpe, est_p, true_p = [], [], [], []
    for s, stamps, T_map, m in zip(est.sessions, est.keyframe_stamps_s, est.T_map_cam, est.map_of_session):
        cam = np.asarray(sessions[s]["camera_w"], dtype=float)
        stamps = np.asarray(stamps, dtype=float).reshape(-1)
        T_map = np.asarray(T_map, dtype=float).reshape(-1, 4, 4)
        if len(stamps) != len(T_map):
            return failure_metrics(episode, f"session {s}: {len(stamps)} keyframe stamps, {len(T_map)} poses")
        p_true = true_keyframe_poses(cam, stamps)
        if m == 0:
            T_w = T_we @ T_map
            ate_sq.append(np.sum((T_w[:, :3, 3] - p_true) ** 2, axis=1))
            est_p.append(T_w[:, :3, 3])
            true_p.append(p_true)
        t = cam[:, 0]
        idx = np.clip(np.searchsorted(t, stamps), 0, len(t) - 1)
        rpe.append(rpe_errors(T_map, p_true, _quat_to_R(cam[idx, 4:8])))
    ate = np.concatenate(ate_sq) if ate_sq else np.zeros(0)
    rp = np.concatenate(rpe) if rpe else np.zeros(0)
    out: dict[str, Any] = {
        "failed": False,
        "ate_m": float(np.sqrt(np.mean(ate))) if len(ate) else float("nan"),
        "ate_aligned_m": aligned_rmse(np.concatenate(est_p), np.concatenate(true_p)) if est_p else float("nan"),
        "rpe_1m_m": float(np.sqrt(np.mean(rp ** 2))) if len(rp) else float("nan"),
        **change_metrics(episode, est, T_we),
    }
    maps = {
        "": est.merged_map_points, "_no_change_detection": est.map_points_no_change_detection,
        "_single_session": est.map_points_single_session,
    }  # fmt: skip
    surface = np.asarray(truth["surface_last_day"], dtype=float)
    pw = {suffix: _to_world(T_we, pts) for suffix, pts in maps.items()}
    # one tree of the surfaces (a building's, millions of samples) for the three maps
    every = map_errors(np.concatenate(list(pw.values())), surface)
    start = 0
    for suffix, p in pw.items():
        e, start = every[start:start + len(p)], start + len(p)
        if suffix:
            out[f"map_error_mean_m{suffix}"] = float(np.mean(e)) if len(e) else float("nan")
        else:
            out.update(error_metrics(e))
    out.update({
        "merge_time_s": float(est.merge_time_s), "peak_memory_mb": float(est.peak_memory_mb), "n_sessions": n,
        "n_separate_sessions": len(est.separate_sessions), "n_inter_edges": len(est.inter_edges),
        "n_keyframes": int(sum(len(s) for s in est.keyframe_stamps_s)),
        "separate_sessions": [int(s) for s in est.separate_sessions],
    })  # fmt: skip
    return out


def true_changes(truth: dict[str, Any], day_prior: int, day: int) -> np.ndarray:
    """The appeared and disappeared samples of days ``day_prior + 1 .. day`` on the changed
    objects (world, m): object-level change, as the paper annotated it. A static surface that an
    object covered or uncovered (the floor under a box put down) keeps its occupancy on both days
    and no camera of the later session sees it: it is no change (truth recorded before the
    ``*_on_object`` flags: every sample)."""
    parts = []
    for d in range(day_prior + 1, day + 1):
        if d not in truth["changes"]:
            continue
        for kind in ("appeared", "disappeared"):
            pts = np.asarray(truth["changes"][d][kind], dtype=float).reshape(-1, 3)
            on = truth["changes"][d].get(f"{kind}_on_object")
            parts.append(pts if on is None else pts[np.asarray(on, dtype=bool).reshape(-1)])
    return np.concatenate(parts) if parts else np.zeros((0, 3))


def change_metrics(episode: Episode, est: MultiSessionEstimate, T_we: np.ndarray) -> dict[str, float]:
    """Table II's figures summed over the change runs between different days (module docstring)."""
    truth = episode.truth.extra
    day_of = dict(zip(est.sessions, est.days))
    area, whole = ChangeConfusion(0, 0, 0, 0), ChangeConfusion(0, 0, 0, 0)
    chamfers, runs = [], 0
    if not (len(est.change_pairs) == len(est.removed_points) == len(est.added_points) == len(est.static_masks)):
        raise ValueError("change_pairs, removed_points, added_points and static_masks differ in length")
    every = np.asarray(est.map_points_no_change_detection, dtype=float).reshape(-1, 3)
    for (a, b), rem, add, mask in zip(est.change_pairs, est.removed_points, est.added_points, est.static_masks):
        mask = np.asarray(mask, dtype=bool).reshape(-1)
        if mask.shape != (len(every),):
            raise ValueError(f"static mask of {mask.shape[0]} flags for {len(every)} map points")
        stat = every[mask]
        da, db = day_of.get(a, -1), day_of.get(b, -1)
        if da < 0 or db <= da:
            continue
        tc = true_changes(truth, da, db)
        surf = truth["surfaces_by_day"]
        ts = tuple(np.asarray(surf[d], dtype=float) for d in (da, db) if d in surf)  # not joined: a building each
        dc = _to_world(T_we, np.concatenate([np.asarray(rem).reshape(-1, 3), np.asarray(add).reshape(-1, 3)]))
        ds = _to_world(T_we, stat)
        c1, c2 = change_confusion(dc, ds, tc, ts), change_confusion(dc, ds, tc, ts, area_m=None)
        area = ChangeConfusion(area.tp + c1.tp, area.fp + c1.fp, area.fn + c1.fn, area.tn + c1.tn)
        whole = ChangeConfusion(whole.tp + c2.tp, whole.fp + c2.fp, whole.fn + c2.fn, whole.tn + c2.tn)
        # Chamfer over the changes the two sessions observed: true samples with a map point within
        # 5 cm (the paper annotated changes in what was recorded); unobserved ones count nowhere
        seen = tc[_near(tc, np.concatenate([dc, ds]), ASSOCIATION_M)]
        chamfers.append(change_chamfer_m(dc, seen))
        runs += 1
    ch = [c for c in chamfers if np.isfinite(c)]
    return {
        "change_precision": area.precision, "change_recall": area.recall, "change_f1": area.f1,
        "change_chamfer_m": float(np.mean(ch)) if ch else float("nan"),
        "change_precision_whole_map": whole.precision, "change_recall_whole_map": whole.recall,
        "n_change_runs": runs,
    }  # fmt: skip
