"""Compiled loops (numba) of the BVH caster, the surface labels and a sweep's returns: one pass per ray or point.

After Embree names each ray's geom, the caster recomputes the hit with MuJoCo's arithmetic and
judges the faces that share its plane (:mod:`~exobench.envs.sensors.lidar.bvh`); the labels test
each hit against its geom's surfaces (:mod:`~exobench.envs.sensors.lidar.labels`). In numpy each of
these is a few hundred operations on whole arrays, and a sweep spent more time in their per-call
overhead and temporaries than in the arithmetic. Here each is one loop, with the same operations in
the same order as before: products and sums as written (no fast-math: LLVM neither fuses a product
and a sum into one rounding nor reorders them), IEEE division and square root, so every result is
the numpy version's bit for bit (and so MuJoCo's, ``engine_ray.c``'s ``ray_box`` / ``ray_plane``).
``error_model="numpy"``: a division by zero gives inf or nan as numpy's does (the tests after it
reject those), never an exception.

The functions are compiled on first use and cached on disk (``cache=True``: beside this file, or
in the user's cache directory where that is not writable); ``nogil``: casting threads may run them
side by side.
"""

from __future__ import annotations

import numba
import numpy as np

MJMINVAL = 1e-15  # MuJoCo's mjMINVAL (double precision)

_jit = numba.njit(cache=True, nogil=True, error_model="numpy")
# The helpers called for every ray take scalars only: a compiled call (even one inlined by numba)
# that passes arrays reference-counts them, which cost more than the arithmetic in the loops below;
# those taking arrays (_geom_hit, _normal, _seam_ray) run for the few rays that need them.


@_jit
def _hit(p0, p1, p2, m0, m1, m2, m3, m4, m5, m6, m7, m8, s0, s1, s2, is_plane, o0, o1, o2, u0, u1, u2):  # noqa: ANN001, ANN202 - numba infers the types
    """MuJoCo's ``ray_box`` / ``ray_plane`` of the ray (o, u) on a geom at p with frame m (row-major
    ``geom_xmat``) and size s: (distance or -1, face: ``2 axis + (side > 0)``, a plane's 5, -1 none)."""
    d0, d1, d2 = o0 - p0, o1 - p1, o2 - p2
    lp0 = m0 * d0 + m3 * d1 + m6 * d2
    lp1 = m1 * d0 + m4 * d1 + m7 * d2
    lp2 = m2 * d0 + m5 * d1 + m8 * d2
    lv0 = m0 * u0 + m3 * u1 + m6 * u2
    lv1 = m1 * u0 + m4 * u1 + m7 * u2
    lv2 = m2 * u0 + m5 * u1 + m8 * u2
    if is_plane:  # front face only, within the rendered rectangle (size <= 0: infinite)
        sol = -lp2 / lv2
        q0 = lp0 + sol * lv0
        q1 = lp1 + sol * lv1
        inside = (s0 <= 0 or abs(q0) <= s0) and (s1 <= 0 or abs(q1) <= s1)
        if lv2 <= -MJMINVAL and sol >= 0 and inside:
            return sol, 5
        return -1.0, -1
    # box: the bounding sphere first, then the six faces in MuJoCo's order (axis, then side -1, +1)
    ssz = s0 * s0 + s1 * s1 + s2 * s2
    a = u0 * u0 + u1 * u1 + u2 * u2
    b = u0 * d0 + u1 * d1 + u2 * d2
    c = d0 * d0 + d1 * d1 + d2 * d2 - ssz
    det = b * b - a * c
    if not det >= MJMINVAL:
        return -1.0, -1
    sq = np.sqrt(det)
    if not ((-b - sq) / a >= 0 or (-b + sq) / a >= 0):
        return -1.0, -1
    x, face = -1.0, -1
    for i in range(3):
        if i == 0:
            lpi, lvi, si, lpj, lvj, sj, lpk, lvk, sk = lp0, lv0, s0, lp1, lv1, s1, lp2, lv2, s2
        elif i == 1:
            lpi, lvi, si, lpj, lvj, sj, lpk, lvk, sk = lp1, lv1, s1, lp0, lv0, s0, lp2, lv2, s2
        else:
            lpi, lvi, si, lpj, lvj, sj, lpk, lvk, sk = lp2, lv2, s2, lp0, lv0, s0, lp1, lv1, s1
        if not abs(lvi) > MJMINVAL:
            continue
        for side in (-1.0, 1.0):
            sol = (side * si - lpi) / lvi
            if sol >= 0 and abs(lpj + sol * lvj) <= sj and abs(lpk + sol * lvk) <= sk and (x < 0 or sol < x):
                x, face = sol, 2 * i + (1 if side > 0 else 0)
    return x, face


