"""TSDF map of the terrain and its ray-cast "smoothed depth image" (seeds/002, II-E eq. 19-22, II-F).

API (other modules code against exactly this)::

    from exobench.mapping.tsdf import Tsdf, TsdfConfig
    tsdf = Tsdf(TsdfConfig())                  # or Tsdf() for the defaults
    tsdf.reset()                               # empty map
    tsdf.integrate(depth_m, K, T_world_cam)    # -> None; (H,W) float32 metres, 0 = invalid
    tsdf.raycast_depth(K, T_world_cam, width, height)  # -> (height,width) float32, 0 = no hit
    tsdf.surface_points()                      # -> (N,3) float64 world points, for display
    tsdf.stats                                 # TsdfStats: frames integrated / skipped, blocks

``K`` is the 3x3 pinhole matrix of the image passed (pixel (u, v) = column, row), ``T_world_cam``
the 4x4 camera-to-world pose of the optical frame (x right, y down, z forward).

The map is Open3D's tensor ``VoxelBlockGrid`` (CPU) with a float32 ``tsdf`` and ``weight`` per
voxel; voxel values live at the voxel corners i * voxel_size_m.

Update of eq. 19-22 and why Open3D's own kernel is used for it
--------------------------------------------------------------
Eq. 19-22 update "every voxel": the blocks passed to the kernel are the blocks within
t_delta of the frame's measured points (newly allocated as needed) plus every allocated block
in the view frustum, so free space in front of a new measurement is carved too (lambda' = -1:
stale surfaces such as a passer-by fade out). For every voxel t_j of these blocks that
projects into the image onto a valid depth, ``VoxelBlockGrid.integrate`` computes
sdf = d_c - d_tj (measured depth minus the voxel's camera z), skips voxels with sdf < -t_delta
(occluded, far behind the surface, as in [18]), truncates tsdf' = min(1, sdf / t_delta) and
updates tsdf <- (W tsdf + tsdf') / (W + 1), W <- W + 1. The paper's w_j is "a preset
parameter" (one constant per observation), so eq. 21 is invariant to expressing all weights
in units of w_j: storing W / w_j makes Open3D's kernel compute eq. 20-21 exactly; eq. 22's cap
W_max is then applied to the touched blocks' weight tensor after each frame
(weight <- min(weight, W_max / w_j)), which reproduces min(W + w, W_max). No per-pixel weight is
needed for the paper's scheme, hence no hand-written voxel loop: the C++ kernel is ~10x faster
than the same update in numpy. ``weight`` read from the grid times ``obs_weight`` is W of the
paper (:meth:`Tsdf.voxel_values` does that). Sign: eq. 19 defines SDF = d_tj - d_c (positive
behind the surface); the stored ``tsdf`` is Open3D's d_c - d_tj, i.e. exactly -lambda of
eq. 20-21 (they are odd/linear in SDF), so the surface is the same zero set.

Open3D's kernel reads the depth at the truncated (floored) projected pixel coordinate; K is
passed to it with c_x, c_y + 0.5 so that the nearest pixel is read (pixel centres at integer
coordinates, the convention of K here); without that, surfaces seen at a grazing angle come out
up to 2 cm too far.

Ray casting (II-F, [19])
------------------------
1. ``VoxelBlockGrid.ray_cast`` (C++) marches each pixel ray through the blocks in the view
   frustum and interpolates the zero crossing linearly between two samples, but it reads the
   *nearest-lower* voxel (floor) at each sample: an error of up to a voxel. It is run from the
   camera shifted by half a voxel along each world axis, so every sample reads the nearest
   voxel corner instead (no bias, error up to ~half a voxel, grid-aligned ripples).
2. Newton refinement in numpy (``refine_raycast``): along a pixel's own ray the projective SDF
   falls with slope -1/t_delta per metre of z-depth, so t <- t + t_delta tsdf(t), with tsdf
   trilinearly interpolated from a dense copy of the blocks in view, converges to the zero
   crossing of the trilinear field in one or two steps (``refine_steps`` = 2). No step where a
   corner voxel is unobserved or the value is saturated (outside the truncation band).
Measured on the analytic staircases of tests/mapping/test_mapping_tsdf.py (one noise-free frame, away
from edges): median |error| 0.5-0.8 mm, 99th percentile < 1.5 cm (grazing far treads), versus
~1 cm RMS without step 2; planes extracted from the ray cast of 6 noisy frames (sigma 1 cm)
are within 1.5 deg and 0.3 mm of the true treads and risers. A voxel needs
W >= raycast_min_weight to stop a ray.

``ray_cast`` keeps a buffer of range-map fragments in the grid that it sizes on its first call
and that overflows silently (rays find nothing) and sometimes crashes open3d 0.20 when a later
call needs more; :meth:`Tsdf._prime` therefore makes the first call itself with a large buffer.
Its range map is the image // 8; when the width or height is not a multiple of 8 (212 x 120, a
424 x 240 camera at half resolution) the rays of the last partial cell read outside the range
map and ``ray_cast`` was seen to hang there. :meth:`Tsdf.raycast_depth` therefore casts an image
padded to whole cells (same K: the extra rays lie beyond the right / bottom edge) and crops it.

Choices the paper leaves open [A]: voxel 0.02 m, t_delta = 0.06 m, w_j = 1, W_max = 50 (once
capped, each frame has weight w / (W_max + w) = 1/51: a forgetting time constant of ~1.7 s at
30 Hz, so stale geometry such as a passer-by fades out), depth range 0.3-4.0 m (D455),
raycast_min_weight = 1 (one observation).

Faulty input never raises: a frame whose depth is None, not 2-D, all invalid (0, NaN, inf,
outside the depth range) or whose K / pose is not finite is skipped (``stats.frames_skipped``,
``stats.last_status``); NaN / inf pixels are treated as invalid. Deterministic: Open3D updates
each voxel independently, so values do not depend on thread scheduling; the hash map's buffer
order may, so blocks are sorted before the ray cast and :meth:`surface_points` sorts its output.

Cost (2-core machine shared with other jobs, 640x480 staircase, median CPU time per call summed
over threads; wall time was 3-4x that under a load average of ~9): integrate 7.8 ms (stride 1)
/ 5.3 ms (stride 2), i.e. well above 30 frames/s at full resolution when the cores are free;
ray cast 50 ms at 640x480, 16 ms at 320x240 (refinement included, 2-4 ms of it). Callers that
need frame rate should ray cast at 320x240 (K scaled; c' = (c - 0.5) / 2 for pixel centres).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import open3d as o3d

from exobench.core import check_int, check_range

o3c = o3d.core
_CPU = o3c.Device("CPU:0")
_RANGE_DOWN = 8  # ray_cast's range map is 1/8 of the image
_PRIME_FRAGMENTS = 120_000  # half of what _prime allocates, as a margin


@dataclass(frozen=True)
class TsdfConfig:
    """Parameters of the map (eq. 19-22); all lengths in metres.

    voxel_size_m: voxel edge. truncation_m: t_delta of eq. 20. depth_min_m / depth_max_m:
    depths outside are invalid (integration and ray cast). block_resolution: voxels per block
    edge. block_count: initial hash map capacity (blocks; it grows by itself; 4000 = 16 MB).
    obs_weight: w_j of eq. 21-22.
    max_weight: W_max of eq. 22. raycast_min_weight: W a voxel needs to stop a ray (and to be
    a surface point). integrate_stride_px: integrate every n-th pixel row/column (1 = all).
    refine_raycast: sub-voxel refinement of the ray cast (module docstring); it is skipped when
    the dense copy of the blocks in view would exceed refine_max_voxels voxels (4 bytes each).
    """

    voxel_size_m: float = 0.02
    truncation_m: float = 0.06
    depth_min_m: float = 0.3
    depth_max_m: float = 4.0
    block_resolution: int = 8
    block_count: int = 4000
    obs_weight: float = 1.0
    max_weight: float = 50.0
    raycast_min_weight: float = 1.0
    integrate_stride_px: int = 1
    refine_raycast: bool = True
    refine_steps: int = 2
    refine_max_voxels: int = 30_000_000

    def __post_init__(self) -> None:
        check_range("tsdf.voxel_size_m", self.voxel_size_m, 0.001, 1.0)
        check_range("tsdf.truncation_m", self.truncation_m, self.voxel_size_m, 10.0)
        check_range("tsdf.depth_min_m", self.depth_min_m, 0.0, 100.0)
        check_range("tsdf.depth_max_m", self.depth_max_m, self.depth_min_m, 100.0, low_open=True)
        for name, low in (("block_resolution", 2), ("block_count", 1), ("integrate_stride_px", 1),
                          ("refine_max_voxels", 1), ("refine_steps", 1)):
            object.__setattr__(self, name, check_int(f"tsdf.{name}", getattr(self, name), low))
        check_range("tsdf.obs_weight", self.obs_weight, 0.0, 1e6, low_open=True)
        check_range("tsdf.max_weight", self.max_weight, self.obs_weight, 1e9)
        check_range("tsdf.raycast_min_weight", self.raycast_min_weight, 0.0, self.max_weight, low_open=True)


@dataclass
class TsdfStats:
    """Counters of the map: frames integrated / skipped, active blocks, last frame's status."""

    frames_integrated: int = 0
    frames_skipped: int = 0
    active_blocks: int = 0
    last_status: str = "empty"


