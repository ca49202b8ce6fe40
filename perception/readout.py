"""Staircase read-out from estimated surfaces S0..S4: riser height and tread depth.

Shared by every stairs pipeline so that they differ only in how they estimate the planes.
Only reliable planes are used; a value that cannot be read is NaN.

- Riser height: for each pair of consecutive reliable treads (S0, S2) and (S2, S4), the
  difference of the two tread planes' heights evaluated at the midpoint (in x-y) of the two
  centroids -- for planes, the mean of the differences at the two centroids; the mean over the
  available pairs.
- Tread depth: distance between the riser planes S1 and S3 along S1's horizontal normal
  direction ``h``, measured on the line through the midpoint of their centroids along ``h``.
  For vertical parallel risers this is ``h . (e3 - e1)``.
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np

from exobench.core.estimates import PlaneEstimate

__all__ = ["MIN_TREAD_NZ", "orient_normal", "plane_height_at", "riser_height_m", "tread_depth_m"]

# |n_z| above which a plane is read as a tread, below which as a riser (45 deg)
MIN_TREAD_NZ = float(np.cos(np.radians(45.0)))


def orient_normal(normal: np.ndarray, centroid: np.ndarray) -> np.ndarray:
    """Sign a plane normal for reporting: treads up; risers towards the ``stance_ground`` origin.

    The origin lies on the ground below the stance foot, on the walker's side of the staircase,
    so a riser normal pointing at it points out of the solid, like the ground truth's.
    """
    n = np.asarray(normal, dtype=float)
    if not np.all(np.isfinite(n)):
        return n
    if abs(n[2]) >= MIN_TREAD_NZ:
        return n if n[2] >= 0 else -n
    return n if np.dot(n[:2], -np.asarray(centroid, dtype=float)[:2]) >= 0 else -n


def plane_height_at(plane: PlaneEstimate, xy: np.ndarray) -> float:
    """Height of a (tread) plane above the point ``xy``; NaN for a steep plane."""
    n, e = plane.normal, plane.centroid
    if not abs(n[2]) >= MIN_TREAD_NZ:
        return float("nan")
    return float(e[2] - (n[0] * (xy[0] - e[0]) + n[1] * (xy[1] - e[1])) / n[2])


def _reliable(planes: Iterable[PlaneEstimate]) -> dict[int, PlaneEstimate]:
    return {p.index: p for p in planes if p.reliable and np.all(np.isfinite(p.normal))}


def riser_height_m(planes: Iterable[PlaneEstimate]) -> float:
    """Mean height difference of consecutive reliable treads (S2-S0, S4-S2), m."""
    by = _reliable(planes)
    diffs = []
    for lo, hi in ((0, 2), (2, 4)):
        if lo in by and hi in by:
            mid = 0.5 * (by[lo].centroid[:2] + by[hi].centroid[:2])
            d = plane_height_at(by[hi], mid) - plane_height_at(by[lo], mid)
            if np.isfinite(d):
                diffs.append(d)
    return float(np.mean(diffs)) if diffs else float("nan")


def tread_depth_m(planes: Iterable[PlaneEstimate]) -> float:
    """Horizontal distance between the reliable risers S1 and S3 along S1's normal, m."""
    by = _reliable(planes)
    if 1 not in by or 3 not in by:
        return float("nan")
    r1, r3 = by[1], by[3]
    h = np.array([r1.normal[0], r1.normal[1], 0.0])
    if np.linalg.norm(h) < MIN_TREAD_NZ:
        return float("nan")
    h /= np.linalg.norm(h)
    mid = 0.5 * (r1.centroid + r3.centroid)
    t = []
    for r in (r1, r3):
        c = float(np.dot(r.normal, h))
        if abs(c) < MIN_TREAD_NZ:
            return float("nan")
        t.append(float(np.dot(r.normal, r.centroid - mid)) / c)
    return abs(t[1] - t[0])