@_jit
def _geom_hit(pos, mat, size, plane, g, o0, o1, o2, u0, u1, u2):  # noqa: ANN001, ANN202
    """:func:`_hit` on geom ``g`` of the per-geom arrays."""
    m = mat[g]
    return _hit(pos[g, 0], pos[g, 1], pos[g, 2], m[0], m[1], m[2], m[3], m[4], m[5], m[6], m[7], m[8],
                size[g, 0], size[g, 1], size[g, 2], plane[g], o0, o1, o2, u0, u1, u2)  # fmt: skip


@_jit
def _normal(mat, g, face, nrm, r):  # noqa: ANN001, ANN202
    """The world normal of ``face`` of geom ``g`` into ``nrm[r]`` (zero for no face)."""
    if face < 0:
        nrm[r, 0] = nrm[r, 1] = nrm[r, 2] = 0.0
        return
    ax = face // 2
    sg = 1.0 if face % 2 == 1 else -1.0
    nrm[r, 0], nrm[r, 1], nrm[r, 2] = sg * mat[g, ax], sg * mat[g, 3 + ax], sg * mat[g, 6 + ax]


@_jit
def exact_hits_into(pos, mat, size, plane, geom, pnt, vec, x, nrm, face):  # noqa: ANN001, ANN201
    """MuJoCo's hit of each ray (``pnt[r], vec[r]``) on geom ``geom[r]`` (rows of the per-geom
    ``pos, mat, size, plane``) into ``x`` (-1 none), ``nrm``, ``face``."""
    for r in range(len(geom)):
        g = geom[r]
        x[r], face[r] = _geom_hit(pos, mat, size, plane, g, pnt[r, 0], pnt[r, 1], pnt[r, 2], vec[r, 0], vec[r, 1], vec[r, 2])
        _normal(mat, g, face[r], nrm, r)


@_jit
def _face_hit(c0, c1, c2, c3, c4, c5, c6, c7, c8, p0, p1, p2, s, hj, hk, o0, o1, o2, u0, u1, u2):  # noqa: ANN001, ANN202
    """``bvh.face_hits`` of one ray on one face (the columns of its row of the face table: the
    frame's rows for the face's axes i, j, k, the position, ``side size[i]`` and the shrunk half
    sizes j, k): (distance, sure)."""
    d0, d1, d2 = o0 - p0, o1 - p1, o2 - p2
    lp0 = c0 * d0 + c1 * d1 + c2 * d2
    lp1 = c3 * d0 + c4 * d1 + c5 * d2
    lp2 = c6 * d0 + c7 * d1 + c8 * d2
    lv0 = c0 * u0 + c1 * u1 + c2 * u2
    lv1 = c3 * u0 + c4 * u1 + c5 * u2
    lv2 = c6 * u0 + c7 * u1 + c8 * u2
    sol = (s - lp0) / lv0
    return sol, abs(lv0) > MJMINVAL and sol >= 0 and abs(lp1 + sol * lv1) <= hj and abs(lp2 + sol * lv2) <= hk


@_jit
def face_hits_into(t, row, pnt, vec, x, sure):  # noqa: ANN001, ANN201
    for r in range(len(row)):
        f = row[r]
        x[r], sure[r] = _face_hit(t[0, f], t[1, f], t[2, f], t[3, f], t[4, f], t[5, f], t[6, f], t[7, f], t[8, f],
                                  t[9, f], t[10, f], t[11, f], t[12, f], t[13, f], t[14, f],
                                  pnt[r, 0], pnt[r, 1], pnt[r, 2], vec[r, 0], vec[r, 1], vec[r, 2])  # fmt: skip


@_jit
def _beyond(p0, p1, p2, rbound, o0, o1, o2, cutoff):  # noqa: ANN001, ANN202
    """``mj_multiRay``'s cut-off: the geom's bounding sphere lies beyond ``cutoff`` (< 0: none) from the origin."""
    e0, e1, e2 = p0 - o0, p1 - o1, p2 - o2
    return cutoff >= 0 and np.sqrt(e0 * e0 + e1 * e1 + e2 * e2) > cutoff + rbound


