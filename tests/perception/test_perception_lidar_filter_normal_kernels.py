"""The compiled range-image normals (perception.lidar_filter.normal_kernels) against the numpy code
they replaced, kept here as the oracle (:func:`_reference_candidates`, verbatim): the same normals
bit for bit, on simulated VLP-16 sweeps of the glazed office (glass, ghosts, depth jumps, NaN
points) and on random ring-organised clouds, with every parameter of the range image varied."""

from __future__ import annotations

import numpy as np
import pytest

from exobench.perception.lidar_filter.normals import range_image_index, range_image_normal_candidates


def _unit_components(v: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``_unit(v.astype(float)).T`` of (M, 3) vectors as three contiguous arrays, the same bits:
    the norm summed in the same order, ``(x*x + y*y) + z*z`` (``np.linalg.norm`` along an axis
    of three and strided components cost more than the arithmetic)."""
    x, y, z = (np.ascontiguousarray(c, dtype=float) for c in np.asarray(v).reshape(-1, 3).T)
    n = np.sqrt(x * x + y * y + z * z)
    with np.errstate(invalid="ignore", divide="ignore"):
        return x / n, y / n, z / n


def _reference_candidates(
    points_xyz: np.ndarray,
    ring: np.ndarray | None,
    *,
    col_halfwidth: int = 4,
    azimuth_jump_rel: float = 0.1,
    ring_jump_rel: float = 0.3,
    max_ring_skip: int = 2,
    min_neighbours: int = 2,
    min_sin: float = 0.2,
) -> np.ndarray | None:
    """The four one-sided range-image normals of each point, (N, 4, 3), NaN where undefined.

    Order: (left, up), (left, down), (right, up), (right, down). Side ``s`` of the azimuth
    tangent: the least-squares line through the point and its neighbours ``p[c + s j]``,
    ``j = 1..col_halfwidth``, whose range is within ``azimuth_jump_rel`` of the point's; at
    least ``min_neighbours`` such neighbours are needed. Ring tangent: to the nearest return in the ring above (below),
    in the same column or the next one on either side, at most ``max_ring_skip`` rings away,
    whose range ``r_n`` is within ``|r_n - r| <= ring_jump_rel * min(r_n, r)`` of the point's
    (returns across a depth jump are passed over); none when there is no such return.
    The normal ``t_az x t_ring`` is flipped towards the sensor (origin); NaN when the tangents
    are nearly parallel (sine of their angle below ``min_sin``). None when the scan is not
    ring-organised (:func:`range_image_index`).
    """
    p = np.asarray(points_xyz, dtype=float).reshape(-1, 3)
    organised = range_image_index(p, ring)
    if organised is None:
        return None
    index, _ = organised
    n_rows, n_cols = index.shape
    has = index >= 0
    pad = int(max_ring_skip)
    # the image in float32: half the memory traffic; a few mm of rounding at 100 m is far below range noise
    P = np.full((n_rows + 2 * pad, n_cols, 3), np.nan, dtype=np.float32)
    P[pad : pad + n_rows][has] = p[index[has]]
    rg = np.sqrt(np.einsum("rci,rci->rc", P, P))  # range image, NaN where empty
    Pc, rc = P[pad : pad + n_rows], rg[pad : pad + n_rows]

    cw = int(col_halfwidth)
    Pw = np.concatenate([Pc[:, n_cols - cw :], Pc, Pc[:, :cw]], axis=1)  # columns wrap round (360 deg)
    rw = np.concatenate([rc[:, n_cols - cw :], rc, rc[:, :cw]], axis=1)
    t_az = {}
    with np.errstate(invalid="ignore", divide="ignore"):
        tol = azimuth_jump_rel * rc
        for s in (-1, 1):
            # least-squares line through the point and its kept neighbours j on this side, in
            # coordinates relative to the point: direction sum_j (j - mean j) q_j = S_jq - S_j S_q / n
            s_q = np.zeros((n_rows, n_cols, 3), dtype=np.float32)
            s_jq = np.zeros((n_rows, n_cols, 3), dtype=np.float32)
            s_j = np.zeros((n_rows, n_cols), dtype=np.float32)
            k = np.zeros((n_rows, n_cols), dtype=np.float32)
            for j in range(1, cw + 1):
                lo = cw + s * j
                ok = np.abs(rw[:, lo : lo + n_cols] - rc) <= tol  # False where either is empty
                q = np.where(ok[..., None], Pw[:, lo : lo + n_cols] - Pc, np.float32(0.0))
                s_q += q
                s_jq += np.float32(j) * q
                s_j += np.float32(j) * ok
                k += ok
            t = s_jq - (s_j / (k + 1))[..., None] * s_q
            t[k < min_neighbours] = np.nan
            t_az[s] = s * t

        t_ring = {}
        Pr = np.concatenate([P[:, -1:], P, P[:, :1]], axis=1)  # one wrapped column each side
        rr = np.concatenate([rg[:, -1:], rg, rg[:, :1]], axis=1)
        for s in (1, -1):
            nb = np.full((n_rows, n_cols, 3), np.nan, dtype=np.float32)
            for k in range(pad, 0, -1):  # nearer rings overwrite farther ones
                r0 = pad + s * k
                for dc in (1, -1, 0):  # the same column overwrites its neighbours
                    qs = rr[r0 : r0 + n_rows, 1 + dc : 1 + dc + n_cols]
                    # a return, and no depth jump: range ratio within 1 + ring_jump_rel (False where empty)
                    m = np.abs(qs - rc) <= ring_jump_rel * np.fmin(qs, rc)
                    np.copyto(nb, Pr[r0 : r0 + n_rows, 1 + dc : 1 + dc + n_cols], where=m[..., None])
            d = s * (nb - Pc)
            t_ring[s] = d

        # the cells with a return only, as component arrays (cheaper than strided (.., 3) ops)
        idx = index[has]
        az_u = {k: _unit_components(v[has]) for k, v in t_az.items()}
        ring_u = {k: _unit_components(v[has]) for k, v in t_ring.items()}
        px, py, pz = (np.ascontiguousarray(c) for c in p[idx].T)
        cells = np.empty((len(idx), 4, 3))
        for c, (sa, sr) in enumerate(((-1, 1), (-1, -1), (1, 1), (1, -1))):
            (ax, ay, az), (bx, by, bz) = az_u[sa], ring_u[sr]
            nx, ny, nz = ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx
            sin = np.sqrt(nx * nx + ny * ny + nz * nz)
            # unit normal, NaN when the tangents are (nearly) parallel; towards the sensor: n . (0 - p) >= 0
            scale = np.where(sin > min_sin, 1.0, np.nan) / sin
            scale = np.where(nx * px + ny * py + nz * pz > 0, -scale, scale)
            cells[:, c, 0], cells[:, c, 1], cells[:, c, 2] = nx * scale, ny * scale, nz * scale
    out = np.full((len(p), 4, 3), np.nan)
    out[idx] = cells  # one scatter of whole rows: a cell's point is never another cell's
    return out


def _same_bits(got: np.ndarray | None, want: np.ndarray | None) -> None:
    assert (got is None) == (want is None)
    if want is None:
        return
    assert got.shape == want.shape and got.dtype == want.dtype
    nan = np.isnan(want)
    np.testing.assert_array_equal(np.isnan(got), nan)
    np.testing.assert_array_equal(got[~nan].view(np.uint64), want[~nan].view(np.uint64))  # -0.0 is not 0.0


@pytest.fixture(scope="module")
def office_scans():
    """The first sweeps of the glazed loop (ring-windows-lowe: low-e windows, glass partitions,
    strongest echo, the VLP-16 at 0.68 m) with a NaN-point fault."""
    from exobench.benchmarks.tracks.lidar_filter.track import REFLECTIVE_CASES, LidarFilterTrack
    from exobench.core import LidarScan

    track = LidarFilterTrack()
    scenario = track.validate_scenario({**REFLECTIVE_CASES["ring-windows-lowe"], "max_distance_m": 0.5, "lidar_nan_points": 0.02})
    scans = []
    for frame in track.stream(scenario, 0).frames:
        if isinstance(frame, LidarScan):
            scans.append(frame)
            if len(scans) == 3:
                break
    return scans


PARAMS = [
    {},
    {"col_halfwidth": 1, "max_ring_skip": 1, "min_neighbours": 1},
    {"col_halfwidth": 7, "azimuth_jump_rel": 0.03, "ring_jump_rel": 0.6, "max_ring_skip": 3, "min_sin": 0.5},
    {"min_neighbours": 4, "min_sin": 0.0},
]


@pytest.mark.parametrize("params", PARAMS)
def test_office_sweeps_give_the_numpy_normals_bit_for_bit(office_scans, params):
    assert len(office_scans) == 3
    for scan in office_scans:
        p = np.asarray(scan.points_xyz, dtype=float)
        assert np.isnan(p).any() and len(p) > 10_000
        got = range_image_normal_candidates(p, scan.ring, **params)
        assert np.isfinite(got).any()
        _same_bits(got, _reference_candidates(p, scan.ring, **params))


def _random_rings(rng: np.random.Generator, n_rings: int, n_cols: int) -> tuple[np.ndarray, np.ndarray]:
    """A ring-organised cloud of random ranges (boxes at random depths, so depth jumps everywhere),
    with random dropouts and NaN points, shuffled."""
    el = np.sort(rng.uniform(-0.3, 0.3, n_rings))
    az = np.arange(n_cols) * (2 * np.pi / n_cols)
    E, A = np.meshgrid(el, az, indexing="ij")
    blocks = rng.uniform(0.5, 30.0, (n_rings, n_cols // 7 + 1)).repeat(7, axis=1)[:, :n_cols]
    r = blocks * (1 + rng.normal(0, 0.01, (n_rings, n_cols)))
    pts = np.stack([r * np.cos(E) * np.cos(A), r * np.cos(E) * np.sin(A), r * np.sin(E)], axis=-1).reshape(-1, 3)
    ring = np.repeat(np.arange(n_rings), n_cols).astype(np.uint16)
    keep = rng.uniform(size=len(pts)) > 0.15
    pts, ring = pts[keep], ring[keep]
    pts[rng.uniform(size=len(pts)) < 0.02] = np.nan
    perm = rng.permutation(len(pts))
    return pts[perm], ring[perm]


@pytest.mark.parametrize("seed", range(4))
def test_random_ring_clouds_give_the_numpy_normals_bit_for_bit(seed):
    rng = np.random.default_rng(seed)
    pts, ring = _random_rings(rng, int(rng.integers(2, 20)), int(rng.integers(40, 400)))
    assert range_image_index(pts, ring) is not None
    for params in PARAMS:
        _same_bits(range_image_normal_candidates(pts, ring, **params), _reference_candidates(pts, ring, **params))


def test_no_ring_layout_is_still_none():
    pts = np.random.default_rng(0).normal(size=(100, 3))
    assert range_image_normal_candidates(pts, None) is None
    assert range_image_normal_candidates(pts, np.zeros(100)) is None


def test_a_half_width_wider_than_the_image_falls_back_as_a_scan_without_rings():
    # a sparse scan has few columns; the numpy code failed on it with a broadcast error, and a
    # filter never raises on data: the normal filter takes the knn normals instead
    from exobench.perception.lidar_filter.config import NormalGroundConfig
    from exobench.perception.lidar_filter.filters import NormalGroundFilter

    pts, ring = _random_rings(np.random.default_rng(5), 4, 20)
    n_cols = range_image_index(pts, ring)[0].shape[1]
    assert range_image_normal_candidates(pts, ring, col_halfwidth=n_cols + 1) is None
    flt = NormalGroundFilter(NormalGroundConfig(ri_col_halfwidth=n_cols + 1))
    ok = np.isfinite(pts).all(axis=1)
    _, method = flt.cosines_and_method(pts[ok], np.eye(4), ring[ok])
    assert method == "knn"
