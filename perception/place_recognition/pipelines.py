"""Place-recognition pipelines of the loop-closure track: SC++ and Gaussian Scan Context on keyframes.

Four pipelines (track ``loop-closure``) share one driver, :class:`PlaceRecognitionPipeline`, and
differ in the descriptor (seeds/003 section 4.2.3):

- ``sc++``: Scan Context++, the maximum height per bin (eq. 4.20-4.25,
  :class:`~exobench.perception.place_recognition.scan_context.ScanContextPP`);
- ``gsc-height``: GSC, ``mu^z + alpha Sigma^zz`` per bin (eq. 4.26-4.28);
- ``gsc-huber``: GSC with Huber-weighted statistics (eq. 4.29-4.33, then 4.28);
- ``gsc-intensity``: GSC on the intensity (eq. 4.28 on ``psi``)
  (:class:`~exobench.perception.place_recognition.gaussian_scan_context.GaussianScanContext`).

What a pipeline does with the frames (it sees the calibration and the frames, never the truth):

- IMU samples (``kind == "imu"`` mount): the latest orientations are kept; each scan is levelled
  with the orientation nearest to its mid-sweep time, ``R_world_lidar = R_world_imu R_imu_lidar``
  (``R_imu_lidar`` from the two mounts, which share the trunk link). Without any IMU sample the
  LiDAR is taken as level (counted in ``stats["no_imu"]``).
- Keyframes: every ``keyframe_every``-th LiDAR scan (0-based scan index ``i`` with
  ``i % keyframe_every == keyframe_every - 1``). The pipelines have no odometry, so "every k-th
  scan" stands in for the thesis' distance-based keyframes: at the exoskeleton's 0.3-0.6 m/s and
  10 Hz, k = 5 is one keyframe every 0.15-0.3 m.
- ``on = "scan"``: the keyframe scan alone, in its level frame
  (:func:`~exobench.perception.place_recognition.scan_context.level_frame`: gravity-aligned, x along the sensor's
  heading, origin at the sensor). ``on = "submap"``: the last ``submap_scans`` scans accumulated in
  the keyframe's level frame (:func:`~exobench.perception.place_recognition.scan_context.accumulate_submap`) with
  each scan's IMU orientation and *no translation* (there is no odometry: at walking speed the
  sensor moves 0.15-0.3 m over 5 scans, which smears the submap by that much). The submap gives
  the 16-ring LiDAR the denser vertical coverage the thesis' submap-based SC is after (the trunk
  sways, so the rings of successive scans fall at different heights).
- Ceiling removal (:func:`~.config.remove_ceiling`).
- Description and query: the descriptor of the keyframe cloud, then the best match among the
  earlier keyframes except the ``exclude_recent`` most recent (the thesis' ``xi``), by ring-key
  k-d tree and column-shift alignment (eq. 4.23-4.24); then the keyframe is stored. The
  reported distance is ``1 - sim`` (eq. 4.24); no threshold is applied here (the track sweeps
  ``tau``, as section 5.2.3 does). ``time_per_keyframe_s`` is the wall time of levelling,
  accumulation, ceiling removal, description, query and insertion.

GSC cells are computed by :class:`~.component_gsc.ComponentGaussianScanContext` (only the mean
and variance that eq. 4.28 reads; ``component_cells=False``: the full 4 x 4 covariance of the
reference module, same cells).

The input is counted on the estimate's ``counts`` (:mod:`exobench.core.counters`): frames of
other kinds, of another LiDAR or of another IMU are ignored; a repeated or out-of-order scan or
IMU sample is not used (a scan so skipped does not advance the keyframe count); an IMU sample
that is not finite or absurd (:func:`exobench.core.limits.imu_absurd`) is skipped; NaN and
absurd points of a scan are counted and dropped.

Faulty input never raises: non-finite points (coordinates or intensity) are dropped; a
scan whose intensity array does not match its points keeps its geometry with zero intensity
(``stats["bad_intensity_scans"]``; the intensity descriptor of it is then invalid); an empty scan, a scan with
fewer than ``min_points`` points, or a degenerate one occupying fewer than
``min_occupied_cells`` bins (a scan that sees only a glass pane or a wall next to the sensor) has
no valid descriptor: its keyframe gets ``match_index = -1``, ``distance = inf`` and is counted in
``stats["invalid_keyframes"]`` (by reason in ``stats["descriptor_status"]``); it is stored but
never a candidate.
"""

