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
import weakref
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from exobench.core.counters import admitted
from exobench.core.episode import Episode
from exobench.core.estimates import FilterEstimate
from exobench.core.limits import finite_rows

from ... import trajectory as tj
from ..office_walks import GENUINE, GHOST, GLASS, NAN_POINT, lidar_pairs, point_classes
from ..scan_spool import ScanPairs

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


class MaskTally:
    """The counts behind :func:`mask_fractions`, summed scan by scan (:meth:`add`), so that an
    episode is scored without holding its scans: the same integers, the same fractions."""

    def __init__(self) -> None:
        self.n = dict.fromkeys(("points", "spur", "spur_removed", "ground", "ground_kept", "glass", "glass_removed",
                                "ghost", "ghost_removed", "gen", "gen_kept", "nonground", "nonground_kept", "real",
                                "real_kept", "bad"), 0)  # fmt: skip

    def add(self, c: np.ndarray, g: np.ndarray, k: np.ndarray | None, m: np.ndarray | None = None) -> None:
        """One scan: classes ``c``, ground flags ``g``, keep mask ``k`` (missing or of the wrong
        length: a bad mask, every point removed), measured flags ``m`` (None: all)."""
        k = None if k is None else np.asarray(k, dtype=bool).reshape(-1)
        if k is None or len(k) != len(c):
            self.n["bad"] += 1
            k = np.zeros(len(c), dtype=bool)
        c, g = np.array(c, copy=True), np.array(g, dtype=bool, copy=True)
        if m is not None:  # a point the scan reports as NaN is a NaN point, whatever its truth
            m = np.asarray(m, dtype=bool).reshape(-1)
            c[~m], g[~m] = NAN_POINT, False
        spur = (c == GLASS) | (c == GHOST)
        gen = c == GENUINE
        real = c != NAN_POINT
        glass, ghost = c == GLASS, c == GHOST
        n = self.n
        for key, mask in (("spur", spur), ("ground", g), ("glass", glass), ("ghost", ghost), ("gen", gen),
                          ("nonground", gen & ~g), ("real", real)):  # fmt: skip
            n[key] += int(np.count_nonzero(mask))
        for key, mask in (("spur_removed", spur & ~k), ("ground_kept", g & k), ("glass_removed", glass & ~k),
                          ("ghost_removed", ghost & ~k), ("gen_kept", gen & k), ("nonground_kept", gen & ~g & k),
                          ("real_kept", k & real)):  # fmt: skip
            n[key] += int(np.count_nonzero(mask))
        n["points"] += len(c)

    def metrics(self) -> dict[str, Any]:
        """The fractions and counts of the module docstring."""
        n = self.n
        return {
            "spurious_removed_frac": _frac(n["spur_removed"], n["spur"]),
            "ground_kept_frac": _frac(n["ground_kept"], n["ground"]),
            "glass_removed_frac": _frac(n["glass_removed"], n["glass"]),
            "ghost_removed_frac": _frac(n["ghost_removed"], n["ghost"]),
            "genuine_kept_frac": _frac(n["gen_kept"], n["gen"]),
            "nonground_kept_frac": _frac(n["nonground_kept"], n["nonground"]),
            "kept_frac": _frac(n["real_kept"], n["real"]),
            "n_points": n["points"], "n_glass": n["glass"], "n_ghost": n["ghost"], "n_ground": n["ground"],
            "n_nan": n["points"] - n["real"], "bad_masks": n["bad"],
        }  # fmt: skip


def mask_fractions(classes: Sequence[np.ndarray], ground: Sequence[np.ndarray], keep: Sequence[np.ndarray],
                   measured: Sequence[np.ndarray] | None = None) -> dict[str, Any]:
    """The fractions and counts of the module docstring from per-scan classes, ground flags and
    keep masks (a mask of the wrong length, or missing, removes every point of its scan).
    ``measured`` (per scan, per point; None: all) marks the points that are not, the scan's NaN
    points, as NaN points (``n_nan``), which every fraction leaves out."""
    tally = MaskTally()
    for i, (c, g) in enumerate(zip(classes, ground, strict=True)):
        tally.add(c, g, keep[i] if i < len(keep) else None, None if measured is None else measured[i])
    return tally.metrics()


