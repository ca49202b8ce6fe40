"""The four LiDAR intensity filters of seeds/003 Sec. 4.2.2 and ours as pipelines (track ``lidar-filter``).

``filter-none``, ``filter-threshold`` (eq. 4.15), ``filter-naive-ground`` (eq. 4.16),
``filter-normal-ground`` (eq. 4.17-4.19) and ``filter-floor-ground`` (eq. 4.16 with the ground
a band about the scan's own floor plane; not in the thesis) wrap the filters of
:mod:`exobench.perception.lidar_filter.filters` unchanged (each scan's ``ring`` goes to the filter:
the normal filter's range-image normals use it); each returns a
:class:`~exobench.core.estimates.FilterEstimate` with one keep mask per LiDAR scan and the
compute time per scan (kinematics + filter). Online, ``process`` returns the
:class:`FilterEstimate` of the scan it was given (one stamp, one mask; None for any other
frame): how a pipeline that filters before its own work, such as ``kiss-icp``'s ``filter``
stage, reads each mask through the pipeline protocol.

The ground-aware filters need ``T_footprint_sensor`` per scan. It is taken from the
exoskeleton's kinematics and trunk tilt, not assumed level (:class:`FootprintKinematics`):

- the latest encoder state (:class:`~exobench.core.frames.JointState`) and trunk IMU orientation
  (:class:`~exobench.core.frames.ImuSample`, ``R_world_imu``) go through the URDF of the
  calibration with pinocchio (:class:`~exobench.perception.kinematics.tof_kinematics.TofKinematics`), which
  gives the LiDAR mount in ``stance_ground``: gravity-aligned axes, origin on the ground under
  the stance ankle (foot flat: ``sole_height_m`` below the joint);
- the footprint frame ``f`` is that frame turned about the vertical to the trunk's heading (x
  forward, z up against gravity). Only its z axis and origin height enter eq. (4.16)/(4.19), so
  the heading choice does not change a mask;
- the stance foot: the side whose insole pads report contact when only one side does;
  otherwise (double support, or no contact samples) the foot that is lower along gravity by the
  same kinematics.

The state used for a scan is the latest received before the scan (scans are stamped at the end
of the sweep). The input is counted on ``FilterEstimate.counts`` (:mod:`exobench.core.counters`:
scans of another LiDAR and, for the filters without a footprint, every other frame are
ignored; a repeated or out-of-order scan gets no mask; an encoder state, IMU sample or contact
that is not finite or absurd is skipped, the previous state kept). Faults never raise; the
filter's own are counted in ``FilterEstimate.stats``:

- an empty scan gets an empty mask (``empty_scans``);
- before both an encoder state and an IMU orientation have arrived, or when the transform is not
  finite, the ground-aware filters fall back to the plain band of eq. (4.15) for that scan
  (``no_kinematics``) -- the conservative choice: nothing outside the band is kept;
- non-finite points are dropped by the filters (``DROPPED_INVALID``; ``invalid_points``); those
  the scan itself holds as NaN are counted apart (``counts["lidar"].nan_values``) and scored
  neither kept nor removed;
- absurd points (a distance from the sensor outside the mount's range limits, the origin
  included: :class:`exobench.core.limits.RangeLimits`) are dropped as non-finite ones
  (``counts["lidar"].absurd_values``);
- the normal filter counts the scans whose normals came from the range image
  (``normals_range_image_scans``) and from the knn fallback (``normals_knn_scans``);
- the naive and floor filters count the scans whose ground test used the scan's own floor plane
  (``ground_plane_refined_scans``) and the footprint plane (``ground_plane_footprint_scans``:
  ``ground_test`` ``"band"`` / ``"below"``, or no floor plane found).
"""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from exobench.core.calibration import Calibration
from exobench.core.counters import FrameCounts, StreamCounters, nan_values
from exobench.core.errors import ConfigError
from exobench.core.estimates import FilterEstimate
from exobench.core.frames import ContactSample, Frame, ImuSample, JointState, LidarScan
from exobench.core.limits import (
    JointLimits,
    RangeLimits,
    contact_absurd,
    finite_rows,
    imu_absurd,
    scrub_points,
)
from exobench.core.pipeline import check_frame

