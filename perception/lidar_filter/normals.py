"""Surface normals of LiDAR points for the normal ground-aware filter (eq. 4.17-4.18).

- ``"knn"``: the thesis' method, PCA of the ``normal_k`` nearest neighbours within
  ``normal_radius_m`` (PCL's ``NormalEstimation``), flipped towards the sensor. On a 16-ring
  LiDAR the nearest points of a floor point all lie on its own ring, so the "plane" is a line:
  the sparsity limitation section 5.2.2 reports.
- ``"range-image"`` (default; a reading of step 1, not the thesis' PCL call): the scan organised
  as a range image (rows = rings by elevation, columns = azimuth); each point has four one-sided
  normals, the cross products of an azimuth tangent (left / right) and a ring tangent (up / down)
  that skip neighbours across a depth jump. A point on a crease (floor meeting a wall) lies on
  both surfaces, so the filter reads eq. (4.19) as "some one-sided normal is parallel to the
  footprint's z axis". Scans without a ring layout fall back to ``"knn"``. The tangents and
  normals of the cells are computed in one compiled pass (:mod:`.normal_kernels`).
"""

from __future__ import annotations

import numpy as np

from exobench.core.limits import finite_rows

from .normal_kernels import candidate_cells


def estimate_normals(
    points_xyz: np.ndarray, k: int = 10, radius_m: float = 0.5, viewpoint_xyz: np.ndarray | None = None
) -> np.ndarray:
    """PCA normals (PCL ``NormalEstimation``), flipped towards the viewpoint; (N, 3), NaN if none.

    Neighbours: the ``k`` nearest points (the query point included) within ``radius_m``. A point
    with fewer than 3 neighbours, or whose neighbours are collinear (middle eigenvalue below
    1e-6 of the largest), gets NaN: its normal is undefined.
    """
    from scipy.spatial import cKDTree

    p = np.asarray(points_xyz, dtype=float).reshape(-1, 3)
    n = len(p)
    normals = np.full((n, 3), np.nan)
    if n < 3:
        return normals
    kk = min(k, n)
    dist, idx = cKDTree(p).query(p, k=kk, distance_upper_bound=radius_m)
    dist = dist.reshape(n, kk)
    idx = idx.reshape(n, kk)
    valid = np.isfinite(dist)
    count = valid.sum(axis=1)
    nbr = p[np.where(valid, idx, 0)]  # (n, kk, 3); invalid slots masked below
    w = valid[..., None].astype(float)
    mean = (nbr * w).sum(axis=1) / np.maximum(count, 1)[:, None]
    d = (nbr - mean[:, None, :]) * w
    cov = np.einsum("nki,nkj->nij", d, d) / np.maximum(count, 1)[:, None, None]
    evals, evecs = np.linalg.eigh(cov)  # ascending
    ok = (count >= 3) & (evals[:, 1] > 1e-6 * np.maximum(evals[:, 2], 1e-300))
    normal = evecs[:, :, 0]
    vp = np.zeros(3) if viewpoint_xyz is None else np.asarray(viewpoint_xyz, dtype=float)
    flip = np.einsum("ni,ni->n", normal, vp - p) < 0
    normal[flip] *= -1.0
    normals[ok] = normal[ok]
    return normals