from __future__ import annotations

import dataclasses
import math
import time
from abc import ABC, abstractmethod
from collections import Counter, deque
from typing import ClassVar

import numpy as np

from exobench.core.calibration import Calibration
from exobench.core.counters import StreamCounters
from exobench.core.errors import ConfigError
from exobench.core.estimates import PlaceRecognitionEstimate
from exobench.core.frames import Frame, ImuSample, LidarScan
from exobench.core.limits import RangeLimits, imu_absurd, scrub_points
from exobench.core.pipeline import check_frame
from exobench.core.transforms import quat_wxyz_to_matrix

from .component_gsc import ComponentGaussianScanContext
from .config import GaussianPlaceRecognitionConfig, PlaceRecognitionConfig, remove_ceiling
from .gaussian_scan_context import GaussianScanContext
from .recognizer import PlaceRecognizer, ScanContextPP
from .scan_context import accumulate_submap

__all__ = [
    "GscHeightPipeline",
    "GscHuberPipeline",
    "GscIntensityPipeline",
    "PlaceRecognitionPipeline",
    "ScanContextPPPipeline",
]

IMU_BUFFER = 512


class PlaceRecognitionPipeline(ABC):
    """Keyframe place recognition (see the module docstring); subclasses pick the descriptor."""

    name: ClassVar[str] = ""
    track: ClassVar[str] = "loop-closure"
    Config: ClassVar[type] = PlaceRecognitionConfig

    def __init__(self, config: PlaceRecognitionConfig | None = None) -> None:
        self.config = config if config is not None else self.Config()
        if not isinstance(self.config, PlaceRecognitionConfig):
            raise ConfigError(f"{self.name}.config", type(self.config).__name__, "a PlaceRecognitionConfig")
        self._reset_state()
        self._was_reset = False

    @abstractmethod
    def _recognizer(self) -> PlaceRecognizer:
        """The descriptor of the pipeline (a fresh database)."""

    def _reset_state(self) -> None:
        self.recognizer = self._recognizer()
        self._imu_t: deque[float] = deque(maxlen=IMU_BUFFER)
        self._imu_R: deque[np.ndarray] = deque(maxlen=IMU_BUFFER)
        self._scans: deque[tuple[np.ndarray, np.ndarray, np.ndarray]] = deque(maxlen=self.config.submap_scans)
        self._n_scans = 0
        self._stamps: list[float] = []
        self._match: list[int] = []
        self._dist: list[float] = []
        self._yaw: list[float] = []
        self._time: list[float] = []
        self._scan_index: list[int] = []
        self._desc_status: Counter[str] = Counter()
        self._match_status: Counter[str] = Counter()
        self._counters = StreamCounters()
        self._limits = RangeLimits()
        self._no_imu = 0
        self._bad_intensity = 0
        self._ceiling_cuts: list[float] = []
        self._lidar_id = self.config.lidar_id
        self._imu_id = ""
        self._R_imu_lidar = np.eye(3)
        self._sweep_s = 0.1

    def reset(self, calibration: Calibration) -> None:
        """Forget all state; find the LiDAR and IMU mounts."""
        self._reset_state()
        self._was_reset = True
        self._counters = StreamCounters.of(calibration)
        lidars = calibration.mounts_of_kind("lidar")
        lidar = None
        if self.config.lidar_id:
            lidar = calibration.mount(self.config.lidar_id)
        elif lidars:
            lidar = lidars[0]
        imus = calibration.mounts_of_kind("imu")
        if lidar is not None:
            self._lidar_id = lidar.sensor_id
            self._limits = RangeLimits.of_mount(lidar)
            rate = float(lidar.params.get("rate_hz", 10.0) or 10.0)
            self._sweep_s = 1.0 / rate if rate > 0 else 0.1
        if lidar is not None and imus:
            imu = next((m for m in imus if m.parent_link == lidar.parent_link), imus[0])
            self._imu_id = imu.sensor_id
            if imu.parent_link == lidar.parent_link:
                R_p_imu = np.asarray(imu.T_parent_sensor, dtype=float)[:3, :3]
                R_p_lidar = np.asarray(lidar.T_parent_sensor, dtype=float)[:3, :3]
                self._R_imu_lidar = R_p_imu.T @ R_p_lidar

    def process(self, frame: Frame) -> PlaceRecognitionEstimate | None:
        """IMU samples are buffered; every keyframe scan is described and queried."""
        check_frame(self, frame, self._was_reset)
        if isinstance(frame, ImuSample):
            c = self._counters.admit(frame, not self._imu_id or frame.sensor_id == self._imu_id)
            if c is not None:
                q = np.asarray(frame.quat_wxyz, dtype=float)
                if c.judge(frame, q.shape != (4,) or imu_absurd(frame)):
                    self._imu_t.append(float(frame.stamp_s))
                    self._imu_R.append(quat_wxyz_to_matrix(q / np.linalg.norm(q)))
            return None
        lidar = isinstance(frame, LidarScan) and not (self._lidar_id and frame.sensor_id != self._lidar_id)
        c = self._counters.admit(frame, lidar)
        if c is None:
            return None
        c.used += 1
        t0 = time.perf_counter()
        pts = np.asarray(frame.points_xyz, dtype=float).reshape(-1, 3)
        c.add_nan(int(np.count_nonzero(~np.all(np.isfinite(pts), axis=1))))
        pts, n_absurd = scrub_points(pts, self._limits)
        c.add_absurd(n_absurd)
        inten = np.asarray(frame.intensity, dtype=float).reshape(-1)
        if len(inten) != len(pts):  # a broken intensity channel: the geometry is still usable
            self._bad_intensity += 1
            inten = np.zeros(len(pts))
        ok = np.all(np.isfinite(pts), axis=1) & np.isfinite(inten)
        T = np.eye(4)
        T[:3, :3] = self._orientation(float(frame.sweep_start_s) + 0.5 * self._sweep_s)
        self._scans.append((pts[ok], inten[ok], T))
        index = self._n_scans
        self._n_scans += 1
        if index % self.config.keyframe_every != self.config.keyframe_every - 1:
            return None
        self._keyframe(float(frame.sweep_start_s), index, t0)
        return self._estimate()

    def finalize(self) -> PlaceRecognitionEstimate:
        return self._estimate()

    # ------------------------------------------------------------------ internals

    def _orientation(self, t: float) -> np.ndarray:
        """R_world_lidar from the IMU sample nearest to ``t`` (identity without IMU)."""
        if not self._imu_t:
            self._no_imu += 1
            return np.eye(3)
        ts = np.fromiter(self._imu_t, dtype=float, count=len(self._imu_t))
        k = int(np.argmin(np.abs(ts - t)))
        return self._imu_R[k] @ self._R_imu_lidar

    def cloud(self) -> tuple[np.ndarray, np.ndarray]:
        """The current keyframe cloud (level frame of the newest scan) and its intensities."""
        scans = list(self._scans) if self.config.on == "submap" else [self._scans[-1]]
        T_key = scans[-1][2]
        pts = accumulate_submap([(p, T) for p, _, T in scans], T_key)
        inten = np.concatenate([i for _, i, _ in scans]) if scans else np.zeros(0)
        keep, cut = remove_ceiling(pts, self.config)
        self._ceiling_cuts.append(cut)
        return pts[keep], inten[keep]

    def _keyframe(self, stamp: float, scan_index: int, t0: float) -> None:
        pts, inten = self.cloud()
        desc = self.recognizer.describe(pts, inten)
        if desc.valid and np.count_nonzero(desc.matrix) < self.config.min_occupied_cells:
            desc = dataclasses.replace(desc, status="too_few_cells")
        self._desc_status[desc.status] += 1
        match = self.recognizer.query(desc, self.config.exclude_recent)
        self.recognizer.add(desc)
        elapsed = time.perf_counter() - t0
        self._match_status[match.status if match.status in ("no_descriptor", "no_candidates") else "candidate"] += 1
        found = match.index >= 0 and math.isfinite(match.distance)
        self._stamps.append(stamp)
        self._scan_index.append(scan_index)
        self._match.append(int(match.index) if found else -1)
        self._dist.append(float(match.distance) if found else math.inf)
        self._yaw.append(float(match.yaw_rad) if found else math.nan)
        self._time.append(elapsed)

    def _estimate(self) -> PlaceRecognitionEstimate:
        cuts = np.array([c for c in self._ceiling_cuts if math.isfinite(c)])
        stats = {
            "pipeline": self.name,
            "on": self.config.on,
            "keyframe_every": self.config.keyframe_every,
            "exclude_recent": self.config.exclude_recent,
            "n_scans": self._n_scans,
            "n_keyframes": len(self._stamps),
            "keyframe_scan_index": list(self._scan_index),
            "invalid_keyframes": sum(v for k, v in self._desc_status.items() if k != "ok"),
            "descriptor_status": dict(self._desc_status),
            "match_status": dict(self._match_status),
            "no_imu": self._no_imu,
            "bad_intensity_scans": self._bad_intensity,
            "ceiling_found": int(len(cuts)),
            "ceiling_cut_m": float(np.median(cuts)) if len(cuts) else math.nan,
        }
        return PlaceRecognitionEstimate(
            stamps_s=np.array(self._stamps, dtype=float),
            match_index=np.array(self._match, dtype=np.int64),
            distance=np.array(self._dist, dtype=float),
            yaw_rad=np.array(self._yaw, dtype=float),
            time_per_keyframe_s=np.array(self._time, dtype=float),
            stats=stats,
            counts=self._counters.snapshot(),
        )


