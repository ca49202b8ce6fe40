"""Static geometry in a BVH (Embree, through Open3D's ``RaycastingScene``), hits as MuJoCo computes them.

A procedural building is hundreds of static boxes and finite planes; ``mj_multiRay`` tests each ray
against every geom its bounding-angle cull lets through, so a sweep's cost grows with the building.
Embree's BVH finds each ray's first triangle in about log(triangles) steps, whatever the
building's size. :class:`StaticBvh` puts every static ray-visible box and plane (infinite planes
as a quad far beyond the scene) in one Embree scene, one mesh per geom, and then recomputes the
hit on the geom Embree names with MuJoCo's own arithmetic in float64 (``ray_box``, ``ray_plane``
of ``engine_ray.c``, operation for operation): the distance and the normal are MuJoCo's, bit for
bit, whenever Embree names the geom MuJoCo would. Embree casts in single precision, so it can
name another geom only where two surfaces lie within its rounding (~1e-6 of the range) of each
other: a beam grazing a box's silhouette edge, coplanar faces meeting at a seam, or two faces
closer than a few micrometres. When the exact recomputation rejects Embree's geom (a plane seen
from behind, which MuJoCo does not hit, an edge Embree's rounding caught, or the surface a
secondary ray has just left, which float32 rounds its start back onto), the ray is cast again from
just past that hit, the geoms whose boxes hold the hit point judged exactly (:meth:`StaticBvh._recast`);
where that hit is rejected too, the ray's every Embree intersection is listed and the nearest one
the exact test accepts is taken. Embree can
also miss a box whose edge a ray grazes where MuJoCo hits it (a mullion's corner, a pane's end
against a mullion's side), metres before the surface it names: the geoms whose edges a ray passes
near before its hit (:mod:`~exobench.envs.sensors.lidar.edges`) are judged exactly too.

Curved static geoms (spheres, cylinders, capsules, ellipsoids: a tessellation would change their
distances by its sag) and every moving geom (the exoskeleton, pedestrians) are left to MuJoCo.
:class:`Proxies` bounds each of them by an enlarged oriented box in a small per-sweep Embree scene,
so a secondary ray (whose origin is its own) is sent to ``mj_ray`` only when it may reach one of
them before the static hit.
"""

from __future__ import annotations

import numpy as np

from .edges import TUBE_M, EdgeTubes
from .kernels import (
    MJMINVAL,
    boxes_before,
    exact_hits_into,
    face_hits_into,
    first_hits,
    near_hits,
    nearest_listed,
    odd_crossings,
    proxy_hits,
    seams,
)

_PROXY_MARGIN_M = 1e-3  # proxy boxes are this much larger than the geom's box, beyond float32 rounding

_BOX_VERTS = np.array([[x, y, z] for z in (-1, 1) for y in (-1, 1) for x in (-1, 1)], dtype=float)
_BOX_TRIS = np.array(
    [[0, 2, 1], [1, 2, 3], [4, 5, 6], [5, 7, 6], [0, 1, 4], [1, 5, 4],
     [2, 6, 3], [3, 6, 7], [0, 4, 2], [2, 4, 6], [1, 3, 5], [3, 7, 5]], dtype=np.uint32,
)  # fmt: skip
_c = _BOX_VERTS[_BOX_TRIS].mean(axis=1)
_BOX_FACE_NORMALS = np.eye(3)[np.argmax(np.abs(_c), axis=1)] * np.sign(_c[np.arange(12), np.argmax(np.abs(_c), axis=1)])[:, None]
_TRI_FACE = 2 * np.argmax(np.abs(_BOX_FACE_NORMALS), axis=1) + (_BOX_FACE_NORMALS.sum(axis=1) > 0)
_QUAD_VERTS = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], dtype=float)
_QUAD_TRIS = np.array([[0, 1, 2], [0, 2, 3]], dtype=np.uint32)


def _scene(boxes: list[tuple[np.ndarray, np.ndarray]]) -> object:
    """An Embree scene of one mesh per (world vertices, triangles); mesh ids are list positions."""
    import open3d as o3d

    scene = o3d.t.geometry.RaycastingScene()
    for verts, tris in boxes:
        scene.add_triangles(o3d.core.Tensor(verts.astype(np.float32)), o3d.core.Tensor(tris))
    return scene


def embree_rays(o: np.ndarray, u: np.ndarray) -> object:
    """The rays (origins, directions) as Embree takes them (float32), for :meth:`StaticBvh.cast` and
    :meth:`Proxies.may_hit_before` of the same rays."""
    import open3d as o3d

    r = np.empty((len(o), 6), dtype=np.float32)
    r[:, :3], r[:, 3:] = o, u
    return o3d.core.Tensor(r)


