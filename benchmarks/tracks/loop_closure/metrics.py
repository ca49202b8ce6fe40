"""Scoring of place recognition against the true trajectory (seeds/003 section 5.2.3, eq. 5.3).

Pure functions over arrays, so each can be checked against a hand-computed case:

- :func:`keyframe_poses`: the true position and yaw of each keyframe from
  ``EpisodeTruth.trajectory_w`` (the LiDAR pose at each scan start; a keyframe's stamp is its
  scan's ``sweep_start_s``, matched to the nearest row).
- :func:`eligible_pairs`: candidate ``j`` is eligible for query ``k`` when it is earlier by at
  least ``exclude_recent_s`` (the thesis' condition (1), "excluding the most recent ``xi``
  keyframes", stated in time so that it does not depend on a pipeline's keyframe rate).
- :func:`true_loops`: condition (3): keyframe ``k`` has a true loop when an eligible earlier
  keyframe lies within ``revisit_m`` (5 m).
- :func:`pr_curve`: for each threshold ``tau`` on the match distance (``1 - sim``; a detection
  at ``tau`` is a match with distance ``<= tau`` to an eligible keyframe), the thesis'
  classification of each keyframe: TP when the match is within ``revisit_m`` (conditions 1, 2),
  FP when it is not, FN when there is no detection but a true loop (condition 3), TN otherwise;
  ``P = TP / (TP + FP)`` and ``R = TP / (TP + FN)`` (eq. 5.3). A match with a too-recent
  keyframe is no detection (condition 1 fails). The thresholds are every distinct distance, so
  the curve is exact.
- :func:`max_recall_at_full_precision`, :func:`pr_auc` (area under the step-wise PR curve from
  recall 0: ``sum (R_n - R_(n-1)) P_n``, average precision as scikit-learn computes it),
  :func:`best_f1`.
- :func:`score_place_recognition`: every metric of one estimate (the track's scorer) from the
  above; :func:`failure_metrics` for a failed pipeline or simulation.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from exobench.core.episode import Episode
from exobench.core.estimates import PlaceRecognitionEstimate

REVISIT_M = 5.0  # a revisit: an earlier keyframe within this distance (the thesis' 5 m)
EXCLUDE_RECENT_S = 20.0  # keyframes younger than this are no revisit (the thesis' xi, in time)

__all__ = [
    "EXCLUDE_RECENT_S",
    "PRCurve",
    "REVISIT_M",
    "best_f1",
    "eligible_pairs",
    "failure_metrics",
    "keyframe_poses",
    "max_recall_at_full_precision",
    "pr_auc",
    "pr_curve",
    "score_place_recognition",
    "true_loops",
    "wrap_angle",
    "yaw_errors",
]


def wrap_angle(a: np.ndarray | float) -> np.ndarray:
    """Angles wrapped to (-pi, pi]."""
    return np.pi - np.mod(np.pi - np.asarray(a, dtype=float), 2.0 * np.pi)


def keyframe_poses(trajectory_w: np.ndarray, stamps_s: np.ndarray, tol_s: float = 0.051) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(position (K, 3), yaw (K,), found (K,))`` of each keyframe from the nearest trajectory row.

    ``trajectory_w`` rows are ``[t, x, y, z, qw, qx, qy, qz]``; a stamp farther than ``tol_s``
    from every row is not found (NaN pose).
    """
    tr = np.asarray(trajectory_w, dtype=float).reshape(-1, 8)
    st = np.asarray(stamps_s, dtype=float).reshape(-1)
    pos = np.full((len(st), 3), np.nan)
    yaw = np.full(len(st), np.nan)
    found = np.zeros(len(st), dtype=bool)
    if len(tr) == 0 or len(st) == 0:
        return pos, yaw, found
    order = np.argsort(tr[:, 0], kind="stable")
    t = tr[order, 0]
    i = np.clip(np.searchsorted(t, st), 1, max(1, len(t) - 1)) if len(t) > 1 else np.zeros(len(st), dtype=int)
    if len(t) > 1:
        i = np.where(np.abs(t[i - 1] - st) <= np.abs(t[i] - st), i - 1, i)
    rows = tr[order[i]]
    found = np.isfinite(st) & (np.abs(rows[:, 0] - st) <= tol_s)
    pos[found] = rows[found, 1:4]
    qw, qx, qy, qz = rows[:, 4], rows[:, 5], rows[:, 6], rows[:, 7]
    y = np.arctan2(2.0 * (qw * qz + qx * qy), 1.0 - 2.0 * (qy * qy + qz * qz))
    yaw[found] = y[found]
    return pos, yaw, found