def scored_pairs(episode: Episode) -> ScanPairs:
    """:func:`..office_walks.lidar_pairs` of the scans a pipeline uses (not repeated, in order),
    read on demand when the episode was streamed."""
    if episode.truth.lidar_scans is not None:
        pairs = lidar_pairs(episode)
        return pairs.select(pairs.used) if isinstance(pairs, ScanPairs) else ScanPairs.of(pairs)
    used = {id(f) for f, ok in zip(episode.frames, admitted(episode.frames), strict=True) if ok}
    return ScanPairs.of([(s, t) for s, t in lidar_pairs(episode) if id(s) in used])


def _kiss(downsample: str) -> Any:
    from exobench.mapping.odometry.kiss_icp import KissConfig, KissOdometry

    return KissOdometry(KissConfig(downsample=downsample))


# KISS-ICP's trajectory on an estimate's kept points as score_filter registered them: the figure
# and the recording of the same episode take it from here instead of registering every scan
# again (KISS-ICP is deterministic: the same poses; that second pass was a fifth of a paper
# episode's time). Held only while the estimate lives.
_SCORED_ODOMETRY: weakref.WeakKeyDictionary[FilterEstimate, tuple[Any, str, Any]] = weakref.WeakKeyDictionary()


def scored_odometry(episode: Episode, est: Any, downsample: str) -> Any:
    """The trajectory :func:`score_filter` registered for ``est`` on ``episode`` with
    ``downsample``, or None when it did not (not scored, another episode or downsampling)."""
    try:
        got = _SCORED_ODOMETRY.get(est)
    except TypeError:  # not weakly referable: never stored
        return None
    if got is None or got[0]() is not episode or got[1] != downsample:
        return None
    return got[2]


def kiss_on_kept(episode: Episode, keep: Sequence[np.ndarray], downsample: str = "single",
                 pairs: ScanPairs | None = None) -> Any:
    """kiss-icp's :class:`TrajectoryEstimate` on the kept points of every scan of
    :func:`scored_pairs` (or of ``pairs``, when given), one scan read at a time (as
    :func:`~exobench.mapping.odometry.kiss_icp.run_kiss_icp` registers them)."""
    from exobench.mapping.odometry.kiss_icp import KissConfig, run_kiss_icp

    scans = (s for s, _ in (scored_pairs(episode) if pairs is None else pairs))
    return run_kiss_icp(scans, keep, KissConfig(downsample=downsample))


def kiss_trajectories(episode: Episode, estimates: Mapping[str, Any], downsample: str = "single") -> dict[str, Any]:
    """``kiss-icp+<name>`` -> :func:`kiss_on_kept` of each estimate whose masks fit every scan
    (those :func:`score_filter` scores through odometry)."""
    pairs = scored_pairs(episode)
    out = {}
    for name, est in estimates.items():
        if not isinstance(est, FilterEstimate) or not len(pairs):
            continue
        try:
            masks, _ = masks_by_scan(pairs.stamps_s, est)
        except ValueError:
            continue
        if all(m is not None and len(m) == n for m, n in zip(masks, pairs.n_points, strict=True)):
            traj = scored_odometry(episode, est, downsample)
            out[f"kiss-icp+{name}"] = traj if traj is not None else kiss_on_kept(episode, masks, downsample, pairs)
    return out


def _odom_metrics(episode: Episode, est: Any) -> dict[str, Any]:
    """kiss-icp's trajectory scored as the odometry track does: the ``odom_`` metrics."""
    from ..lidar_trajectory import score_trajectory

    m = score_trajectory(episode, est)
    out = {f"odom_{k}": m.get(k, math.nan) for k in ("te_m", "oe_rad", "tve_x_m", "tve_y_m", "tve_z_m", "ate_m", "rpe_m",
                                                     "drift_per_m", "time_per_scan_ms")}  # fmt: skip
    out["odom_failures"] = m.get("failures", math.nan)
    return out


def odometry_through_filter(episode: Episode, keep: Sequence[np.ndarray], downsample: str = "single") -> dict[str, Any]:
    """kiss-icp on the kept points of every scan (:func:`kiss_on_kept`), scored as the odometry
    track does: the ``odom_`` metrics."""
    return _odom_metrics(episode, kiss_on_kept(episode, keep, downsample))