def range_image_index(points_xyz: np.ndarray, ring: np.ndarray | None) -> tuple[np.ndarray, float] | None:
    """Organise a spinning LiDAR scan as a range image of point indices.

    Rows are the rings sorted by their mean elevation (lowest first), columns the azimuth
    ``atan2(y, x)`` in steps of the scan's own azimuth resolution (the median gap between
    successive returns of a ring), with a per-ring phase so that rings fired at slightly
    different azimuths (interleaved lasers, per-laser offsets) still fall on whole columns.

    Returns ``(index, azimuth_step_rad)``: ``index`` (rows, columns) int64 with the point index
    of each cell, -1 where there is no return (two returns in one cell: the later one wins);
    None when the scan has no usable ring layout (no ring, mismatched length, fewer than two
    rings or than 8 columns, non-finite points only), so the caller falls back to knn.
    Non-finite points are left out.
    """
    p = np.asarray(points_xyz, dtype=float).reshape(-1, 3)
    if ring is None:
        return None
    ring_arr = np.asarray(ring).reshape(-1)
    if len(ring_arr) != len(p) or len(p) == 0:
        return None
    valid = finite_rows(p) & (np.einsum("ni,ni->n", p, p) > 1e-12)
    if ring_arr.dtype.kind == "f":
        valid &= np.isfinite(ring_arr)
    vi = np.flatnonzero(valid)
    if len(vi) < 4:
        return None
    _, rinv = np.unique(ring_arr[vi], return_inverse=True)
    rinv = rinv.reshape(-1)
    n_rows = int(rinv.max()) + 1
    if n_rows < 2:
        return None
    q = p[vi]
    az = np.arctan2(q[:, 1], q[:, 0])
    el = np.arctan2(q[:, 2], np.hypot(q[:, 0], q[:, 1]))
    mean_el = np.bincount(rinv, el, n_rows) / np.bincount(rinv, None, n_rows)  # a ring's elevation is fixed
    row_of_ring = np.empty(n_rows, dtype=np.int64)
    row_of_ring[np.argsort(mean_el, kind="stable")] = np.arange(n_rows)
    row = row_of_ring[rinv]
    o = np.argsort(row * 8.0 + az, kind="stable")  # by row, then azimuth (|az| <= pi < 4)
    gaps = np.diff(az[o])
    gaps = gaps[(row[o][1:] == row[o][:-1]) & (gaps > 1e-9)]
    if len(gaps) == 0:
        return None
    step = float(np.median(gaps))
    n_cols = int(round(2.0 * np.pi / step))
    if n_cols < 8 or n_cols > 1_000_000:
        return None
    u = az / step
    w = 2.0 * np.pi * u
    phase = np.arctan2(np.bincount(row, np.sin(w), n_rows), np.bincount(row, np.cos(w), n_rows)) / (2.0 * np.pi)
    col = np.rint(u - phase[row]).astype(np.int64) % n_cols
    index = np.full((n_rows, n_cols), -1, dtype=np.int64)
    index[row, col] = vi
    return index, step


def _unit(v: np.ndarray) -> np.ndarray:
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        return v / n


