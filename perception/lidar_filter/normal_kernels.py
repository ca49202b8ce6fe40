"""Compiled loop (numba) of the range-image normals (:func:`.normals.range_image_normal_candidates`).

The numpy version built each one-sided tangent from a dozen passes over whole (rings x columns x 3)
images, with their temporaries: about 10 ms a VLP-16 scan, the largest cost of the lidar-filter
pipelines after KISS-ICP. Here each cell with a return is one pass, with the same operations in the
same order and the same precision: the image's tangents in float32 (numpy adds a Python float to a
float32 array in float32, so the tolerances are float32 products here too), the unit tangents,
their cross product and its scale in float64; no fast-math, so LLVM neither fuses a product and a
sum into one rounding nor reorders them. The normals are the numpy version's bit for bit
(tests/perception/test_perception_lidar_filter_normal_kernels.py).

Compiled on first use and cached on disk (``cache=True``), as
:mod:`exobench.envs.sensors.lidar.kernels`.
"""

from __future__ import annotations

import math

import numba
import numpy as np

_jit = numba.njit(cache=True, nogil=True, error_model="numpy")
_F0 = np.float32(0.0)
_F1 = np.float32(1.0)


@_jit
def _unit3(x, y, z):  # noqa: ANN001, ANN202 - numba infers the types
    """A float32 vector as a float64 unit vector, the norm summed ``(x*x + y*y) + z*z`` as the numpy code did."""
    x, y, z = np.float64(x), np.float64(y), np.float64(z)
    n = math.sqrt(x * x + y * y + z * z)
    return x / n, y / n, z / n


@_jit
def candidate_cells(index, p, Pw, rw, Pr, rr, rc, cw, az_rel, ring_rel, pad, min_neighbours, min_sin):  # noqa: ANN001, ANN201
    """The four one-sided normals (left/right x up/down, as the numpy version orders them) of each
    cell with a return, in row-major order of ``index``: (cells, 4, 3) float64.

    ``Pw`` / ``rw``: the image (float32 points, ranges) of the rings, ``cw`` columns wrapped on each
    side; ``Pr`` / ``rr``: the image with ``pad`` empty rings above and below, one column wrapped on
    each side; ``rc``: the rings' ranges; ``az_rel`` / ``ring_rel``: float32 tolerances."""
    n_rows, n_cols = index.shape
    n = 0
    for r in range(n_rows):
        for c in range(n_cols):
            if index[r, c] >= 0:
                n += 1
    out = np.empty((n, 4, 3))
    taz = np.empty((2, 3), dtype=np.float32)  # side -1, +1
    trg = np.empty((2, 3), dtype=np.float32)  # side +1, -1
    m = 0
    for r in range(n_rows):
        for c in range(n_cols):
            i = index[r, c]
            if i < 0:
                continue
            r0c = rc[r, c]
            x0, y0, z0 = Pw[r, cw + c, 0], Pw[r, cw + c, 1], Pw[r, cw + c, 2]
            tol = az_rel * r0c
            for si in range(2):
                s = 2 * si - 1
                q0 = q1 = q2 = _F0
                jq0 = jq1 = jq2 = _F0
                sj = _F0
                k = _F0
                for j in range(1, cw + 1):
                    col = cw + s * j + c
                    if abs(rw[r, col] - r0c) <= tol:  # False where either is empty (NaN)
                        fj = np.float32(j)
                        d0, d1, d2 = Pw[r, col, 0] - x0, Pw[r, col, 1] - y0, Pw[r, col, 2] - z0
                        q0 += d0
                        q1 += d1
                        q2 += d2
                        jq0 += fj * d0
                        jq1 += fj * d1
                        jq2 += fj * d2
                        sj += fj
                        k += _F1
                    else:  # numpy adds the zeros too: -0.0 + 0.0 is +0.0
                        q0 += _F0
                        q1 += _F0
                        q2 += _F0
                        jq0 += np.float32(j) * _F0
                        jq1 += np.float32(j) * _F0
                        jq2 += np.float32(j) * _F0
                        sj += np.float32(j) * _F0
                        k += _F0
                if k < min_neighbours:
                    taz[si, 0] = taz[si, 1] = taz[si, 2] = np.float32(np.nan)
                else:
                    w = sj / (k + _F1)
                    fs = np.float32(s)
                    taz[si, 0] = fs * (jq0 - w * q0)
                    taz[si, 1] = fs * (jq1 - w * q1)
                    taz[si, 2] = fs * (jq2 - w * q2)
            for si in range(2):
                s = 1 - 2 * si
                nb0 = nb1 = nb2 = np.float32(np.nan)
                for kk in range(pad, 0, -1):  # nearer rings overwrite farther ones
                    row = pad + r + s * kk
                    for dc in (1, -1, 0):  # the same column overwrites its neighbours
                        col = 1 + dc + c
                        qs = rr[row, col]
                        if abs(qs - r0c) <= ring_rel * np.fmin(qs, r0c):
                            nb0, nb1, nb2 = Pr[row, col, 0], Pr[row, col, 1], Pr[row, col, 2]
                fs = np.float32(s)
                trg[si, 0] = fs * (nb0 - x0)
                trg[si, 1] = fs * (nb1 - y0)
                trg[si, 2] = fs * (nb2 - z0)
            px, py, pz = p[i, 0], p[i, 1], p[i, 2]
            for cell in range(4):
                sa, sr = cell // 2, cell % 2  # (left, up), (left, down), (right, up), (right, down)
                ax, ay, az = _unit3(taz[sa, 0], taz[sa, 1], taz[sa, 2])
                bx, by, bz = _unit3(trg[sr, 0], trg[sr, 1], trg[sr, 2])
                nx, ny, nz = ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx
                sin = math.sqrt(nx * nx + ny * ny + nz * nz)
                scale = (1.0 if sin > min_sin else np.nan) / sin
                if nx * px + ny * py + nz * pz > 0:
                    scale = -scale
                out[m, cell, 0], out[m, cell, 1], out[m, cell, 2] = nx * scale, ny * scale, nz * scale
            m += 1
    return out
