"""Thin boxes around every edge of the BVH's static geoms: the rays Embree may miss a geom by.

Embree casts in single precision: a ray that meets a box within its rounding (a few micrometres)
of an edge of the face it enters may be missed by Embree and hit by MuJoCo, which then reports
that box, perhaps metres before the surface Embree names (a beam grazing a mullion's corner, a
chair seat's lower edge, or a pane's end where it abuts a mullion's side). Whatever the face and
however the boxes touch, such a ray passes within that rounding of one of the box's edges before
(or at) the hit Embree reports. :class:`EdgeTubes` holds, in a second Embree scene, a box of
half-width ``TUBE_M`` (far above the rounding) around every edge of every static box and finite
plane, and around the creases where two of them interpenetrate (there two surfaces meet away from
either's edges); the geoms whose tubes a ray crosses before its hit are the only ones Embree may
have missed, and :meth:`StaticBvh.cast` judges each with MuJoCo's exact arithmetic.
"""

from __future__ import annotations

import numpy as np

from .kernels import tube_pairs, tube_rays

TUBE_M = 1e-4  # half-width of an edge's tube: about 25 times float32's rounding at 100 m from the origin
_UNIT = np.array([[x, y, z] for z in (-1, 1) for y in (-1, 1) for x in (-1, 1)], dtype=float)
# two orthonormal directions: of any two, one is at least 45 deg from any line (their squared cosines
# to a unit vector sum to at most 1); the first alone is 54.7 deg from each world axis
_PROBES = np.array([[1.0, 1.0, 1.0], [1.0, -1.0, 0.0]]) / np.sqrt([[3.0], [2.0]])
_TRIS = np.array(
    [[0, 2, 1], [1, 2, 3], [4, 5, 6], [5, 7, 6], [0, 1, 4], [1, 5, 4],
     [2, 6, 3], [3, 6, 7], [0, 4, 2], [2, 4, 6], [1, 3, 5], [3, 7, 5]], dtype=np.uint32,
)  # fmt: skip


def _tubes(
    pos: np.ndarray, mat: np.ndarray, half: np.ndarray, finite: np.ndarray, far_m: float
) -> tuple[np.ndarray, np.ndarray]:
    """Corners (T, 8, 3) and owner (T,) of the tubes around the edges of the boxes of half sizes
    ``half`` (G, 3); a plane is a box of no thickness, infinite along its sides not ``finite``
    (G x 3): its edges along such a side reach ``far_m``, and it has none across it."""
    corners, owner = [], []
    for i in range(3):  # edges along the box's axis i, at the four (side j, side k) corners
        j, k = [a for a in range(3) if a != i]
        for sj in (-1.0, 1.0):
            for sk in (-1.0, 1.0):
                ok = finite[:, j] & finite[:, k]
                # an edge at a plane's zero thickness exists twice (sides -1 and +1 coincide): once
                ok &= (sj > 0) | (half[:, j] > 0)
                ok &= (sk > 0) | (half[:, k] > 0)
                g = np.flatnonzero(ok)
                if len(g) == 0:
                    continue
                centre = np.zeros((len(g), 3))
                centre[:, j], centre[:, k] = sj * half[g, j], sk * half[g, k]
                ext = np.full((len(g), 3), TUBE_M)
                ext[:, i] = np.where(finite[g, i], half[g, i] + TUBE_M, far_m)
                local = centre[:, None, :] + _UNIT[None] * ext[:, None, :]  # (n, 8, 3)
                R = mat[g].reshape(-1, 3, 3)
                corners.append(np.einsum("gij,gvj->gvi", R, local) + pos[g, None, :])
                owner.append(g)
    if not corners:
        return np.zeros((0, 8, 3)), np.zeros(0, dtype=np.int64)
    return np.concatenate(corners), np.concatenate(owner).astype(np.int64)


def _crossings(pos: np.ndarray, mat: np.ndarray, half: np.ndarray) -> tuple[np.ndarray, ...]:
    """Tubes (corners, owners (T, 2), then the zones' bounds) where two geoms' surfaces cross away
    from their edges: for each pair that interpenetrates (a box sunk into another, a plane through
    a box), the edges of their common box when they share their axes (the crossings lie on them),
    else a zone, the whole of their common world bounds (grown by ``TUBE_M``). One tube names both
    geoms (Embree reports one of two coincident triangles)."""
    R = mat.reshape(-1, 3, 3)
    ext = np.einsum("gij,gj->gi", np.abs(R), half)
    lo, hi = pos - ext, pos + ext
    inter = np.ones((len(pos), len(pos)), dtype=bool)
    for c in range(3):  # strictly overlapping on every axis (touching boxes do not cross)
        inter &= (lo[:, None, c] < hi[None, :, c] - 1e-9) & (hi[:, None, c] > lo[None, :, c] + 1e-9)
    a, b = np.nonzero(np.triu(inter, 1))
    corners, owner = [np.zeros((0, 8, 3))], [np.zeros((0, 2), dtype=np.int64)]
    same = np.all(mat[a] == mat[b], axis=1)
    sa, sb = a[same], b[same]
    if len(sa):  # the common box in the first geom's frame, and its edges
        d = np.einsum("gji,gj->gi", R[sa], pos[sb] - pos[sa])
        c_lo, c_hi = np.maximum(-half[sa], d - half[sb]), np.minimum(half[sa], d + half[sb])
        centre = pos[sa] + np.einsum("gij,gj->gi", R[sa], 0.5 * (c_lo + c_hi))
        box_half = 0.5 * (c_hi - c_lo)
        tc, to = _tubes(centre, mat[sa], box_half, np.ones((len(sa), 3), dtype=bool), 0.0)
        corners.append(tc)
        owner.append(np.column_stack([sa[to], sb[to]]))
    ra, rb = a[~same], b[~same]
    zlo = np.maximum(lo[ra], lo[rb]) - TUBE_M
    zhi = np.minimum(hi[ra], hi[rb]) + TUBE_M
    if len(ra):
        corners.append(0.5 * (zlo + zhi)[:, None, :] + _UNIT[None] * (0.5 * (zhi - zlo))[:, None, :])
        owner.append(np.column_stack([ra, rb]))
    return np.concatenate(corners), np.concatenate(owner).astype(np.int64), zlo, zhi