@_jit
def first_hits(k, prim, tri_face, n_geom, t, pos, mat, size, plane, rbound, o, u, cutoff, skip,
               gid, x, nrm, face, state):  # noqa: ANN001, ANN201
    """Each ray's hit on the geom Embree names (``k``, ``prim``: its triangle): the sure face's
    distance (``bvh.face_hits``), else the exact one (``exact_hits``); culled beyond ``cutoff``
    (< 0: none) and on ``skip`` geoms. ``state``: 0 no Embree hit, 1 a hit (``gid, x, nrm, face``),
    2 Embree's geom rejected (the ray's every intersection must be listed)."""
    for r in range(len(k)):
        if k[r] >= n_geom:
            continue
        g = np.int64(k[r])
        gid[r] = g
        o0, o1, o2, u0, u1, u2 = o[r, 0], o[r, 1], o[r, 2], u[r, 0], u[r, 1], u[r, 2]
        fc = tri_face[min(np.int64(prim[r]), 11)]
        f = 6 * g + fc
        sure = False
        if not plane[g]:
            xs, sure = _face_hit(t[0, f], t[1, f], t[2, f], t[3, f], t[4, f], t[5, f], t[6, f], t[7, f], t[8, f],
                                 t[9, f], t[10, f], t[11, f], t[12, f], t[13, f], t[14, f], o0, o1, o2, u0, u1, u2)  # fmt: skip
        if sure:
            x[r], face[r] = xs, fc
            nrm[r, 0], nrm[r, 1], nrm[r, 2] = t[15, f], t[16, f], t[17, f]
        else:
            m = mat[g]
            x[r], face[r] = _hit(pos[g, 0], pos[g, 1], pos[g, 2], m[0], m[1], m[2], m[3], m[4], m[5], m[6], m[7], m[8],
                                 size[g, 0], size[g, 1], size[g, 2], plane[g], o0, o1, o2, u0, u1, u2)  # fmt: skip
            _normal(mat, g, face[r], nrm, r)
        if skip[g] or _beyond(pos[g, 0], pos[g, 1], pos[g, 2], rbound[g], o0, o1, o2, cutoff):
            x[r] = -1.0
        state[r] = 1 if x[r] >= 0 else 2


@_jit
def nearest_listed(redo, splits, ids, pos, mat, size, plane, rbound, rk, skip, o, u, cutoff, gid, x, nrm):  # noqa: ANN001, ANN201
    """``StaticBvh._listed``: for each ray ``redo[i]``, of the geoms Embree listed along it
    (``ids[splits[i]:splits[i + 1]]``), the nearest exact hit not culled beyond ``cutoff`` (< 0: none)
    nor on a ``skip`` geom, of equal ones the first in ``rk``, into ``gid, x, nrm`` (rays with none
    are left as they are)."""
    for i in range(len(redo)):
        r = redo[i]
        o0, o1, o2, u0, u1, u2 = o[r, 0], o[r, 1], o[r, 2], u[r, 0], u[r, 1], u[r, 2]
        bx, brank, bg, bf = -1.0, 0, -1, -1
        for a in range(splits[i], splits[i + 1]):
            q = np.int64(ids[a])
            if skip[q]:
                continue
            x2, f2 = _geom_hit(pos, mat, size, plane, q, o0, o1, o2, u0, u1, u2)
            if not x2 >= 0 or _beyond(pos[q, 0], pos[q, 1], pos[q, 2], rbound[q], o0, o1, o2, cutoff):
                continue
            if bg < 0 or x2 < bx or (x2 == bx and rk[q] < brank):
                bx, brank, bg, bf = x2, rk[q], q, f2
        if bg >= 0:
            gid[r], x[r] = bg, bx
            _normal(mat, bg, bf, nrm, r)


@_jit
def near_hits(named, p, nb_start, nb_geom, lo, hi, pos, mat, size, plane, rbound, rk, skip, o, u, cutoff,
              gid, x, nrm, state):  # noqa: ANN001, ANN201
    """``StaticBvh._recast``: for each ray ``r`` not left rejected (``state[r]`` 0 or 1), the geom Embree
    named at ``p[r]`` (``named[r]``) and its neighbours (``nb_start, nb_geom``: CSR of the geoms whose
    boxes ``lo, hi`` overlap its box) whose box holds ``p[r]``, each judged by its exact hit from the
    ray's own origin against the hit in ``gid, x, nrm`` (``state`` 1): the nearest kept, of equal ones
    the first in ``rk``, not culled beyond ``cutoff`` (< 0: none) nor on a ``skip`` geom; ``state``
    becomes 1 where one is kept."""
    for r in range(len(named)):
        if state[r] == 2:
            continue
        px, py, pz = p[r, 0], p[r, 1], p[r, 2]
        o0, o1, o2, u0, u1, u2 = o[r, 0], o[r, 1], o[r, 2], u[r, 0], u[r, 1], u[r, 2]
        k = np.int64(named[r])
        bx, brank, bg, bf = -1.0, 0, -1, -1
        if state[r] == 1:
            bx, brank, bg = x[r], rk[gid[r]], gid[r]
        for a in range(nb_start[k], nb_start[k + 1] + 1):
            q = k if a == nb_start[k + 1] else nb_geom[a]
            if skip[q] or not _in_box(lo[q, 0], lo[q, 1], lo[q, 2], hi[q, 0], hi[q, 1], hi[q, 2], px, py, pz):
                continue
            x2, f2 = _geom_hit(pos, mat, size, plane, q, o0, o1, o2, u0, u1, u2)
            if not x2 >= 0 or _beyond(pos[q, 0], pos[q, 1], pos[q, 2], rbound[q], o0, o1, o2, cutoff):
                continue
            if bg < 0 or x2 < bx or (x2 == bx and rk[q] < brank):
                bx, brank, bg, bf = x2, rk[q], q, f2
        if bf >= 0:
            gid[r], x[r], state[r] = bg, bx, 1
            _normal(mat, bg, bf, nrm, r)


