"""Scoring of a :class:`FilterEstimate` against the true kind of every LiDAR point (lidar-filter track).

Masks are matched to scans by stamp, not by position. Per point the truth (:func:`..office_walks.point_classes`) says genuine (a real surface on the
straight ray, also through glass), glass (the pane's own weak reflection) or ghost (a surface
seen in a mirror or pane, reported along the original ray), and whether a genuine point lies on
a ground surface (SceneTruth kinds ``ground``, ``tread``, ``landing``, ``ramp``). Points the
sensor reported as NaN (``ReturnKind.NAN``, a sensor fault) are counted (``n_nan``) and left out of
every fraction, whether the filter keeps or removes them. Pooled over all scans of the episode:

- ``spurious_removed_frac``: glass + ghost points removed / glass + ghost points (NaN if none);
- ``ground_kept_frac``: genuine ground points kept / genuine ground points;
- ``glass_removed_frac``, ``ghost_removed_frac``, ``genuine_kept_frac``,
  ``nonground_kept_frac`` (genuine points off the ground kept), ``kept_frac`` (all points but NaN);
- counts ``n_points`` (NaN included), ``n_glass``, ``n_ghost``, ``n_ground``, ``n_nan``; ``bad_masks`` (scans whose mask
  is missing or of the wrong length; any makes the estimate fail, fractions NaN);
- ``time_per_scan_ms``: median compute time per scan.

Points the scan itself holds as NaN (a faulty driver) were never measured: they count neither as
kept nor as removed, nor in ``n_points``; the filter's own counts (``FilterEstimate.stats``,
e.g. ``empty_scans``) are reported as ``stat_*``. A repeated or out-of-order scan, which a
pipeline does not use (:mod:`exobench.core.counters`), is not scored: each instant once.

Through odometry (Table 5.4 layout, when asked): kiss-icp on the kept points, scored by
:func:`..lidar_trajectory.score_trajectory` with the keys prefixed ``odom_`` (``odom_te_m``, ``odom_oe_rad``,
``odom_tve_{x,y,z}_m``, ``odom_ate_m``, ``odom_rpe_m``, ...). KISS-ICP registers as the thesis ran it,
with one of its two downsamplings removed (the scoring setting ``odometry_downsample``, ``"single"``
by default; :class:`~exobench.mapping.odometry.kiss_icp.KissConfig`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from exobench.core.counters import admitted
from exobench.core.episode import Episode
from exobench.core.estimates import FilterEstimate

from ... import trajectory as tj
from ..office_walks import GENUINE, GHOST, GLASS, NAN_POINT, lidar_pairs, point_classes

COUNT_KEYS = ("n_points", "n_glass", "n_ghost", "n_ground", "n_nan", "bad_masks")
FRACTION_KEYS = ("spurious_removed_frac", "ground_kept_frac", "glass_removed_frac", "ghost_removed_frac",
                 "genuine_kept_frac", "nonground_kept_frac", "kept_frac")  # fmt: skip
ODOM_KEYS = ("odom_te_m", "odom_oe_rad", "odom_tve_x_m", "odom_tve_y_m", "odom_tve_z_m", "odom_ate_m", "odom_rpe_m",
             "odom_drift_per_m", "odom_time_per_scan_ms")  # fmt: skip


def failure_metrics(episode: Episode | None, reason: str) -> dict[str, Any]:
    out: dict[str, Any] = {k: math.nan for k in (*FRACTION_KEYS, *COUNT_KEYS, *ODOM_KEYS, "time_per_scan_ms")}
    out.update(failed=True, failed_reason=reason)
    return out


def _frac(num: int, den: int) -> float:
    return num / den if den else math.nan


def mask_fractions(classes: Sequence[np.ndarray], ground: Sequence[np.ndarray], keep: Sequence[np.ndarray],
                   measured: Sequence[np.ndarray] | None = None) -> dict[str, Any]:
    """The fractions and counts of the module docstring from per-scan classes, ground flags and
    keep masks (a mask of the wrong length, or missing, removes every point of its scan).
    ``measured`` (per scan, per point; None: all) marks the points that are not, the scan's NaN
    points, as NaN points (``n_nan``), which every fraction leaves out."""
    c_all, g_all, k_all = [], [], []
    bad = 0
    for i, (c, g) in enumerate(zip(classes, ground, strict=True)):
        k = np.asarray(keep[i], dtype=bool).reshape(-1) if i < len(keep) else None
        if k is None or len(k) != len(c):
            bad += 1
            k = np.zeros(len(c), dtype=bool)
        c, g = np.array(c, copy=True), np.array(g, dtype=bool, copy=True)
        if measured is not None:  # a point the scan reports as NaN is a NaN point, whatever its truth
            m = np.asarray(measured[i], dtype=bool).reshape(-1)
            c[~m], g[~m] = NAN_POINT, False
        c_all.append(c)
        g_all.append(g)
        k_all.append(k)
    c = np.concatenate(c_all) if c_all else np.zeros(0, dtype=int)
    g = np.concatenate(g_all) if g_all else np.zeros(0, dtype=bool)
    k = np.concatenate(k_all) if k_all else np.zeros(0, dtype=bool)
    spur = (c == GLASS) | (c == GHOST)
    gen = c == GENUINE
    real = c != NAN_POINT

    def n(mask: np.ndarray) -> int:
        return int(np.count_nonzero(mask))

    return {
        "spurious_removed_frac": _frac(n(spur & ~k), n(spur)),
        "ground_kept_frac": _frac(n(g & k), n(g)),
        "glass_removed_frac": _frac(n((c == GLASS) & ~k), n(c == GLASS)),
        "ghost_removed_frac": _frac(n((c == GHOST) & ~k), n(c == GHOST)),
        "genuine_kept_frac": _frac(n(gen & k), n(gen)),
        "nonground_kept_frac": _frac(n(gen & ~g & k), n(gen & ~g)),
        "kept_frac": _frac(n(k & real), n(real)),
        "n_points": len(c), "n_glass": n(c == GLASS), "n_ghost": n(c == GHOST), "n_ground": n(g), "n_nan": n(~real),
        "bad_masks": bad,
    }  # fmt: skip


def scored_pairs(episode: Episode) -> list[tuple[Any, Any]]:
    """:func:`..office_walks.lidar_pairs` of the scans a pipeline uses (not repeated, in order)."""
    used = {id(f) for f, ok in zip(episode.frames, admitted(episode.frames), strict=True) if ok}
    return [(s, t) for s, t in lidar_pairs(episode) if id(s) in used]


def kiss_on_kept(episode: Episode, keep: Sequence[np.ndarray], downsample: str = "single") -> Any:
    """kiss-icp's :class:`TrajectoryEstimate` on the kept points of every scan of :func:`scored_pairs`."""
    from exobench.mapping.odometry.kiss_icp import KissConfig, run_kiss_icp

    scans = [s for s, _ in scored_pairs(episode)]
    return run_kiss_icp(scans, keep, KissConfig(downsample=downsample))