def eligible_pairs(stamps_s: np.ndarray, exclude_recent_s: float) -> np.ndarray:
    """``E[k, j]``: keyframe ``j`` may be matched by ``k`` (``t_k - t_j >= exclude_recent_s``), (K, K)."""
    t = np.asarray(stamps_s, dtype=float).reshape(-1)
    return (t[:, None] - t[None, :]) >= exclude_recent_s


def true_loops(positions: np.ndarray, stamps_s: np.ndarray, revisit_m: float, exclude_recent_s: float) -> np.ndarray:
    """Condition (3): an eligible earlier keyframe lies within ``revisit_m``, (K,) bool."""
    p = np.asarray(positions, dtype=float).reshape(-1, 3)
    d = np.linalg.norm(p[:, None, :] - p[None, :, :], axis=2)
    with np.errstate(invalid="ignore"):
        near = d <= revisit_m
    return np.any(near & eligible_pairs(stamps_s, exclude_recent_s), axis=1)


@dataclass(frozen=True)
class PRCurve:
    """Counts and rates at each threshold (ascending), plus the per-keyframe classification inputs.

    Attributes:
        tau: thresholds on the match distance, (T,).
        tp, fp, fn: counts at each threshold, (T,).
        precision, recall: eq. (5.3) (precision 1 when nothing is detected), (T,).
        n_keyframes: keyframes scored. n_loops: keyframes with a true loop (condition 3).
        n_detectable: keyframes with an eligible match (a detection at some threshold).
        correct: per keyframe, the match is within ``revisit_m`` (False without a match), (K,).
    """

    tau: np.ndarray
    tp: np.ndarray
    fp: np.ndarray
    fn: np.ndarray
    precision: np.ndarray
    recall: np.ndarray
    n_keyframes: int
    n_loops: int
    n_detectable: int
    correct: np.ndarray