@_jit
def own_first(geoms, row, o, u, x, nb_start, nb_geom, pos, mat, size, plane, lo, hi, rk, others_lo, others_hi,
              out):  # noqa: ANN001, ANN201
    """Rays that surely meet the static box ``geoms[r]`` (original id; ``row``: its BVH row) first, at
    ``x[r]`` (its exact distance, where the ray leaves it): the origin lies in the box, so every geom
    met before is a geom whose box overlaps it. None of its static neighbours (``nb_start, nb_geom``:
    CSR of the BVH geoms whose boxes ``lo, hi`` overlap its box) whose box meets the ray's segment is
    met nearer by its exact hit, nor as near and first in ``rk``; none of the boxes ``others_lo,
    others_hi`` (the moving and curved geoms) overlaps its box. ``out[r]`` True for those rays."""
    clear = np.full(len(lo), -1, dtype=np.int8)  # per BVH geom: no other geom's box overlaps it (1) or one does (0)
    for r in range(len(geoms)):
        out[r] = False
        k = row[geoms[r]]
        if k < 0 or plane[k]:
            continue
        if clear[k] < 0:
            clear[k] = 1
            for b in range(len(others_lo)):
                if (lo[k, 0] <= others_hi[b, 0] and hi[k, 0] >= others_lo[b, 0] and lo[k, 1] <= others_hi[b, 1]
                        and hi[k, 1] >= others_lo[b, 1] and lo[k, 2] <= others_hi[b, 2] and hi[k, 2] >= others_lo[b, 2]):  # fmt: skip
                    clear[k] = 0
                    break
        if clear[k] == 0:
            continue
        o0, o1, o2, u0, u1, u2 = o[r, 0], o[r, 1], o[r, 2], u[r, 0], u[r, 1], u[r, 2]
        m = mat[k]
        d0, d1, d2 = o0 - pos[k, 0], o1 - pos[k, 1], o2 - pos[k, 2]
        if not (abs(m[0] * d0 + m[3] * d1 + m[6] * d2) <= size[k, 0] and abs(m[1] * d0 + m[4] * d1 + m[7] * d2) <= size[k, 1]
                and abs(m[2] * d0 + m[5] * d1 + m[8] * d2) <= size[k, 2]):  # fmt: skip
            continue
        # the segment's bounds: a geom met on it has its hit point there
        e0, e1, e2 = o0 + x[r] * u0, o1 + x[r] * u1, o2 + x[r] * u2
        s0, s1, s2 = min(o0, e0), min(o1, e1), min(o2, e2)
        t0, t1, t2 = max(o0, e0), max(o1, e1), max(o2, e2)
        sure = True
        for a in range(nb_start[k], nb_start[k + 1]):
            q = nb_geom[a]
            if not (lo[q, 0] <= t0 and hi[q, 0] >= s0 and lo[q, 1] <= t1 and hi[q, 1] >= s1 and lo[q, 2] <= t2
                    and hi[q, 2] >= s2):  # fmt: skip
                continue
            x2, _ = _geom_hit(pos, mat, size, plane, q, o0, o1, o2, u0, u1, u2)
            if x2 >= 0 and (x2 < x[r] or (x2 == x[r] and rk[q] < rk[k])):
                sure = False
                break
        out[r] = sure


@_jit
def world_boxes(geoms, aabb, xpos, xmat, margin, lo, hi):  # noqa: ANN001, ANN201
    """World bounds of the boxes ``aabb`` (centre, half sizes in the geom frame) of ``geoms``, posed by
    ``xpos, xmat``, ``margin`` larger, into ``lo, hi``."""
    for i in range(len(geoms)):
        g = geoms[i]
        for a in range(3):
            c = xpos[g, a]
            e = 0.0
            for b in range(3):
                c += xmat[g, 3 * a + b] * aabb[g, b]
                e += abs(xmat[g, 3 * a + b]) * aabb[g, 3 + b]
            lo[i, a] = c - e - margin
            hi[i, a] = c + e + margin


@_jit
def _in_box(lx, ly, lz, hx, hy, hz, px, py, pz):  # noqa: ANN001, ANN202
    return lx <= px <= hx and ly <= py <= hy and lz <= pz <= hz