def kiss_trajectories(episode: Episode, estimates: Mapping[str, Any], downsample: str = "single") -> dict[str, Any]:
    """``kiss-icp+<name>`` -> :func:`kiss_on_kept` of each estimate whose masks fit every scan
    (those :func:`score_filter` scores through odometry)."""
    pairs = scored_pairs(episode)
    out = {}
    for name, est in estimates.items():
        if not isinstance(est, FilterEstimate) or not pairs:
            continue
        try:
            masks, _ = masks_by_scan(pairs, est)
        except ValueError:
            continue
        if all(m is not None and len(m) == len(s.points_xyz) for m, (s, _) in zip(masks, pairs, strict=True)):
            out[f"kiss-icp+{name}"] = kiss_on_kept(episode, masks, downsample)
    return out


def odometry_through_filter(episode: Episode, keep: Sequence[np.ndarray], downsample: str = "single") -> dict[str, Any]:
    """kiss-icp on the kept points of every scan (:func:`kiss_on_kept`), scored as the odometry
    track does: the ``odom_`` metrics."""
    from ..lidar_trajectory import score_trajectory

    est = kiss_on_kept(episode, keep, downsample)
    m = score_trajectory(episode, est)
    out = {f"odom_{k}": m.get(k, math.nan) for k in ("te_m", "oe_rad", "tve_x_m", "tve_y_m", "tve_z_m", "ate_m", "rpe_m",
                                                     "drift_per_m", "time_per_scan_ms")}  # fmt: skip
    out["odom_failures"] = m.get("failures", math.nan)
    return out


