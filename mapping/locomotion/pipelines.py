"""Locomotion-mode prediction pipelines of seeds/002 (track ``locomotion``).

``terrain-recon`` (:class:`TerrainReconstructionPipeline`), the paper's method: per RGB-D frame
the camera pose from odometry, TSDF integration (eq. 19-22, :mod:`exobench.mapping.tsdf`), a
ray-cast smoothed depth image (cast at 1/``raycast_downsample`` of the input resolution and
interpolated back to it, :func:`~.depth.upsample_depth`), AHC plane extraction on it
(:mod:`exobench.perception.terrain.plane_extraction`), the plane set update by IoU (eq. 23) with
the voxels seen in the smoothed image as the scope, the terrain description (II-F) and the mode
of the next step at the footprint predicted by eq. 16-18 (II-D; :mod:`.predict`).
``single-frame`` (:class:`SingleFramePipeline`), the ablation baseline: AHC on the raw depth of
the current frame only, a fresh plane set each frame, no TSDF; same footprint and mode logic.

A depth image wider than ``max_work_width_px`` (the D455's 424 px mode) is first decimated to
every m-th pixel with K adjusted (:func:`~.depth.decimate`); the 5 cm plane cells and voxels gain
nothing from more pixels.
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np

from exobench.mapping.tsdf import Tsdf
from exobench.perception.terrain.plane_extraction import extract_planes
from exobench.perception.terrain.plane_tracking import PlaneSet, voxel_keys

from .base import LocomotionPipeline
from .config import TerrainReconConfig
from .depth import backproject, scale_intrinsics, upsample_depth

__all__ = ["SingleFramePipeline", "TerrainReconstructionPipeline"]


class TerrainReconstructionPipeline(LocomotionPipeline):
    """The paper's pipeline: TSDF, ray-cast smoothed depth, AHC, plane set (eq. 23), terrain,
    footprint (eq. 16-18), mode (module docstring)."""

    name = "terrain-recon"

    Config: ClassVar[type] = TerrainReconConfig

    def _reset_map(self) -> None:
        self._tsdf = Tsdf(self.config.tsdf)

    def _update_planes(self, depth_m: np.ndarray, K: np.ndarray, T_odom_cam: np.ndarray) -> int:
        h, w = depth_m.shape
        n = self.config.raycast_downsample
        self._tsdf.integrate(depth_m, K, T_odom_cam)
        Ks = scale_intrinsics(K, 1.0 / n)
        smooth = np.asarray(self._tsdf.raycast_depth(Ks, T_odom_cam, max(1, w // n), max(1, h // n)), dtype=np.float32)
        smooth = np.where(np.isfinite(smooth) & (smooth > 0), smooth, 0.0).astype(np.float32)
        if n > 1:
            smooth = upsample_depth(smooth, n, (h, w), self.config.upsample_jump_m)
        detected = extract_planes(smooth, K, T_odom_cam, self.config.ahc, self.config.planes.cell_m) \
            if np.any(smooth > 0) else []
        stride = max(1, self.config.observed_stride_px)
        observed = voxel_keys(backproject(smooth, K, T_odom_cam, stride), self.config.planes.cell_m)
        self._plane_set.update(list(detected), observed)
        return len(detected)


class SingleFramePipeline(LocomotionPipeline):
    """Ablation baseline: planes from the current raw depth frame only (AHC, no TSDF), a fresh
    plane set each frame; same footprint and mode logic (module docstring)."""

    name = "single-frame"

    def _reset_map(self) -> None:
        """Nothing to forget: this baseline keeps no map between frames."""

    def _update_planes(self, depth_m: np.ndarray, K: np.ndarray, T_odom_cam: np.ndarray) -> int:
        detected = list(extract_planes(depth_m, K, T_odom_cam, self.config.ahc, self.config.planes.cell_m))
        if detected:  # a frame without planes keeps the last plane set
            self._plane_set = PlaneSet(self.config.planes)
            self._plane_set.update(detected)
        return len(detected)