@_jit
def _seam_ray(r, f, leaving, same_start, same_geom, opp_start, opp_geom, in_start, in_geom, pos, mat, size, plane,
              rbound, lo, hi, skip, rk, o, u, cutoff, gid, x, nrm, px, py, pz):  # noqa: ANN001, ANN202
    """The seam candidates of ray ``r`` (hit point px, py, pz on face row ``f``), in the order the
    numpy version listed them (the same way, the other way if leaving, the boxes it starts in):
    each whose box holds the hit point is judged by its exact hit; the nearest wins, of equal
    ones the first in ``rk``."""
    g = gid[r]
    o0, o1, o2, u0, u1, u2 = o[r, 0], o[r, 1], o[r, 2], u[r, 0], u[r, 1], u[r, 2]
    bx, brank, bg, bf = x[r], rk[g], g, -1
    for part in range(3):
        if part == 0:
            a0, a1, geoms = same_start[f], same_start[f + 1], same_geom
        elif part == 1:
            a0, a1, geoms = opp_start[f], opp_start[f + 1] if leaving else opp_start[f], opp_geom
        else:
            a0, a1, geoms = in_start[r], in_start[r + 1], in_geom
        for a in range(a0, a1):
            q = geoms[a]
            if skip[q] or not _in_box(lo[q, 0], lo[q, 1], lo[q, 2], hi[q, 0], hi[q, 1], hi[q, 2], px, py, pz):
                continue
            x2, f2 = _geom_hit(pos, mat, size, plane, q, o0, o1, o2, u0, u1, u2)
            if _beyond(pos[q, 0], pos[q, 1], pos[q, 2], rbound[q], o0, o1, o2, cutoff):
                continue
            if x2 >= 0 and (x2 < bx or (x2 == bx and rk[q] < brank)):
                bx, brank, bg, bf = x2, rk[q], q, f2
    if bf >= 0:
        gid[r], x[r] = bg, bx
        _normal(mat, bg, bf, nrm, r)


@_jit
def seams(same_start, same_geom, opp_start, opp_geom, in_start, in_geom, pos, mat, size, plane, rbound, lo, hi,
          skip, rk, o, u, cutoff, gid, x, nrm, face, state):  # noqa: ANN001, ANN201
    """``StaticBvh._seams`` for every ray with a hit (``state`` 1): the nearest exact hit of its geom
    and the geoms with a face on the same plane (the same way; the other way where the ray leaves
    through it) and the boxes it starts in (``in_start, in_geom``: per ray, CSR), of equal ones the
    first in ``rk``, each judged only where the ray's hit point lies in its box: nearly no ray has
    such a candidate, so the boxes are tested first, here. ``gid, x, nrm`` are updated."""
    for r in range(len(gid)):
        if state[r] != 1:
            continue
        xh = x[r]
        px, py, pz = o[r, 0] + xh * u[r, 0], o[r, 1] + xh * u[r, 1], o[r, 2] + xh * u[r, 2]
        f = 6 * gid[r] + face[r]
        leaving = nrm[r, 0] * u[r, 0] + nrm[r, 1] * u[r, 1] + nrm[r, 2] * u[r, 2] > -1e-12
        near = False
        for a in range(same_start[f], same_start[f + 1]):
            q = same_geom[a]
            near |= _in_box(lo[q, 0], lo[q, 1], lo[q, 2], hi[q, 0], hi[q, 1], hi[q, 2], px, py, pz)
        if leaving:
            for a in range(opp_start[f], opp_start[f + 1]):
                q = opp_geom[a]
                near |= _in_box(lo[q, 0], lo[q, 1], lo[q, 2], hi[q, 0], hi[q, 1], hi[q, 2], px, py, pz)
        near |= in_start[r + 1] > in_start[r]
        if near:
            _seam_ray(r, f, leaving, same_start, same_geom, opp_start, opp_geom, in_start, in_geom, pos, mat, size,
                      plane, rbound, lo, hi, skip, rk, o, u, cutoff, gid, x, nrm, px, py, pz)  # fmt: skip


@_jit
def tube_rays(o, u, reach, far_m, probes, span, run_of, head, r):  # noqa: ANN001, ANN201
    """``EdgeTubes.crossed``'s Embree rays (float32, ``r``): each ray (``o``, ``u``) scaled to its
    ``span`` (written: its ``reach`` with 1 um and float32's rounding to spare, ``far_m`` where the
    reach is infinite), then the probes from the first ray of each run of equal origins (``head``:
    that ray; ``run_of``: each ray's run), ``len(probes)`` rows each. Returns the number of runs."""
    n, k = len(o), len(probes)
    h = -1
    for i in range(n):
        s = reach[i] * (1.0 + 1e-6) + 1e-6 if np.isfinite(reach[i]) else far_m
        span[i] = s
        o0, o1, o2 = o[i, 0], o[i, 1], o[i, 2]
        r[i, 0], r[i, 1], r[i, 2] = o0, o1, o2
        r[i, 3], r[i, 4], r[i, 5] = u[i, 0] * s, u[i, 1] * s, u[i, 2] * s
        if i == 0 or o0 != o[i - 1, 0] or o1 != o[i - 1, 1] or o2 != o[i - 1, 2]:
            h += 1
            head[h] = i
            for j in range(k):
                row = n + h * k + j
                r[row, 0], r[row, 1], r[row, 2] = o0, o1, o2
                r[row, 3], r[row, 4], r[row, 5] = probes[j, 0], probes[j, 1], probes[j, 2]
        run_of[i] = h
    return h + 1


