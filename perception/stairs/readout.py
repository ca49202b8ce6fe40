"""Staircase read-out from estimated surfaces S0..S4: riser height and tread depth.

Shared by every stairs pipeline so that they differ only in how they estimate the planes.
Only reliable planes are used; a value that cannot be read is NaN.

- Riser height: for each pair of consecutive reliable treads (S0, S2) and (S2, S4), the
  difference of the two tread planes' heights evaluated at one point of x-y; the mean over the
  available pairs. ``at="midpoint"``: the midpoint of the two centroids (for planes, the mean of
  the differences at the two centroids). ``at="upper_centroid"``: the upper tread's centroid,
  i.e. the height of that centroid above the lower plane. The upper tread (S2, S4) is seen last
  and shortest, often by beams that hardly move, so its orientation is the least certain; read
  at its centroid its tilt does not enter, while the lower plane, fitted on more points over a
  longer sweep, is extrapolated instead. ``at="parallel"``: the treads of a staircase are
  parallel and its risers equal (building codes require both), so the treads are read as one
  family: their normal is the least-squares normal of all their points together (the smallest
  eigenvector of the summed scatter matrices, :attr:`PlaneEstimate.scatter`), each tread's
  height is its centroid's along that normal (divided by ``n_z``: a vertical height), and the
  riser is the least-squares slope of the heights against the tread number (S0, S2, S4 are
  0, 1, 2). With three treads this is half the height from S0 to S4, so a tread seen on a few
  centimetres does not tilt the read-out, and it still reads with two treads of the three.
  A single tread's tilt is the largest error of the other read-outs (a plane fitted on a few
  centimetres of 1.5 mm noise tilts by a few tenths of a degree, a few millimetres over the
  0.3 m to the next tread). Planes without a scatter (imposed normals, as HTVR's horizontal
  treads) must share their normal, which is used as it is.
- Tread depth: distance between the riser planes S1 and S3 along S1's horizontal normal
  direction ``h``, measured on the line through the midpoint of their centroids along ``h``.
  For vertical parallel risers this is ``h . (e3 - e1)``.
"""

from __future__ import annotations

import math
from collections.abc import Iterable

import numpy as np

from exobench.core.estimates import PlaneEstimate

__all__ = ["MIN_TREAD_NZ", "RISER_AT", "orient_normal", "plane_height_at", "riser_height_m", "tread_depth_m"]

# |n_z| above which a plane is read as a tread, below which as a riser (45 deg)
MIN_TREAD_NZ = float(np.cos(np.radians(45.0)))

# The read-out runs after every point for the online estimate, on a handful of 3-vectors: it is
# written on Python floats, which is several times faster than numpy calls on arrays this small.


def orient_normal(normal: np.ndarray, centroid: np.ndarray) -> np.ndarray:
    """Sign a plane normal for reporting: treads up; risers towards the ``stance_ground`` origin.

    The origin lies on the ground below the stance foot, on the walker's side of the staircase,
    so a riser normal pointing at it points out of the solid, like the ground truth's.
    """
    n = np.asarray(normal, dtype=float)
    nx, ny, nz = n.tolist()
    if not (math.isfinite(nx) and math.isfinite(ny) and math.isfinite(nz)):
        return n
    if abs(nz) >= MIN_TREAD_NZ:
        return n if nz >= 0 else -n
    cx, cy = float(centroid[0]), float(centroid[1])
    return n if nx * -cx + ny * -cy >= 0 else -n


def _height_at(n: list[float], e: list[float], x: float, y: float) -> float:
    if not abs(n[2]) >= MIN_TREAD_NZ:
        return float("nan")
    return e[2] - (n[0] * (x - e[0]) + n[1] * (y - e[1])) / n[2]


def plane_height_at(plane: PlaneEstimate, xy: np.ndarray) -> float:
    """Height of a (tread) plane above the point ``xy``; NaN for a steep plane."""
    return _height_at(plane.normal.tolist(), plane.centroid.tolist(), float(xy[0]), float(xy[1]))


