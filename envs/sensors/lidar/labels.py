"""Surface labels of LiDAR hits, all points at once, exactly as ``SceneTruth.surface_of_hit`` decides them."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from exobench.core import SceneTruth


@dataclass(frozen=True, eq=False)
class SurfaceTable:
    """A scene's surfaces as arrays, for labelling hits (rows index ``sid``).

    ``cand[g, :count[g]]`` are the rows of geom ``g``'s surfaces in ``geom_surfaces`` order;
    polygons are padded with zero-length edges, which the edge test skips.
    """

    sid: np.ndarray  # (S,) surface id of each row
    point_normal: np.ndarray  # (S, 2, 3) a point of the plane and its normal
    edge_a: np.ndarray  # (S, V, 3) first vertex of each edge
    edge_m: np.ndarray  # (S, V, 3) cross(normal, edge)
    edge_len: np.ndarray  # (S, V) edge length, m
    cand: np.ndarray  # (ngeom, K) candidate rows per geom, padded with 0
    count: np.ndarray  # (ngeom,)

    @staticmethod
    def build(truth: SceneTruth, geom_names: list[str]) -> SurfaceTable:
        surfaces = list(truth.surfaces)
        row_of = {sf.surface_id: i for i, sf in enumerate(surfaces)}
        S, V = len(surfaces), max((len(sf.polygon_w) for sf in surfaces), default=1)
        edge_a, edge_m, edge_len = np.zeros((S, V, 3)), np.zeros((S, V, 3)), np.zeros((S, V))
        for i, sf in enumerate(surfaces):
            poly, nv = np.asarray(sf.polygon_w, dtype=float), np.asarray(sf.normal_w, dtype=float)
            edge_a[i] = poly[-1] if len(poly) else 0.0
            for j in range(len(poly)):
                a, b = poly[j], poly[(j + 1) % len(poly)]
                e = b - a
                edge_a[i, j] = a
                edge_m[i, j] = [
                    nv[1] * e[2] - nv[2] * e[1],
                    nv[2] * e[0] - nv[0] * e[2],
                    nv[0] * e[1] - nv[1] * e[0],
                ]
                edge_len[i, j] = float(np.sqrt(e @ e))
        rows = [[row_of[sid] for sid in truth.geom_surfaces.get(name, ())] for name in geom_names]
        K = max((len(r) for r in rows), default=0)
        cand = np.zeros((len(geom_names), max(K, 1)), dtype=np.int64)
        for g, r in enumerate(rows):
            cand[g, : len(r)] = r
        return SurfaceTable(
            sid=np.array([sf.surface_id for sf in surfaces], dtype=np.int64),
            point_normal=np.array([[sf.point_w, sf.normal_w] for sf in surfaces], dtype=float).reshape(S, 2, 3),
            edge_a=edge_a, edge_m=edge_m, edge_len=edge_len, cand=cand,
            count=np.array([len(r) for r in rows], dtype=np.int64),
        )  # fmt: skip


def label_surfaces(tab: SurfaceTable, geom: np.ndarray, hit_w: np.ndarray, tol_m: float = 1e-4) -> np.ndarray:
    """Surface id of each hit (-1 if none), as ``SceneTruth.surface_of_hit`` decides it, all hits at once.

    Of a geom's surfaces, those whose plane passes within ``tol_m`` of the point and whose
    polygon contains it qualify; the nearest plane wins, the last listed of equally near ones
    (the order ``surface_of_hit`` visits them in).
    """
    n = len(geom)
    out = np.full(n, -1, dtype=np.int64)
    cnt = tab.count[geom]
    pt = np.repeat(np.arange(n), cnt)  # one row per (point, candidate surface)
    if len(pt) == 0:
        return out
    slot = np.arange(len(pt)) - np.repeat(np.cumsum(cnt) - cnt, cnt)
    row = tab.cand[geom[pt], slot]
    # column by column on 1-D arrays (gathers of (P, 3) rows and reductions over short axes cost
    # more than the arithmetic); each dot product is summed (x0 y0 + x1 y1) + x2 y2, the order
    # surface_of_hit's test is checked against, so the labels are the same
    hc = np.ascontiguousarray(hit_w.T)
    pnc = np.ascontiguousarray(tab.point_normal.transpose(1, 2, 0))  # (2, 3, S)
    q = [hc[c][pt] - pnc[0, c][row] for c in range(3)]
    d = np.abs(q[0] * pnc[1, 0][row] + q[1] * pnc[1, 1][row] + q[2] * pnc[1, 2][row])
    near = np.flatnonzero(d <= tol_m)
    pt, slot, row, d = pt[near], slot[near], row[near], d[near]
    p = [hc[c][pt] for c in range(3)]
    # the edge test of PlanarSurface.contains: the edges not within tol_m of the point must
    # all see it on the same side (zero-length padding edges are always within)
    ea = np.ascontiguousarray(tab.edge_a.transpose(1, 2, 0))  # (V, 3, S)
    em = np.ascontiguousarray(tab.edge_m.transpose(1, 2, 0))
    el = np.ascontiguousarray(tab.edge_len.T)  # (V, S)
    above = np.zeros(len(pt), dtype=bool)
    below = np.zeros(len(pt), dtype=bool)
    for e in range(ea.shape[0]):
        c = (p[0] - ea[e, 0][row]) * em[e, 0][row] + (p[1] - ea[e, 1][row]) * em[e, 1][row]
        c += (p[2] - ea[e, 2][row]) * em[e, 2][row]
        within = tol_m * el[e][row]
        above |= c > within
        below |= c < -within
    ok = ~(above & below)
    pt, slot, row, d = pt[ok], slot[ok], row[ok], d[ok]
    single = np.bincount(pt, minlength=n)[pt] == 1
    out[pt[single]] = tab.sid[row[single]]
    multi = np.flatnonzero(~single)
    if len(multi):  # several qualify: the nearest plane, the last listed of ties
        pts, at = np.unique(pt[multi], return_inverse=True)
        dd = np.full((len(pts), tab.cand.shape[1]), np.inf)
        dd[at, slot[multi]] = d[multi]
        best = dd.min(axis=1)
        last = dd.shape[1] - 1 - np.argmax((dd == best[:, None])[:, ::-1], axis=1)
        out[pts] = tab.sid[tab.cand[geom[pts], last]]
    return out
