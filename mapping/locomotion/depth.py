"""Depth-image helpers of the locomotion pipelines: back-projection, decimation, resampling."""

from __future__ import annotations

import numpy as np

__all__ = ["backproject", "decimate", "scale_intrinsics", "upsample_depth"]


def backproject(depth_m: np.ndarray, K: np.ndarray, T_world_cam: np.ndarray, stride: int = 1) -> np.ndarray:
    """World points (N, 3) of the valid (> 0, finite) pixels of a z-depth image, every ``stride``-th
    row and column."""
    d = np.asarray(depth_m, dtype=float)[::stride, ::stride]
    v, u = np.nonzero(np.isfinite(d) & (d > 0))
    z = d[v, u]
    u = u * stride
    v = v * stride
    x = (u - K[0, 2]) * z / K[0, 0]
    y = (v - K[1, 2]) * z / K[1, 1]
    p = np.column_stack([x, y, z])
    return p @ T_world_cam[:3, :3].T + T_world_cam[:3, 3]


def upsample_depth(depth_m: np.ndarray, n: int, shape: tuple[int, int], jump_m: float = 0.05) -> np.ndarray:
    """A z-depth image ray cast at 1/n resolution (K scaled by :func:`scale_intrinsics`) brought
    back to ``shape``: bilinear interpolation of the inverse depth, which is exact on planes
    (1/z is affine in the pixel coordinates of a plane); where a neighbour is invalid or the
    four neighbours' depths span more than ``jump_m`` (an edge), the nearest sample instead."""
    d = np.asarray(depth_m, dtype=np.float32)
    h, w = shape
    hs, ws = d.shape
    # pixel u of the full image is at (u + 0.5) / n - 0.5 in the small one
    y = np.clip((np.arange(h) + 0.5) / n - 0.5, 0.0, hs - 1.0)
    x = np.clip((np.arange(w) + 0.5) / n - 0.5, 0.0, ws - 1.0)
    y0 = np.minimum(np.floor(y).astype(int), hs - 1)
    x0 = np.minimum(np.floor(x).astype(int), ws - 1)
    y1, x1 = np.minimum(y0 + 1, hs - 1), np.minimum(x0 + 1, ws - 1)
    fy, fx = (y - y0).astype(np.float32)[:, None], (x - x0).astype(np.float32)[None, :]
    inv_small = np.zeros_like(d)
    np.divide(1.0, d, out=inv_small, where=d > 0)
    rows0, rows1 = d[y0], d[y1]
    c = (rows0[:, x0], rows0[:, x1], rows1[:, x0], rows1[:, x1])  # 00, 01, 10, 11
    cmax = np.maximum(np.maximum(c[0], c[1]), np.maximum(c[2], c[3]))
    cmin = np.minimum(np.minimum(c[0], c[1]), np.minimum(c[2], c[3]))
    smooth = (cmin > 0) & (cmax - cmin <= jump_m)
    i0, i1 = inv_small[y0], inv_small[y1]
    iv = (i0[:, x0] * (1 - fx) + i0[:, x1] * fx) * (1 - fy) + (i1[:, x0] * (1 - fx) + i1[:, x1] * fx) * fy
    near = d[np.clip(np.rint(y).astype(int), 0, hs - 1)][:, np.clip(np.rint(x).astype(int), 0, ws - 1)]
    out = near.copy()
    np.divide(1.0, iv, out=out, where=smooth)
    return out


def decimate(depth_m: np.ndarray, K: np.ndarray, max_width_px: int) -> tuple[np.ndarray, np.ndarray]:
    """(depth, K) of the image kept at every m-th pixel, m = ceil(width / ``max_width_px``) (the
    pixel at the centre of each m x m block, (m - 1) // 2 in; K exact for those pixels); the
    image itself when it is no wider than ``max_width_px``."""
    w = depth_m.shape[1]
    m = -(-w // max(1, int(max_width_px)))
    if m <= 1:
        return depth_m, K
    off = (m - 1) // 2
    out = np.array(K, dtype=float)
    out[0, 0] /= m
    out[1, 1] /= m
    out[0, 2] = (out[0, 2] - off) / m
    out[1, 2] = (out[1, 2] - off) / m
    return np.ascontiguousarray(depth_m[off::m, off::m]), out


def scale_intrinsics(K: np.ndarray, s: float) -> np.ndarray:
    """K of the image resized by ``s`` (pixel centres at integer coordinates)."""
    out = np.array(K, dtype=float)
    out[0, 0] *= s
    out[1, 1] *= s
    out[0, 2] = (out[0, 2] + 0.5) * s - 0.5
    out[1, 2] = (out[1, 2] + 0.5) * s - 0.5
    return out