@_jit
def tube_pairs(rows, splits, prim, t, span, owner, h_out, q_out):  # noqa: ANN001, ANN201
    """``EdgeTubes.crossed``'s (ray, geom) pairs from the listed intersections of the rays ``rows``
    (``splits``: CSR; ``prim``: triangle, 12 per tube; ``t``: distance): the owners of each tube
    met within the ray's ``span`` or met an odd number of times (the ray starts in it), each pair
    once, sorted by ray then geom. Returns the number of pairs written to ``h_out, q_out``."""
    m = 0
    for i in range(len(rows)):
        a0, a1 = splits[i], splits[i + 1]
        start = m
        for a in range(a0, a1):
            tube = prim[a] // 12
            seen = False
            for b in range(a0, a):  # each tube once per ray: at its first listing
                if prim[b] // 12 == tube:
                    seen = True
                    break
            if seen:
                continue
            count, first = 0, np.inf
            for b in range(a, a1):
                if prim[b] // 12 == tube:
                    count += 1
                    first = min(first, np.float64(t[b]))
            if not (first <= span[rows[i]] or count % 2 == 1):
                continue
            for c in range(2):
                q = owner[tube, c]
                dup = False
                for e in range(start, m):
                    if q_out[e] == q:
                        dup = True
                        break
                if not dup:
                    e = m  # insert in order
                    while e > start and q_out[e - 1] > q:
                        q_out[e] = q_out[e - 1]
                        e -= 1
                    q_out[e] = q
                    m += 1
        for e in range(start, m):
            h_out[e] = rows[i]
    return m


@_jit
def odd_crossings(rays, splits, ids, plane, n, in_start, in_geom):  # noqa: ANN001, ANN201
    """``StaticBvh._containing``'s boxes: for each ray ``rays[i]`` (ascending) whose probe listed the
    geoms ``ids[splits[i]:splits[i + 1]]``, the boxes (not planes) crossed an odd number of times,
    ascending, as CSR over all ``n`` rays (``in_start`` (n + 1), ``in_geom``). Returns their count."""
    m = 0
    at = 0  # next ray whose start is not yet written
    for i in range(len(rays)):
        r = rays[i]
        while at <= r:
            in_start[at] = m
            at += 1
        a0, a1 = splits[i], splits[i + 1]
        start = m
        for a in range(a0, a1):
            g = ids[a]
            seen = False
            for b in range(a0, a):
                if ids[b] == g:
                    seen = True
                    break
            if seen or plane[g]:
                continue
            count = 0
            for b in range(a, a1):
                count += ids[b] == g
            if count % 2 == 1:
                e = m  # insert in order
                while e > start and in_geom[e - 1] > g:
                    in_geom[e] = in_geom[e - 1]
                    e -= 1
                in_geom[e] = g
                m += 1
    while at <= n:
        in_start[at] = m
        at += 1
    return m


@_jit
def _dot3(a0, a1, a2, b0, b1, b2):  # noqa: ANN001, ANN202
    """``np.einsum("ij,ij->i", a, b)`` of one row as numpy sums three products: in two lanes (the
    first and third product, then the second added)."""
    return (a0 * b0 + a2 * b2) + a1 * b1


@_jit
def to_own_origins(gid, dist, nrm, dirs_w, o_cast, o_own):  # noqa: ANN001, ANN201
    """``RayCaster.cast``: each hit (``gid, dist, nrm``, updated in place) of a ray cast from
    ``o_cast`` moved to the ray's own origin ``o_own`` on the plane of the face hit, ``r = dist +
    (o_cast - o_own) . n / (u . n)`` (along the ray where it grazes the face: ``|u . n| < 1e-6``);
    no hit where ``r < 0``."""
    for i in range(len(gid)):
        e0, e1, e2 = o_cast[i, 0] - o_own[i, 0], o_cast[i, 1] - o_own[i, 1], o_cast[i, 2] - o_own[i, 2]
        if gid[i] < 0 or not dist[i] >= 0.0 or (e0 == 0.0 and e1 == 0.0 and e2 == 0.0):
            continue
        u0, u1, u2, n0, n1, n2 = dirs_w[i, 0], dirs_w[i, 1], dirs_w[i, 2], nrm[i, 0], nrm[i, 1], nrm[i, 2]
        un = _dot3(u0, u1, u2, n0, n1, n2)
        if abs(un) < 1e-6:
            r = dist[i] + _dot3(e0, e1, e2, u0, u1, u2)
        else:
            r = dist[i] + _dot3(e0, e1, e2, n0, n1, n2) / un
        if r >= 0.0:
            dist[i] = r
        else:
            gid[i], dist[i] = -1, -1.0


