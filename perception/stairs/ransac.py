"""Connected sequential RANSAC on the two ToF beams' scans: the stairs track's batch baseline.

:class:`ScanCloud` holds the points of both beams in scan order with their voxel cells;
:func:`connected_ransac_plane` draws plane hypotheses and scores each by its *connected*
support (:func:`connected_support`); :func:`tls_plane` is the total least squares fit used to
refine them. :class:`~exobench.perception.stairs.batch_ransac.BatchRansacStairs` drives them.
"""


from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from exobench.core.errors import ConfigError, check_range


@dataclass(frozen=True, eq=False)
class ScanCloud:
    """The points of two scanning beams, in arrival order, with what connectivity needs.

    Attributes:
        points: (N, 3) points.
        sensor: (N,) beam of each point, 0 or 1.
        stamps_s: (N,) arrival stamps, non-decreasing per beam.
        seq: (N,) position of each point in its own beam's sequence (scan order).
        by_sensor: per beam, the indices of its points in scan order.
        cell: (N,) id of the point's (beam, voxel) cell for voxels of ``voxel_m``: support is
            counted in distinct cells, as after a voxel-grid down-sampling, so that the dense
            spot a beam leaves while it barely moves (the still phase, the end of the swing)
            weighs no more than a few points of a swept surface.
    """

    points: np.ndarray
    sensor: np.ndarray
    stamps_s: np.ndarray
    seq: np.ndarray
    by_sensor: tuple[np.ndarray, np.ndarray]
    cell: np.ndarray

    @classmethod
    def of(cls, points: np.ndarray, sensor: np.ndarray, stamps_s: np.ndarray, voxel_m: float = 0.005) -> ScanCloud:
        P = np.asarray(points, dtype=float).reshape(-1, 3)
        s = np.asarray(sensor, dtype=int).reshape(-1)
        t = np.asarray(stamps_s, dtype=float).reshape(-1)
        if not len(s) == len(t) == len(P) or not np.all((s == 0) | (s == 1)):
            raise ConfigError("sensor", f"{len(s)} beams, {len(t)} stamps, {len(P)} points", "one beam (0 or 1) and one stamp per point")
        check_range("voxel_m", voxel_m, 0.0, None, low_open=True)
        by = (np.flatnonzero(s == 0), np.flatnonzero(s == 1))
        seq = np.zeros(len(P), dtype=int)
        for idx in by:
            seq[idx] = np.arange(len(idx))
        keys = np.column_stack([s, np.floor(P / voxel_m).astype(np.int64)]) if len(P) else np.zeros((0, 4), dtype=np.int64)
        cell = np.unique(keys, axis=0, return_inverse=True)[1].reshape(-1)
        return cls(P, s, t, seq, by, cell)

    def score(self, indices: np.ndarray) -> int:
        """Support of the points ``indices``: the number of distinct (beam, voxel) cells."""
        return len(np.unique(self.cell[indices]))

    def cell_means(self, indices: np.ndarray) -> np.ndarray:
        """(M, 3) mean of the points ``indices`` in each of their M cells: a voxel-grid
        down-sampling, which weighs a spot the beam dwelt on like a few swept points."""
        idx = np.asarray(indices, dtype=int)
        cells, inv = np.unique(self.cell[idx], return_inverse=True)
        out = np.zeros((len(cells), 3))
        np.add.at(out, inv.reshape(-1), self.points[idx])
        return out / np.bincount(inv.reshape(-1), minlength=len(cells))[:, None]