def _reliable(planes: Iterable[PlaneEstimate]) -> dict[int, tuple[list[float], list[float]]]:
    """Reliable planes with a finite normal: index -> (normal, centroid) as floats."""
    out = {}
    for p in planes:
        if p.reliable:
            n = p.normal.tolist()
            if all(map(math.isfinite, n)):
                out[p.index] = (n, p.centroid.tolist())
    return out


RISER_AT = ("midpoint", "upper_centroid", "parallel")


def riser_height_m(planes: Iterable[PlaneEstimate], at: str = "midpoint") -> float:
    """Mean height difference of consecutive reliable treads (S2-S0, S4-S2), m.

    ``at``: where the two planes are compared, ``"midpoint"`` or ``"upper_centroid"``, or
    ``"parallel"``: the treads as one parallel family (module docstring).
    """
    if at not in RISER_AT:
        raise ValueError(f"at must be one of {RISER_AT}, not {at!r}")
    if at == "parallel":
        return _riser_parallel(planes)
    by = _reliable(planes)
    diffs = []
    for lo, hi in ((0, 2), (2, 4)):
        if lo in by and hi in by:
            (n_lo, e_lo), (n_hi, e_hi) = by[lo], by[hi]
            if at == "midpoint":
                x, y = 0.5 * (e_lo[0] + e_hi[0]), 0.5 * (e_lo[1] + e_hi[1])
            else:
                x, y = e_hi[0], e_hi[1]
            d = _height_at(n_hi, e_hi, x, y) - _height_at(n_lo, e_lo, x, y)
            if math.isfinite(d):
                diffs.append(d)
    return sum(diffs) / len(diffs) if diffs else float("nan")


def _riser_parallel(planes: Iterable[PlaneEstimate]) -> float:
    """``riser_at="parallel"`` (module docstring)."""
    treads = [p for p in planes if p.reliable and p.index in (0, 2, 4) and np.all(np.isfinite(p.normal))]
    if len(treads) < 2:
        return float("nan")
    with_scatter = [p.scatter is not None for p in treads]
    if all(with_scatter):
        _, U = np.linalg.eigh(sum(p.scatter for p in treads))
        n = U[:, 0]
    elif not any(with_scatter) and all(np.array_equal(p.normal, treads[0].normal) for p in treads):
        n = np.asarray(treads[0].normal, dtype=float)
    else:
        raise ValueError("riser_at='parallel' needs a scatter for every tread, or one shared normal")
    if not abs(n[2]) >= MIN_TREAD_NZ:
        return float("nan")
    k = np.array([p.index / 2.0 for p in treads])
    h = np.array([float(n @ p.centroid) / n[2] for p in treads])
    k -= k.mean()
    return float(k @ (h - h.mean()) / (k @ k))


def tread_depth_m(planes: Iterable[PlaneEstimate]) -> float:
    """Horizontal distance between the reliable risers S1 and S3 along S1's normal, m."""
    by = _reliable(planes)
    if 1 not in by or 3 not in by:
        return float("nan")
    (n1, e1), (n3, e3) = by[1], by[3]
    norm = math.hypot(n1[0], n1[1])
    if norm < MIN_TREAD_NZ:
        return float("nan")
    h = (n1[0] / norm, n1[1] / norm, 0.0)
    mid = [0.5 * (a + b) for a, b in zip(e1, e3, strict=True)]
    t = []
    for n, e in ((n1, e1), (n3, e3)):
        c = n[0] * h[0] + n[1] * h[1] + n[2] * h[2]
        if abs(c) < MIN_TREAD_NZ:
            return float("nan")
        t.append((n[0] * (e[0] - mid[0]) + n[1] * (e[1] - mid[1]) + n[2] * (e[2] - mid[2])) / c)
    return abs(t[1] - t[0])