_SHIFT_M = 0.5 * TUBE_M  # a rejected hit's recast starts this far past it (StaticBvh._recast), far above float32's rounding
_PROBE = np.array([0.2672612419124244, 0.5345224838248488, 0.8017837257372732])  # (1, 2, 3) / |(1, 2, 3)|
_EDGE_M = 1e-4  # hits this near a face's edge are checked against every face (Embree rounds in float32)
_OTHER = np.array([[1, 2], [0, 2], [0, 1]])


def _face_table(pos: np.ndarray, mat: np.ndarray, size: np.ndarray) -> np.ndarray:
    """Per box face (row ``6 geom + face``, face ``2 axis + (side > 0)``) the numbers :func:`face_hits`
    reads, as columns (18, 6G): the rows of ``mat`` for the face's axis i and the two others j, k
    (``mat[a], mat[3 + a], mat[6 + a]``), the geom's position, ``side size[i]``, ``size[j] - _EDGE_M``,
    ``size[k] - _EDGE_M`` and the outward normal ``side (mat[i], mat[3 + i], mat[6 + i])``: one gather
    per column instead of gathering whole geom rows and then the face's entries."""
    g = len(pos)
    t = np.empty((18, g, 6))
    for face in range(6):
        i, side = face // 2, (1.0 if face % 2 else -1.0)
        j, k = _OTHER[i]
        for c, a in enumerate((i, j, k)):
            t[3 * c : 3 * c + 3, :, face] = mat[:, [a, 3 + a, 6 + a]].T
        t[9:12, :, face] = pos.T
        t[12, :, face] = side * size[:, i]
        t[13, :, face] = size[:, j] - _EDGE_M
        t[14, :, face] = size[:, k] - _EDGE_M
        t[15:18, :, face] = side * mat[:, [i, 3 + i, 6 + i]].T
    return t.reshape(18, 6 * g)


