"""KISS-ICP LiDAR odometry (Vizzo et al. 2023; the peer of seeds/003 Tables 5.3-5.4) as a pipeline.

``kiss-icp`` (track ``odometry``) feeds every :class:`~exobench.core.frames.LidarScan` to the
installed ``kiss-icp`` package (``KissICP.register_frame(points, timestamps)``) and returns a
:class:`~exobench.core.estimates.TrajectoryEstimate` of the LiDAR poses, the first scan at the
identity.

Details:

- Timestamps: the per-point ``time_offset_s``; kiss-icp normalises them per scan and deskews
  every point to the pose at the *last* firing (constant-velocity model), so the pose it reports
  is the LiDAR at ``sweep_start_s + max(time_offset_s)`` and that is the stamp stored. With
  ``deskew=False`` the scan is taken as instantaneous and stamped ``sweep_start_s``.
- ``voxel_size_m = 0`` takes kiss-icp's own default (``max_range_m / 100``).
- ``downsample``: ``"double"`` is kiss-icp as released (the scan voxelised at half the voxel size
  for the map, that again at 1.5 voxels for registration); ``"single"`` registers the half-voxel
  scan itself, the authors' fix for 16-beam LiDARs, whose double-downsampled scans keep too few
  points (kiss-icp issues #128 and #240, ``voxelize`` returning ``frame_downsample`` twice). Table
  5.4 of seeds/003 ran KISS-ICP this way ("remove one of the two downsampling filters ... as the
  authors suggested", section 5.2.2).
- ``filter``: the intensity filter stage run before odometry, as Table 5.4 does
  (:class:`~exobench.perception.lidar_filter.FilterStageConfig`: ``filter.kind`` is ``"none"``
  (default), ``"threshold"``, ``"naive-ground"``, ``"normal-ground"`` or ``"floor-ground"``,
  each with its parameters nested, e.g. ``filter.naive_ground.ground_margin_m``), with
  ``T_footprint_sensor`` from the exoskeleton's kinematics. The stage is the filter's pipeline,
  fed every frame; the mask of a scan is the one its ``process`` returns.
  :func:`run_kiss_icp` takes precomputed keep masks instead.
- Points at a distance the LiDAR cannot report (:class:`exobench.core.limits.RangeLimits`) are
  dropped as NaN ones. The input is counted on ``TrajectoryEstimate.counts``
  (:mod:`exobench.core.counters`): scans of another LiDAR are ignored, a repeated or
  out-of-order scan is not registered (no pose); frames of other kinds are ignored, or, with a
  filter stage, counted as the stage counts them.
- Faults never raise: a scan with fewer than ``min_points`` usable points (empty, all NaN, or
  all removed by the filter) keeps the last pose with status ``"empty_scan"``; a registration
  that raises or returns a non-finite pose keeps the last pose with status ``"failed"`` (and the
  odometry is rebuilt from that pose, so later scans still register); both are counted in
  ``stats``.
"""

from __future__ import annotations

import dataclasses
import functools
import time
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from exobench.core.calibration import Calibration
from exobench.core.counters import StreamCounters, nan_values
from exobench.core.errors import ConfigError, check_int, check_range
from exobench.core.estimates import TrajectoryEstimate
from exobench.core.frames import Frame, LidarScan
from exobench.core.limits import RangeLimits, finite_rows, scrub_points
from exobench.core.pipeline import check_frame
from exobench.perception.lidar_filter.config import FilterStageConfig

DOWNSAMPLE = ("double", "single")

__all__ = ["KissConfig", "KissIcpPipeline", "KissOdometry", "run_kiss_icp"]


