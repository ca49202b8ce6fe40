"""Surface labels of LiDAR hits, all points at once, exactly as ``SceneTruth.surface_of_hit`` decides them."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from exobench.core import SceneTruth

from .kernels import label_points


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
    out = np.empty(len(geom), dtype=np.int64)
    label_points(tab.cand, tab.count, tab.sid, tab.point_normal, tab.edge_a, tab.edge_m, tab.edge_len,
                 np.ascontiguousarray(geom, dtype=np.int64), np.ascontiguousarray(hit_w, dtype=np.float64), float(tol_m), out)  # fmt: skip
    return out