def range_image_normal_candidates(
    points_xyz: np.ndarray,
    ring: np.ndarray | None,
    *,
    col_halfwidth: int = 4,
    azimuth_jump_rel: float = 0.1,
    ring_jump_rel: float = 0.3,
    max_ring_skip: int = 2,
    min_neighbours: int = 2,
    min_sin: float = 0.2,
) -> np.ndarray | None:
    """The four one-sided range-image normals of each point, (N, 4, 3), NaN where undefined.

    Order: (left, up), (left, down), (right, up), (right, down). Side ``s`` of the azimuth
    tangent: the least-squares line through the point and its neighbours ``p[c + s j]``,
    ``j = 1..col_halfwidth``, whose range is within ``azimuth_jump_rel`` of the point's; at
    least ``min_neighbours`` such neighbours are needed. Ring tangent: to the nearest return in the ring above (below),
    in the same column or the next one on either side, at most ``max_ring_skip`` rings away,
    whose range ``r_n`` is within ``|r_n - r| <= ring_jump_rel * min(r_n, r)`` of the point's
    (returns across a depth jump are passed over); none when there is no such return.
    The normal ``t_az x t_ring`` is flipped towards the sensor (origin); NaN when the tangents
    are nearly parallel (sine of their angle below ``min_sin``). None when the scan is not
    ring-organised (:func:`range_image_index`) or has fewer columns than ``col_halfwidth`` (the
    caller falls back to knn, as for any scan without a usable ring layout).
    """
    p = np.asarray(points_xyz, dtype=float).reshape(-1, 3)
    organised = range_image_index(p, ring)
    if organised is None:
        return None
    index, _ = organised
    n_rows, n_cols = index.shape
    has = index >= 0
    pad = int(max_ring_skip)
    # the image in float32: half the memory traffic; a few mm of rounding at 100 m is far below range noise
    P = np.full((n_rows + 2 * pad, n_cols, 3), np.nan, dtype=np.float32)
    P[pad : pad + n_rows][has] = p[index[has]]
    rg = np.sqrt(np.einsum("rci,rci->rc", P, P))  # range image, NaN where empty
    Pc, rc = P[pad : pad + n_rows], rg[pad : pad + n_rows]

    cw = int(col_halfwidth)
    Pw = np.concatenate([Pc[:, n_cols - cw :], Pc, Pc[:, :cw]], axis=1)  # columns wrap round (360 deg)
    rw = np.concatenate([rc[:, n_cols - cw :], rc, rc[:, :cw]], axis=1)
    Pr = np.concatenate([P[:, -1:], P, P[:, :1]], axis=1)  # one wrapped column each side
    rr = np.concatenate([rg[:, -1:], rg, rg[:, :1]], axis=1)
    if Pw.shape[1] != n_cols + 2 * cw:  # a sparse scan with fewer columns than the half-width: no tangent wraps whole
        return None
    # one compiled pass per cell (:mod:`.normal_kernels`); the tolerances are float32, as numpy
    # multiplies a float32 image by a Python float
    cells = candidate_cells(index, p, Pw, rw, Pr, rr, rc, cw, np.float32(azimuth_jump_rel), np.float32(ring_jump_rel),
                            pad, int(min_neighbours), float(min_sin))  # fmt: skip
    idx = index[has]
    out = np.full((len(p), 4, 3), np.nan)
    out[idx] = cells  # one scatter of whole rows: a cell's point is never another cell's
    return out


def estimate_range_image_normals(
    points_xyz: np.ndarray, ring: np.ndarray | None, *, max_spread_deg: float = 20.0, **params: float
) -> np.ndarray | None:
    """One range-image normal per point, (N, 3): the mean of the defined one-sided normals of
    :func:`range_image_normal_candidates` when they all lie within ``max_spread_deg`` of that
    mean, NaN otherwise (no side defined, or a crease / depth jump). None when the scan is not
    ring-organised."""
    cand = range_image_normal_candidates(points_xyz, ring, **params)
    if cand is None:
        return None
    defined = ~np.isnan(cand[..., 0])
    mean = _unit(np.where(defined[..., None], cand, 0.0).sum(axis=1))
    with np.errstate(invalid="ignore"):
        cos = np.einsum("nki,ni->nk", cand, mean)
        agree = np.all(~defined | (cos >= np.cos(np.radians(max_spread_deg))), axis=1) & defined.any(axis=1)
    mean[~agree] = np.nan
    return mean


def normal_cosines(normals_sensor: np.ndarray, T_footprint_sensor: np.ndarray) -> np.ndarray:
    """Eq. (4.17)-(4.18): cosine between each normal, rotated into ``f``, and ``f``'s z; (N,).

    NaN where the normal is undefined. ``(R eta)_z = R[2, :] . eta``: only the last row of the
    rotation is needed (computed without BLAS, whose idle threads cost more than the product).
    """
    r = np.asarray(T_footprint_sensor, dtype=float)[2, :3]
    eta = np.asarray(normals_sensor, dtype=float).reshape(-1, 3)
    with np.errstate(invalid="ignore", divide="ignore"):
        z = eta[:, 0] * r[0] + eta[:, 1] * r[1] + eta[:, 2] * r[2]
        return z / np.sqrt(np.einsum("ni,ni->n", eta, eta))


