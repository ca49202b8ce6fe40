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

WALKABLE = ("ground", "tread", "ramp", "landing")


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
        self.truth = truth
        self._tol = tol_m
        self._surfaces = [s for s in truth.surfaces if s.kind in kinds and abs(s.normal_w[2]) >= 1e-6]
        pad = 10.0 * tol_m
        self._boxes = [
            (s.polygon_w[:, 0].min() - pad, s.polygon_w[:, 0].max() + pad, s.polygon_w[:, 1].min() - pad, s.polygon_w[:, 1].max() + pad)
            for s in self._surfaces
        ]

    def query(self, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(height (N,), surface id (N,), -1 where none) of the terrain under points (N, 2)."""
        xy = np.atleast_2d(np.asarray(xy, dtype=float))[:, :2]
        best_z = np.full(len(xy), -np.inf)
        best_id = np.full(len(xy), -1, dtype=int)
        for s, (x0, x1, y0, y1) in zip(self._surfaces, self._boxes):
            rows = np.flatnonzero((xy[:, 0] >= x0) & (xy[:, 0] <= x1) & (xy[:, 1] >= y0) & (xy[:, 1] <= y1))
            if not len(rows):
                continue
            q = xy[rows]
            n, p = s.normal_w, s.point_w
            z = p[2] - (n[0] * (q[:, 0] - p[0]) + n[1] * (q[:, 1] - p[1])) / n[2]
            better = self._inside(s.polygon_w, n, q, z) & (z > best_z[rows])
            best_z[rows[better]] = z[better]
            best_id[rows[better]] = s.surface_id
        best_z[best_id < 0] = np.nan
        return best_z, best_id

    def height(self, xy: np.ndarray) -> np.ndarray:
        return self.query(xy)[0]

    def _inside(self, poly: np.ndarray, n: np.ndarray, xy: np.ndarray, z: np.ndarray) -> np.ndarray:
        return inside_polygon(poly, n, np.column_stack([xy, z]), self._tol)

    def penetration(self, points_w: np.ndarray) -> np.ndarray:
        """Depth of points (N, 3) below the terrain under them, m (0 above it or off the map)."""
        z = self.height(points_w[:, :2])
        depth = z - points_w[:, 2]
        return np.where(np.isfinite(depth), np.maximum(depth, 0.0), 0.0)
