"""Vectorised terrain queries on a scene's ground truth.

:func:`exobench.core.height_at` answers one point at a time; the motion planners
(:mod:`exobench.envs.motion`), the contact sensors and the penetration check ask thousands of
points per episode, so :class:`Terrain` answers arrays of points with the same rule: the highest
walkable surface (ground, tread, ramp, landing) whose polygon covers the point, NaN where none
does. :func:`label_hits` labels many ray hits with their surfaces at once. This module sits below
both the motion and the sensor modules, which import it and nothing of each other.
"""

from __future__ import annotations

import numpy as np

from exobench.core import SceneTruth
from exobench.core.errors import check_range

WALKABLE = ("ground", "tread", "ramp", "landing")
_ROWS = 4096


def inside_polygon(poly: np.ndarray, n: np.ndarray, pts: np.ndarray, tol_m: float) -> np.ndarray:
    """The edge test of :meth:`PlanarSurface.contains` for points (N, 3) on the plane, vectorised."""
    sign = np.zeros(len(pts))
    ok = np.ones(len(pts), dtype=bool)
    for i in range(len(poly)):
        a, b = poly[i], poly[(i + 1) % len(poly)]
        e = b - a
        # cross(e, p - a) . n == (p - a) . cross(n, e)
        m = np.array([n[1] * e[2] - n[2] * e[1], n[2] * e[0] - n[0] * e[2], n[0] * e[1] - n[1] * e[0]])
        c = (pts - a) @ m
        skip = np.abs(c) <= tol_m * float(np.sqrt(e @ e))
        sc = np.sign(c)
        first = (sign == 0.0) & ~skip
        sign = np.where(first, sc, sign)
        ok &= skip | first | (sc == sign)
    return ok


def _edge_table(poly: np.ndarray, n: np.ndarray, tol_m: float) -> tuple[list[tuple[np.ndarray, np.ndarray]], np.ndarray]:
    """Each edge's start and in-plane normal, and its skip band, as :func:`inside_polygon` computes
    them: built once per surface for :func:`_inside_edges`."""
    edges, limits = [], []
    for i in range(len(poly)):
        a, b = poly[i], poly[(i + 1) % len(poly)]
        e = b - a
        edges.append((a, np.array([n[1] * e[2] - n[2] * e[1], n[2] * e[0] - n[0] * e[2], n[0] * e[1] - n[1] * e[0]])))
        limits.append(tol_m * float(np.sqrt(e @ e)))
    return edges, np.array(limits)


def _inside_edges(table: tuple[list[tuple[np.ndarray, np.ndarray]], np.ndarray], pts: np.ndarray) -> np.ndarray:
    """:func:`inside_polygon` on an :func:`_edge_table`, the same values for a tolerance >= 0: the
    same products per edge, then the edge loop's rule over all edges at once. An edge is skipped
    where ``|c|`` is within its band, so one that is not has ``c`` of sign +-1 (or NaN): the point
    is inside when every edge not skipped has the sign of the first one not skipped."""
    edges, limits = table
    c = np.empty((len(pts), len(edges)))
    for i, (a, m) in enumerate(edges):
        c[:, i] = (pts - a) @ m
    skip = np.abs(c) <= limits
    sc = np.sign(c)
    rows = np.arange(len(pts))
    first = np.argmax(~skip, axis=1)  # 0 where every edge is skipped (then every edge passes)
    ok = skip | (sc == sc[rows, first][:, None])
    ok[rows, first] = True
    return ok.all(axis=1)


