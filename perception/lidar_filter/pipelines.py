"""The four LiDAR intensity filters of seeds/003 Sec. 4.2.2 and ours as pipelines (track ``lidar-filter``).

``filter-none``, ``filter-threshold`` (eq. 4.15), ``filter-naive-ground`` (eq. 4.16),
``filter-normal-ground`` (eq. 4.17-4.19) and ``filter-floor-ground`` (eq. 4.16 with the ground
a band about the scan's own floor plane; not in the thesis) wrap the filters of
:mod:`exobench.perception.lidar_filter.filters` unchanged (each scan's ``ring`` goes to the filter:
the normal filter's range-image normals use it); each returns a
:class:`~exobench.core.estimates.FilterEstimate` with one keep mask per LiDAR scan and the
compute time per scan (kinematics + filter).

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
of the sweep). Faults never raise; they are counted in ``FilterEstimate.stats``:

- an empty scan gets an empty mask (``empty_scans``);
- before both an encoder state and an IMU orientation have arrived, or when the transform is not
  finite, the ground-aware filters fall back to the plain band of eq. (4.15) for that scan
  (``no_kinematics``) -- the conservative choice: nothing outside the band is kept;
- non-finite points are dropped by the filters (``DROPPED_INVALID``; ``invalid_points``);
- the normal filter counts the scans whose normals came from the range image
  (``normals_range_image_scans``) and from the knn fallback (``normals_knn_scans``);
- the naive and floor filters count the scans whose ground test used the scan's own floor plane
  (``ground_plane_refined_scans``) and the footprint plane (``ground_plane_footprint_scans``:
  ``ground_test`` ``"band"`` / ``"below"``, or no floor plane found).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from exobench.core.calibration import Calibration
from exobench.core.errors import ConfigError
from exobench.core.estimates import FilterEstimate
from exobench.core.frames import ContactSample, Frame, ImuSample, JointState, LidarScan

from .filters import (
    FilterReason,
    FloorGroundConfig,
    FloorGroundFilter,
    IntensityBandConfig,
    IntensityThresholdFilter,
    NaiveGroundConfig,
    NaiveGroundFilter,
    NoFilter,
    NormalGroundConfig,
    NormalGroundFilter,
)

__all__ = [
    "FilterFloorGround",
    "FilterNaiveGround",
    "FilterNone",
    "FilterNormalGround",
    "FilterThreshold",
    "FootprintKinematics",
    "footprint_from_stance",
]


def footprint_from_stance(T_stance_sensor: np.ndarray, R_world_base: np.ndarray) -> np.ndarray:
    """``T_footprint_sensor`` from the sensor pose in ``stance_ground`` and the trunk rotation.

    The footprint frame is ``stance_ground`` rotated about its z axis by the heading of the base
    link's x axis (projected on the horizontal plane; identity when it is vertical).
    """
    x = np.asarray(R_world_base, dtype=float)[:, 0]
    yaw = math.atan2(x[1], x[0]) if math.hypot(x[0], x[1]) > 1e-9 else 0.0
    c, s = math.cos(yaw), math.sin(yaw)
    T_f_stance = np.eye(4)
    T_f_stance[:2, :2] = [[c, s], [-s, c]]  # Rz(-yaw)
    return T_f_stance @ np.asarray(T_stance_sensor, dtype=float)


class FootprintKinematics:
    """``T_footprint_sensor`` of one sensor from encoders, the trunk IMU and insole contacts.

    Args:
        calibration: URDF, mounts and ``sole_height_m`` of the device.
        sensor_id: the LiDAR mount.
        imu_sensor_id: the trunk IMU whose orientation is ``R_world_imu``.
    """

    def __init__(self, calibration: Calibration, sensor_id: str, imu_sensor_id: str = "imu_trunk") -> None:
        from exobench.perception.kinematics.tof_kinematics import TofKinematics

        self.sensor_id = sensor_id
        self.imu_sensor_id = imu_sensor_id
        self._kin = {side: TofKinematics(calibration, side, imu_sensor_id) for side in ("l", "r")}
        self._kin["l"].T_base_sensor(sensor_id)  # unknown mount: UnknownNameError now, not per scan
        self._contact: dict[str, bool] = {}  # pad sensor id -> in contact
        self.stance_side: str | None = None

    @property
    def has_state(self) -> bool:
        return self._kin["l"].has_state

    def update(self, frame: Frame) -> None:
        """Take an encoder state, an IMU orientation of the trunk IMU or an insole contact."""
        if isinstance(frame, JointState):
            for k in self._kin.values():
                k.update_joints(frame)
        elif isinstance(frame, ImuSample) and frame.sensor_id == self.imu_sensor_id:
            if np.all(np.isfinite(np.asarray(frame.quat_wxyz, dtype=float))) and np.linalg.norm(frame.quat_wxyz) > 0:
                for k in self._kin.values():
                    k.update_imu(frame)
        elif isinstance(frame, ContactSample):
            self._contact[frame.sensor_id] = bool(frame.in_contact)

    def _side_in_contact(self, side: str) -> bool | None:
        pads = [v for sid, v in self._contact.items() if sid.startswith(f"contact_{side}_")]
        return any(pads) if pads else None

    def T_footprint_sensor(self) -> np.ndarray | None:
        """The transform at the current state, None without a state or when not finite."""
        if not self.has_state:
            return None
        T = {side: k.T_estimator_sensor(self.sensor_id) for side, k in self._kin.items()}
        left, right = self._side_in_contact("l"), self._side_in_contact("r")
        if left and not right:
            side = "l"
        elif right and not left:
            side = "r"
        else:  # the stance foot is the lower one: the sensor is higher above it
            side = "l" if T["l"][2, 3] >= T["r"][2, 3] else "r"
        self.stance_side = side
        out = footprint_from_stance(T[side], self._kin[side].R_world_base())
        return out if np.all(np.isfinite(out)) else None


@dataclass(frozen=True)
class _BaseConfig:
    """Common fields: which LiDAR is filtered (empty: every LiDAR scan) and the trunk IMU."""

    lidar_id: str = ""
    imu_id: str = "imu_trunk"


class _FilterPipeline:
    """Feeds scans through one filter; see the module docstring."""

    name: ClassVar[str] = ""
    track: ClassVar[str] = "lidar-filter"
    uses_footprint: ClassVar[bool] = False

    def __init__(self, config: Any | None = None) -> None:
        self.config = config if config is not None else self.Config()  # type: ignore[attr-defined]
        self.filter = self._make_filter()
        self._kin: dict[str, FootprintKinematics] = {}
        self._calibration: Calibration | None = None
        self._reset_state()

    def _make_filter(self) -> NoFilter:
        return NoFilter()

    def _reset_state(self) -> None:
        self._stamps: list[float] = []
        self._keep: list[np.ndarray] = []
        self._times: list[float] = []
        self._T: list[np.ndarray] = []
        self._status: list[str] = []
        self._stance: list[str] = []
        self._stats = {"scans": 0, "empty_scans": 0, "no_kinematics": 0, "all_removed": 0, "invalid_points": 0,
                       "points": 0, "kept_points": 0, "kept_ground_rescued": 0, "malformed_scans": 0}  # fmt: skip

    def reset(self, calibration: Calibration) -> None:
        self._calibration = calibration
        self._kin = {}
        self._reset_state()
        if not self.uses_footprint:
            return
        ids = [self.config.lidar_id] if self.config.lidar_id else [m.sensor_id for m in calibration.mounts_of_kind("lidar")]
        for sid in ids:
            try:
                self._kin[sid] = FootprintKinematics(calibration, sid, self.config.imu_id)
            except Exception as e:  # no usable kinematics: band-only fallback, reported
                self._stats["kinematics_error"] = f"{sid}: {type(e).__name__}: {e}"

    def process(self, frame: Frame) -> FilterEstimate | None:
        if isinstance(frame, LidarScan):
            if self.config.lidar_id and frame.sensor_id != self.config.lidar_id:
                return None
            self._scan(frame)
        elif self.uses_footprint and isinstance(frame, (JointState, ImuSample, ContactSample)):
            for kin in self._kin.values():
                kin.update(frame)
        return None

    def _scan(self, scan: LidarScan) -> None:
        t0 = time.perf_counter()
        T: np.ndarray | None = None
        stance = ""
        if self.uses_footprint:
            kin = self._kin.get(scan.sensor_id)
            if kin is not None:
                T = kin.T_footprint_sensor()
                stance = kin.stance_side or ""
        pts = np.asarray(scan.points_xyz, dtype=float).reshape(-1, 3)
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
        self._stamps.append(float(scan.stamp_s))
        self._keep.append(np.asarray(res_keep, dtype=bool))
        self._times.append(dt)
        self._T.append(np.full((4, 4), np.nan) if T is None else T)
        self._status.append(status)
        self._stance.append(stance)

    @property
    def last_keep(self) -> np.ndarray | None:
        """The keep mask of the latest scan, None before the first."""
        return self._keep[-1] if self._keep else None

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
        )


class FilterNone(_FilterPipeline):
    """``filter-none``: every finite point is kept (the baseline)."""

    name: ClassVar[str] = "filter-none"

    @dataclass(frozen=True)
    class Config(_BaseConfig):
        """Only the common fields: the filter itself has no parameters."""

    def _make_filter(self) -> NoFilter:
        return NoFilter()


@dataclass(frozen=True)
class _BandFields(_BaseConfig):
    """The kept intensity band ``psi*`` (bytes); defaults as :class:`IntensityBandConfig`."""

    intensity_min: float = IntensityBandConfig.intensity_min
    intensity_max: float = IntensityBandConfig.intensity_max

    def band(self) -> dict[str, float]:
        return {"intensity_min": float(self.intensity_min), "intensity_max": float(self.intensity_max)}


class FilterThreshold(_FilterPipeline):
    """``filter-threshold``: the plain intensity band of eq. (4.15)."""

    name: ClassVar[str] = "filter-threshold"

    @dataclass(frozen=True)
    class Config(_BandFields):
        def __post_init__(self) -> None:
            IntensityBandConfig(**self.band())

    def _make_filter(self) -> NoFilter:
        return IntensityThresholdFilter(IntensityBandConfig(**self.config.band()))


class FilterNaiveGround(_FilterPipeline):
    """``filter-naive-ground``: eq. (4.16) with ``T_footprint_sensor`` from kinematics."""

    name: ClassVar[str] = "filter-naive-ground"
    uses_footprint: ClassVar[bool] = True

    @dataclass(frozen=True)
    class Config(_BandFields):
        ground_test: str = NaiveGroundConfig.ground_test
        ground_margin_m: float = NaiveGroundConfig.ground_margin_m
        ground_depth_m: float = NaiveGroundConfig.ground_depth_m
        plane_margin_m: float = NaiveGroundConfig.plane_margin_m
        plane_search_m: float = NaiveGroundConfig.plane_search_m
        use_full_transform: bool = NaiveGroundConfig.use_full_transform

        def __post_init__(self) -> None:
            self.filter_config()

        def filter_config(self) -> NaiveGroundConfig:
            return NaiveGroundConfig(**self.band(), ground_test=self.ground_test, ground_margin_m=self.ground_margin_m,
                                     ground_depth_m=self.ground_depth_m, plane_margin_m=self.plane_margin_m,
                                     plane_search_m=self.plane_search_m, use_full_transform=self.use_full_transform)  # fmt: skip

    def _make_filter(self) -> NoFilter:
        return NaiveGroundFilter(self.config.filter_config())


class FilterFloorGround(FilterNaiveGround):
    """``filter-floor-ground``: eq. (4.16) with the ground a band about the scan's own floor plane
    (:class:`~exobench.perception.lidar_filter.filters.FloorGroundFilter`), ``T_footprint_sensor``
    from kinematics."""

    name: ClassVar[str] = "filter-floor-ground"

    @dataclass(frozen=True)
    class Config(FilterNaiveGround.Config):
        ground_test: str = FloorGroundConfig.ground_test

    def _make_filter(self) -> NoFilter:
        return FloorGroundFilter(self.config.filter_config())


class FilterNormalGround(_FilterPipeline):
    """``filter-normal-ground``: eq. (4.17)-(4.19) with ``T_footprint_sensor`` from kinematics."""

    name: ClassVar[str] = "filter-normal-ground"
    uses_footprint: ClassVar[bool] = True

    @dataclass(frozen=True)
    class Config(_BandFields):
        epsilon_eta: float = NormalGroundConfig.epsilon_eta
        normal_method: str = NormalGroundConfig.normal_method
        normal_k: int = NormalGroundConfig.normal_k
        normal_radius_m: float = NormalGroundConfig.normal_radius_m
        ri_col_halfwidth: int = NormalGroundConfig.ri_col_halfwidth
        ri_azimuth_jump_rel: float = NormalGroundConfig.ri_azimuth_jump_rel
        ri_ring_jump_rel: float = NormalGroundConfig.ri_ring_jump_rel
        ri_max_ring_skip: int = NormalGroundConfig.ri_max_ring_skip

        def __post_init__(self) -> None:
            self.filter_config()

        def filter_config(self) -> NormalGroundConfig:
            return NormalGroundConfig(**self.band(), epsilon_eta=self.epsilon_eta, normal_method=self.normal_method,
                                      normal_k=self.normal_k, normal_radius_m=self.normal_radius_m,
                                      ri_col_halfwidth=self.ri_col_halfwidth, ri_azimuth_jump_rel=self.ri_azimuth_jump_rel,
                                      ri_ring_jump_rel=self.ri_ring_jump_rel,
                                      ri_max_ring_skip=self.ri_max_ring_skip)  # fmt: skip

    def _make_filter(self) -> NoFilter:
        return NormalGroundFilter(self.config.filter_config())


FILTER_PIPELINES: dict[str, type[_FilterPipeline]] = {
    "none": FilterNone,
    "threshold": FilterThreshold,
    "naive-ground": FilterNaiveGround,
    "normal-ground": FilterNormalGround,
    "floor-ground": FilterFloorGround,
}


def filter_pipeline(kind: str) -> type[_FilterPipeline]:
    """The pipeline class of a filter kind (a key of :data:`FILTER_PIPELINES`)."""
    if kind not in FILTER_PIPELINES:
        raise ConfigError("filter", kind, " or ".join(repr(k) for k in FILTER_PIPELINES))
    return FILTER_PIPELINES[kind]
