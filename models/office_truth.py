"""Exact planar surfaces of the office and dense point samples of everything in it (numpy only).

Every box of the office is axis-aligned, so the part of a box face a ray can reach is the face
rectangle minus the cross-sections of the boxes that touch or cut its plane from outside; it is
computed exactly on the grid of their edges and merged into a few rectangles, each one
:class:`~exobench.core.truth.PlanarSurface`. Faces on the floor, at the ceiling and on the
outside of the building are left out (nobody inside can see them). Floors and ceilings are one
rectangle per area (corridor or room) including the strips under walls and furniture (hidden
parts, as allowed by the truth contract); samples there are dropped where a solid covers them.
Curved solids (pots, foliage, bins) are not planar surfaces; they are sampled from their
primitives, stored in ``truth.params["solids"]``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from exobench.core.truth import PlanarSurface, SceneTruth

from .office_furniture import Rect, Solid

EPS_M = 1e-9


def _cuts(values: Sequence[float], lo: float, hi: float) -> np.ndarray:
    v = sorted([lo, hi] + [x for x in values if lo + EPS_M < x < hi - EPS_M])
    out = [v[0]]
    for x in v[1:]:
        if x > out[-1] + EPS_M:
            out.append(x)
    out[-1] = hi
    return np.array(out)


def _free_rects(face: tuple[float, float, float, float], covers: list[tuple[float, float, float, float]]) -> list[tuple]:
    """Rectangles (b0, b1, c0, c1) covering ``face`` minus the union of ``covers``, merged greedily."""
    b0, b1, c0, c1 = face
    if not covers:
        return [face]
    bs = _cuts([x for r in covers for x in r[:2]], b0, b1)
    cs = _cuts([x for r in covers for x in r[2:]], c0, c1)
    bm, cm = 0.5 * (bs[1:] + bs[:-1]), 0.5 * (cs[1:] + cs[:-1])
    free = np.ones((len(bm), len(cm)), dtype=bool)
    for r in covers:
        free[np.ix_((bm > r[0]) & (bm < r[1]), (cm > r[2]) & (cm < r[3]))] = False
    out = []
    for i in range(len(bm)):
        j = 0
        while j < len(cm):
            if not free[i, j]:
                j += 1
                continue
            j1 = j
            while j1 + 1 < len(cm) and free[i, j1 + 1]:
                j1 += 1
            i1 = i
            while i1 + 1 < len(bm) and free[i1 + 1, j:j1 + 1].all():
                i1 += 1
            free[i:i1 + 1, j:j1 + 1] = False
            out.append((bs[i], bs[i1 + 1], cs[j], cs[j1 + 1]))
            j = j1 + 1
    return out


def _rect_polygon(axis: int, plane: float, normal_sign: float, b: tuple[float, float], c: tuple[float, float]) -> np.ndarray:
    """Rectangle in the plane x[axis] = plane, counter-clockwise seen from the side of its normal."""
    ib, ic = [k for k in range(3) if k != axis]
    pts = np.zeros((4, 3))
    pts[:, axis] = plane
    pts[:, ib] = [b[0], b[1], b[1], b[0]]
    pts[:, ic] = [c[0], c[0], c[1], c[1]]
    n = np.zeros(3)
    n[axis] = normal_sign
    area = np.cross(pts[1] - pts[0], pts[2] - pts[1])
    return pts if area @ n > 0 else pts[::-1].copy()


def office_surfaces(solids: list[Solid], ceiling_m: float, extent: Rect) -> tuple[list[PlanarSurface], dict[str, tuple[int, ...]]]:
    """Planar surfaces of planes (one each) and exposed box faces, and each geom's surface ids."""
    surfaces: list[PlanarSurface] = []
    geom_surfaces: dict[str, list[int]] = {s.name: [] for s in solids}

    def add(kind: str, axis: int, sign: float, plane: float, b: tuple, c: tuple, geom: str) -> None:
        poly = _rect_polygon(axis, plane, sign, b, c)
        n = np.zeros(3)
        n[axis] = sign
        sid = len(surfaces)
        surfaces.append(PlanarSurface(surface_id=sid, kind=kind, normal_w=n, point_w=poly.mean(axis=0), polygon_w=poly,
                                      geom_names=(geom,)))
        geom_surfaces[geom].append(sid)

    for s in solids:
        if s.shape == "plane":
            lo, hi = s.lo, s.hi
            add(s.kind, 2, 1.0 if s.up else -1.0, s.centre[2], (lo[0], hi[0]), (lo[1], hi[1]), s.name)
    boxes = [s for s in solids if s.shape == "box"]
    lo = np.array([s.lo for s in boxes])
    hi = np.array([s.hi for s in boxes])
    outer = {(0, -1.0): extent[0], (0, 1.0): extent[1], (1, -1.0): extent[2], (1, 1.0): extent[3]}
    for i, s in enumerate(boxes):
        for axis in range(3):
            ib, ic = [k for k in range(3) if k != axis]
            for sign in (-1.0, 1.0):
                plane = hi[i, axis] if sign > 0 else lo[i, axis]
                if axis == 2 and ((sign < 0 and plane <= EPS_M) or (sign > 0 and plane >= ceiling_m - EPS_M)):
                    continue  # on the floor or against the ceiling
                if (axis, sign) in outer and abs(plane - outer[(axis, sign)]) <= EPS_M:
                    continue  # outside of the building
                if sign > 0:
                    m = (lo[:, axis] <= plane + EPS_M) & (hi[:, axis] > plane + EPS_M)
                else:
                    m = (hi[:, axis] >= plane - EPS_M) & (lo[:, axis] < plane - EPS_M)
                m &= (lo[:, ib] < hi[i, ib] - EPS_M) & (hi[:, ib] > lo[i, ib] + EPS_M)
                m &= (lo[:, ic] < hi[i, ic] - EPS_M) & (hi[:, ic] > lo[i, ic] + EPS_M)
                m[i] = False
                covers = [(lo[j, ib], hi[j, ib], lo[j, ic], hi[j, ic]) for j in np.flatnonzero(m)]
                for b0, b1, c0, c1 in _free_rects((lo[i, ib], hi[i, ib], lo[i, ic], hi[i, ic]), covers):
                    add(s.kind, axis, sign, plane, (b0, b1), (c0, c1), s.name)
    return surfaces, {k: tuple(v) for k, v in geom_surfaces.items()}