def pr_curve(
    positions: np.ndarray,
    stamps_s: np.ndarray,
    match_index: np.ndarray,
    distance: np.ndarray,
    *,
    revisit_m: float = 5.0,
    exclude_recent_s: float = 20.0,
) -> PRCurve:
    """The precision-recall curve over every distinct match distance (see the module docstring)."""
    p = np.asarray(positions, dtype=float).reshape(-1, 3)
    t = np.asarray(stamps_s, dtype=float).reshape(-1)
    m = np.asarray(match_index, dtype=np.int64).reshape(-1)
    d = np.asarray(distance, dtype=float).reshape(-1)
    K = len(t)
    loops = true_loops(p, t, revisit_m, exclude_recent_s)
    valid = (m >= 0) & (m < K) & np.isfinite(d)
    mm = np.where(valid, m, 0)
    valid &= (t - t[mm]) >= exclude_recent_s
    gap = np.linalg.norm(p - p[mm], axis=1)
    with np.errstate(invalid="ignore"):
        correct = valid & (gap <= revisit_m)
    taus = np.unique(d[valid])
    if len(taus) == 0:
        taus = np.array([math.inf])
    det = valid[None, :] & (d[None, :] <= taus[:, None])  # (T, K)
    tp = np.sum(det & correct[None, :], axis=1)
    fp = np.sum(det & ~correct[None, :], axis=1)
    fn = np.sum(~det & loops[None, :], axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        precision = np.where(tp + fp > 0, tp / np.maximum(tp + fp, 1), 1.0)
        recall = np.where(tp + fn > 0, tp / np.maximum(tp + fn, 1), 0.0)
    return PRCurve(taus, tp, fp, fn, precision.astype(float), recall.astype(float), K, int(loops.sum()),
                   int(valid.sum()), correct)  # fmt: skip


def max_recall_at_full_precision(curve: PRCurve) -> float:
    """Largest recall at a threshold with no false positive and at least one true positive (0 if none)."""
    ok = (curve.fp == 0) & (curve.tp > 0)
    return float(curve.recall[ok].max()) if np.any(ok) else 0.0


def pr_auc(curve: PRCurve) -> float:
    """Area under the step-wise PR curve from recall 0 (average precision); NaN without true loops."""
    if curve.n_loops == 0:
        return math.nan
    r = np.concatenate([[0.0], curve.recall])
    return float(np.sum(np.diff(r) * curve.precision))


def best_f1(curve: PRCurve) -> tuple[float, float]:
    """``(F1, tau)`` at the threshold with the highest F1 (first on ties); ``(0, nan)`` without TP."""
    p, r = curve.precision, curve.recall
    with np.errstate(invalid="ignore", divide="ignore"):
        f = np.where(p + r > 0, 2 * p * r / np.where(p + r > 0, p + r, 1.0), 0.0)
    f = np.where(curve.tp > 0, f, 0.0)
    if not np.any(f > 0):
        return 0.0, math.nan
    k = int(np.argmax(f))
    return float(f[k]), float(curve.tau[k])


def yaw_errors(yaw_true: np.ndarray, match_index: np.ndarray, yaw_est: np.ndarray, correct: np.ndarray) -> np.ndarray:
    """|wrap(estimated - true)| of the relative yaw of the correct matches, rad.

    The column shift's convention (:class:`~exobench.perception.place_recognition.scan_context.PlaceMatch`): the
    query cloud is the match's cloud rotated by ``yaw_est``, i.e. ``yaw_est = yaw_match - yaw_query``.
    """
    y = np.asarray(yaw_true, dtype=float).reshape(-1)
    m = np.asarray(match_index, dtype=np.int64).reshape(-1)
    c = np.asarray(correct, dtype=bool).reshape(-1) & (m >= 0)
    k = np.flatnonzero(c)
    return np.abs(wrap_angle(np.asarray(yaw_est, dtype=float)[k] - (y[m[k]] - y[k])))


def _nan_metrics() -> dict[str, Any]:
    keys = ("max_recall_at_full_precision", "pr_auc", "best_f1", "tau_best_f1", "time_per_keyframe_ms",
            "n_keyframes", "n_revisits", "n_detectable", "invalid_keyframes",
            "yaw_error_deg", "correct_match_fraction")  # fmt: skip
    return {k: math.nan for k in keys}


def failure_metrics(episode: Episode | None, reason: str) -> dict[str, Any]:
    """Metrics of a failed pipeline or simulation: every key of a scored estimate, NaN (counts
    included: unknown) or an empty PR curve."""
    return {"failed": True, "failed_reason": reason, **_nan_metrics(), "pr_tau": [], "pr_precision": [], "pr_recall": []}


def score_place_recognition(episode: Episode, estimate: PlaceRecognitionEstimate, *, revisit_m: float = REVISIT_M,
                            exclude_recent_s: float = EXCLUDE_RECENT_S) -> dict[str, Any]:
    """Every metric of one estimate (see the module docstring) under the scoring settings
    ``revisit_m`` and ``exclude_recent_s``; never raises on a bad estimate."""
    revisit, exclude = float(revisit_m), float(exclude_recent_s)
    stamps = np.asarray(estimate.stamps_s, dtype=float).reshape(-1)
    K = len(stamps)
    arrays = [np.asarray(a).reshape(-1) for a in (estimate.match_index, estimate.distance, estimate.yaw_rad, estimate.time_per_keyframe_s)]
    if any(len(a) != K for a in arrays):
        return failure_metrics(episode, "estimate arrays of different lengths")
    match, dist, yaw_est, times = arrays
    if K == 0:  # nothing described: not a perfect (empty) PR curve
        return failure_metrics(episode, "no keyframes")
    pos, yaw, found = keyframe_poses(episode.truth.trajectory_w, stamps)
    if K and not np.all(found):
        return failure_metrics(episode, f"{int(np.sum(~found))} keyframe stamps match no scan start")
    curve = pr_curve(pos, stamps, match, dist, revisit_m=revisit, exclude_recent_s=exclude)
    f1, tau = best_f1(curve)
    yerr = yaw_errors(yaw, match, yaw_est, curve.correct)
    has_loop = curve.n_loops
    correct_frac = float(np.sum(curve.correct) / has_loop) if has_loop else math.nan
    stats = estimate.stats or {}
    out = {
        "failed": False,
        "max_recall_at_full_precision": max_recall_at_full_precision(curve),
        "pr_auc": pr_auc(curve),
        "best_f1": f1,
        "tau_best_f1": tau,
        "time_per_keyframe_ms": float(np.mean(times) * 1000.0) if K else math.nan,
        "n_keyframes": K,
        "n_revisits": has_loop,
        "n_detectable": curve.n_detectable,
        "invalid_keyframes": int(stats.get("invalid_keyframes", int(np.sum(match < 0)))),
        "correct_match_fraction": correct_frac,
        "yaw_error_deg": float(np.degrees(np.median(yerr))) if len(yerr) else math.nan,
        "pr_tau": np.round(curve.tau, 6).tolist(),
        "pr_precision": np.round(curve.precision, 6).tolist(),
        "pr_recall": np.round(curve.recall, 6).tolist(),
    }
    if out["invalid_keyframes"] >= K:  # no descriptor at all (e.g. every return NaN): recall 0 measures nothing
        out.update({k: math.nan for k in ("max_recall_at_full_precision", "pr_auc", "best_f1", "tau_best_f1")})
        out.update(failed=True, failed_reason=f"every keyframe is invalid ({out['invalid_keyframes']} of {K}): nothing to match")
    return out