@dataclass(frozen=True)
class KissConfig:
    """kiss-icp parameters (its ``KISSConfig`` fields) and the adapter's own.

    Attributes:
        max_range_m / min_range_m: ``data.max_range`` / ``data.min_range``, m.
        voxel_size_m: ``mapping.voxel_size``, m (0: ``max_range_m / 100``, kiss-icp's default).
        downsample: ``"double"`` (kiss-icp as released) or ``"single"`` (module docstring).
        deskew: ``data.deskew``.
        max_points_per_voxel: ``mapping.max_points_per_voxel``.
        max_threads: ``registration.max_num_threads`` (0 = automatic).
        min_points: scans with fewer usable points keep the last pose.
        lidar_id: the LiDAR used (empty: the first LiDAR seen).
        filter: the intensity filter stage applied before odometry (kind and parameters).
    """

    max_range_m: float = 100.0
    min_range_m: float = 0.3
    voxel_size_m: float = 0.0
    downsample: str = "double"
    deskew: bool = True
    max_points_per_voxel: int = 20
    max_threads: int = 1
    min_points: int = 50
    lidar_id: str = ""
    filter: FilterStageConfig = FilterStageConfig()

    def __post_init__(self) -> None:
        check_range("max_range_m", self.max_range_m, 0.0, 1000.0, low_open=True)
        check_range("min_range_m", self.min_range_m, 0.0, self.max_range_m, high_open=True)
        check_range("voxel_size_m", self.voxel_size_m, 0.0, 10.0)
        for name, lo, hi in (("max_points_per_voxel", 1, 1000), ("max_threads", 0, 64), ("min_points", 1, 10**6)):
            object.__setattr__(self, name, check_int(name, getattr(self, name), lo, hi))
        if self.downsample not in DOWNSAMPLE:
            raise ConfigError("downsample", self.downsample, " or ".join(repr(d) for d in DOWNSAMPLE))
        if not isinstance(self.deskew, bool):
            raise ConfigError("deskew", self.deskew, "True or False")
        if not isinstance(self.filter, FilterStageConfig):
            raise ConfigError("filter", self.filter, "a FilterStageConfig")

    def kiss_config(self) -> Any:
        """The package's ``KISSConfig`` (pydantic) with these values."""
        from kiss_icp.config import KISSConfig

        cfg = KISSConfig()
        cfg.data.max_range = float(self.max_range_m)
        cfg.data.min_range = float(self.min_range_m)
        cfg.data.deskew = bool(self.deskew)
        cfg.mapping.voxel_size = float(self.voxel_size_m) if self.voxel_size_m > 0 else float(self.max_range_m / 100.0)
        cfg.mapping.max_points_per_voxel = int(self.max_points_per_voxel)
        cfg.registration.max_num_threads = int(self.max_threads)
        return cfg