class ScanContextPPPipeline(PlaceRecognitionPipeline):
    """``sc++``: Scan Context++ (maximum height per bin, eq. 4.22)."""

    name: ClassVar[str] = "sc++"
    Config: ClassVar[type] = PlaceRecognitionConfig

    def _recognizer(self) -> PlaceRecognizer:
        return ScanContextPP(self.config.context_config())


class _GscPipeline(PlaceRecognitionPipeline):
    variant: ClassVar[str] = "huber"
    Config: ClassVar[type] = GaussianPlaceRecognitionConfig

    def __init__(self, config: GaussianPlaceRecognitionConfig | None = None) -> None:
        if config is not None and not isinstance(config, GaussianPlaceRecognitionConfig):
            raise ConfigError(f"{self.name}.config", type(config).__name__, "a GaussianPlaceRecognitionConfig")
        super().__init__(config)

    def _recognizer(self) -> PlaceRecognizer:
        cls = ComponentGaussianScanContext if self.config.component_cells else GaussianScanContext
        return cls(self.config.context_config(self.variant))


class GscHeightPipeline(_GscPipeline):
    """``gsc-height``: ``mu^z + alpha Sigma^zz`` of the plain bin Gaussian (eq. 4.26-4.28)."""

    name: ClassVar[str] = "gsc-height"
    variant: ClassVar[str] = "height"
    Config: ClassVar[type] = GaussianPlaceRecognitionConfig


class GscHuberPipeline(_GscPipeline):
    """``gsc-huber``: the Huber-weighted bin Gaussian (eq. 4.29-4.33, then 4.28)."""

    name: ClassVar[str] = "gsc-huber"
    variant: ClassVar[str] = "huber"
    Config: ClassVar[type] = GaussianPlaceRecognitionConfig


class GscIntensityPipeline(_GscPipeline):
    """``gsc-intensity``: eq. (4.28) on the intensity, ``mu^psi + alpha Sigma^psipsi``."""

    name: ClassVar[str] = "gsc-intensity"
    variant: ClassVar[str] = "intensity"
    Config: ClassVar[type] = GaussianPlaceRecognitionConfig