def masks_by_scan(pairs: Sequence[tuple[Any, Any]], est: FilterEstimate) -> tuple[list[np.ndarray | None], int]:
    """Each scan's mask, matched by stamp so that a dropped or empty scan shifts nothing: (one mask
    or None per scan of ``pairs``, the number of masks that match no scan). A
    :class:`FilterEstimate` carries no sensor ids: masks of one stamp go to that stamp's scans
    (of any sensor) in order."""
    stamps = np.asarray(est.stamps_s, dtype=float).reshape(-1)
    keep = list(est.keep)
    if len(stamps) != len(keep):
        raise ValueError(f"{len(stamps)} stamps for {len(keep)} masks")
    free: dict[float, list[int]] = {}
    for i, t in enumerate(stamps):
        free.setdefault(round(float(t), 9), []).append(i)
    out: list[np.ndarray | None] = []
    for scan, _ in pairs:
        cands = free.get(round(float(scan.stamp_s), 9), [])
        out.append(np.asarray(keep[cands.pop(0)], dtype=bool).reshape(-1) if cands else None)
    return out, sum(len(v) for v in free.values())


def score_filter(episode: Episode, est: FilterEstimate, *, odometry: bool = False,
                 downsample: str = "single") -> dict[str, Any]:
    """The metrics of the module docstring (never raises on a bad estimate); with ``odometry``
    also through kiss-icp registering with ``downsample``.

    A scan without a mask of its length is never scored as filtered: when any scan has none
    (no masks at all, masks for another sensor or other stamps), the estimate fails with the
    count in its reason and NaN fractions.
    """
    try:
        pairs = scored_pairs(episode)
        if not pairs:
            return failure_metrics(episode, "the episode has no LiDAR scan with point truth")
        classes, ground, measured = [], [], []
        for scan, truth in pairs:
            c, g = point_classes(episode, truth)
            classes.append(c)
            ground.append(g)
            p = np.asarray(scan.points_xyz, dtype=float).reshape(-1, 3)
            measured.append(np.all(np.isfinite(p), axis=1) if len(p) == len(c) else np.ones(len(c), dtype=bool))
        masks, unmatched = masks_by_scan(pairs, est)
        bad = sum(m is None or len(m) != len(c) for m, c in zip(masks, classes, strict=True))
        if bad:
            out = failure_metrics(
                episode,
                f"{bad} of {len(pairs)} scans have no mask of their length ({len(est.keep)} masks, {unmatched} match no scan)",
            )
            out.update({k: v for k, v in mask_fractions(classes, ground, []).items() if k in COUNT_KEYS})
            out["bad_masks"] = bad
            return out
        keep = [m for m in masks if m is not None]
        out: dict[str, Any] = {"failed": False, "failed_reason": ""}
        out.update(mask_fractions(classes, ground, keep, measured))
        if not any(math.isfinite(out[k]) for k in FRACTION_KEYS):  # e.g. every return NaN: nothing was filtered
            out.update(failed=True, failed_reason=f"no point to score: {out['n_nan']} of {out['n_points']} points are NaN")
        stats = est.stats if isinstance(est.stats, dict) else {}
        out.update({f"stat_{k}": v for k, v in stats.items() if isinstance(v, (int, float)) and not isinstance(v, bool)})
        out["time_per_scan_ms"] = tj.time_per_scan_ms(est.time_per_scan_s)
        if unmatched:
            note = f"{unmatched} masks match no scan (ignored)"
            out["failed_reason"] = f"{out['failed_reason']}; {note}" if out["failed_reason"] else note
        out.update({k: math.nan for k in ODOM_KEYS})
        if odometry:
            out.update(odometry_through_filter(episode, keep, downsample))
        return out
    except Exception as e:  # a scorer never raises on an estimate
        return failure_metrics(episode, f"scoring raised {type(e).__name__}: {e}")