@functools.cache
def _single_downsample_class() -> type:
    """kiss-icp's ``KissICP`` registering the map's half-voxel scan (``downsample="single"``)."""
    from kiss_icp.kiss_icp import KissICP
    from kiss_icp.voxelization import voxel_down_sample

    class SingleDownsampleKissICP(KissICP):
        def voxelize(self, iframe: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            frame_downsample = voxel_down_sample(iframe, self.config.mapping.voxel_size * 0.5)
            return frame_downsample, frame_downsample

    return SingleDownsampleKissICP


class KissOdometry:
    """Scan-by-scan kiss-icp with the fault handling of the module docstring."""

    def __init__(self, config: KissConfig) -> None:
        self.config = config
        self._odom: Any = None
        self.stamps: list[float] = []
        self.poses: list[np.ndarray] = []
        self.times: list[float] = []
        self.status: list[str] = []
        self.stats: dict[str, Any] = {"scans": 0, "empty_scans": 0, "failed_scans": 0, "points_used": 0}
        self._last = np.eye(4)

    def _new_odometry(self, pose: np.ndarray) -> Any:
        from kiss_icp.kiss_icp import KissICP

        cls = _single_downsample_class() if self.config.downsample == "single" else KissICP
        odom = cls(config=self.config.kiss_config())
        odom.last_pose = pose.copy()
        return odom

    def add(self, scan: LidarScan, keep: np.ndarray | None = None) -> None:
        """Register one scan (``keep``: the points to use, None = all)."""
        t0 = time.perf_counter()
        pts = np.asarray(scan.points_xyz, dtype=float).reshape(-1, 3)
        offs = np.asarray(scan.time_offset_s, dtype=float).reshape(-1)
        if len(offs) != len(pts):
            offs = np.zeros(len(pts))
        ok = finite_rows(pts) & np.isfinite(offs)
        if keep is not None:
            k = np.asarray(keep, dtype=bool).reshape(-1)
            ok &= k if len(k) == len(pts) else np.zeros(len(pts), dtype=bool)
        pts, offs = pts[ok], offs[ok]
        stamp = float(scan.sweep_start_s)
        if self.config.deskew and len(offs):
            stamp += float(np.max(offs))
        status = "ok"
        if len(pts) < self.config.min_points:
            status = "empty_scan"
            self.stats["empty_scans"] += 1
        else:
            try:
                if self._odom is None:
                    self._odom = self._new_odometry(self._last)
                self._odom.register_frame(np.ascontiguousarray(pts), np.ascontiguousarray(offs))
                pose = np.asarray(self._odom.last_pose, dtype=float)
                if not np.all(np.isfinite(pose)):
                    raise FloatingPointError("non-finite pose")
                self._last = pose.copy()
                self.stats["points_used"] += len(pts)
            except Exception as e:  # a failed registration is a result: keep the last pose
                status = "failed"
                self.stats["failed_scans"] += 1
                self.stats["last_error"] = f"{type(e).__name__}: {e}"
                self._odom = None
        self.stats["scans"] += 1
        self.stamps.append(stamp)
        self.poses.append(self._last.copy())
        self.status.append(status)
        self.times.append(time.perf_counter() - t0)

    def estimate(self, extra_stats: dict[str, Any] | None = None) -> TrajectoryEstimate:
        stats = {**self.stats, **dict(extra_stats or {})}
        return TrajectoryEstimate(
            stamps_s=np.array(self.stamps, dtype=float),
            T_world_sensor=np.array(self.poses, dtype=float).reshape(-1, 4, 4),
            time_per_scan_s=np.array(self.times, dtype=float),
            status=tuple(self.status),
            stats=stats,
        )


def run_kiss_icp(scans: Iterable[LidarScan], keep: Sequence[np.ndarray] | None = None,
                 config: KissConfig | None = None) -> TrajectoryEstimate:
    """kiss-icp over ``scans`` (read one at a time, in order) using only the points of ``keep``
    (one mask per scan; None: all).

    The time per scan is the odometry's only (the masks are given).
    """
    odo = KissOdometry(config or KissConfig())
    for i, scan in enumerate(scans):
        odo.add(scan, None if keep is None else (keep[i] if i < len(keep) else np.zeros(0, dtype=bool)))
    return odo.estimate()


class KissIcpPipeline:
    """``kiss-icp``: KISS-ICP odometry of the trunk LiDAR, optionally after an intensity filter."""

    name: ClassVar[str] = "kiss-icp"
    track: ClassVar[str] = "odometry"
    Config = KissConfig

    def __init__(self, config: KissConfig | None = None) -> None:
        self.config = config if config is not None else KissConfig()
        self._odo = KissOdometry(self.config)
        self._filter: Any = None
        self._lidar: str = self.config.lidar_id
        self._limits: dict[str, RangeLimits] | None = None  # None until reset
        self._counters = StreamCounters()

    def reset(self, calibration: Calibration) -> None:
        self._limits = {m.sensor_id: RangeLimits.of_mount(m) for m in calibration.mounts_of_kind("lidar")}
        self._counters = StreamCounters.of(calibration)
        self._odo = KissOdometry(self.config)
        self._lidar = self.config.lidar_id
        self._filter = None
        stage = self.config.filter
        if stage.kind != "none":
            from exobench.perception.lidar_filter.pipelines import filter_pipeline

            cls = filter_pipeline(stage.kind)
            params = dataclasses.asdict(stage.config())
            self._filter = cls(cls.Config(lidar_id=self.config.lidar_id, **params))
            self._filter.reset(calibration)

    def process(self, frame: Frame) -> TrajectoryEstimate | None:
        check_frame(self, frame, self._limits is not None)
        if not isinstance(frame, LidarScan):
            if self._filter is not None:  # the stage reads (and counts) the frames of other kinds
                self._filter.process(frame)
            else:
                self._counters.admit(frame, consumed=False)
            return None
        if not self._lidar:
            self._lidar = frame.sensor_id
        c = self._counters.admit(frame, consumed=frame.sensor_id == self._lidar)
        if c is None:
            return None
        c.add_nan(nan_values(frame))
        c.used += 1
        keep = None
        t0 = time.perf_counter()
        pts, n_absurd = scrub_points(frame.points_xyz, self._limits.get(frame.sensor_id) or RangeLimits())
        if n_absurd:
            c.add_absurd(n_absurd)
            frame = dataclasses.replace(frame, points_xyz=pts)
        if self._filter is not None:
            online = self._filter.process(frame)  # the FilterEstimate of this scan alone
            keep = online.keep[0] if online is not None else None
        t_filter = time.perf_counter() - t0
        self._odo.add(frame, keep)
        self._odo.times[-1] += t_filter
        return None

    def finalize(self) -> TrajectoryEstimate:
        extra: dict[str, Any] = {"filter": self.config.filter.kind}
        counts = self._counters.snapshot()
        if self._filter is not None:
            stage = self._filter.finalize()
            extra["filter_stats"] = {k: v for k, v in stage.stats.items() if isinstance(v, (int, float, str))}
            # the stage saw every frame of the other kinds; the LiDAR is counted here
            counts = {**{k: v for k, v in stage.counts.items() if k != "lidar"}, **counts}
        return dataclasses.replace(self._odo.estimate(extra), counts=counts)