def _finite_matrix(a: object, shape: tuple[int, int]) -> np.ndarray | None:
    try:
        m = np.asarray(a, dtype=np.float64)
    except (TypeError, ValueError):
        return None
    if m.shape != shape or not np.all(np.isfinite(m)):
        return None
    return m


class Tsdf:
    """The TSDF map S of II-E on an Open3D VoxelBlockGrid (see the module docstring)."""

    def __init__(self, config: TsdfConfig | None = None) -> None:
        self.config = config or TsdfConfig()
        self.reset()

    # -- state ---------------------------------------------------------------------------------
    def reset(self) -> None:
        """Forget the map and the counters."""
        c = self.config
        self._vbg = o3d.t.geometry.VoxelBlockGrid(
            attr_names=("tsdf", "weight"), attr_dtypes=(o3c.float32, o3c.float32), attr_channels=((1), (1)),
            voxel_size=c.voxel_size_m, block_resolution=c.block_resolution, block_count=c.block_count,
            device=_CPU)
        self.stats = TsdfStats()
        self._prime()

    def _prime(self) -> None:
        """Size Open3D's ray-cast fragment buffer once, before the map is used.

        ``ray_cast`` first projects every block to a rectangle of the 1/8 range map, cut into
        16 x 16 fragments, stored in a buffer the grid keeps between calls. The first call
        allocates it from its own image size (h w / 5.12 fragments at a range-map factor 1);
        when a later call needs more, open3d 0.20 drops the excess fragments (rays there find
        nothing), warns, grows the buffer for the next call, and was seen to crash now and then
        in that path. So the first call is made here, at 1280 x 960 with factor 1 and one block
        far out of view: the buffer holds 240000 fragments (5.8 MB) and never overflows in
        :meth:`raycast_depth`, which passes at most _PRIME_FRAGMENTS / (fragments per block)
        blocks (20 per block at 640 x 480: 6000 blocks, far more than 4 m of terrain holds)."""
        w, h = 1280, 960
        K = np.array([[500.0, 0.0, w / 2], [0.0, 500.0, h / 2], [0.0, 0.0, 1.0]])
        self._vbg.ray_cast(o3c.Tensor(np.full((1, 3), -100000, np.int32)), o3c.Tensor(K), o3c.Tensor(np.eye(4)),
                           w, h, ["depth"], 1.0, 0.1, 1.0, 1e9, self._trunc_mult, 1)

    @property
    def _trunc_mult(self) -> float:
        return self.config.truncation_m / self.config.voxel_size_m

    def _skip(self, status: str) -> None:
        self.stats.frames_skipped += 1
        self.stats.last_status = status

    # -- eq. 19-22 -----------------------------------------------------------------------------
    def integrate(self, depth_m: np.ndarray | None, K: np.ndarray, T_world_cam: np.ndarray) -> None:
        """Fuse one depth image (eq. 19-22). Faulty frames are skipped (see ``stats``)."""
        c = self.config
        if depth_m is None:
            return self._skip("dropped frame")
        d = np.asarray(depth_m)
        if d.ndim != 2 or d.shape[0] < 2 or d.shape[1] < 2 or not np.issubdtype(d.dtype, np.number):
            return self._skip("depth is not an (H, W) number image")
        Km = _finite_matrix(K, (3, 3))
        T = _finite_matrix(T_world_cam, (4, 4))
        if Km is None or T is None or Km[0, 0] <= 0 or Km[1, 1] <= 0:
            return self._skip("K or T_world_cam not finite")
        s = c.integrate_stride_px
        if s > 1:
            d = d[::s, ::s]
            Km = Km.copy()
            Km[:2] /= s
        d = np.array(d, dtype=np.float32, copy=True)
        bad = ~np.isfinite(d) | (d < c.depth_min_m) | (d > c.depth_max_m)
        d[bad] = 0.0
        if bad.all():
            return self._skip("no valid depth")
        try:
            T_cam_world = np.linalg.inv(T)
        except np.linalg.LinAlgError:
            return self._skip("T_world_cam not invertible")
        img = o3d.t.geometry.Image(o3c.Tensor(np.ascontiguousarray(d)))
        K_o3d = Km.copy()
        K_o3d[:2, 2] += 0.5  # Open3D truncates the projected pixel coordinate: make it round
        intr = o3c.Tensor(K_o3d)
        extr = o3c.Tensor(T_cam_world)
        vbg = self._vbg
        try:
            blocks = vbg.compute_unique_block_coordinates(img, intr, extr, 1.0, c.depth_max_m, self._trunc_mult)
        except RuntimeError:  # e.g. "No block is touched": nothing of the frame within range
            return self._skip("open3d refused the frame")
        if blocks.shape[0] == 0:
            return self._skip("no blocks in view")
        if vbg.hashmap().size() > 0:  # "every voxel" in view: also the allocated blocks in the frustum
            old = self._active_keys()
            old = old[self._blocks_in_view(old, Km, T, d.shape)]
            if len(old):
                both = np.unique(np.concatenate([blocks.numpy().astype(np.int64), old]), axis=0)
                blocks = o3c.Tensor(np.ascontiguousarray(both.astype(np.int32)))
        vbg.integrate(blocks, img, intr, extr, 1.0, c.depth_max_m, self._trunc_mult)
        # eq. 22: W <- min(W + w, W_max), weights stored in units of w
        buf, found = vbg.hashmap().find(blocks)
        idx = buf.numpy()[found.numpy()].astype(np.int64)
        w = vbg.attribute("weight").numpy()  # a view of the grid's buffer
        cap = np.float32(c.max_weight / c.obs_weight)
        sub = w[idx]
        np.minimum(sub, cap, out=sub)
        w[idx] = sub
        self.stats.frames_integrated += 1
        self.stats.active_blocks = int(vbg.hashmap().size())
        self.stats.last_status = "ok"

    def voxel_values(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(corner coordinates (N,3) m, lambda (N,) in the paper's sign of eq. 19, W (N,)) of
        every allocated voxel, sorted by coordinate (for inspection and tests)."""
        vbg = self._vbg
        if vbg.hashmap().size() == 0:
            return np.zeros((0, 3)), np.zeros(0), np.zeros(0)
        xyz, flat = vbg.voxel_coordinates_and_flattened_indices()
        idx = flat.numpy().reshape(-1)
        lam = -vbg.attribute("tsdf").numpy().reshape(-1)[idx].astype(np.float64)
        W = vbg.attribute("weight").numpy().reshape(-1)[idx].astype(np.float64) * self.config.obs_weight
        p = xyz.numpy().astype(np.float64)
        order = np.lexsort((p[:, 2], p[:, 1], p[:, 0]))
        return p[order], lam[order], W[order]

    # -- II-F ray casting ----------------------------------------------------------------------
    def raycast_depth(self, K: np.ndarray, T_world_cam: np.ndarray, width: int, height: int) -> np.ndarray:
        """The smoothed depth image I_D^s seen from ``T_world_cam`` with intrinsics ``K``:
        (height, width) float32 z-depth in metres, 0 where no surface is hit."""
        c = self.config
        out = np.zeros((max(int(height), 0), max(int(width), 0)), dtype=np.float32)
        Km = _finite_matrix(K, (3, 3))
        T = _finite_matrix(T_world_cam, (4, 4))
        vbg = self._vbg
        if Km is None or T is None or min(out.shape) < _RANGE_DOWN or vbg.hashmap().size() == 0 \
                or Km[0, 0] <= 0 or Km[1, 1] <= 0:
            return out  # (images smaller than 8 px would give Open3D an empty range map)
        hm = vbg.hashmap()
        buf = hm.active_buf_indices().numpy().astype(np.int64)
        keys = hm.key_tensor().numpy()[buf].astype(np.int64)  # key_tensor() also holds free slots
        sel = self._blocks_in_view(keys, Km, T, out.shape)
        if not sel.any():
            return out
        buf, keys = buf[sel], keys[sel]
        order = np.lexsort((keys[:, 2], keys[:, 1], keys[:, 0]))  # fixed order, whatever the hash map's
        buf, keys = buf[order], keys[order]
        # Open3D's range map is image // _RANGE_DOWN; the rays of a last partial cell (width or
        # height not a multiple of it) read outside the range map and were seen to hang
        # ray_cast (212 x 120): the image is padded to whole cells and cropped afterwards.
        hp, wp = -(-out.shape[0] // _RANGE_DOWN) * _RANGE_DOWN, -(-out.shape[1] // _RANGE_DOWN) * _RANGE_DOWN
        h_down, w_down = hp // _RANGE_DOWN, wp // _RANGE_DOWN
        max_blocks = _PRIME_FRAGMENTS // max(1, -(-h_down // 16) * -(-w_down // 16)) - 1
        if len(keys) > max_blocks:  # keep the nearest blocks (see _prime)
            dist = np.linalg.norm((keys + 0.5) * c.voxel_size_m * c.block_resolution - T[:3, 3], axis=1)
            keep = np.sort(np.argsort(dist, kind="stable")[:max_blocks])
            buf, keys = buf[keep], keys[keep]
            self.stats.last_status = "ray cast limited to the nearest blocks"
        T_shift = T.copy()
        T_shift[:3, 3] += 0.5 * c.voxel_size_m  # nearest-voxel lookups, see module docstring
        try:
            res = vbg.ray_cast(o3c.Tensor(np.ascontiguousarray(keys.astype(np.int32))), o3c.Tensor(Km),
                               o3c.Tensor(np.linalg.inv(T_shift)), wp, hp, ["depth"],
                               1.0, c.depth_min_m, c.depth_max_m, c.raycast_min_weight / c.obs_weight,
                               self._trunc_mult, _RANGE_DOWN)
        except (RuntimeError, np.linalg.LinAlgError):
            return out
        d = np.ascontiguousarray(res["depth"].numpy().reshape(hp, wp)[:out.shape[0], :out.shape[1]], dtype=np.float32)
        d[~np.isfinite(d) | (d < c.depth_min_m) | (d > c.depth_max_m)] = 0.0
        if c.refine_raycast:
            self._refine(d, Km, T, buf, keys)
        return d

    def _active_keys(self) -> np.ndarray:
        hm = self._vbg.hashmap()
        return hm.key_tensor().numpy()[hm.active_buf_indices().numpy().astype(np.int64)].astype(np.int64)

    def _blocks_in_view(self, keys: np.ndarray, Km: np.ndarray, T: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
        """Blocks whose bounding sphere meets the view frustum (depth_min..depth_max)."""
        c = self.config
        bs = c.voxel_size_m * c.block_resolution
        rad = 0.5 * np.sqrt(3.0) * bs
        p = ((keys + 0.5) * bs - T[:3, 3]) @ T[:3, :3]  # block centres in the camera frame
        x, y, z = p[:, 0], p[:, 1], p[:, 2]
        h, w = shape
        ok = (z >= c.depth_min_m - rad) & (z <= c.depth_max_m + rad)
        for a, coord in (((-0.5 - Km[0, 2]) / Km[0, 0], x), ((-0.5 - Km[1, 2]) / Km[1, 1], y)):
            ok &= a * z - coord <= rad * np.sqrt(1 + a * a)  # coord >= a z
        for a, coord in (((w - 0.5 - Km[0, 2]) / Km[0, 0], x), ((h - 0.5 - Km[1, 2]) / Km[1, 1], y)):
            ok &= coord - a * z <= rad * np.sqrt(1 + a * a)  # coord <= a z
        return ok

    def _refine(self, d: np.ndarray, Km: np.ndarray, T: np.ndarray, buf: np.ndarray, keys: np.ndarray) -> None:
        """Sub-voxel zero crossing along each hit ray: ``refine_steps`` Newton steps on the
        trilinear interpolation of the TSDF from Open3D's hit t0 (in place). No step is taken
        where the interpolation touches an unobserved voxel (NaN) or is saturated (|tsdf| ~ 1,
        outside the truncation band, where the slope is unknown)."""
        c = self.config
        r = c.block_resolution
        vs = c.voxel_size_m
        kmin = keys.min(axis=0)
        nb = keys.max(axis=0) - kmin + 1
        dims = nb * r
        if int(np.prod(dims)) > c.refine_max_voxels:
            return
        tsdf = self._vbg.attribute("tsdf").numpy().reshape(-1, r, r, r)[buf]  # (nb, z, y, x)
        wgt = self._vbg.attribute("weight").numpy().reshape(-1, r, r, r)[buf]
        tsdf = np.where(wgt >= c.raycast_min_weight / c.obs_weight, tsdf, np.nan).transpose(0, 3, 2, 1)
        vol = np.full((nb[0], r, nb[1], r, nb[2], r), np.nan, dtype=np.float32)
        kb = keys - kmin
        vol[kb[:, 0], :, kb[:, 1], :, kb[:, 2], :] = tsdf
        flat = vol.reshape(-1)
        origin = kmin * (r * vs)
        vv, uu = np.nonzero(d > 0)
        if vv.size == 0:
            return
        t0 = d[vv, uu]
        f32 = np.float32
        rx = ((uu - Km[0, 2]) / Km[0, 0]).astype(f32)
        ry = ((vv - Km[1, 2]) / Km[1, 1]).astype(f32)
        R = (T[:3, :3] / vs).astype(f32)
        dirs = [R[i, 0] * rx + R[i, 1] * ry + R[i, 2] for i in range(3)]  # world ray per unit z, voxels
        org = ((T[:3, 3] - origin) / vs).astype(f32)
        n1, n2 = int(dims[1]), int(dims[2])
        offs = (0, 1, n2, n2 + 1, n1 * n2, n1 * n2 + 1, n1 * n2 + n2, n1 * n2 + n2 + 1)

        def phi(t: np.ndarray) -> np.ndarray:
            inside = np.ones(t.shape, bool)
            base = np.zeros(t.shape, np.int64)
            frac = []
            for axis in range(3):
                g = org[axis] + t * dirs[axis]
                i = np.floor(g)
                frac.append(g - i)
                ii = i.astype(np.int64)
                inside &= (ii >= 0) & (ii < dims[axis] - 1)
                base = base * int(dims[axis]) + ii if axis else ii
            base[~inside] = 0
            fx, fy, fz = frac
            cv = [flat[base + o] for o in offs]  # corners (x, y, z) = 000, 001, 010, 011, 100, ...
            c00 = cv[0] + fz * (cv[1] - cv[0])
            c01 = cv[2] + fz * (cv[3] - cv[2])
            c10 = cv[4] + fz * (cv[5] - cv[4])
            c11 = cv[6] + fz * (cv[7] - cv[6])
            c0 = c00 + fy * (c01 - c00)
            c1 = c10 + fy * (c11 - c10)
            val = c0 + fx * (c1 - c0)
            val[~inside] = np.nan
            return val

        # Along a pixel's own ray the projective SDF of eq. 19 falls with slope -1 / t_delta in
        # z-depth, so a Newton step is t <- t + t_delta * tsdf(t) (stored sign: + in front).
        t = t0
        for _ in range(c.refine_steps):
            val = phi(t)
            t = np.where(np.abs(val) < 0.99, t + f32(c.truncation_m) * val, t)  # NaN: no step
        d[vv, uu] = t.astype(np.float32)

    def surface_points(self) -> np.ndarray:
        """Zero-crossing points (N, 3) of the map in the world frame, sorted (for display)."""
        if self._vbg.hashmap().size() == 0:
            return np.zeros((0, 3))
        pcd = self._vbg.extract_point_cloud(self.config.raycast_min_weight / self.config.obs_weight)
        if "positions" not in pcd.point or pcd.point.positions.shape[0] == 0:
            return np.zeros((0, 3))
        p = pcd.point.positions.numpy().astype(np.float64)
        return p[np.lexsort((p[:, 2], p[:, 1], p[:, 0]))]
