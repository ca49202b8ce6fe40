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

``terrain-recon`` takes the camera poses from the odometry stream (``odometry="given"``) or from
D-VIO run inside it (``"dvio"``, :mod:`.own_odometry`; the registered ``terrain-recon-dvio``):
then each frame waits for its D-VIO pose, a frame while D-VIO is lost takes the pose of its IMU
propagation of its last good state for a short loss (``loss_pose``; not fused into the map), a
frame without a pose (D-VIO initialising, or lost beyond that) makes a prediction without a mode
or footprint (status ``no_odometry``), the strikes take D-VIO's frame
poses (velocity from the last two; a strike before D-VIO's first pose waits for it and the
poses of its initialisation window), with ``reinit_map="reset"`` a re-initialisation starts a
new map (and places the strikes of the loss so),
and the estimate says its poses are its own (``LocomotionEstimate.odometry``), each prediction
carrying the pose it used.

A depth image wider than ``max_work_width_px`` (the D455's 424 px mode) is first decimated to
every m-th pixel with K adjusted (:func:`~.depth.decimate`); the 5 cm plane cells and voxels gain
nothing from more pixels.
"""

from __future__ import annotations

import time
from typing import ClassVar

import numpy as np

from exobench.core import (
    Calibration,
    ContactSample,
    Frame,
    ImuSample,
    LocomotionEstimate,
    ModePrediction,
    RgbdFrame,
)
from exobench.core.counters import nan_values
from exobench.core.limits import imu_absurd
from exobench.core.pipeline import check_frame
from exobench.mapping.tsdf import Tsdf
from exobench.perception.terrain.footprint import HeelStrike
from exobench.perception.terrain.plane_extraction import extract_planes
from exobench.perception.terrain.plane_tracking import PlaneSet, voxel_keys

from .base import LocomotionPipeline
from .config import TerrainReconConfig, TerrainReconDvioConfig
from .depth import backproject, scale_intrinsics, upsample_depth
from .own_odometry import DvioOdometry

__all__ = ["SingleFramePipeline", "TerrainReconDvioPipeline", "TerrainReconstructionPipeline"]

# the longest gap between two D-VIO poses over which their difference is a velocity, s
_MAX_VELOCITY_GAP_S = 0.5


class TerrainReconstructionPipeline(LocomotionPipeline):
    """The paper's pipeline: TSDF, ray-cast smoothed depth, AHC, plane set (eq. 23), terrain,
    footprint (eq. 16-18), mode (module docstring)."""

    name = "terrain-recon"

    Config: ClassVar[type] = TerrainReconConfig

    def reset(self, calibration: Calibration) -> None:
        super().reset(calibration)
        self._own: DvioOdometry | None = None
        if self.config.odometry == "dvio":
            self._own = DvioOdometry(self.config.dvio, calibration, self._rgbd_id)
            # D-VIO's poses are the camera's: the tracked point hangs off the camera itself
            self._T_body_cam = np.eye(4)
            self._T_body_track = self._T_cam_track
            self._odometry = "dvio"
            self._last_own: tuple[float, np.ndarray] | None = None
            self._posed = False  # whether the last frame released had a pose
            self._unplaced: list[tuple[HeelStrike, float]] = []  # strikes since then, with their instants
            self._stats.update(odometry_sensor_id="dvio", odometry_mount="camera", n_strikes_placed_with_window=0,
                               n_map_resets=0, n_frames_dead_reckoned=0)

    def process(self, frame: Frame) -> ModePrediction | None:
        if getattr(self, "_own", None) is None:  # the given odometry (or not reset: refused there)
            return super().process(frame)
        t0 = time.perf_counter()
        check_frame(self, frame, self._ready)
        own = self._own
        if isinstance(frame, ImuSample):
            c = self._counters.admit(frame, frame.sensor_id == own.imu_id)
            if c is not None:
                # counted as D-VIO takes it: a NaN or absurd sample is skipped there
                c.judge(frame, nan_values(frame) > 0 or imu_absurd(frame))
                own.feed(frame)
        elif isinstance(frame, ContactSample):
            c = self._counters.admit(frame, frame.sensor_id in self._heels)
            if c is not None:
                if own.idle():
                    self._on_contact(frame, c)
                else:
                    own.hold(frame, c, t0)
        else:  # the odometry stream is not read
            c = self._counters.admit(frame, isinstance(frame, RgbdFrame) and frame.sensor_id == self._rgbd_id)
            if c is not None:
                own.hold(frame, c, t0)
                own.feed(frame)
        return self._release()

    def _release(self) -> ModePrediction | None:
        """Use the held frames whose turn has come (:meth:`DvioOdometry.released`); the last
        prediction made."""
        pred = None
        for frame, c, t0, T in self._own.released():
            if isinstance(frame, ContactSample):
                self._on_contact(frame, c)
                continue
            if T is not None:
                # D-VIO's first pose after a gap: at its initialisation, or at a re-initialisation
                # whose new frame gets a new map (reinit_map), the strikes of the gap are placed
                # with its window's poses; a kept map stays in the old frame, and so do the strikes
                first = not self._posed and (self._last_own is None or self.config.reinit_map == "reset")
                if first and self._last_own is not None:
                    self._forget_old_frame()
                if first:
                    for t_kf, T_kf in self._own.window_poses(float(frame.stamp_s)):
                        self._remember_own(t_kf - self._cam_latency_s, T_kf)
                self._remember_own(float(frame.stamp_s) - self._cam_latency_s, T)
                if first:
                    self._place_gap_strikes()
                elif not self._posed:  # the map kept: the strikes of the loss stay without a pose
                    self._unplaced.clear()
            self._posed = T is not None
            dead = None if T is not None or self.config.loss_pose != "imu" or self._last_own is None \
                else self._own.dead_reckoned(float(frame.stamp_s), self.config.max_dead_reckon_s)
            if dead is not None:
                # lost: D-VIO's IMU propagation places the strikes and this frame's footprint,
                # in the frame its next segment will be anchored in; its depth is not fused,
                # as a dead-reckoned pose drifts quadratically and the map should not
                self._remember_own(float(frame.stamp_s) - self._cam_latency_s, dead)
                self._stats["n_frames_dead_reckoned"] += 1
                pred = self._on_rgbd(frame, c, t0, own=True, T_own=dead, map_update=False) or pred
                continue
            pred = self._on_rgbd(frame, c, t0, own=True, T_own=T) or pred
        return pred

    def _forget_old_frame(self) -> None:
        """D-VIO has re-initialised (``reinit_map="reset"``). Its new segment is anchored on the IMU's dead reckoning
        through the loss, so the new frame is off the old one by that dead reckoning's error
        (0.4-5.4 m, most of it vertical, on the unconventional walks; docs/tracks/locomotion.md):
        the map, in the old frame, would hold the surfaces seen before a second time, that far
        off. It is forgotten, as a system whose map is its odometry's starts a new map with a new
        odometry frame (nothing relates the two frames but the dead reckoning whose error this
        is), and so are the poses kept for the strikes. The strikes themselves are kept: forgetting
        them too left every step undecided until three strikes in the new frame, and decided
        fewer steps right on both walks measured (docs)."""
        self._reset_map()
        self._plane_set = PlaneSet(self.config.planes)
        self._description = None
        self._odom = []
        self._last_own = None
        self._stats["n_map_resets"] += 1

    def _strike_without_pose(self, strike: HeelStrike, t_s: float) -> None:
        super()._strike_without_pose(strike, t_s)
        if getattr(self, "_own", None) is not None:
            self._unplaced.append((strike, t_s))

    def _place_gap_strikes(self) -> None:
        """At D-VIO's first pose after a gap (its initialisation, or a re-initialisation), the
        strikes of the gap placed with the poses D-VIO now gives that frame and the keyframes of
        its window before it (:meth:`DvioOdometry.window_poses`), as a strike with a pose is: the
        predictor gets the strikes of the initialisation window at once, instead of waiting for
        three more."""
        st, placed = self._stats, False
        for strike, t_s in self._unplaced:
            odo = self._odometry_at(t_s)
            if odo is None:  # too far from any keyframe of the window: stays without a pose
                continue
            # as a strike with a pose is placed: the nearest pose moved on at its velocity
            p = self._track(odo[0]) + odo[1] * odo[2]
            self._divider.strikes.append(HeelStrike(strike.stamp_s, strike.side, p, odo[1].copy()))
            st["n_strikes_without_odometry"] -= 1
            st["n_heel_strikes"] += 1
            st["n_strikes_placed_with_window"] += 1
            placed = True
        if placed:  # after any strike placed before the gap with the poses of before
            self._divider.strikes.sort(key=lambda s: s.stamp_s)
        self._unplaced.clear()

    def _remember_own(self, t_s: float, T: np.ndarray) -> None:
        """Keep a D-VIO pose for the strikes, with the velocity from the previous pose."""
        v = np.zeros(3)
        if self._last_own is not None and 0.0 < t_s - self._last_own[0] <= _MAX_VELOCITY_GAP_S:
            v = (T[:3, 3] - self._last_own[1]) / (t_s - self._last_own[0])
        self._last_own = (t_s, T[:3, 3].copy())
        self._remember_pose(t_s, T, v)

    def finalize(self) -> LocomotionEstimate:
        if getattr(self, "_own", None) is None:
            return super().finalize()
        dvio_stats = self._own.finish()
        self._release()
        self._stats.update({f"dvio_{k}": v for k, v in dvio_stats.items()})
        self._stats["n_frames_without_pose"] = dict(self._own.n_without_pose)
        return super().finalize()

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


class TerrainReconDvioPipeline(TerrainReconstructionPipeline):
    """``terrain-recon`` on D-VIO's poses by default (``odometry="dvio"``), so that one run
    shows both."""

    name = "terrain-recon-dvio"

    Config: ClassVar[type] = TerrainReconDvioConfig