def solids_from_truth(truth: SceneTruth) -> list[Solid]:
    """The primitives stored in ``truth.params["solids"]``."""
    return [Solid(d["name"], d["shape"], tuple(d["centre"]), tuple(d["half"]), d["material"], "", d["kind"], d["up"])
            for d in truth.params["solids"]]


def inside_solid(solid: Solid, points_w: np.ndarray, tol_m: float = EPS_M) -> np.ndarray:
    """Whether points (N, 3) lie in the closed solid (grown by ``tol_m``); planes contain nothing."""
    p = np.asarray(points_w, dtype=float) - np.asarray(solid.centre)
    h = np.asarray(solid.half)
    if solid.shape == "box":
        return np.all(np.abs(p) <= h + tol_m, axis=1)
    if solid.shape == "cylinder":
        return (np.hypot(p[:, 0], p[:, 1]) <= h[0] + tol_m) & (np.abs(p[:, 2]) <= h[2] + tol_m)
    if solid.shape == "sphere":
        return np.linalg.norm(p, axis=1) <= h[0] + tol_m
    return np.zeros(len(p), dtype=bool)


class SolidIndex:
    """The solids (not planes) of an office with their bounding boxes, for fast inside tests."""

    def __init__(self, solids: Sequence[Solid]) -> None:
        self.solids = [s for s in solids if s.shape != "plane"]
        self.lo = np.array([s.lo for s in self.solids]).reshape(-1, 3)
        self.hi = np.array([s.hi for s in self.solids]).reshape(-1, 3)

    def inside(self, points_w: np.ndarray, exclude: Sequence[str] = (),
               shapes: Sequence[str] = ("box", "cylinder", "sphere")) -> np.ndarray:
        """Whether each point (N, 3) lies in (or on) a solid other than ``exclude`` of one of ``shapes``."""
        pts = np.atleast_2d(np.asarray(points_w, dtype=float))
        out = np.zeros(len(pts), dtype=bool)
        if not len(pts) or not self.solids:
            return out
        near = np.all(self.lo <= pts.max(axis=0) + EPS_M, axis=1) & np.all(self.hi >= pts.min(axis=0) - EPS_M, axis=1)
        for j in np.flatnonzero(near):
            s = self.solids[j]
            if s.shape in shapes and s.name not in exclude:
                out |= inside_solid(s, pts)
        return out


def points_inside_solids(truth: SceneTruth, points_w: np.ndarray, exclude: Sequence[str] = ()) -> np.ndarray:
    """Whether each point (N, 3) lies in (or on) any solid of the office other than ``exclude``."""
    return SolidIndex(solids_from_truth(truth)).inside(points_w, exclude)


def _grid_on_polygon(poly: np.ndarray, normal: np.ndarray, spacing_m: float) -> np.ndarray:
    """Cell centres of a grid of about ``spacing_m`` over a convex polygon (K, 3)."""
    u = poly[1] - poly[0]
    u /= np.linalg.norm(u)
    v = np.cross(normal, u)
    uv = np.stack([(poly - poly[0]) @ u, (poly - poly[0]) @ v], axis=1)
    lo, hi = uv.min(axis=0), uv.max(axis=0)
    nu, nv = (max(1, math.ceil((hi[k] - lo[k]) / spacing_m - 1e-9)) for k in (0, 1))
    gu = lo[0] + (np.arange(nu) + 0.5) * (hi[0] - lo[0]) / nu
    gv = lo[1] + (np.arange(nv) + 0.5) * (hi[1] - lo[1]) / nv
    G = np.stack(np.meshgrid(gu, gv, indexing="ij"), axis=-1).reshape(-1, 2)
    keep = np.ones(len(G), dtype=bool)
    for k in range(len(uv)):  # inside every edge of the counter-clockwise polygon
        a, b = uv[k], uv[(k + 1) % len(uv)]
        keep &= (b[0] - a[0]) * (G[:, 1] - a[1]) - (b[1] - a[1]) * (G[:, 0] - a[0]) >= -1e-12
    G = G[keep]
    return poly[0] + G[:, :1] * u + G[:, 1:] * v