def masks_by_scan(stamps_s: Sequence[float], est: FilterEstimate) -> tuple[list[np.ndarray | None], int]:
    """Each scan's mask (the scans' stamps ``stamps_s``, in order), matched by stamp so that a
    dropped or empty scan shifts nothing: (one mask or None per scan, the number of masks that
    match no scan). A :class:`FilterEstimate` carries no sensor ids: masks of one stamp go to
    that stamp's scans (of any sensor) in order."""
    stamps = np.asarray(est.stamps_s, dtype=float).reshape(-1)
    keep = list(est.keep)
    if len(stamps) != len(keep):
        raise ValueError(f"{len(stamps)} stamps for {len(keep)} masks")
    free: dict[float, list[int]] = {}
    for i, t in enumerate(stamps):
        free.setdefault(round(float(t), 9), []).append(i)
    out: list[np.ndarray | None] = []
    for stamp in stamps_s:
        cands = free.get(round(float(stamp), 9), [])
        out.append(np.asarray(keep[cands.pop(0)], dtype=bool).reshape(-1) if cands else None)
    return out, sum(len(v) for v in free.values())


def score_filter(episode: Episode, est: FilterEstimate, *, odometry: bool = False,
                 downsample: str = "single") -> dict[str, Any]:
    """The metrics of the module docstring (never raises on a bad estimate); with ``odometry``
    also through kiss-icp registering with ``downsample``.

    A scan without a mask of its length is never scored as filtered: when any scan has none
    (no masks at all, masks for another sensor or other stamps), the estimate fails with the
    count in its reason and NaN fractions.

    One pass over the scans, each read once (from the spool of a streamed episode): its
    classes are counted (:class:`MaskTally`) and, with ``odometry``, its kept points registered.
    """
    try:
        pairs = scored_pairs(episode)
        if not len(pairs):
            return failure_metrics(episode, "the episode has no LiDAR scan with point truth")
        masks, unmatched = masks_by_scan(pairs.stamps_s, est)
        bad = sum(m is None or len(m) != n for m, n in zip(masks, pairs.n_points, strict=True))
        tally = MaskTally()
        odo = _kiss(downsample) if odometry and not bad else None
        for (scan, truth), mask in zip(pairs, masks, strict=True):
            c, g = point_classes(episode, truth)
            if bad:  # only the counts are reported, over the truth alone
                tally.add(c, g, None)
                continue
            p = np.asarray(scan.points_xyz, dtype=float).reshape(-1, 3)
            tally.add(c, g, mask, finite_rows(p) if len(p) == len(c) else np.ones(len(c), dtype=bool))
            if odo is not None:
                odo.add(scan, mask)
        if bad:
            out = failure_metrics(
                episode,
                f"{bad} of {len(pairs)} scans have no mask of their length ({len(est.keep)} masks, {unmatched} match no scan)",
            )
            out.update({k: v for k, v in tally.metrics().items() if k in COUNT_KEYS})
            out["bad_masks"] = bad
            return out
        out: dict[str, Any] = {"failed": False, "failed_reason": ""}
        out.update(tally.metrics())
        if not any(math.isfinite(out[k]) for k in FRACTION_KEYS):  # e.g. every return NaN: nothing was filtered
            out.update(failed=True, failed_reason=f"no point to score: {out['n_nan']} of {out['n_points']} points are NaN")
        stats = est.stats if isinstance(est.stats, dict) else {}
        out.update({f"stat_{k}": v for k, v in stats.items() if isinstance(v, (int, float)) and not isinstance(v, bool)})
        out["time_per_scan_ms"] = tj.time_per_scan_ms(est.time_per_scan_s)
        if unmatched:
            note = f"{unmatched} masks match no scan (ignored)"
            out["failed_reason"] = f"{out['failed_reason']}; {note}" if out["failed_reason"] else note
        out.update({k: math.nan for k in ODOM_KEYS})
        if odo is not None:
            traj = odo.estimate()
            _SCORED_ODOMETRY[est] = (weakref.ref(episode), downsample, traj)
            out.update(_odom_metrics(episode, traj))
        return out
    except Exception as e:  # a scorer never raises on an estimate
        return failure_metrics(episode, f"scoring raised {type(e).__name__}: {e}")