from .config import (
    FloorGroundConfig,
    IntensityBandConfig,
    NaiveGroundConfig,
    NoFilterConfig,
    NormalGroundConfig,
)
from .filters import (
    FilterReason,
    FloorGroundFilter,
    IntensityThresholdFilter,
    NaiveGroundFilter,
    NoFilter,
    NormalGroundFilter,
)
from .footprint import FootprintKinematics

__all__ = [
    "FILTER_PIPELINES",
    "FilterFloorGround",
    "FilterNaiveGround",
    "FilterNone",
    "FilterNormalGround",
    "FilterThreshold",
    "filter_pipeline",
]


@dataclass(frozen=True)
class _PipelineFields:
    """The pipeline's own fields beside its filter's: which LiDAR is filtered (empty: every LiDAR
    scan) and the trunk IMU."""

    lidar_id: str = ""
    imu_id: str = "imu_trunk"


class _FilterPipeline:
    """Feeds scans through one filter; see the module docstring."""

    name: ClassVar[str] = ""
    track: ClassVar[str] = "lidar-filter"
    uses_footprint: ClassVar[bool] = False
    filter_cls: ClassVar[type[NoFilter]] = NoFilter

    def __init__(self, config: Any | None = None) -> None:
        self.config = config if config is not None else self.Config()  # type: ignore[attr-defined]
        self.filter = self.filter_cls(self.filter_config())
        self._kin: dict[str, FootprintKinematics] = {}
        self._calibration: Calibration | None = None
        self._reset_state()

    def filter_config(self) -> Any:
        """The filter's own config: the fields of ``filter_cls.Config`` of this pipeline's config."""
        cfg_cls = self.filter_cls.Config
        return cfg_cls(**{f.name: getattr(self.config, f.name) for f in dataclasses.fields(cfg_cls)})

    def _reset_state(self) -> None:
        self._stamps: list[float] = []
        self._keep: list[np.ndarray] = []
        self._times: list[float] = []
        self._T: list[np.ndarray] = []
        self._status: list[str] = []
        self._stance: list[str] = []
        self._stats = {"scans": 0, "empty_scans": 0, "no_kinematics": 0, "all_removed": 0, "invalid_points": 0,
                       "points": 0, "kept_points": 0, "kept_ground_rescued": 0, "malformed_scans": 0}  # fmt: skip
        self._limits: dict[str, RangeLimits] = {}
        self._counters = StreamCounters()
        self._joint_limits = JointLimits(None)

    def reset(self, calibration: Calibration) -> None:
        self._calibration = calibration
        self._kin = {}
        self._reset_state()
        self._limits = {m.sensor_id: RangeLimits.of_mount(m) for m in calibration.mounts_of_kind("lidar")}
        self._counters = StreamCounters.of(calibration)
        self._joint_limits = JointLimits(calibration)
        if not self.uses_footprint:
            return
        ids = [self.config.lidar_id] if self.config.lidar_id else [m.sensor_id for m in calibration.mounts_of_kind("lidar")]
        for sid in ids:
            try:
                self._kin[sid] = FootprintKinematics(calibration, sid, self.config.imu_id)
            except Exception as e:  # no usable kinematics: band-only fallback, reported
                self._stats["kinematics_error"] = f"{sid}: {type(e).__name__}: {e}"

    def process(self, frame: Frame) -> FilterEstimate | None:
        check_frame(self, frame, self._calibration is not None)
        if isinstance(frame, LidarScan):
            c = self._counters.admit(frame, not self.config.lidar_id or frame.sensor_id == self.config.lidar_id)
            if c is None:
                return None
            self._scan(frame, c)
            return FilterEstimate(stamps_s=np.array(self._stamps[-1:], dtype=float), keep=(self._keep[-1],),
                                  time_per_scan_s=np.array(self._times[-1:], dtype=float))  # fmt: skip
        elif self.uses_footprint and self._reads_state(frame):
            c = self._counters.admit(frame)
            if c is not None and self._valid_state(c, frame):
                for kin in self._kin.values():
                    kin.update(frame)
        else:
            self._counters.admit(frame, consumed=False)
        return None

    def _reads_state(self, frame: Frame) -> bool:
        """Whether the footprint kinematics read this frame (encoders, the trunk IMU, the pads)."""
        return isinstance(frame, (JointState, ContactSample)) or (isinstance(frame, ImuSample) and frame.sensor_id == self.config.imu_id)

    def _valid_state(self, c: FrameCounts, frame: Frame) -> bool:
        """Count and refuse a state that is not finite or absurd (:mod:`exobench.core.limits`)."""
        if isinstance(frame, JointState):
            bad = self._joint_limits.absurd(frame)  # non-finite angles included
        elif isinstance(frame, ImuSample):
            bad = imu_absurd(frame)  # non-finite values included
        else:
            bad = contact_absurd(frame) or nan_values(frame) > 0
        return c.judge(frame, bad)

    def _scan(self, scan: LidarScan, c: FrameCounts) -> None:
        t0 = time.perf_counter()
        T: np.ndarray | None = None
        stance = ""
        if self.uses_footprint:
            kin = self._kin.get(scan.sensor_id)
            if kin is not None:
                T = kin.T_footprint_sensor()
                stance = kin.stance_side or ""
        pts = np.asarray(scan.points_xyz, dtype=float).reshape(-1, 3)
        n_nan = len(pts) - int(np.count_nonzero(finite_rows(pts)))
        pts, n_absurd = scrub_points(pts, self._limits.get(scan.sensor_id) or RangeLimits())
        psi = np.asarray(scan.intensity, dtype=float).reshape(-1)
        if len(psi) != len(pts):  # malformed scan: nothing can be trusted
            res_keep, status, reason = np.zeros(len(pts), dtype=bool), "malformed", None
        else:
            ring = getattr(scan, "ring", None)
            ring = None if ring is None or np.asarray(ring).reshape(-1).shape != (len(pts),) else np.asarray(ring).reshape(-1)
            res = self.filter.apply(pts, psi, T, ring=ring)
            res_keep, status, reason = res.keep, res.status, res.reason
            if res.normal_method:  # the normal filter: which normal estimate ran on this scan
                key = f"normals_{res.normal_method.replace('-', '_')}_scans"
                self._stats[key] = self._stats.get(key, 0) + 1
            if res.ground_plane:  # the naive filter: the scan's floor plane or the footprint's
                key = f"ground_plane_{res.ground_plane}_scans"
                self._stats[key] = self._stats.get(key, 0) + 1
        dt = time.perf_counter() - t0
        st = self._stats
        st["scans"] += 1
        st["points"] += len(pts)
        st["kept_points"] += int(np.count_nonzero(res_keep))
        if reason is not None:
            st["invalid_points"] += int(np.count_nonzero(reason == FilterReason.DROPPED_INVALID))
            st["kept_ground_rescued"] += int(np.count_nonzero(reason == FilterReason.KEPT_GROUND))
        if status == "empty_input":
            st["empty_scans"] += 1
        elif status == "all_removed":
            st["all_removed"] += 1
        if self.uses_footprint and T is None and len(pts):
            st["no_kinematics"] += 1
        st["malformed_scans"] += int(status == "malformed")
        c.add_nan(n_nan)
        c.add_absurd(n_absurd)
        c.used += 1
        self._stamps.append(float(scan.stamp_s))
        self._keep.append(np.asarray(res_keep, dtype=bool))
        self._times.append(dt)
        self._T.append(np.full((4, 4), np.nan) if T is None else T)
        self._status.append(status)
        self._stance.append(stance)

    def finalize(self) -> FilterEstimate:
        stats: dict[str, Any] = dict(self._stats)
        stats["filter"] = self.filter.name
        stats["status"] = list(self._status)
        if self.uses_footprint:
            stats["T_footprint_sensor"] = np.array(self._T).reshape(-1, 4, 4)
            stats["stance_side"] = list(self._stance)
        return FilterEstimate(
            stamps_s=np.array(self._stamps, dtype=float),
            keep=tuple(self._keep),
            time_per_scan_s=np.array(self._times, dtype=float),
            stats=stats,
            counts=self._counters.snapshot(),
        )