def tls_plane(points: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """Total least squares plane of (N >= 3, 3) points: unit normal, centroid, sigma of distances."""
    P = np.asarray(points, dtype=float)
    c = P.mean(axis=0)
    w, U = np.linalg.eigh((P - c).T @ (P - c))
    return U[:, 0], c, float(math.sqrt(max(w[0], 0.0) / len(P)))


def connected_support(
    cloud: ScanCloud,
    inliers: np.ndarray,
    *,
    min_run: int,
    max_gap: int,
    link_radius_m: float,
    min_score: int = 1,
) -> np.ndarray:
    """Indices (ascending) of the largest connected cluster among the inliers of a plane.

    ``inliers`` is a boolean mask over the cloud. Each beam's inliers are split into runs that
    are contiguous in its scan order (at most ``max_gap`` of its readings missing inside a run);
    runs shorter than ``min_run`` are dropped. Runs (of either beam) closer than
    ``link_radius_m`` at their nearest points are connected; the cluster of connected runs
    with the highest :meth:`ScanCloud.score` that holds runs of both beams wins (ties: the
    earliest). The radius must bridge the spacing of the two beams' tracks on a surface and
    stay below the gap between a tread and the level below it: the accidental planes of a
    two-beam scan -- through the stair corners, along one beam's own (nearly planar) sweep,
    or "rolled" through one beam's track on a tread and the other's on the level below --
    then give only short runs, runs of one beam, or runs too far apart. Empty when no
    cluster reaches ``min_score``.
    """
    runs: list[np.ndarray] = []
    beams: list[int] = []
    for b, by in enumerate(cloud.by_sensor):
        idx = by[inliers[by]]
        cut = np.flatnonzero(np.diff(cloud.seq[idx]) > max_gap + 1) + 1
        for r in np.split(idx, cut):
            if len(r) >= min_run:
                runs.append(r)
                beams.append(b)
    if len(set(beams)) < 2 or cloud.score(np.concatenate(runs)) < min_score:
        return np.zeros(0, dtype=int)
    pts = cloud.points[np.concatenate(runs)]
    starts = np.cumsum([0] + [len(r) for r in runs[:-1]])
    d2 = np.sum((pts[:, None, :] - pts[None, :, :]) ** 2, axis=2)
    d2 = np.minimum.reduceat(np.minimum.reduceat(d2, starts, axis=0), starts, axis=1)
    near = d2 <= link_radius_m**2
    cluster = list(range(len(runs)))  # union-find over the runs
    for a, b in zip(*np.nonzero(np.triu(near, 1)), strict=True):
        ra, rb = _root(cluster, int(a)), _root(cluster, int(b))
        cluster[max(ra, rb)] = min(ra, rb)
    best, best_score = np.zeros(0, dtype=int), max(min_score, 1) - 1
    roots = [_root(cluster, k) for k in range(len(runs))]
    for root in sorted(set(roots)):
        members = [k for k in range(len(runs)) if roots[k] == root]
        if len({beams[k] for k in members}) < 2:
            continue
        idx = np.sort(np.concatenate([runs[k] for k in members]))
        score = cloud.score(idx)
        if score > best_score:
            best, best_score = idx, score
    return best


def _root(parent: list[int], k: int) -> int:
    while parent[k] != k:
        parent[k] = parent[parent[k]]
        k = parent[k]
    return k


def _local_samples(cloud: ScanCloud, active: np.ndarray, rng: np.random.Generator, k: int, window: int) -> np.ndarray:
    """(m <= k, 3) index triples: a random active point, an active point of the same beam within
    ``window`` readings in scan order, and an active point of the other beam within ``window``
    readings of the same moment (NAPSAC-style local sampling; invalid draws are dropped)."""
    pool = np.flatnonzero(active)
    i = pool[rng.integers(0, len(pool), size=k)]
    off = np.stack(
        [rng.integers(1, window + 1, size=k) * np.where(rng.random(k) < 0.5, -1, 1), rng.integers(-window, window + 1, size=k)],
        axis=1,
    )
    s = cloud.sensor[i]
    j = np.full(k, -1)
    m = np.full(k, -1)
    for b in (0, 1):
        sel = s == b
        same, other = cloud.by_sensor[b], cloud.by_sensor[1 - b]
        pj = cloud.seq[i[sel]] + off[sel, 0]
        ok = (pj >= 0) & (pj < len(same))
        j[np.flatnonzero(sel)[ok]] = same[pj[ok]]
        if len(other):
            pm = np.searchsorted(cloud.stamps_s[other], cloud.stamps_s[i[sel]]) + off[sel, 1]
            ok = (pm >= 0) & (pm < len(other))
            m[np.flatnonzero(sel)[ok]] = other[pm[ok]]
    good = (j >= 0) & (m >= 0)
    good[good] &= active[j[good]] & active[m[good]]
    return np.stack([i, j, m], axis=1)[good]


def _run_cells_bound(
    cloud: ScanCloud, act: np.ndarray, inside: np.ndarray, min_run: int, max_gap: int, link: np.ndarray
) -> np.ndarray:
    """An upper bound of the score of every hypothesis at once (see :func:`connected_support`).

    ``inside`` holds the inlier masks (columns) of the hypotheses over the points ``act``;
    ``link`` says which points of beam 0 and beam 1 (rows, columns; in the order of ``act``)
    are within the link radius. The bound is the number of distinct cells of the inliers in
    runs of at least ``min_run``, or 0 when no such run of one beam is near one of the other.
    """
    k = inside.shape[1]
    n_cells = int(cloud.cell.max()) + 1 if len(cloud.cell) else 1
    keys, kept_masks = [], []
    for b in (0, 1):
        rows = np.flatnonzero(cloud.sensor[act] == b)
        col, pos = np.nonzero(inside[rows].T)  # by hypothesis, then scan order
        seq = cloud.seq[act[rows[pos]]]
        kept = np.zeros(len(col), dtype=bool)
        if len(col):
            run = np.cumsum(np.r_[True, (np.diff(col) != 0) | (np.diff(seq) > max_gap + 1)]) - 1
            kept = np.bincount(run)[run] >= min_run
        mask = np.zeros((k, len(rows)))
        mask[col[kept], pos[kept]] = 1.0
        kept_masks.append(mask)
        keys.append(col[kept].astype(np.int64) * n_cells + cloud.cell[act[rows[pos[kept]]]])
    linked = np.einsum("ij,ij->i", kept_masks[0] @ link, kept_masks[1]) > 0
    cols = np.unique(np.concatenate(keys)) // n_cells
    return np.where(linked, np.bincount(cols, minlength=k), 0)


def connected_ransac_plane(
    cloud: ScanCloud,
    active: np.ndarray,
    *,
    threshold_m: float,
    iterations: int,
    rng: np.random.Generator,
    window: int,
    min_run: int,
    max_gap: int,
    link_radius_m: float,
    min_score: int = 1,
    refine_iterations: int = 5,
) -> tuple[np.ndarray, int]:
    """The connected support of the best plane among the ``active`` points, and its score.

    RANSAC with local sampling (:func:`_local_samples`); a hypothesis scores the size, in
    distinct cells (:meth:`ScanCloud.score`), of its :func:`connected_support` among the active
    points within ``threshold_m``, not its raw inlier count. Every new best is refined
    (LO-RANSAC): a TLS fit on its support, new inliers, new support, until the support stops
    growing (at most ``refine_iterations`` times).
    Hypotheses scoring below ``min_score`` are not examined; none found gives ``([], 0)``.
    Deterministic for a seeded ``rng``: hypotheses are drawn in chunks and examined in the
    order of their inliers' distinct cells (ties by draw order), which bound the score.
    """
    P = cloud.points
    support_kw = {"min_run": min_run, "max_gap": max_gap, "link_radius_m": link_radius_m}
    best, best_score = np.zeros(0, dtype=int), max(min_score, 1) - 1
    if np.count_nonzero(active) < 3:
        return best, 0

    def support_of(normal: np.ndarray, point: np.ndarray, need: int) -> np.ndarray:
        inliers = active & (np.abs((P - point) @ normal) <= threshold_m)
        return connected_support(cloud, inliers, min_score=need, **support_kw)

    act = np.flatnonzero(active)
    beam = cloud.sensor[act]
    d2 = np.sum((P[act[beam == 0], None, :] - P[None, act[beam == 1], :]) ** 2, axis=2)
    link = (d2 <= link_radius_m**2).astype(float)
    for start in range(0, iterations, 256):  # chunks bound the (N x chunk) distance matrix
        tri = _local_samples(cloud, active, rng, min(256, iterations - start), window)
        if not len(tri):
            continue
        a, b, c = P[tri[:, 0]], P[tri[:, 1]], P[tri[:, 2]]
        n = np.cross(b - a, c - a)
        norm = np.linalg.norm(n, axis=1)
        ok = norm > 1e-9
        n, a = n[ok] / norm[ok, None], a[ok]
        inside = np.abs(P[act] @ n.T - np.sum(n * a, axis=1)) <= threshold_m
        bound = _run_cells_bound(cloud, act, inside, min_run, max_gap, link)
        for h in np.argsort(-bound, kind="stable"):
            if bound[h] <= best_score:
                break
            sup = support_of(n[h], a[h], best_score + 1)
            if not len(sup):
                continue
            score = cloud.score(sup)
            for _ in range(refine_iterations):  # local optimisation of the new best
                normal, centroid, _s = tls_plane(cloud.cell_means(sup))
                grown = support_of(normal, centroid, score + 1)
                if not len(grown):
                    break
                sup, score = grown, cloud.score(grown)
            best, best_score = sup, score
    return (best, best_score) if len(best) else (best, 0)