class EdgeTubes:
    """The edge tubes of static boxes and planes (BVH geom order), in one Embree mesh."""

    def __init__(self, pos: np.ndarray, mat: np.ndarray, size: np.ndarray, plane: np.ndarray, far_m: float) -> None:
        import open3d as o3d

        self.far_m = far_m  # the reach of a ray without a hit: beyond the whole scene
        half = np.where(plane[:, None], np.column_stack([size[:, :2], np.zeros(len(size))]), size)
        # a plane's side of size <= 0 is infinite: it has no edge across it
        finite = ~plane[:, None] | np.column_stack([size[:, 0] > 0, size[:, 1] > 0, np.ones(len(size), dtype=bool)])
        corners, own = _tubes(pos, mat, half, finite, far_m)
        c2, o2, self._zone_lo, self._zone_hi = _crossings(pos, mat, np.where(finite, half, far_m))
        # each tube's geoms (a crossing's two; an edge's one, twice)
        self.owner = np.concatenate([np.column_stack([own, own]), o2])
        # tubes along the world axes (every geom's axes are: a building's walls) need one probe
        self._probes = _PROBES[:1] if np.all(np.isin(mat, (-1.0, 0.0, 1.0))) else _PROBES
        corners = np.concatenate([corners, c2])
        self.scene = None
        if len(self.owner):
            tris = (_TRIS[None] + 8 * np.arange(len(self.owner), dtype=np.uint32)[:, None, None]).reshape(-1, 3)
            self.scene = o3d.t.geometry.RaycastingScene()
            self.scene.add_triangles(o3d.core.Tensor(corners.reshape(-1, 3).astype(np.float32)), o3d.core.Tensor(tris))

    def crossed(self, o: np.ndarray, u: np.ndarray, reach: np.ndarray, nthreads: int) -> tuple[np.ndarray, np.ndarray]:
        """(ray, geom) pairs, each once: the geoms whose edge tubes each ray (origin ``o``, unit
        direction ``u``) meets within ``reach`` of its origin (inf: anywhere), or starts in.

        Embree first tests each ray up to its reach alone (any tube, stopping at the first: rays
        that meet none, nearly all of them, cost one cheap test) and probes each distinct origin
        for a tube around it; only the rays flagged list their tubes.
        """
        import open3d as o3d

        none = np.zeros(0, dtype=np.int64)
        if self.scene is None or len(o) == 0:
            return none, none
        # the ray scaled to its reach (1 um and float32's rounding to spare): Embree's t = 1 there;
        # the probes of _in_tube in the same call (one call costs less than two); one compiled pass
        n, k = len(o), len(self._probes)
        o, u, reach = _f64(o), _f64(u), _f64(reach)
        span, run_of, head = np.empty(n), np.empty(n, dtype=np.int64), np.empty(n, dtype=np.int64)
        r = np.empty((n + k * n, 6), dtype=np.float32)
        n_heads = tube_rays(o, u, reach, self.far_m, self._probes * (10.0 * TUBE_M), span, run_of, head, r)
        heads = o[head[:n_heads]]
        hit = self.scene.test_occlusions(o3d.core.Tensor(r[: n + k * n_heads]), tfar=1.0, nthreads=nthreads).numpy()
        flag = hit[:n] | self._in_tube(heads, hit[n:].reshape(-1, k))[run_of]
        rows = np.flatnonzero(flag)
        if len(rows) == 0:
            return none, none
        r = np.empty((len(rows), 6), dtype=np.float32)
        r[:, :3], r[:, 3:] = o[rows], u[rows]
        li = self.scene.list_intersections(o3d.core.Tensor(r), nthreads=nthreads)
        prim = li["primitive_ids"].numpy()
        # a tube met before the reach, or left an odd number of times (the ray starts in it)
        h, q = np.empty(2 * len(prim), dtype=np.int64), np.empty(2 * len(prim), dtype=np.int64)
        m = tube_pairs(rows, li["ray_splits"].numpy().astype(np.int64), prim, li["t_hit"].numpy(), span, self.owner, h, q)
        return h[:m], q[:m]

    def _in_tube(self, heads: np.ndarray, probed: np.ndarray) -> np.ndarray:
        """Origins ``heads`` that may lie in a tube: a short probe from inside meets the tube's
        surface along one of two orthogonal directions, at least 45 deg from the tube's axis, within
        4 half-widths (probes 10 long, ``probed``: whether each met a tube; where every tube lies
        along a world axis, the first alone, 54.7 deg from each); or in a crossing's zone (by its
        bounds). Each run of equal origins (a primary window) is tested once."""
        inside = probed.any(axis=1)
        for lo, hi in zip(self._zone_lo, self._zone_hi):  # zones are few (differently turned geoms that cross)
            within = np.ones(len(heads), dtype=bool)
            for c in range(3):
                within &= (heads[:, c] >= lo[c]) & (heads[:, c] <= hi[c])
            inside |= within
        return inside


def _f64(a: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(a, dtype=np.float64)


__all__ = ["TUBE_M", "EdgeTubes"]