@_jit
def proxy_hits(t, prim, out_w, u, dist, out):  # noqa: ANN001, ANN201
    """``Proxies.may_hit_before``'s first test from Embree's first hits on the proxy boxes (``t``:
    float32 distance, inf none; ``prim``: triangle, 12 per box; ``out_w``: each box triangle's
    outward normal): ``out[i]`` where ray i meets a box no farther than ``dist[i]`` (-1: no hit; a
    1e-4 relative slack), or first meets one leaving it (it starts inside: ``n . u >= 0``, summed as
    ``np.einsum`` sums it)."""
    for i in range(len(t)):
        ti = np.float64(t[i])
        if not np.isfinite(ti):
            out[i] = False
        elif dist[i] < 0 or ti <= dist[i] + 1e-4 * (1.0 + abs(dist[i])):
            out[i] = True
        else:
            k, tri = prim[i] // 12, prim[i] % 12
            out[i] = _dot3(out_w[k, tri, 0], out_w[k, tri, 1], out_w[k, tri, 2], u[i, 0], u[i, 1], u[i, 2]) >= 0.0


@_jit
def _slab(lp, lv, h, t_in, t_out):  # noqa: ANN001, ANN202
    """The ray's interval (t_in, t_out) narrowed to the slab |x| <= h it crosses at lp + t lv."""
    if lv == 0.0:
        return (np.inf, -np.inf) if abs(lp) > h else (t_in, t_out)
    t1, t2 = (-h - lp) / lv, (h - lp) / lv
    return max(t_in, min(t1, t2)), min(t_out, max(t1, t2))


@_jit
def boxes_before(o, u, dist, pos, mat, ctr, half, lo, hi, out):  # noqa: ANN001, ANN201
    """``out[i]`` set where ray i (origin ``o``, unit direction ``u``) meets one of the oriented boxes
    (geom poses ``pos``, row-major ``mat``; box centre ``ctr`` and half sizes ``half`` in the geom's
    frame) no farther than ``dist[i]`` (-1: no hit; a 1e-4 relative slack), or starts in one: a slab
    test in float64 (``Proxies.may_hit_before``'s question without an Embree scene, for a few boxes).
    Rays that miss the world box ``[lo, hi]`` around them all, nearly all, are not tested further."""
    c0, c1, c2 = 0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1]), 0.5 * (lo[2] + hi[2])
    h0, h1, h2 = 0.5 * (hi[0] - lo[0]), 0.5 * (hi[1] - lo[1]), 0.5 * (hi[2] - lo[2])
    for i in range(len(o)):
        if out[i]:
            continue
        reach = np.inf if dist[i] < 0.0 else dist[i] + 1e-4 * (1.0 + abs(dist[i]))
        t_in, t_out = _slab(o[i, 0] - c0, u[i, 0], h0, -np.inf, np.inf)
        t_in, t_out = _slab(o[i, 1] - c1, u[i, 1], h1, t_in, t_out)
        t_in, t_out = _slab(o[i, 2] - c2, u[i, 2], h2, t_in, t_out)
        if not (t_out >= max(t_in, 0.0) and t_in <= reach):
            continue
        for b in range(len(pos)):
            d0, d1, d2 = o[i, 0] - pos[b, 0], o[i, 1] - pos[b, 1], o[i, 2] - pos[b, 2]
            t_in, t_out = -np.inf, np.inf
            for a in range(3):
                lp = mat[b, a] * d0 + mat[b, 3 + a] * d1 + mat[b, 6 + a] * d2 - ctr[b, a]
                lv = mat[b, a] * u[i, 0] + mat[b, 3 + a] * u[i, 1] + mat[b, 6 + a] * u[i, 2]
                t_in, t_out = _slab(lp, lv, half[b, a], t_in, t_out)
            if t_out >= max(t_in, 0.0) and t_in <= reach:
                out[i] = True
                break


@_jit
def beams_start(geom_in, dist, o, u, geom, path, hit_w):  # noqa: ANN001, ANN201
    """``optics.follow_beams``'s primary hits: ``geom`` (-1 where none or ``dist`` < 0), ``path`` (NaN
    where none) and ``hit_w = o + dist u`` (``o`` where none, as ``o + 0 u``), one pass."""
    for i in range(len(geom_in)):
        hit = geom_in[i] >= 0 and dist[i] >= 0.0
        geom[i] = geom_in[i] if hit else -1
        path[i] = dist[i] if hit else np.nan
        w = dist[i] if hit else 0.0
        hit_w[i, 0] = o[i, 0] + w * u[i, 0]
        hit_w[i, 1] = o[i, 1] + w * u[i, 1]
        hit_w[i, 2] = o[i, 2] + w * u[i, 2]