def _curved_samples(s: Solid, spacing_m: float) -> tuple[np.ndarray, np.ndarray]:
    c, h = np.asarray(s.centre), np.asarray(s.half)
    if s.shape == "sphere":
        n = max(8, math.ceil(4 * math.pi * h[0] ** 2 / spacing_m**2))
        k = np.arange(n) + 0.5
        z = 1 - 2 * k / n
        phi = k * math.pi * (3 - math.sqrt(5))
        d = np.stack([np.sqrt(1 - z * z) * np.cos(phi), np.sqrt(1 - z * z) * np.sin(phi), z], axis=1)
        return c + h[0] * d, d
    r, hz = h[0], h[2]
    na = max(8, math.ceil(2 * math.pi * r / spacing_m))
    nz = max(1, math.ceil(2 * hz / spacing_m))
    a = (np.arange(na) + 0.5) * 2 * math.pi / na
    zz = -hz + (np.arange(nz) + 0.5) * 2 * hz / nz
    A, Z = np.meshgrid(a, zz, indexing="ij")
    d = np.stack([np.cos(A).ravel(), np.sin(A).ravel(), np.zeros(A.size)], axis=1)
    pts = [c + r * d + np.outer(Z.ravel(), [0, 0, 1])]
    nrm = [d]
    caps = [1.0] if c[2] - hz <= EPS_M else [1.0, -1.0]  # the bottom of a solid on the floor is hidden
    nr = max(1, math.ceil(r / spacing_m))
    for sign in caps:
        for i in range(nr):
            rho = (i + 0.5) * r / nr
            m = max(1, math.ceil(2 * math.pi * rho / spacing_m))
            b = (np.arange(m) + 0.5) * 2 * math.pi / m
            pts.append(np.stack([c[0] + rho * np.cos(b), c[1] + rho * np.sin(b), np.full(m, c[2] + sign * hz)], axis=1))
            nrm.append(np.tile([0.0, 0.0, sign], (m, 1)))
    return np.concatenate(pts), np.concatenate(nrm)


def sample_surface(truth: SceneTruth, spacing_m: float, kinds: Sequence[str] | None = None
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Points (N, 3) about ``spacing_m`` apart on every exposed surface, their outward normals
    (N, 3) and surface ids (N,) (-1 on curved solids).

    ``kinds`` keeps only surfaces of those kinds (curved solids have the kind of their solid,
    ``furniture``). Deterministic: cell centres of a grid on each surface.
    """
    if not spacing_m > 0:
        raise ValueError(f"spacing_m must be > 0, got {spacing_m}")
    solids = solids_from_truth(truth)
    index = SolidIndex(solids)
    pts, nrm, ids = [], [], []
    for s in truth.surfaces:
        if kinds is not None and s.kind not in kinds:
            continue
        p = _grid_on_polygon(s.polygon_w, s.normal_w, spacing_m)
        flat = s.kind in ("ground", "ceiling")  # these include parts hidden under solids
        hidden = index.inside(p, exclude=s.geom_names, shapes=("box", "cylinder", "sphere") if flat else ("cylinder", "sphere"))
        p = p[~hidden]
        pts.append(p)
        nrm.append(np.tile(s.normal_w, (len(p), 1)))
        ids.append(np.full(len(p), s.surface_id))
    for s in solids:
        if s.shape not in ("cylinder", "sphere") or (kinds is not None and s.kind not in kinds):
            continue
        p, d = _curved_samples(s, spacing_m)
        hidden = index.inside(p, exclude=(s.name,))
        pts.append(p[~hidden])
        nrm.append(d[~hidden])
        ids.append(np.full(int((~hidden).sum()), -1))
    if not pts:
        return np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0, dtype=int)
    return np.concatenate(pts), np.concatenate(nrm), np.concatenate(ids).astype(int)


def sample_surface_points(truth: SceneTruth, spacing_m: float, kinds: Sequence[str] | None = None) -> np.ndarray:
    """Dense points (N, 3) on all exposed surfaces (floors, ceilings, walls, glass, furniture),
    about ``spacing_m`` apart, for scoring maps; see :func:`sample_surface`."""
    return sample_surface(truth, spacing_m, kinds)[0]
