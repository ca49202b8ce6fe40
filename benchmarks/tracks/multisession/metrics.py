"""Scoring of change detection and of the merged map (seeds/000 Exp B, Table II; Exp C, Table III).

Pure functions over point sets (map frame, m), each checkable on a hand-computed case.

Change detection as the paper scores it, a classification of the output's points with a 5 cm
association (:data:`ASSOCIATION_M`): each output point is associated with the nearest true
surface sample within 5 cm, changed or static (a tie goes to the changed one). A point *detected
changed* (added or removed) is a true positive when that sample is a truly changed one, a false
positive when it is a static one; a point *detected static* (kept in the map, unflagged) is a
false negative, or a true negative, likewise. A point near neither is not associated and not
counted. The nearest sample, not "any changed sample within 5 cm": the floor around a box's foot
or the wall behind it lies within 5 cm of the box's lowest or rearmost samples, and would count
as missed change wherever a map keeps it, though the truth has it static (docs/tracks/multisession.md).

- :func:`change_confusion`: those counts, over the truly changed areas (the paper restricts
  the evaluation to them, since merging also flags misaligned points elsewhere): only points
  within :data:`CHANGE_AREA_M` of a truly changed sample are counted; ``area_m=None`` counts the
  whole map.
- :func:`change_precision`, :func:`change_recall`, :func:`change_f1` (over the changed areas) and
  :func:`change_precision_whole_map`, :func:`change_recall_whole_map`.
- :func:`change_chamfer_m`: symmetric Chamfer distance between the detected changes (in the
  changed areas) and the truly changed samples, the mean of the two directed mean
  nearest-neighbour distances (a distance in m, as the paper's 0.034-0.043 m).
- :func:`map_errors`, :func:`map_error_metrics`: point-to-point distance of each merged-map
  point to the nearest true surface sample; mean, median, 90th percentile and max
  (``map_error_mean_m``, ``map_error_median_m``, ``map_error_p90_m``, ``map_error_max_m``).

An undefined ratio (no detection for a precision, no truly changed point for a recall) is NaN.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

ASSOCIATION_M = 0.05  # the paper's 5 cm association of predicted and true changes
CHANGE_AREA_M = 0.3  # a point belongs to a truly changed area within this of a changed sample

__all__ = [
    "ASSOCIATION_M",
    "CHANGE_AREA_M",
    "ChangeConfusion",
    "change_chamfer_m",
    "change_confusion",
    "change_f1",
    "change_precision",
    "change_precision_whole_map",
    "change_recall",
    "change_recall_whole_map",
    "error_metrics",
    "map_error_metrics",
    "map_errors",
]


@dataclass(frozen=True)
class ChangeConfusion:
    """Point counts of the change classification (module docstring)."""

    tp: int
    fp: int
    fn: int
    tn: int

    @property
    def precision(self) -> float:
        return self.tp / (self.tp + self.fp) if self.tp + self.fp else float("nan")

    @property
    def recall(self) -> float:
        return self.tp / (self.tp + self.fn) if self.tp + self.fn else float("nan")

    @property
    def f1(self) -> float:
        p, r = self.precision, self.recall
        if np.isnan(p) or np.isnan(r):
            return float("nan")
        return 2 * p * r / (p + r) if p + r else 0.0


def _pts(points: np.ndarray) -> np.ndarray:
    a = np.asarray(points, dtype=float)
    return a.reshape(-1, 3) if a.size else np.zeros((0, 3))


def _within(points: np.ndarray, reference: np.ndarray, radius_m: float) -> np.ndarray:
    """Whether each point has a reference point within ``radius_m``."""
    if not len(points) or not len(reference):
        return np.zeros(len(points), dtype=bool)
    return cKDTree(reference).query(points, k=1, distance_upper_bound=radius_m)[0] <= radius_m


def _nearest(points: np.ndarray, reference: np.ndarray) -> np.ndarray:
    return cKDTree(reference).query(points, k=1)[0]


def change_confusion(detected_changed: np.ndarray, detected_static: np.ndarray, true_changed: np.ndarray,
                     true_static: np.ndarray | tuple[np.ndarray, ...], association_m: float = ASSOCIATION_M,
                     area_m: float | None = CHANGE_AREA_M) -> ChangeConfusion:
    """TP, FP, FN, TN of the detected changed and static points against the true changed and
    static surface samples (module docstring); ``area_m`` None scores the whole map.
    ``true_static`` may be a tuple of sample sets (the days' surfaces, each a building's worth):
    the nearest of them all, without joining them."""
    dc, ds, tc = (_pts(a) for a in (detected_changed, detected_static, true_changed))
    ts = tuple(_pts(a) for a in true_static) if isinstance(true_static, tuple) else (_pts(true_static),)
    if area_m is not None:
        dc = dc[_within(dc, tc, area_m)]
        ds = ds[_within(ds, tc, area_m)]
    points = np.concatenate([dc, ds])
    changed, static = _associate(points, tc, ts, association_m)
    k = len(dc)
    return ChangeConfusion(int(changed[:k].sum()), int(static[:k].sum()), int(changed[k:].sum()), int(static[k:].sum()))


def _distance(points: np.ndarray, reference: np.ndarray, radius_m: float) -> np.ndarray:
    """Distance of each point to its nearest reference point, inf beyond ``radius_m``. Where
    the points' bounding box grown by the radius holds few of the reference points (a changed
    area's against a building's samples) only those go into the tree: the others are farther
    than the radius from every point."""
    if len(points) and len(reference):
        lo, hi = points.min(axis=0) - radius_m, points.max(axis=0) + radius_m
        box = np.all((reference >= lo) & (reference <= hi), axis=1)
        if 2 * np.count_nonzero(box) < len(box):  # else the copy would cost more than it saves
            reference = reference[box]
    if not len(points) or not len(reference):
        return np.full(len(points), np.inf)
    return cKDTree(reference).query(points, k=1, distance_upper_bound=radius_m)[0]


def _associate(points: np.ndarray, true_changed: np.ndarray, true_static: tuple[np.ndarray, ...],
               radius_m: float) -> tuple[np.ndarray, np.ndarray]:
    """Whether each point's nearest sample within ``radius_m`` is a changed one (ties: changed)
    or a static one (the nearest of the sets of ``true_static``); neither when no sample is that near."""
    d_changed = _distance(points, true_changed, radius_m)
    d_static = np.full(len(points), np.inf)
    for part in true_static:  # one tree at a time
        d_static = np.minimum(d_static, _distance(points, part, radius_m))
    changed = np.isfinite(d_changed) & (d_changed <= d_static)
    return changed, ~changed & np.isfinite(d_static)


def change_precision(detected_changed: np.ndarray, detected_static: np.ndarray, true_changed: np.ndarray,
                     true_static: np.ndarray) -> float:
    """``TP / (TP + FP)`` over the truly changed areas."""
    return change_confusion(detected_changed, detected_static, true_changed, true_static).precision


def change_recall(detected_changed: np.ndarray, detected_static: np.ndarray, true_changed: np.ndarray,
                  true_static: np.ndarray) -> float:
    """``TP / (TP + FN)`` over the truly changed areas."""
    return change_confusion(detected_changed, detected_static, true_changed, true_static).recall


def change_f1(detected_changed: np.ndarray, detected_static: np.ndarray, true_changed: np.ndarray,
              true_static: np.ndarray) -> float:
    """F-score of :func:`change_precision` and :func:`change_recall`."""
    return change_confusion(detected_changed, detected_static, true_changed, true_static).f1


def change_precision_whole_map(detected_changed: np.ndarray, detected_static: np.ndarray, true_changed: np.ndarray,
                               true_static: np.ndarray) -> float:
    """``TP / (TP + FP)`` over the whole map."""
    return change_confusion(detected_changed, detected_static, true_changed, true_static, area_m=None).precision


def change_recall_whole_map(detected_changed: np.ndarray, detected_static: np.ndarray, true_changed: np.ndarray,
                            true_static: np.ndarray) -> float:
    """``TP / (TP + FN)`` over the whole map."""
    return change_confusion(detected_changed, detected_static, true_changed, true_static, area_m=None).recall


def change_chamfer_m(detected_changed: np.ndarray, true_changed: np.ndarray, area_m: float | None = CHANGE_AREA_M) -> float:
    """Symmetric Chamfer distance (m) between detected changes inside the truly changed areas and
    the truly changed samples: ``(mean_d min_t |d - t| + mean_t min_d |t - d|) / 2``; NaN when
    either set is empty."""
    dc, tc = _pts(detected_changed), _pts(true_changed)
    if area_m is not None:
        dc = dc[_within(dc, tc, area_m)]
    if not len(dc) or not len(tc):
        return float("nan")
    return float(0.5 * (_nearest(dc, tc).mean() + _nearest(tc, dc).mean()))


def map_errors(map_points: np.ndarray, true_surface: np.ndarray) -> np.ndarray:
    """Distance (m) of each map point to the nearest true surface sample."""
    mp, ts = _pts(map_points), _pts(true_surface)
    if not len(ts):
        return np.full(len(mp), np.nan)
    return _nearest(mp, ts) if len(mp) else np.zeros(0)


def map_error_metrics(map_points: np.ndarray, true_surface: np.ndarray) -> dict[str, float]:
    """``map_error_mean_m``, ``_median_m``, ``_p90_m``, ``_max_m`` of :func:`map_errors` (Table III);
    NaN for an empty map."""
    return error_metrics(map_errors(map_points, true_surface))


def error_metrics(e: np.ndarray) -> dict[str, float]:
    """The four figures of :func:`map_error_metrics` of errors ``e`` (NaN for none)."""
    if not len(e):
        nan = float("nan")
        return {"map_error_mean_m": nan, "map_error_median_m": nan, "map_error_p90_m": nan, "map_error_max_m": nan}
    return {"map_error_mean_m": float(np.mean(e)), "map_error_median_m": float(np.median(e)),
            "map_error_p90_m": float(np.percentile(e, 90)), "map_error_max_m": float(np.max(e))}
