"""Plane extraction from a (smoothed) depth image by agglomerative hierarchical clustering
(seeds/002, II-F; the AHC of its ref. [34], Feng et al., ICRA 2014).

API (other modules code against exactly this)::

    from exobench.perception.terrain.plane_extraction import AhcConfig, extract_planes, segment_depth
    planes = extract_planes(depth_m, K, T_world_cam, AhcConfig(), cell_m=0.05)  # list[DetectedPlane]
    seg = segment_depth(depth_m, K, AhcConfig())   # AhcSegmentation, camera frame
    seg.labels_px     # (H, W) int32: plane index (same order as extract_planes) or -1
    seg.planes        # list[AhcPlane]: n_px, center_cam_m, normal_cam, mse_m2, area_m2, cell_index

``depth_m`` (H, W) float metres (0 / NaN / inf = invalid), ``K`` its 3x3 pinhole matrix,
``T_world_cam`` the 4x4 camera-to-world pose of the optical frame (x right, y down, z forward).
``extract_planes`` returns :class:`exobench.perception.terrain.plane_tracking.DetectedPlane` objects in
the world frame: centre = mean and unit normal = PCA of the points of the plane's interior
cells (below), the normal oriented towards the camera; ``area_m2`` (occupied ``cell_m`` squares
in the plane's 2-D grid times cell_m^2) and ``cells`` (support voxels, ``voxel_keys``) as in
``plane_tracking.plane_from_points``, from the points of all its cells sampled every
``support_stride_px``-th pixel row and column; pass the PlaneSet's ``cell_m``. Planes are
ordered by decreasing pixel count.

Steps of II-F:
1. the image is cut into cells of H_p x W_p = ``cell_px`` x ``cell_px`` pixels (the border
   rest is ignored); per cell the point moments (N, sum p, sum p p^T) in the camera frame;
2. each cell gets a PCA plane (normal = eigenvector of the least eigenvalue of the covariance,
   MSE = that eigenvalue = mean squared point-plane distance); cells "exhibiting apparent
   discontinuity" are dropped: any invalid pixel, a jump between neighbouring pixels larger
   than T_dz(z) = depth_alpha z + depth_change_tol_m, or MSE >= T_mse,init(z) = (sigma z^2 +
   std_tol_init_m)^2 ([34]'s noise model). Neighbouring cells (4-connectivity) are linked if
   their normals differ by less than T_ang(z), growing linearly from ``angle_near_deg`` at
   z_near to ``angle_far_deg`` at z_far ([34]);
3. clustering: clusters are merged across links; a merge of A and B is allowed if their normals
   differ by < ``merge_angle_deg`` and the PCA of the union has MSE < T_mse,merge(z) =
   (sigma z^2 + std_tol_merge_m)^2 (the distance threshold: an RMS point-plane distance), and
   the lowest merged MSE goes first. Clusters of >= ``min_support_px`` pixels whose area (sum
   of the pixel footprints on the plane) is >= ``min_area_m2`` and whose width sqrt(12 l1)
   (l1 = middle PCA eigenvalue; the full width of a uniform strip) is >= ``min_width_m``
   become planes. The width test [A] drops the strips of cells that straddle a step's nosing:
   such cells fit a plane halfway between tread and riser within T_mse,init on clean depth and
   line up along the edge into one thin cluster.

The merging order [A]: [34] pops the cluster of least MSE from a heap and merges it with its
neighbour of least merged MSE, one merge at a time; in Python that loop costs ~100 ms per
640x480 frame. Here it runs in vectorised rounds (Boruvka style): in each round every cluster
proposes its allowed neighbour of least merged MSE (ties by ids); the proposals form trees,
and a tree is merged at once if the PCA of its union still passes the MSE test, otherwise only
its mutual proposals (pairs that chose each other) are merged. The least allowed merge of the
graph is always mutual, so every round merges something until no allowed merge is left
(5-6 rounds on the test staircases). Where merges compete the result can differ from [34]'s
one-at-a-time order. The vectorised statistics are in :mod:`.ahc_math`. [34]'s pixel-wise boundary refinement is not part of the paper's three
steps and is not done (labels are per cell), but as [34] erodes cluster borders before it,
the final PCA of a plane uses its interior cells (all 4 neighbours in the cluster; all cells
if fewer than 4): border cells may straddle an edge and tilt the fit by a few degrees; then
only the cells whose own normal is within ``refit_angle_deg`` = 10 deg [A] of that fit are
kept (small far clusters have no interior cells).
3x3 eigen-problems are solved in closed form (vectorised), ``numpy.linalg.eigh`` only for
near-degenerate ones.
Parameter values: [34]'s defaults (``ai4ce/peac`` ParamSet, mm converted to m: sigma 1.6e-6
mm^-1 = 1.6e-3 m^-1, tolerances 5 / 8 mm, T_ang 15-90 deg over 0.5-4 m, merge 60 deg, T_dz
0.04 z + 0.02 mm, cells 10 x 10 px, min support 800 px); ``min_area_m2`` = 0.02 and
``min_width_m`` = 0.08 [A] (a 0.17 m riser is 0.17 wide, a nosing strip ~0.04).

Faulty input (None, wrong shape, all invalid, NaN, non-finite K or pose) gives no planes and
an all -1 label image; never raises. Pure numpy, deterministic.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from exobench.core import check_int, check_range
from exobench.perception.terrain.plane_tracking import DetectedPlane, voxel_keys

from .ahc_math import forest_labels, group_sum, moment_mse, moment_pca


@dataclass(frozen=True)
class AhcConfig:
    """Thresholds of the AHC ([34] defaults in SI units, see the module docstring)."""

    cell_px: int = 10
    depth_sigma_per_m: float = 1.6e-3
    std_tol_init_m: float = 0.005
    std_tol_merge_m: float = 0.008
    z_near_m: float = 0.5
    z_far_m: float = 4.0
    angle_near_deg: float = 15.0
    angle_far_deg: float = 90.0
    merge_angle_deg: float = 60.0
    depth_alpha: float = 0.04
    depth_change_tol_m: float = 2e-5
    min_support_px: int = 800
    min_area_m2: float = 0.02
    min_width_m: float = 0.08
    refit_angle_deg: float = 10.0
    max_rounds: int = 200
    support_stride_px: int = 3

    def __post_init__(self) -> None:
        for name, low in (("cell_px", 2), ("min_support_px", 1), ("max_rounds", 1), ("support_stride_px", 1)):
            object.__setattr__(self, name, check_int(f"ahc.{name}", getattr(self, name), low))
        check_range("ahc.depth_sigma_per_m", self.depth_sigma_per_m, 0.0, 1.0)
        check_range("ahc.std_tol_init_m", self.std_tol_init_m, 0.0, 1.0, low_open=True)
        check_range("ahc.std_tol_merge_m", self.std_tol_merge_m, 0.0, 1.0, low_open=True)
        check_range("ahc.z_near_m", self.z_near_m, 0.0, 100.0)
        check_range("ahc.z_far_m", self.z_far_m, self.z_near_m, 100.0, low_open=True)
        check_range("ahc.angle_near_deg", self.angle_near_deg, 0.0, 90.0)
        check_range("ahc.angle_far_deg", self.angle_far_deg, self.angle_near_deg, 90.0)
        check_range("ahc.merge_angle_deg", self.merge_angle_deg, 0.0, 90.0, low_open=True)
        check_range("ahc.depth_alpha", self.depth_alpha, 0.0, 10.0)
        check_range("ahc.depth_change_tol_m", self.depth_change_tol_m, 0.0, 10.0)
        check_range("ahc.min_area_m2", self.min_area_m2, 0.0, 1e6)
        check_range("ahc.min_width_m", self.min_width_m, 0.0, 1e3)
        check_range("ahc.refit_angle_deg", self.refit_angle_deg, 0.0, 90.0, low_open=True)

    def t_mse(self, z_m: np.ndarray, tol_m: float) -> np.ndarray:
        """T_mse(z) = (sigma z^2 + tol)^2 in m^2."""
        return (self.depth_sigma_per_m * z_m * z_m + tol_m) ** 2

    def cos_t_ang_init(self, z_m: np.ndarray) -> np.ndarray:
        """cos of T_ang(z), linear in clipped z from angle_near to angle_far."""
        zc = np.clip(z_m, self.z_near_m, self.z_far_m)
        f = (zc - self.z_near_m) / (self.z_far_m - self.z_near_m)
        return np.cos(np.radians(self.angle_near_deg + f * (self.angle_far_deg - self.angle_near_deg)))


@dataclass(frozen=True)
class AhcPlane:
    """One extracted cluster in the camera frame: pixel count, PCA centre / unit normal (towards
    the camera), MSE (m^2), area (m^2, sum of the pixel footprints z^2 / (fx fy |n . ray|) on the
    plane, per cell) and the flat indices of its cells in the (rows, cols) cell grid."""

    n_px: int
    center_cam_m: np.ndarray
    normal_cam: np.ndarray
    mse_m2: float
    area_m2: float
    cell_index: np.ndarray


@dataclass
class AhcSegmentation:
    """Result of :func:`segment_depth`: per-pixel labels, planes, cell grid and counters."""

    labels_px: np.ndarray
    planes: list[AhcPlane] = field(default_factory=list)
    cell_grid: tuple[int, int] = (0, 0)
    stats: dict[str, float | str] = field(default_factory=dict)



def _empty(shape: tuple[int, ...], status: str) -> AhcSegmentation:
    h, w = (shape if len(shape) == 2 else (0, 0))
    return AhcSegmentation(np.full((h, w), -1, np.int32), [], (0, 0), {"status": status})


def _valid_k(K: object) -> np.ndarray | None:
    try:
        Km = np.asarray(K, dtype=np.float64)
    except (TypeError, ValueError):
        return None
    if Km.shape != (3, 3) or not np.all(np.isfinite(Km)) or Km[0, 0] <= 0 or Km[1, 1] <= 0:
        return None
    return Km


def segment_depth(depth_m: np.ndarray | None, K: np.ndarray, config: AhcConfig | None = None) -> AhcSegmentation:
    """Steps 1-3 of II-F on one depth image (camera frame); see the module docstring."""
    c = config or AhcConfig()
    if depth_m is None:
        return _empty((0, 0), "no depth")
    d = np.asarray(depth_m)
    if d.ndim != 2 or not np.issubdtype(d.dtype, np.number):
        return _empty((0, 0), "depth is not an (H, W) image")
    Km = _valid_k(K)
    if Km is None:
        return _empty(d.shape, "K not finite")
    k = c.cell_px
    H, W = d.shape
    hc, wc = H // k, W // k
    labels_px = np.full((H, W), -1, np.int32)
    if hc == 0 or wc == 0:
        return AhcSegmentation(labels_px, [], (hc, wc), {"status": "image smaller than a cell", "cells": 0.0})

    # step 1: cells and their moments (weights 1, u, v, u^2, uv, v^2 are separable, so every
    # moment is a row pass then a column pass over z or z^2)
    z = d[: hc * k, : wc * k].astype(np.float64)
    ok = np.isfinite(z) & (z > 0)
    z[~ok] = 0.0
    # step 2: cells with a missing pixel or a depth jump inside (T_dz) are dropped
    bad = ~ok
    inner_x = (np.arange(wc * k - 1) % k) != k - 1  # pixel pairs inside one cell
    bad[:, :-1] |= (np.abs(z[:, 1:] - z[:, :-1]) > c.depth_alpha * z[:, :-1] + c.depth_change_tol_m) & inner_x
    inner_y = ((np.arange(hc * k - 1) % k) != k - 1)[:, None]
    bad[:-1] |= (np.abs(z[1:] - z[:-1]) > c.depth_alpha * z[:-1] + c.depth_change_tol_m) & inner_y
    cell_ok = bad.reshape(hc, k, wc * k).sum(axis=1).reshape(hc, wc, k).sum(axis=2) == 0
    idx_ok = np.flatnonzero(cell_ok.reshape(-1))
    stats: dict[str, float | str] = {"status": "ok", "cells": float(hc * wc), "cells_valid_depth": float(idx_ok.size)}
    if idx_ok.size == 0:
        return AhcSegmentation(labels_px, [], (hc, wc), stats)
    u = ((np.arange(wc * k) - Km[0, 2]) / Km[0, 0]).reshape(wc, k)
    v = ((np.arange(hc * k) - Km[1, 2]) / Km[1, 1]).reshape(hc, k)
    z2 = z * z

    def rows(a: np.ndarray, p: int) -> np.ndarray:  # sum_r a v^p within each cell row -> (hc, W)
        ar = a.reshape(hc, k, wc * k)
        return ar.sum(axis=1) if p == 0 else np.matmul((v ** p)[:, None, :], ar)[:, 0, :]

    def cols(a: np.ndarray, p: int) -> np.ndarray:  # sum_c a u^p within each cell column -> (hc*wc,)
        ac = a.reshape(hc, wc, k)
        return (ac.sum(axis=2) if p == 0 else (ac * (u ** p)[None]).sum(axis=2)).reshape(-1)

    z_r0, z_r1 = rows(z, 0), rows(z, 1)
    q_r0, q_r1, q_r2 = rows(z2, 0), rows(z2, 1), rows(z2, 2)
    n_px = np.full(hc * wc, float(k * k))
    mom_all = np.stack([n_px, cols(z_r0, 1), cols(z_r1, 0), cols(z_r0, 0), cols(q_r0, 2), cols(q_r1, 1),
                        cols(q_r0, 1), cols(q_r2, 0), cols(q_r1, 0), cols(q_r0, 0)], axis=1)
    mom = mom_all[idx_ok]
    mean, normal, mse, _ = moment_pca(mom)
    keep = mse < c.t_mse(mean[:, 2], c.std_tol_init_m)
    idx_ok, mom, mean, normal = idx_ok[keep], mom[keep], mean[keep], normal[keep]
    stats["cells_planar"] = float(idx_ok.size)
    n_cells = idx_ok.size
    if n_cells == 0:
        return AhcSegmentation(labels_px, [], (hc, wc), stats)

    # links between 4-neighbour planar cells with similar normals (T_ang init)
    node = np.full(hc * wc, -1, np.int64)
    node[idx_ok] = np.arange(n_cells)
    grid = node.reshape(hc, wc)
    a = np.concatenate([grid[:, :-1].ravel(), grid[:-1, :].ravel()])
    b = np.concatenate([grid[:, 1:].ravel(), grid[1:, :].ravel()])
    both = (a >= 0) & (b >= 0)
    a, b = a[both], b[both]
    zab = 0.5 * (mean[a, 2] + mean[b, 2])
    link = np.abs(np.einsum("ij,ij->i", normal[a], normal[b])) >= c.cos_t_ang_init(zab)
    ea, eb = a[link], b[link]

    # step 3: agglomerative merging in rounds
    label = np.arange(n_cells)
    cos_merge = np.cos(np.radians(c.merge_angle_deg))
    n_clusters = n_cells
    rounds = 0
    while ea.size and rounds < c.max_rounds:
        rounds += 1
        cm = group_sum(label, mom, n_clusters)
        _, cn, _, _ = moment_pca(cm)
        la, lb = label[ea], label[eb]
        diff = la != lb
        lo, hi = np.minimum(la[diff], lb[diff]), np.maximum(la[diff], lb[diff])
        key = np.unique(lo * n_clusters + hi)
        if key.size == 0:
            break
        pa, pb = key // n_clusters, key % n_clusters
        mean_m, mse_m = moment_mse(cm[pa] + cm[pb])
        allowed = (np.abs(np.einsum("ij,ij->i", cn[pa], cn[pb])) >= cos_merge) & \
                  (mse_m < c.t_mse(mean_m[:, 2], c.std_tol_merge_m))
        if not allowed.any():
            break
        pa, pb, mse_m, key = pa[allowed], pb[allowed], mse_m[allowed], key[allowed]
        order = np.lexsort((key, mse_m))  # least merged MSE first, ties by ids
        ends = np.concatenate([pa[order], pb[order]])
        rank = np.concatenate([np.arange(order.size), np.arange(order.size)])
        first = np.full(n_clusters, order.size, np.int64)
        np.minimum.at(first, ends, rank)
        proposer = np.flatnonzero(first < order.size)
        best_edge = first[proposer]  # rank in ``order`` of each proposer's choice
        e_sorted_a, e_sorted_b = pa[order], pb[order]
        partner = np.where(e_sorted_a[best_edge] == proposer, e_sorted_b[best_edge], e_sorted_a[best_edge])
        # trees of proposals
        _, comp = forest_labels(n_clusters, proposer, partner)
        gm = group_sum(comp, cm, int(comp.max()) + 1)
        g_mean, g_mse = moment_mse(gm)
        tree_ok = g_mse < c.t_mse(g_mean[:, 2], c.std_tol_merge_m)
        use = tree_ok[comp[proposer]]
        mutual = first[partner] == best_edge
        use |= mutual
        n_new, comp2 = forest_labels(n_clusters, proposer[use], partner[use])
        if n_new == n_clusters:
            break
        label = comp2[label]
        n_clusters = n_new
    stats["rounds"] = float(rounds)

    # clusters -> planes. The final PCA uses the cluster's interior cells (all 4 neighbours in
    # the cluster), as [34] erodes cluster borders before its refinement: border cells are the
    # ones that may straddle an edge and tilt the fit; all cells if fewer than 4 are interior.
    cm = group_sum(label, mom, n_clusters)
    full = np.full(hc * wc, -1, np.int64)
    full[idx_ok] = label
    fg = np.pad(full.reshape(hc, wc), 1, mode="edge")
    centre = fg[1:-1, 1:-1]
    interior = ((fg[:-2, 1:-1] == centre) & (fg[2:, 1:-1] == centre) & (fg[1:-1, :-2] == centre)
                & (fg[1:-1, 2:] == centre)).reshape(-1)[idx_ok]
    cm_in = group_sum(label[interior], mom[interior], n_clusters)
    n_in = np.bincount(label[interior], minlength=n_clusters)
    fit = np.where((n_in >= 4)[:, None], cm_in, cm)
    _, c_normal, _, _ = moment_pca(fit)
    # then only the cells whose own normal is within refit_angle_deg of that fit (drops the
    # straddling cells of small clusters that have no interior)
    close = np.abs(np.einsum("ij,ij->i", normal, c_normal[label])) >= np.cos(np.radians(c.refit_angle_deg))
    cm_close = group_sum(label[close], mom[close], n_clusters)
    n_close = np.bincount(label[close], minlength=n_clusters)
    fit = np.where((n_close >= 1)[:, None], cm_close, fit)
    c_mean, c_normal, c_mse, _ = moment_pca(fit)
    _, _, _, full_mid = moment_pca(cm)
    n_px = cm[:, 0]
    width = np.sqrt(12.0 * full_mid)  # full width of a uniform strip
    big = np.flatnonzero((n_px >= c.min_support_px) & (width >= c.min_width_m))
    # deterministic order: most pixels first, then the lowest cell index
    first_cell = np.full(n_clusters, hc * wc, np.int64)
    np.minimum.at(first_cell, label, idx_ok)
    big = big[np.lexsort((first_cell[big], -n_px[big]))]
    planes: list[AhcPlane] = []
    cell_label = np.full(hc * wc, -1, np.int32)
    ray = mean / mean[:, 2:3]
    for cl in big:
        n = c_normal[cl]
        if n @ c_mean[cl] > 0:  # towards the camera (origin)
            n = -n
        members = label == cl
        cos_inc = np.maximum(np.abs(ray[members] @ n), 0.05)
        area = float(np.sum(mom[members, 9] / cos_inc) / (Km[0, 0] * Km[1, 1]))
        if area < c.min_area_m2:
            continue
        cells = idx_ok[members]
        cell_label[cells] = len(planes)
        planes.append(AhcPlane(int(n_px[cl]), c_mean[cl].copy(), n.copy(), float(c_mse[cl]), area, cells))
    labels_px[: hc * k, : wc * k] = np.repeat(np.repeat(cell_label.reshape(hc, wc), k, axis=0), k, axis=1)
    stats["clusters"] = float(n_clusters)
    stats["planes"] = float(len(planes))
    return AhcSegmentation(labels_px, planes, (hc, wc), stats)


def _area_and_cells(p_w: np.ndarray, center: np.ndarray, normal: np.ndarray,
                    cell_m: float) -> tuple[float, np.ndarray]:
    """plane_from_points' area (occupied cell_m squares in the plane's 2-D grid) and voxels."""
    e1 = np.cross(normal, [1.0, 0.0, 0.0] if abs(normal[0]) < 0.9 else [0.0, 1.0, 0.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(normal, e1)
    q = p_w - center
    iu = np.floor(q @ e1 / cell_m).astype(np.int64)
    iv = np.floor(q @ e2 / cell_m).astype(np.int64)
    area = np.unique((iu - iu.min()) * (int(iv.max() - iv.min()) + 1) + (iv - iv.min())).size * cell_m * cell_m
    return float(area), voxel_keys(p_w, cell_m)


def extract_planes(depth_m: np.ndarray | None, K: np.ndarray, T_world_cam: np.ndarray,
                   config: AhcConfig | None = None, cell_m: float = 0.05) -> list[DetectedPlane]:
    """The planes of one (smoothed) depth image as world-frame DetectedPlanes (II-F); the
    i-th plane is label i of ``segment_depth(depth_m, K, config).labels_px``."""
    c = config or AhcConfig()
    check_range("extract_planes.cell_m", cell_m, 0.0, 10.0, low_open=True)
    try:
        T = np.asarray(T_world_cam, dtype=np.float64)
    except (TypeError, ValueError):
        return []
    if T.shape != (4, 4) or not np.all(np.isfinite(T)):
        return []
    seg = segment_depth(depth_m, K, c)
    if not seg.planes:
        return []
    Km = np.asarray(K, dtype=np.float64)
    R, t = T[:3, :3], T[:3, 3]
    s = min(c.support_stride_px, c.cell_px)  # every cell keeps a sample
    lab = seg.labels_px[::s, ::s]
    z = np.asarray(depth_m, dtype=np.float64)[::s, ::s]
    vv, uu = np.nonzero(lab >= 0)
    zz = z[vv, uu]
    pts_cam = np.column_stack([(uu * s - Km[0, 2]) / Km[0, 0] * zz, (vv * s - Km[1, 2]) / Km[1, 1] * zz, zz])
    pts_w = pts_cam @ R.T + t
    lab_s = lab[vv, uu]
    order = np.argsort(lab_s, kind="stable")
    bounds = np.searchsorted(lab_s[order], np.arange(len(seg.planes) + 1))
    out: list[DetectedPlane] = []
    for i, pl in enumerate(seg.planes):
        center = R @ pl.center_cam_m + t
        normal = R @ pl.normal_cam
        normal /= np.linalg.norm(normal)
        p_w = pts_w[order[bounds[i]:bounds[i + 1]]]
        area, cells = _area_and_cells(p_w, center, normal, cell_m)
        out.append(DetectedPlane(center, normal, area, cells))
    return out
