"""The compiled loops of the LiDAR (envs/sensors/lidar/kernels.py) against independent computations.

The exact hits are checked against ``mj_ray`` in test_envs_lidar_bvh.py (``exact_hits`` and
``face_hits`` run the compiled loops); here the surface labels against ``SceneTruth.surface_of_hit``
point by point, and the grouping loops against numpy's ``np.unique`` on random listings.
"""

from __future__ import annotations

import numpy as np

from exobench.envs.sensors.lidar import kernels
from exobench.envs.sensors.lidar.labels import SurfaceTable, label_surfaces


def _unit_rows(rng: np.random.Generator, n: int) -> np.ndarray:
    """``n`` random unit vectors (rows)."""
    v = rng.normal(size=(n, 3))
    return v / np.linalg.norm(v, axis=1)[:, None]


def test_surface_labels_are_surface_of_hit_on_points_near_edges_and_planes():
    """Points on and within a few tolerances of every surface's plane and polygon edges, the
    decisions where a label could flip: the compiled labels equal SceneTruth.surface_of_hit's."""
    from exobench.models.office import build_office
    from exobench.models.office_params import OfficeParams

    world = build_office(OfficeParams(facade="windows", glass_fraction=1.0))
    truth = world.truth
    names = sorted(truth.geom_surfaces)
    rng = np.random.default_rng(7)
    geom, pts = [], []
    for g, name in enumerate(names):
        for sid in truth.geom_surfaces[name]:
            sf = truth.surface(sid)
            poly, nv = np.asarray(sf.polygon_w, dtype=float), np.asarray(sf.normal_w, dtype=float)
            for _ in range(3):  # a point on a random edge, moved in and out of the polygon and the plane
                j = rng.integers(len(poly))
                a, b = poly[j], poly[(j + 1) % len(poly)]
                p = a + rng.uniform(-0.05, 1.05) * (b - a)
                p = p + rng.choice([0.0, 1.0]) * rng.uniform(-3e-4, 3e-4, 3)
                p = p + rng.choice([0.0, 1e-4, -1e-4, 5e-5, 2e-4]) * nv
                geom.append(g)
                pts.append(p)
    geom, pts = np.array(geom), np.array(pts)
    tab = SurfaceTable.build(truth, names)
    got = label_surfaces(tab, geom, pts)
    ref = np.array([truth.surface_of_hit(names[g], p) for g, p in zip(geom, pts)])
    np.testing.assert_array_equal(got, ref)
    assert np.count_nonzero(ref >= 0) > 0.2 * len(ref) and np.count_nonzero(ref < 0) > 0.05 * len(ref)


def _grouped(rays, splits, key):
    """(ray, key, count) of each distinct key of each ray's listing, sorted, by np.unique."""
    which = np.repeat(rays, np.diff(splits))
    big = int(key.max()) + 1 if len(key) else 1
    pair, count = np.unique(which * big + key, return_counts=True)
    return pair // big, pair % big, count