class FilterNone(_FilterPipeline):
    """``filter-none``: every finite point is kept (the baseline)."""

    name: ClassVar[str] = "filter-none"

    @dataclass(frozen=True)
    class Config(NoFilterConfig, _PipelineFields):
        """Only the pipeline's fields: the filter itself has no parameters."""


class FilterThreshold(_FilterPipeline):
    """``filter-threshold``: the plain intensity band of eq. (4.15)."""

    name: ClassVar[str] = "filter-threshold"
    filter_cls: ClassVar[type[NoFilter]] = IntensityThresholdFilter

    @dataclass(frozen=True)
    class Config(IntensityBandConfig, _PipelineFields):
        """:class:`IntensityBandConfig` and the pipeline's fields."""


class FilterNaiveGround(_FilterPipeline):
    """``filter-naive-ground``: eq. (4.16) with ``T_footprint_sensor`` from kinematics."""

    name: ClassVar[str] = "filter-naive-ground"
    uses_footprint: ClassVar[bool] = True
    filter_cls: ClassVar[type[NoFilter]] = NaiveGroundFilter

    @dataclass(frozen=True)
    class Config(NaiveGroundConfig, _PipelineFields):
        """:class:`NaiveGroundConfig` and the pipeline's fields."""


class FilterFloorGround(_FilterPipeline):
    """``filter-floor-ground``: eq. (4.16) with the ground a band about the scan's own floor plane
    (:class:`~exobench.perception.lidar_filter.filters.FloorGroundFilter`), ``T_footprint_sensor``
    from kinematics."""

    name: ClassVar[str] = "filter-floor-ground"
    uses_footprint: ClassVar[bool] = True
    filter_cls: ClassVar[type[NoFilter]] = FloorGroundFilter

    @dataclass(frozen=True)
    class Config(FloorGroundConfig, _PipelineFields):
        """:class:`FloorGroundConfig` and the pipeline's fields."""


class FilterNormalGround(_FilterPipeline):
    """``filter-normal-ground``: eq. (4.17)-(4.19) with ``T_footprint_sensor`` from kinematics."""

    name: ClassVar[str] = "filter-normal-ground"
    uses_footprint: ClassVar[bool] = True
    filter_cls: ClassVar[type[NoFilter]] = NormalGroundFilter

    @dataclass(frozen=True)
    class Config(NormalGroundConfig, _PipelineFields):
        """:class:`NormalGroundConfig` and the pipeline's fields."""


FILTER_PIPELINES: dict[str, type[_FilterPipeline]] = {
    cls.filter_cls.name: cls for cls in (FilterNone, FilterThreshold, FilterNaiveGround, FilterNormalGround, FilterFloorGround)
}
"""Filter name (:data:`~exobench.perception.lidar_filter.filters.FILTERS`) -> its pipeline."""


def filter_pipeline(kind: str) -> type[_FilterPipeline]:
    """The pipeline class of a filter kind (a key of :data:`FILTER_PIPELINES`)."""
    if kind not in FILTER_PIPELINES:
        raise ConfigError("filter", kind, " or ".join(repr(k) for k in FILTER_PIPELINES))
    return FILTER_PIPELINES[kind]