def label_hits(truth: SceneTruth, geom_names: list[str], points_w: np.ndarray, tol_m: float = 1e-4) -> np.ndarray:
    """:meth:`SceneTruth.surface_of_hit` for many hits at once: surface id per point, -1 if none."""
    pts = np.atleast_2d(np.asarray(points_w, dtype=float))
    out = np.full(len(pts), -1, dtype=int)
    names = np.asarray(geom_names, dtype=object)
    for name in set(geom_names):
        rows = np.flatnonzero(names == name)
        p = pts[rows]
        best = np.full(len(rows), -1, dtype=int)
        best_d = np.full(len(rows), tol_m)
        for sid in truth.geom_surfaces.get(name, ()):
            s = truth.surface(sid)
            d = np.abs((p - s.point_w) @ s.normal_w)
            ok = (d <= best_d) & (d <= max(tol_m, 1e-6)) & inside_polygon(s.polygon_w, s.normal_w, p, max(tol_m, 1e-6))
            best = np.where(ok, sid, best)
            best_d = np.where(ok, d, best_d)
        out[rows] = best
    return out


class Terrain:
    """Height and surface id of the walkable terrain under arrays of (x, y) points."""

    def __init__(self, truth: SceneTruth, kinds: tuple[str, ...] = WALKABLE, tol_m: float = 1e-6) -> None:
        tol_m = check_range("Terrain.tol_m", tol_m, 0.0)  # _inside_edges' rule holds for a band of zero or more
        self.truth = truth
        self._surfaces = [s for s in truth.surfaces if s.kind in kinds and abs(s.normal_w[2]) >= 1e-6]
        pad = 10.0 * tol_m
        # (x0, x1, y0, y1) of each surface's padded box, one row each: a planner's query of a foot's
        # few points tests every box in one array operation (a Python loop over a course's surfaces
        # was most of the planning's time), then only the surfaces whose box holds a point
        self._boxes = np.array([
            (s.polygon_w[:, 0].min() - pad, s.polygon_w[:, 0].max() + pad, s.polygon_w[:, 1].min() - pad, s.polygon_w[:, 1].max() + pad)
            for s in self._surfaces
        ], dtype=float).reshape(-1, 4)  # fmt: skip
        self._edges = [_edge_table(s.polygon_w, s.normal_w, tol_m) for s in self._surfaces]

    def query(self, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(height (N,), surface id (N,), -1 where none) of the terrain under points (N, 2)."""
        xy = np.atleast_2d(np.asarray(xy, dtype=float))[:, :2]
        best_z = np.full(len(xy), -np.inf)
        best_id = np.full(len(xy), -1, dtype=int)
        for lo in range(0, len(xy), _ROWS):  # a (points x surfaces) mask of at most _ROWS points
            self._query_rows(xy[lo:lo + _ROWS], best_z[lo:lo + _ROWS], best_id[lo:lo + _ROWS])
        best_z[best_id < 0] = np.nan
        return best_z, best_id

    def _query_rows(self, xy: np.ndarray, best_z: np.ndarray, best_id: np.ndarray) -> None:
        """:meth:`query` of some points, into views of its outputs: the surfaces in their order,
        each over the points in its box, the highest covering one kept."""
        x, y, b = xy[:, 0:1], xy[:, 1:2], self._boxes
        in_box = (x >= b[:, 0]) & (x <= b[:, 1]) & (y >= b[:, 2]) & (y <= b[:, 3])
        for k in np.flatnonzero(in_box.any(axis=0)):
            s = self._surfaces[k]
            rows = np.flatnonzero(in_box[:, k])
            q = xy[rows]
            n, p = s.normal_w, s.point_w
            z = p[2] - (n[0] * (q[:, 0] - p[0]) + n[1] * (q[:, 1] - p[1])) / n[2]
            better = _inside_edges(self._edges[k], np.column_stack([q, z])) & (z > best_z[rows])
            best_z[rows[better]] = z[better]
            best_id[rows[better]] = s.surface_id

    def height(self, xy: np.ndarray) -> np.ndarray:
        return self.query(xy)[0]

    def penetration(self, points_w: np.ndarray) -> np.ndarray:
        """Depth of points (N, 3) below the terrain under them, m (0 above it or off the map)."""
        z = self.height(points_w[:, :2])
        depth = z - points_w[:, 2]
        return np.where(np.isfinite(depth), np.maximum(depth, 0.0), 0.0)