def test_tube_pairs_equal_numpys_grouping():
    rng = np.random.default_rng(3)
    n_rays, n_tubes, n_geoms = 400, 60, 25
    owner = rng.integers(0, n_geoms, (n_tubes, 2))
    owner[: n_tubes // 2, 1] = owner[: n_tubes // 2, 0]  # an edge's tube names its geom twice
    rows = np.sort(rng.choice(n_rays, 150, replace=False))
    per = rng.integers(0, 9, len(rows))
    splits = np.concatenate([[0], np.cumsum(per)])
    prim = (12 * rng.integers(0, n_tubes, splits[-1]) + rng.integers(0, 12, splits[-1])).astype(np.uint32)
    t = rng.uniform(0.0, 10.0, splits[-1]).astype(np.float32)
    span = rng.uniform(0.0, 10.0, n_rays)
    h, q = np.empty(2 * len(prim), dtype=np.int64), np.empty(2 * len(prim), dtype=np.int64)
    m = kernels.tube_pairs(rows, splits, prim, t, span, owner, h, q)
    # reference: the first meeting of each (ray, tube) within the span, or an odd count
    ray, tube, count = _grouped(rows, splits, prim.astype(np.int64) // 12)
    which = np.repeat(rows, np.diff(splits))
    first = np.array([t[(which == r) & (prim // 12 == k)].astype(float).min() for r, k in zip(ray, tube)])
    keep = (first <= span[ray]) | (count % 2 == 1)
    ref = np.unique(np.concatenate([ray[keep] * n_geoms + owner[tube[keep], 0], ray[keep] * n_geoms + owner[tube[keep], 1]]))
    np.testing.assert_array_equal(h[:m], ref // n_geoms)
    np.testing.assert_array_equal(q[:m], ref % n_geoms)
    assert 0 < m < 2 * len(prim)


def test_odd_crossings_are_the_boxes_crossed_an_odd_number_of_times():
    rng = np.random.default_rng(5)
    n, n_geoms = 300, 30
    plane = rng.random(n_geoms) < 0.2
    rays = np.sort(rng.choice(n, 120, replace=False))
    splits = np.concatenate([[0], np.cumsum(rng.integers(0, 7, len(rays)))])
    ids = rng.integers(0, n_geoms, splits[-1]).astype(np.uint32)
    start, geoms = np.empty(n + 1, dtype=np.int64), np.empty(len(ids), dtype=np.int64)
    m = kernels.odd_crossings(rays, splits, ids, plane, n, start, geoms)
    ray, g, count = _grouped(rays, splits, ids.astype(np.int64))
    odd = (count % 2 == 1) & ~plane[g]
    np.testing.assert_array_equal(geoms[:m], g[odd])
    np.testing.assert_array_equal(np.diff(start), np.bincount(ray[odd], minlength=n))
    assert start[0] == 0 and start[-1] == m > 0


def test_kernels_are_cached_on_disk_and_release_the_gil():
    """Compiled once per install (a fresh worker process loads them), callable from casting threads."""
    for name in kernels.__all__:
        fn = getattr(kernels, name)
        if callable(fn):
            assert fn._cache.__class__.__name__ == "FunctionCache", name
            assert fn.targetoptions.get("nogil"), name


def test_returns_equal_the_numpy_functions_bit_for_bit():
    """The scan's detected returns (kernels.returns) against optics.return_signal, np.round and
    optics.intensity_byte on beams at the range limits, the detection threshold, ranges exactly
    half a quantum off the grid, bright and retro-reflective surfaces and no surface."""
    from exobench.envs.sensors.lidar.optics import intensity_byte, return_signal

    rng = np.random.default_rng(11)
    n, n_geoms = 5000, 40
    geom = rng.integers(-1, n_geoms, n)
    res, noise, lo, hi, thr = 0.002, 0.015, 0.9, 100.0, 1.5
    path = rng.choice([lo, hi, np.nextafter(lo, 0.0), np.nextafter(hi, 200.0), 3.0], n) + rng.choice([0.0, 1.0], n) * rng.uniform(0.0, 60.0, n)
    path = np.where(geom >= 0, path, np.nan)
    z = rng.standard_normal(n)
    z[: n // 4] = ((np.round(path[: n // 4] / res) + 0.5) * res - path[: n // 4]) / noise  # ties of the quantisation
    cos_inc, gain = rng.uniform(0.0, 1.0, n), rng.choice([1.0, 0.01, 0.3], n)
    refl = rng.uniform(0.02, 3.0, n_geoms)
    retro = rng.random(n_geoms) < 0.3
    u_drop = rng.random(n)
    dirs = _unit_rows(rng, n)
    for signal_level in (True, False):
        # the numpy reference, as the scan computed it before
        ok = geom >= 0
        g = np.where(ok, geom, 0)
        p = np.where(ok, path, 1.0)
        signal = return_signal(refl[g], cos_inc, p, 0.8, 10.0, gain)
        ok &= (p >= lo) & (p <= hi) & (signal >= thr) & (u_drop >= 0.01)
        idx = np.flatnonzero(ok)
        level = signal if signal_level else 100.0 * gain * refl[g] * cos_inc
        r = np.maximum(np.round((p[idx] + noise * z[idx]) / res) * res, 0.0)
        out = (np.empty(n, dtype=np.int64), np.empty(n), np.empty((n, 3)), np.empty(n, dtype=np.uint8))
        k = kernels.returns(geom, path, cos_inc, gain, refl, retro, u_drop, z, dirs, lo, hi, thr, 0.01, 0.8, 10.0,
                            signal_level, noise, res, *out)  # fmt: skip
        np.testing.assert_array_equal(out[0][:k], idx)
        np.testing.assert_array_equal(out[1][:k], signal[idx])
        np.testing.assert_array_equal(out[2][:k], r[:, None] * dirs[idx])
        np.testing.assert_array_equal(out[3][:k], intensity_byte(level[idx], retro[g[idx]]))
        assert 1000 < k < n and len(np.unique(out[3][:k])) > 100


def test_hits_moved_to_the_rays_own_origins_equal_numpys():
    """kernels.to_own_origins against the numpy computation it replaced in RayCaster.cast (its
    einsum dot products included), on rays cast from their own origin or from a window's, grazing
    faces, moved behind their origin, and without a hit."""
    rng = np.random.default_rng(13)
    n = 20000
    gid = rng.integers(-1, 50, n).astype(np.int32)
    dist = np.where(rng.random(n) < 0.1, -1.0, rng.uniform(0.0, 30.0, n))
    nrm = _unit_rows(rng, n)
    u = _unit_rows(rng, n)
    graze = rng.random(n) < 0.2  # u . n within 1e-6 of 0
    u[graze] -= (np.einsum("ij,ij->i", u[graze], nrm[graze]) - rng.uniform(-2e-6, 2e-6, graze.sum()))[:, None] * nrm[graze]
    o_own = rng.uniform(-40.0, 40.0, (n, 3))
    o_cast = o_own + np.where(rng.random(n) < 0.2, 0.0, 1.0)[:, None] * rng.normal(0.0, 0.5, (n, 3))
    # the numpy reference, as RayCaster.cast computed it before
    g0, d0 = gid.copy(), dist.copy()
    delta = o_cast - o_own
    fix = np.flatnonzero((g0 >= 0) & (d0 >= 0.0) & ((delta[:, 0] != 0.0) | (delta[:, 1] != 0.0) | (delta[:, 2] != 0.0)))
    un = np.einsum("ij,ij->i", u[fix], nrm[fix])
    grazing = np.abs(un) < 1e-6
    r = d0[fix] + np.einsum("ij,ij->i", delta[fix], nrm[fix]) / np.where(grazing, 1.0, un)
    r = np.where(grazing, d0[fix] + np.einsum("ij,ij->i", delta[fix], u[fix]), r)
    g0[fix] = np.where(r >= 0.0, g0[fix], -1)
    d0[fix] = np.where(r >= 0.0, r, -1.0)
    g1, d1 = gid.copy(), dist.copy()
    kernels.to_own_origins(g1, d1, nrm, u, o_cast, o_own)
    np.testing.assert_array_equal(g1, g0)
    np.testing.assert_array_equal(d1, d0)
    assert np.count_nonzero(grazing) > 500 and np.count_nonzero(r < 0.0) > 500 and len(fix) > 10000


def test_take_rows_equals_fancy_indexing():
    """``optics.take_rows`` (np.take along the rows, or one row repeated for a broadcast origin)
    gives ``a[idx]``: the same values, shape, dtype and a fresh C-contiguous array."""
    from exobench.envs.sensors.lidar.optics import take_rows

    rng = np.random.default_rng(0)
    a = rng.normal(size=(500, 3))
    one = np.broadcast_to(np.array([1.5, -2.0, 0.25]), (500, 3))  # a sensor at rest: one origin
    for idx in (np.sort(rng.choice(500, 300, replace=False)), rng.integers(0, 500, 50), np.zeros(0, dtype=np.int64)):
        for src in (a, one, a[::-1]):
            got = take_rows(src, idx)
            want = src[idx]
            assert got.shape == want.shape and got.dtype == want.dtype and got.flags.c_contiguous
            np.testing.assert_array_equal(got, want)
    got = take_rows(a, np.arange(10))
    got[0, 0] = 99.0  # a copy, as fancy indexing gives
    assert a[0, 0] != 99.0


def test_tube_rays_equal_the_numpy_construction():
    """``kernels.tube_rays`` (``EdgeTubes.crossed``'s Embree rays in one pass) gives the rays the
    numpy code built: each ray scaled to its reach or ``far_m`` (float32), then the probes from the
    first ray of each run of equal origins; the same spans and runs."""
    rng = np.random.default_rng(5)
    n, far = 3000, 500.0
    o = np.repeat(rng.normal(size=(40, 3)) * 20.0, rng.integers(1, 150, 40), axis=0)[:n]  # runs of equal origins
    o[::7] += 1e-9  # and single rays
    n = len(o)
    u = _unit_rows(rng, n)
    reach = np.where(rng.random(n) < 0.2, np.inf, rng.uniform(0.0, 80.0, n))
    probes = np.array([[1.0, 1.0, 1.0], [1.0, -1.0, 0.0]]) / np.sqrt([[3.0], [2.0]]) * 1e-3
    k = len(probes)
    # the numpy construction it replaces
    span0 = np.where(np.isfinite(reach), reach * (1.0 + 1e-6) + 1e-6, far)
    run = np.append(True, (o[1:, 0] != o[:-1, 0]) | (o[1:, 1] != o[:-1, 1]) | (o[1:, 2] != o[:-1, 2]))
    heads = o[run]
    r0 = np.empty((n + k * len(heads), 6), dtype=np.float32)
    r0[:n, :3], r0[:n, 3:] = o, u * span0[:, None]
    r0[n:, :3] = np.repeat(heads, k, axis=0)
    r0[n:, 3:] = np.tile(probes, (len(heads), 1))
    span, run_of, head = np.empty(n), np.empty(n, dtype=np.int64), np.empty(n, dtype=np.int64)
    r = np.empty((n + k * n, 6), dtype=np.float32)
    m = kernels.tube_rays(o, u, reach, far, probes, span, run_of, head, r)
    assert m == len(heads) > 40
    np.testing.assert_array_equal(r[: n + k * m], r0)
    np.testing.assert_array_equal(span, span0)
    np.testing.assert_array_equal(run_of, np.cumsum(run) - 1)
    np.testing.assert_array_equal(o[head[:m]], heads)


def test_beams_start_and_first_equal_the_numpy_code():
    """``kernels.beams_start`` and ``beams_first`` (``optics.follow_beams``'s first passes) give what
    the numpy code gave: hits, paths (NaN without a hit), hit points (the origin without one, also
    from one broadcast origin), ``|n . u|`` as ``np.einsum`` sums it, and the beams meeting glass or
    a mirror first, for every combination of the two switches."""
    rng = np.random.default_rng(8)
    n = 5000
    geom_in = rng.integers(-1, 30, n).astype(np.int32)
    dist = np.where(rng.random(n) < 0.1, -1.0, rng.uniform(0.0, 90.0, n))
    u = _unit_rows(rng, n)
    nrm = _unit_rows(rng, n)
    kind = rng.integers(0, 4, 30).astype(np.int64)
    for o in (rng.normal(size=(n, 3)) * 10.0, np.broadcast_to(np.array([0.3, -1.2, 0.9]), (n, 3))):
        hit = (geom_in >= 0) & (dist >= 0.0)
        geom0 = np.where(hit, geom_in, -1).astype(np.int64)
        path0 = np.where(hit, dist, np.nan)
        hit_w0 = o + np.where(hit, dist, 0.0)[:, None] * u
        geom, path, hit_w = np.empty(n, dtype=np.int64), np.empty(n), np.empty((n, 3))
        kernels.beams_start(geom_in, dist, o, u, geom, path, hit_w)
        np.testing.assert_array_equal(geom, geom0)
        np.testing.assert_array_equal(path, path0)
        np.testing.assert_array_equal(hit_w, hit_w0)
        first = kind[np.maximum(geom0, 0)]
        for glass in (False, True):
            for mirrors in (False, True):
                cos_inc, sub = np.empty(n), np.empty(n, dtype=np.int64)
                m = kernels.beams_first(geom, nrm, u, kind, 1, 2, glass, mirrors, cos_inc, sub)
                want = np.flatnonzero(hit & (((first == 1) & glass) | ((first == 2) & mirrors)))
                np.testing.assert_array_equal(sub[:m], want)
                np.testing.assert_array_equal(cos_inc, np.abs(np.einsum("ij,ij->i", nrm, u)))
                assert (m > 100) == (glass or mirrors)


def test_proxy_hits_equal_the_numpy_code():
    """``kernels.proxy_hits`` (``Proxies.may_hit_before``'s first test) flags what the numpy code
    flagged: Embree's hit (float32) no farther than the static hit with its slack, or any hit
    without one, or a first hit leaving its box (``n . u >= 0`` as ``np.einsum`` sums it)."""
    rng = np.random.default_rng(9)
    n, g = 20000, 30
    t = np.where(rng.random(n) < 0.3, np.inf, rng.uniform(0.0, 20.0, n)).astype(np.float32)
    dist = np.where(rng.random(n) < 0.2, -1.0, rng.uniform(0.0, 20.0, n))
    dist[:500] = t[:500].astype(float) * (1.0 - 1e-4)  # at the slack's edge
    prim = rng.integers(0, 12 * g, n).astype(np.uint32)
    out_w = rng.normal(size=(g, 12, 3))
    u = rng.normal(size=(n, 3))
    u[:300] = 0.0  # n . u = 0 exactly
    u /= np.maximum(np.linalg.norm(u, axis=1), 1e-300)[:, None]
    tt = t.astype(float)
    want = np.isfinite(tt) & ((dist < 0) | (tt <= dist + 1e-4 * (1.0 + np.abs(dist))))
    rows = np.flatnonzero(np.isfinite(tt) & ~want)
    k, tri = prim[rows].astype(np.int64) // 12, prim[rows].astype(np.int64) % 12
    want[rows] = np.einsum("ij,ij->i", out_w[k, tri], u[rows]) >= 0.0
    got = np.empty(n, dtype=bool)
    kernels.proxy_hits(t, prim, out_w, u, dist, got)
    np.testing.assert_array_equal(got, want)
    assert 1000 < len(rows) and 0 < np.count_nonzero(want[rows]) < len(rows)