def face_hits(table: np.ndarray, row: np.ndarray, pnt: np.ndarray, vec: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """MuJoCo's ``ray_box`` distance on the box face Embree hit (``row`` of :func:`_face_table`: ``6
    geom + face``), where that face is surely the one MuJoCo picks: the hit lies on the face and
    farther than ``_EDGE_M`` from its edges, so no other face of the box can be reached first (the
    ray meets the box's surface there). Returns (distance, sure) per ray; rays not sure need
    :func:`exact_hits`.

    ``ray_map``'s products and sums in MuJoCo's order, for the face's three axes only.
    """
    n = len(row)
    x, sure = np.empty(n), np.empty(n, dtype=bool)
    face_hits_into(np.ascontiguousarray(table), _i64(row), _f64(pnt), _f64(vec), x, sure)
    return x, sure


def exact_hits(
    pos: np.ndarray, mat: np.ndarray, size: np.ndarray, plane: np.ndarray, pnt: np.ndarray, vec: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """MuJoCo's ``ray_box`` / ``ray_plane`` per ray on its own geom (rows): distance (-1 none), world
    normal, and the face hit (``2 axis + (side > 0)``, a plane's 5; -1 none).

    Operation for operation as ``engine_ray.c`` (``ray_map``'s sums in its order), compiled
    (:mod:`~exobench.envs.sensors.lidar.kernels`).
    """
    n = len(pnt)
    x, nrm, face = np.empty(n), np.empty((n, 3)), np.empty(n, dtype=np.int64)
    exact_hits_into(_f64(pos), _f64(mat), _f64(size), np.ascontiguousarray(plane, dtype=bool), np.arange(n),
                    _f64(pnt), _f64(vec), x, nrm, face)  # fmt: skip
    return x, nrm, face


def _f64(a: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(a, dtype=np.float64)


def _i64(a: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(a, dtype=np.int64)


def _coplanar_partners(
    pos: np.ndarray, mat: np.ndarray, size: np.ndarray, plane: np.ndarray, far_m: float
) -> tuple[tuple[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]]:
    """For each face (``6 geom + face``), the other geoms with a face on the same plane overlapping
    it, facing the same way and facing the other way, as (start, geoms) lists (CSR): where MuJoCo
    and Embree may report different geoms at one distance."""
    g = len(pos)
    n_w, off, lo, hi, valid = [], [], [], [], []
    for face in range(6):
        axis, side = face // 2, (1.0 if face % 2 else -1.0)
        col = mat[:, [axis, 3 + axis, 6 + axis]]
        nw = side * col
        centre = pos + (np.where(plane, 0.0, side * size[:, axis]))[:, None] * col  # a plane's size[2] is its grid
        ext = np.where(plane[:, None], np.where(size[:, :2] > 0, size[:, :2], far_m), 0.0)
        half = np.zeros((g, 3))
        for e in range(3):
            if e == axis:
                continue
            le = np.where(plane, ext[:, min(e, 1)], size[:, e])
            half += np.abs(mat[:, [e, 3 + e, 6 + e]]) * le[:, None]
        n_w.append(nw)
        off.append(np.einsum("ij,ij->i", nw, centre))
        lo.append(centre - half)
        hi.append(centre + half)
        valid.append(~plane | (face == 5))
    nw, c = np.stack(n_w, 1).reshape(-1, 3), np.stack(off, 1).reshape(-1)
    lo, hi, ok = np.stack(lo, 1).reshape(-1, 3), np.stack(hi, 1).reshape(-1, 3), np.stack(valid, 1).reshape(-1)
    geom_of = np.repeat(np.arange(g), 6)
    lists: tuple[list[list[int]], list[list[int]]] = ([[] for _ in range(6 * g)], [[] for _ in range(6 * g)])
    tol = TUBE_M  # faces this near one plane: float32 may order them either way (a candidate too many costs nothing)
    for f in np.flatnonzero(ok):
        dot = nw @ nw[f]
        touch = ok & np.all((lo <= hi[f] + tol) & (hi >= lo[f] - tol), axis=1) & (geom_of != geom_of[f])
        same = touch & (dot > 1 - 1e-9) & (np.abs(c - c[f]) < tol)
        opposite = touch & (dot < -1 + 1e-9) & (np.abs(c + c[f]) < tol)
        lists[0][f] = sorted(set(geom_of[same].tolist()))
        lists[1][f] = sorted(set(geom_of[opposite].tolist()))

    def csr(rows: list[list[int]]) -> tuple[np.ndarray, np.ndarray]:
        start = np.concatenate([[0], np.cumsum([len(r) for r in rows])]).astype(np.int64)
        return start, np.array([q for r in rows for q in r], dtype=np.int64)

    return csr(lists[0]), csr(lists[1])


class StaticBvh:
    """The static boxes and planes ``geoms`` (original ids) of a model, posed as in ``data``, in Embree."""

    def __init__(self, model: object, data: object, geoms: np.ndarray, *, far_m: float) -> None:
        import mujoco

        m = model
        self.geom = np.asarray(geoms, dtype=np.int64)
        self.pos = np.array(data.geom_xpos)[self.geom]  # type: ignore[attr-defined]
        self.mat = np.array(data.geom_xmat)[self.geom]  # type: ignore[attr-defined]
        self.size = np.array(m.geom_size)[self.geom].copy()  # type: ignore[attr-defined]
        self.rbound = np.array(m.geom_rbound)[self.geom]  # type: ignore[attr-defined]
        self.plane = np.array(m.geom_type)[self.geom] == int(mujoco.mjtGeom.mjGEOM_PLANE)  # type: ignore[attr-defined]
        meshes = []
        for k in range(len(self.geom)):
            R = self.mat[k].reshape(3, 3)
            if self.plane[k]:
                half = np.where(self.size[k, :2] > 0, self.size[k, :2], far_m)
                local, tris = _QUAD_VERTS * np.append(half, 0.0), _QUAD_TRIS
            else:
                local, tris = _BOX_VERTS * self.size[k], _BOX_TRIS
            meshes.append((local @ R.T + self.pos[k], tris))
        self.scene = _scene(meshes)
        self.faces = _face_table(self.pos, self.mat, self.size)
        self.same_face, self.opposite_face = _coplanar_partners(self.pos, self.mat, self.size, self.plane, far_m)
        # each geom's world box, a little larger (the hit points of nearly coplanar faces, rounded)
        self.lo = np.array([v.min(axis=0) for v, _ in meshes]).reshape(-1, 3) - TUBE_M
        self.hi = np.array([v.max(axis=0) for v, _ in meshes]).reshape(-1, 3) + TUBE_M
        self.edges = EdgeTubes(self.pos, self.mat, self.size, self.plane, far_m)
        self.neighbours = _overlapping(self.lo, self.hi)
        self._no_skip = np.zeros(len(self.geom), dtype=bool)
        self._row = np.full(int(m.ngeom), -1, dtype=np.int64)  # type: ignore[attr-defined]
        self._row[self.geom] = np.arange(len(self.geom))

    def row_of(self, geoms: np.ndarray) -> np.ndarray:
        """The BVH rows of the original geom ids ``geoms`` (-1 for a geom not in the BVH, or -1)."""
        return np.where(geoms >= 0, self._row[np.maximum(geoms, 0)], -1)

    def exact_on(self, geoms: np.ndarray, o: np.ndarray, u: np.ndarray) -> np.ndarray:
        """MuJoCo's distance from each ray (``o, u``) to its geom of ``geoms`` (original ids), -1 where
        the ray misses it or the geom is not one of these."""
        k = self.row_of(geoms)
        x = np.full(len(o), -1.0)
        rows = np.flatnonzero(k >= 0)
        if len(rows):
            g = k[rows]
            x[rows] = exact_hits(self.pos[g], self.mat[g], self.size[g], self.plane[g], o[rows], u[rows])[0]
        return x

    def cast(
        self, o: np.ndarray, u: np.ndarray, nthreads: int, cutoff: float | None = None, rank: np.ndarray | None = None,
        inside: bool = False, skip: np.ndarray | None = None, rays: object | None = None,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(original geom or -1, distance or -1, normal) per ray, as ``mj_ray`` on these geoms alone.

        ``cutoff``: geoms whose bounding sphere lies farther from the ray's origin are not hit (as
        ``mj_multiRay`` culls them). ``rank`` (per original geom; None: the geom id) orders the
        geoms as the MuJoCo reference visits them: of two faces on one plane hit at the same
        distance (a seam), the first visited is reported, as MuJoCo keeps the first of equal hits.
        ``inside``: rays may start inside a geom (see :meth:`_seams`). ``skip`` (per BVH geom):
        geoms not to hit (the sensor's own body, when it is welded to the world). ``rays``: the
        rays' :func:`embree_rays`, if already made.
        """
        n = len(o)
        if n == 0 or len(self.geom) == 0:
            return np.full(n, -1, dtype=np.int32), np.full(n, -1.0), np.zeros((n, 3))
        o, u = _f64(o), _f64(u)
        rays = embree_rays(o, u) if rays is None else rays
        ans = self.scene.cast_rays(rays, nthreads=nthreads)
        gid, x, nrm = np.full(n, -1, dtype=np.int64), np.full(n, -1.0), np.zeros((n, 3))
        face, state = np.full(n, -1, dtype=np.int64), np.zeros(n, dtype=np.int8)
        cut = -1.0 if cutoff is None else float(cutoff)
        skip = self._no_skip if skip is None else np.ascontiguousarray(skip, dtype=bool)
        # a box hit away from the face's edges: that face's distance; the rest: every face
        first_hits(ans["geometry_ids"].numpy(), ans["primitive_ids"].numpy(), _TRI_FACE, len(self.geom), self.faces,
                   self.pos, self.mat, self.size, self.plane, self.rbound, o, u, cut, skip,
                   gid, x, nrm, face, state)  # fmt: skip
        rk = self.geom if rank is None else np.asarray(rank)[self.geom]
        self._seams(o, u, cut, rk, inside, skip, gid, x, nrm, face, state)
        good = state == 1
        gid = np.where(good, gid, -1)
        dist = np.where(good, x, -1.0)
        nrm[~good] = 0.0
        redo = np.flatnonzero(state == 2)
        if len(redo):
            redo = self._recast(ans, redo, o, u, nthreads, cut, rk, inside, skip, gid, dist, nrm)
        if len(redo):
            self._listed(rays[redo], redo, o, u, cutoff, rk, gid, dist, nrm, None if skip is self._no_skip else skip)
        self._grazed(o, u, nthreads, cutoff, rk, None if skip is self._no_skip else skip, gid, dist, nrm)
        out = np.where(gid >= 0, self.geom[np.maximum(gid, 0)], -1).astype(np.int32)
        return out, dist, nrm

    def _recast(self, ans: dict, redo: np.ndarray, o: np.ndarray, u: np.ndarray, nthreads: int, cut: float,
                rk: np.ndarray, inside: bool, skip: np.ndarray, gid: np.ndarray, dist: np.ndarray,
                nrm: np.ndarray) -> np.ndarray:  # fmt: skip
        """The rays ``redo``, whose geom Embree named (``ans``) the exact test rejected, cast once more by
        Embree from ``_SHIFT_M`` past that hit, and judged from their own origins: their hits (``gid, dist,
        nrm``, updated in place); returns those the recast's exact test rejected again, for :meth:`_listed`.

        Nearly all such rays are secondary ones starting 1 um past the surface they leave, which float32
        rounds them back onto (Embree names it at t = 0); listing their whole paths through the building
        cost about 1 us a ray. Embree's nearest hit was the rejected one, so it lists no other before it;
        a geom met within the shift past it has a surface point within ``_SHIFT_M`` of that hit point
        ``p``, so its box (``lo, hi``, grown by ``TUBE_M``) holds ``p`` and overlaps the named geom's
        box: those neighbours are judged by their exact hits (:func:`kernels.near_hits`), the recast's
        hit goes through the same exact test and seams as a first cast, and the edge tubes
        (:meth:`_grazed`) follow for every ray as before."""
        m = len(redo)
        named = ans["geometry_ids"].numpy()[redo].astype(np.int64)
        t1 = ans["t_hit"].numpy()[redo].astype(np.float64)
        o_r, u_r = o[redo], u[redo]
        p = o_r + t1[:, None] * u_r
        again = self.scene.cast_rays(embree_rays(p + _SHIFT_M * u_r, u_r), nthreads=nthreads)
        g2, x2, n2 = np.full(m, -1, dtype=np.int64), np.full(m, -1.0), np.zeros((m, 3))
        f2, s2 = np.full(m, -1, dtype=np.int64), np.zeros(m, dtype=np.int8)
        first_hits(again["geometry_ids"].numpy(), again["primitive_ids"].numpy(), _TRI_FACE, len(self.geom),
                   self.faces, self.pos, self.mat, self.size, self.plane, self.rbound, o_r, u_r, cut, skip,
                   g2, x2, n2, f2, s2)  # fmt: skip
        # a box the ray starts in holds its origin, within t1 of p: where every t1 is within the shift,
        # near_hits judges each such box exactly, so the seams need not probe for them
        self._seams(o_r, u_r, cut, rk, inside and bool(np.any(t1 > _SHIFT_M)), skip, g2, x2, n2, f2, s2)
        start, geoms = self.neighbours
        near_hits(named, p, start, geoms, self.lo, self.hi, self.pos, self.mat, self.size, self.plane, self.rbound,
                  _i64(rk), skip, o_r, u_r, cut, g2, x2, n2, s2)  # fmt: skip
        good = s2 == 1
        gid[redo] = np.where(good, g2, -1)
        dist[redo] = np.where(good, x2, -1.0)
        nrm[redo] = np.where(good[:, None], n2, 0.0)
        return redo[s2 == 2]

    def _seams(self, o: np.ndarray, u: np.ndarray, cut: float, rk: np.ndarray, inside: bool, skip: np.ndarray,
               gid: np.ndarray, x: np.ndarray, nrm: np.ndarray, face: np.ndarray, state: np.ndarray) -> None:  # fmt: skip
        """Where the face hit shares its plane with faces of other geoms, the hit MuJoCo reports:
        the nearest exact one, of equal ones the first in ``rk`` (per BVH geom). ``gid, x, nrm``
        (per ray, for the rays of ``state`` 1) are updated in place (:func:`kernels.seams`).

        Faces facing the same way meet at seams; a face facing the other way ties only where the
        ray leaves a box it started in (a beam crossing a pane) through a face another box is
        entered by: checked for the hits that leave a box and, with ``inside`` (rays that may start
        inside a box: the secondary ones), for hits entering such a face, against every box the
        ray starts in (:meth:`_containing`). Any geom added as a candidate is
        judged by its exact hit, so a candidate too many never changes a result.
        """
        n = len(o)
        in_start, in_geom = np.zeros(n + 1, dtype=np.int64), np.zeros(0, dtype=np.int64)
        if inside:
            start, _ = self.opposite_face
            f = 6 * np.maximum(gid, 0) + np.maximum(face, 0)
            # entering a face another box leaves through (a little generous: a candidate too many changes nothing)
            nu = nrm[:, 0] * u[:, 0] + nrm[:, 1] * u[:, 1] + nrm[:, 2] * u[:, 2]
            back = np.flatnonzero((state == 1) & (nu < 1e-12) & (start[f + 1] > start[f]))
            if len(back):
                in_start, in_geom = self._containing(o, back)
        (s0, g0), (s1, g1) = self.same_face, self.opposite_face
        seams(s0, g0, s1, g1, in_start, in_geom, self.pos, self.mat, self.size, self.plane, self.rbound, self.lo,
              self.hi, skip, _i64(rk), o, u, cut, gid, x, nrm, face, state)  # fmt: skip

    def _containing(self, o: np.ndarray, rays: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The boxes each ray of ``rays`` (ascending) starts in, as CSR over all rays (start (N + 1),
        geoms): a probe ray from inside a closed box crosses its surface an odd number of times
        (along a direction no wall is aligned with)."""
        import open3d as o3d

        p = np.empty((len(rays), 6), dtype=np.float32)
        p[:, :3], p[:, 3:] = o[rays], _PROBE
        li = self.scene.list_intersections(o3d.core.Tensor(p))
        ids = li["geometry_ids"].numpy()
        start, geoms = np.empty(len(o) + 1, dtype=np.int64), np.empty(len(ids), dtype=np.int64)
        m = odd_crossings(_i64(rays), li["ray_splits"].numpy().astype(np.int64), ids, self.plane, len(o), start, geoms)
        return start, geoms[:m]

    def _culled(self, k: np.ndarray, o: np.ndarray, cutoff: float) -> np.ndarray:
        out = np.zeros(len(k), dtype=bool)
        if len(k) == 0:
            return out
        # geoms whose bounding sphere lies within the cut-off from every point of the origins' box
        # (1 um to spare, far above the rounding of the distance) are culled for none of the rays
        lo, hi = _col_min_max(o)
        span = np.maximum(np.abs(self.pos - lo), np.abs(self.pos - hi))
        safe = np.sqrt(np.einsum("ij,ij->i", span, span)) + 1e-6 < cutoff + self.rbound
        test = np.flatnonzero(~safe[k])
        if len(test):
            d = self.pos[k[test]] - o[test]
            out[test] = np.sqrt(d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1] + d[:, 2] * d[:, 2]) > cutoff + self.rbound[k[test]]
        return out

    def _grazed(self, o: np.ndarray, u: np.ndarray, nthreads: int, cutoff: float | None, rk: np.ndarray,
                skip: np.ndarray | None, gid: np.ndarray, dist: np.ndarray, nrm: np.ndarray) -> None:  # fmt: skip
        """Geoms the rays pass within Embree's rounding of an edge of, before their hit (``gid,
        dist, nrm``, BVH geoms, updated in place): MuJoCo's exact hit on each, the nearest kept, of
        equal ones the first in ``rk`` (see :mod:`~exobench.envs.sensors.lidar.edges`)."""
        h, q = self.edges.crossed(o, u, np.where(dist >= 0.0, dist, np.inf), nthreads)
        keep = q != gid[h]
        if skip is not None:
            keep &= ~skip[q]
        h, q = h[keep], q[keep]
        if len(h) == 0:
            return
        x2, n2, _ = exact_hits(self.pos[q], self.mat[q], self.size[q], self.plane[q], o[h], u[h])
        if cutoff is not None:
            x2 = np.where(self._culled(q, o[h], cutoff), -1.0, x2)
        now, g_now = dist[h], gid[h]
        better = (x2 >= 0.0) & ((now < 0.0) | (x2 < now) | ((x2 == now) & (rk[q] < rk[np.maximum(g_now, 0)])))
        h, q, x2, n2 = h[better], q[better], x2[better], n2[better]
        if len(h) == 0:
            return
        order = np.lexsort((rk[q], x2, h))
        win = order[np.append(True, h[order][1:] != h[order][:-1])]
        gid[h[win]], dist[h[win]], nrm[h[win]] = q[win], x2[win], n2[win]

    def _listed(self, rays: object, redo: np.ndarray, o: np.ndarray, u: np.ndarray, cutoff: float | None,
                rk: np.ndarray, gid: np.ndarray, dist: np.ndarray, nrm: np.ndarray,
                skip: np.ndarray | None) -> None:  # fmt: skip
        """The nearest exact hit among every Embree intersection of the rays ``redo``."""
        import open3d as o3d

        li = self.scene.list_intersections(o3d.core.Tensor(rays.numpy()))
        splits = li["ray_splits"].numpy().astype(np.int64)
        ids = li["geometry_ids"].numpy().astype(np.int64)
        nearest_listed(_i64(redo), splits, ids, self.pos, self.mat, self.size, self.plane, self.rbound, _i64(rk),
                       self._no_skip if skip is None else np.ascontiguousarray(skip, dtype=bool), o, u,
                       -1.0 if cutoff is None else float(cutoff), gid, dist, nrm)  # fmt: skip


class Proxies:
    """Enlarged oriented boxes around the geoms MuJoCo casts (``geoms``), posed as in ``data``."""

    def __init__(self, model: object, data: object, geoms: np.ndarray) -> None:
        m = model
        self.geom = np.asarray(geoms, dtype=np.int64)
        aabb = np.asarray(m.geom_aabb)[self.geom]  # type: ignore[attr-defined]
        pos = np.asarray(data.geom_xpos)[self.geom]  # type: ignore[attr-defined]
        mat = np.asarray(data.geom_xmat)[self.geom]  # type: ignore[attr-defined]
        self.pos, self.mat = pos.copy(), mat.copy()  # the poses the boxes were built for (``posed_as``)
        g = len(self.geom)
        R = mat.reshape(-1, 3, 3)
        half = aabb[:, 3:] * (1.0 + 1e-6) + _PROXY_MARGIN_M
        local = aabb[:, None, :3] + _BOX_VERTS[None] * half[:, None]  # (G, 8, 3)
        # every geom's corners at once (the boxes only choose the rays MuJoCo casts, 1 mm to spare)
        world = local[:, :, 0:1] * R[:, None, :, 0] + local[:, :, 1:2] * R[:, None, :, 1]
        world = world + local[:, :, 2:3] * R[:, None, :, 2] + pos[:, None]
        # one mesh (one Embree geometry) of all the boxes: building it costs one call, not one per geom
        tris = (_BOX_TRIS[None] + 8 * np.arange(g, dtype=np.uint32)[:, None, None]).reshape(-1, 3)
        self.scene = _scene([(world.reshape(-1, 3), tris)]) if g else None
        self._out_w = np.einsum("gij,tj->gti", R, _BOX_FACE_NORMALS)  # (G, 12, 3) outward
        # world bounds of each proxy box (they contain it): an origin within may be inside it. Only
        # a box that overlaps another can hide that (the ray's first hit enters the other box)
        lo = world.min(axis=1).reshape(-1, 3) - _PROXY_MARGIN_M
        hi = world.max(axis=1).reshape(-1, 3) + _PROXY_MARGIN_M
        touch = np.ones((len(lo), len(lo)), dtype=bool)
        for c in range(3):  # axis by axis (numpy reduces a 3-long last axis slowly)
            touch &= (lo[:, c, None] <= hi[None, :, c]) & (hi[:, c, None] >= lo[None, :, c])
        overlapping = touch.sum(axis=1) > 1
        self._lo, self._hi = lo[overlapping], hi[overlapping]

    def posed_as(self, data: object) -> bool:
        """Whether the geoms are posed in ``data`` as when the boxes were built."""
        return bool(np.array_equal(np.asarray(data.geom_xpos)[self.geom], self.pos)  # type: ignore[attr-defined]
                    and np.array_equal(np.asarray(data.geom_xmat)[self.geom], self.mat))  # type: ignore[attr-defined]

    def may_hit_before(
        self, o: np.ndarray, u: np.ndarray, dist: np.ndarray, nthreads: int, rays: object | None = None
    ) -> np.ndarray:
        """Rays that may reach one of the geoms nearer than ``dist`` (-1: no hit); ``rays``: their
        :func:`embree_rays`, if already made."""
        if self.scene is None or len(o) == 0:
            return np.zeros(len(o), dtype=bool)
        ans = self.scene.cast_rays(embree_rays(o, u) if rays is None else rays, nthreads=nthreads)
        # a hit before ``dist``, or a first hit leaving its box: the ray starts inside a proxy and
        # may meet its geom at once (one compiled pass)
        out = np.empty(len(o), dtype=bool)
        proxy_hits(ans["t_hit"].numpy(), ans["primitive_ids"].numpy(), self._out_w, _f64(u), _f64(dist), out)
        # proxies overlap (the exoskeleton's): a ray starting inside one may first enter another
        if len(self._lo) == 0:
            return out
        within = ~out
        lo, hi = self._lo.min(axis=0), self._hi.max(axis=0)
        for c in range(3):
            within &= (o[:, c] >= lo[c]) & (o[:, c] <= hi[c])
        near = np.flatnonzero(within)
        if len(near):
            # rays cast from one point (a primary window) come in runs: test each run's origin once
            on = o[near]
            run = np.append(True, _rows_differ(on))
            inside = _in_any_box(on[run], self._lo, self._hi)
            out[near] = inside[np.cumsum(run) - 1]
        return out


class FewBoxes:
    """The proxy boxes of a few geoms (``geoms``, posed as in ``data``) tested in a compiled slab loop
    (:func:`~exobench.envs.sensors.lidar.kernels.boxes_before`): for a dozen boxes this costs less than
    building and committing an Embree scene. The same question as :meth:`Proxies.may_hit_before`, in
    float64; a box is the geom's box 1 mm larger, far beyond the rounding of either."""

    def __init__(self, model: object, data: object, geoms: np.ndarray) -> None:
        self.geom = np.asarray(geoms, dtype=np.int64)
        aabb = np.asarray(model.geom_aabb)[self.geom]  # type: ignore[attr-defined]
        self.pos = np.ascontiguousarray(np.asarray(data.geom_xpos)[self.geom], dtype=float)  # type: ignore[attr-defined]
        self.mat = np.ascontiguousarray(np.asarray(data.geom_xmat)[self.geom], dtype=float)  # type: ignore[attr-defined]
        self.ctr = np.ascontiguousarray(aabb[:, :3], dtype=float)
        self.half = np.ascontiguousarray(aabb[:, 3:] * (1.0 + 1e-6) + _PROXY_MARGIN_M, dtype=float)
        # the world box around them all (their corners' bounds, 1 um to spare for the rounding)
        corners = np.einsum("gij,gvj->gvi", self.mat.reshape(-1, 3, 3), self.ctr[:, None] + _BOX_VERTS[None] * self.half[:, None])
        corners = corners + self.pos[:, None]
        self.lo = corners.reshape(-1, 3).min(axis=0) - 1e-6 if len(self.geom) else np.zeros(3)
        self.hi = corners.reshape(-1, 3).max(axis=0) + 1e-6 if len(self.geom) else np.zeros(3)

    def may_hit_before(self, o: np.ndarray, u: np.ndarray, dist: np.ndarray, out: np.ndarray) -> np.ndarray:
        """``out`` (bool per ray, updated in place and returned) set for the rays that may reach one of
        the geoms nearer than ``dist`` (-1: no hit) or start in a box."""
        if len(self.geom) and len(o):
            boxes_before(_f64(o), _f64(u), _f64(dist), self.pos, self.mat, self.ctr, self.half, self.lo, self.hi, out)
        return out


def _overlapping(lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """For each box ``[lo, hi]``, the other boxes overlapping it (closed), as (start (G + 1), boxes): CSR."""
    rows: list[np.ndarray] = []
    for a in range(0, len(lo), 512):  # a block of rows at a time: G x G booleans for a large building
        touch = np.ones((min(512, len(lo) - a), len(lo)), dtype=bool)
        for c in range(3):
            touch &= (lo[a : a + 512, c, None] <= hi[None, :, c]) & (hi[a : a + 512, c, None] >= lo[None, :, c])
        touch[np.arange(len(touch)), a + np.arange(len(touch))] = False
        rows.extend(np.flatnonzero(t) for t in touch)
    start = np.concatenate([[0], np.cumsum([len(r) for r in rows])]).astype(np.int64)
    return start, (np.concatenate(rows) if rows else np.zeros(0)).astype(np.int64)


def _col_min_max(a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per-column minimum and maximum of an (N, 3) array (a reduction over axis 0 of a narrow array
    is slow in numpy: it runs one short inner loop per row)."""
    return (np.array([a[:, c].min() for c in range(3)]), np.array([a[:, c].max() for c in range(3)]))


def _rows_differ(a: np.ndarray) -> np.ndarray:
    """``a[i + 1] != a[i]`` in any column, for the (N, 3) array ``a`` (N - 1 entries)."""
    out = a[1:, 0] != a[:-1, 0]
    for c in (1, 2):
        out |= a[1:, c] != a[:-1, c]
    return out


def _in_any_box(p: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """Whether each point lies in one of the boxes ``[lo, hi]`` (closed): the points sorted by x,
    each box's x range found by bisection, and only those (point, box) pairs tested in y and z."""
    order = np.argsort(p[:, 0], kind="stable")
    xs = p[order, 0]
    a = np.searchsorted(xs, lo[:, 0], side="left")
    b = np.searchsorted(xs, hi[:, 0], side="right")
    cnt = np.maximum(b - a, 0)
    box = np.repeat(np.arange(len(lo)), cnt)
    pt = order[np.repeat(a - (np.cumsum(cnt) - cnt), cnt) + np.arange(int(cnt.sum()))]
    q = p[pt]
    ok = (q[:, 1] >= lo[box, 1]) & (q[:, 1] <= hi[box, 1]) & (q[:, 2] >= lo[box, 2]) & (q[:, 2] <= hi[box, 2])
    out = np.zeros(len(p), dtype=bool)
    out[pt[ok]] = True
    return out


__all__ = ["MJMINVAL", "FewBoxes", "Proxies", "StaticBvh", "embree_rays", "exact_hits"]