@_jit
def beams_first(geom, nrm, u, kind, glass_code, mirror_code, glass, mirrors, cos_inc, sub):  # noqa: ANN001, ANN201
    """``optics.follow_beams``: ``cos_inc = |n . u|`` (summed as ``np.einsum("ij,ij->i")``: ``_dot3``) and
    the beams whose hit is glass (``glass``) or a mirror (``mirrors``), ascending in ``sub``; returns
    their count."""
    m = 0
    for i in range(len(geom)):
        cos_inc[i] = abs(_dot3(nrm[i, 0], nrm[i, 1], nrm[i, 2], u[i, 0], u[i, 1], u[i, 2]))
        g = geom[i]
        if g >= 0:
            k = kind[g]
            if (k == glass_code and glass) or (k == mirror_code and mirrors):
                sub[m] = i
                m += 1
    return m


@_jit
def returns(geom, path_m, cos_inc, gain, reflectivity, retro, u_drop, z, dirs_s, min_r, max_r, threshold, drop_p,
            rho_ref, r_ref, signal_level, noise_m, res_m, idx, signal, points, intensity):  # noqa: ANN001, ANN201
    """``LidarSensor.scan``'s returns in one pass over the beams: each beam with a surface (``geom``
    >= 0) whose signal (``optics.return_signal``) is detected within the range limits and which
    is not dropped (``u_drop``) is written at the next row: its index, signal, point (range plus
    noise ``z``, quantised to ``res_m`` half to even as ``np.round``, at least 0, along ``dirs_s``)
    and intensity byte (``optics.intensity_byte`` of the signal, or with ``signal_level`` False
    of ``100 G rho |cos|``). Returns the number of rows. The same operations in the same order as
    those numpy functions, so the same bits."""
    m = 0
    for i in range(len(geom)):
        g = geom[i]
        if g < 0:
            continue
        p = path_m[i]
        rho = reflectivity[g]
        q = r_ref / p
        s = 100.0 * gain[i] * (rho / rho_ref) * cos_inc[i] * (q * q)
        if not (p >= min_r and p <= max_r and s >= threshold and u_drop[i] >= drop_p):
            continue
        idx[m] = i
        signal[m] = s
        r = p + noise_m * z[i]
        if res_m > 0.0:
            r = np.rint(r / res_m) * res_m
        r = r if r >= 0.0 else 0.0
        points[m, 0], points[m, 1], points[m, 2] = r * dirs_s[i, 0], r * dirs_s[i, 1], r * dirs_s[i, 2]
        lv = s if signal_level else 100.0 * gain[i] * rho * cos_inc[i]
        v = (101.0 + (lv if lv < 154.0 else 154.0)) if retro[g] else (lv if lv < 100.0 else 100.0)
        intensity[m] = np.uint8(np.rint(v))
        m += 1
    return m


@_jit
def label_points(cand, count, sid, point_normal, edge_a, edge_m, edge_len, geom, hit, tol, out):  # noqa: ANN001, ANN201
    """``labels.label_surfaces`` point by point: of the geom's surfaces whose plane passes within
    ``tol`` of the hit and whose polygon contains it, the nearest plane, the last listed of ties."""
    n_edges = edge_a.shape[1]
    for i in range(len(geom)):
        g = geom[i]
        p0, p1, p2 = hit[i, 0], hit[i, 1], hit[i, 2]
        best_d, best = np.inf, -1
        for s in range(count[g]):
            row = cand[g, s]
            q0, q1, q2 = p0 - point_normal[row, 0, 0], p1 - point_normal[row, 0, 1], p2 - point_normal[row, 0, 2]
            d = abs(q0 * point_normal[row, 1, 0] + q1 * point_normal[row, 1, 1] + q2 * point_normal[row, 1, 2])
            if not d <= tol:
                continue
            above, below = False, False
            for e in range(n_edges):
                c = (p0 - edge_a[row, e, 0]) * edge_m[row, e, 0] + (p1 - edge_a[row, e, 1]) * edge_m[row, e, 1]
                c += (p2 - edge_a[row, e, 2]) * edge_m[row, e, 2]
                within = tol * edge_len[row, e]
                above |= c > within
                below |= c < -within
            if above and below:
                continue
            if d <= best_d:
                best_d, best = d, row
        out[i] = sid[best] if best >= 0 else -1


__all__ = ["MJMINVAL", "exact_hits_into", "face_hits_into", "first_hits", "label_points", "nearest_listed", "odd_crossings",
           "returns", "seams", "to_own_origins", "tube_pairs"]
