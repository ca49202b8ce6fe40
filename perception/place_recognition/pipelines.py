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
- Ceiling removal (the thesis removes the ceiling indoors): ``ceiling = "auto"`` finds the
  ceiling as the most populated ``ceiling_bin_m`` height bin among the points more than
  ``ceiling_search_above_m`` above the sensor, when that bin holds at least
  ``ceiling_min_share`` of them, and removes every point above ``that height - ceiling_margin_m``
  (no ceiling found: nothing removed); ``"fixed"`` removes the points higher than
  ``ceiling_above_sensor_m`` above the sensor; ``"none"`` keeps them.
- Description and query: the descriptor of the keyframe cloud, then the best match among the
  earlier keyframes except the ``exclude_recent`` most recent (the thesis' ``xi``), by ring-key
  k-d tree and column-shift alignment (eq. 4.23-4.24); then the keyframe is stored. The
  reported distance is ``1 - sim`` (eq. 4.24); no threshold is applied here (the track sweeps
  ``tau``, as section 5.2.3 does). ``time_per_keyframe_s`` is the wall time of levelling,
  accumulation, ceiling removal, description, query and insertion.

GSC cells are computed by :class:`ComponentGaussianScanContext` (only the mean and variance that
eq. 4.28 reads; ``component_cells=False``: the full 4 x 4 covariance of the reference module,
same cells). Defaults not given by the text: ``exclude_recent = 40`` keyframes (20 s at 10 Hz
with k = 5, the track's recent window); ``ceiling_min_share = 0.1``: in a 1.8 m corridor a
VLP-16 at head height sees the ceiling only beyond about 3.6 m, so the ceiling layer is a small
share of the points above the sensor, but the densest 5 cm layer by far (walls spread over
every height).

Faulty input never raises: non-finite points (coordinates or intensity) are dropped (counted); a
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
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from exobench.core.calibration import Calibration
from exobench.core.errors import ConfigError, check_range
from exobench.core.estimates import PlaceRecognitionEstimate
from exobench.core.frames import Frame, ImuSample, LidarScan
from exobench.core.transforms import quat_wxyz_to_matrix

from .gaussian_scan_context import GaussianScanContext, GaussianScanContextConfig
from .scan_context import (
    PlaceRecognizer,
    ScanContextConfig,
    ScanContextPP,
    accumulate_submap,
)

__all__ = [
    "CEILING_MODES",
    "ComponentGaussianScanContext",
    "GaussianPlaceRecognitionConfig",
    "GscHeightPipeline",
    "GscHuberPipeline",
    "GscIntensityPipeline",
    "PlaceRecognitionConfig",
    "PlaceRecognitionPipeline",
    "ScanContextPPPipeline",
    "remove_ceiling",
]

CEILING_MODES = ("auto", "fixed", "none")
ON_MODES = ("scan", "submap")
IMU_BUFFER = 512


def _int(name: str, value: Any, low: int, high: int) -> None:
    if not isinstance(value, (int, np.integer)) or isinstance(value, bool) or not low <= value <= high:
        raise ConfigError(name, value, f"an integer in [{low}, {high}]")


@dataclass(frozen=True)
class PlaceRecognitionConfig:
    """Keyframes, cloud preparation and the SC++ descriptor/retrieval parameters.

    Attributes:
        keyframe_every: a keyframe every this many LiDAR scans.
        on: ``"scan"`` or ``"submap"``.
        submap_scans: scans accumulated in a submap (the keyframe scan and the ones before it).
        ceiling: ``"auto"``, ``"fixed"`` or ``"none"`` (see the module docstring).
        ceiling_above_sensor_m: ``"fixed"``: points higher than this above the sensor go, m.
        ceiling_search_above_m / ceiling_bin_m / ceiling_min_share / ceiling_margin_m: ``"auto"``.
        exclude_recent: the most recent keyframes that are never candidates (``xi``).
        min_occupied_cells: fewer occupied bins than this: no valid descriptor.
        lidar_id: LiDAR sensor id; empty = the calibration's first LiDAR mount.
        n_rings, n_sectors, max_radius_m, height_offset_m, ring_key_mode, num_candidates,
        shift_search, search_ratio, beyond_max_radius, min_points: as
        :class:`~exobench.perception.place_recognition.scan_context.ScanContextConfig` (indoor grid: 20 m, 1 m rings,
        6 deg sectors; the height offset puts the ground, 1.7-1.8 m below a trunk LiDAR, above 0).
    """

    keyframe_every: int = 5
    on: str = "scan"
    submap_scans: int = 5
    ceiling: str = "auto"
    ceiling_above_sensor_m: float = 0.6
    ceiling_search_above_m: float = 0.3
    ceiling_bin_m: float = 0.05
    ceiling_min_share: float = 0.1
    ceiling_margin_m: float = 0.1
    exclude_recent: int = 40
    min_occupied_cells: int = 30
    lidar_id: str = ""
    n_rings: int = 20
    n_sectors: int = 60
    max_radius_m: float = 20.0
    height_offset_m: float = 2.0
    ring_key_mode: str = "l0"
    num_candidates: int = 10
    shift_search: str = "all"
    search_ratio: float = 0.1
    beyond_max_radius: str = "clamp"
    min_points: int = 50

    def __post_init__(self) -> None:
        _int("keyframe_every", self.keyframe_every, 1, 10000)
        if self.on not in ON_MODES:
            raise ConfigError("on", self.on, " or ".join(ON_MODES))
        _int("submap_scans", self.submap_scans, 1, 1000)
        if self.ceiling not in CEILING_MODES:
            raise ConfigError("ceiling", self.ceiling, ", ".join(CEILING_MODES))
        check_range("ceiling_above_sensor_m", self.ceiling_above_sensor_m, 0.0, 100.0)
        check_range("ceiling_search_above_m", self.ceiling_search_above_m, 0.0, 100.0)
        check_range("ceiling_bin_m", self.ceiling_bin_m, 0.0, 10.0, low_open=True)
        check_range("ceiling_min_share", self.ceiling_min_share, 0.0, 1.0)
        check_range("ceiling_margin_m", self.ceiling_margin_m, 0.0, 10.0)
        _int("exclude_recent", self.exclude_recent, 0, 10**9)
        _int("min_occupied_cells", self.min_occupied_cells, 0, 10**9)
        if not isinstance(self.lidar_id, str):
            raise ConfigError("lidar_id", self.lidar_id, "a sensor id string")
        self.context_config()  # validates the descriptor fields (ConfigError names the field)

    def _context_fields(self) -> dict[str, Any]:
        names = ("n_rings", "n_sectors", "max_radius_m", "height_offset_m", "ring_key_mode", "num_candidates",
                 "shift_search", "search_ratio", "beyond_max_radius", "min_points")  # fmt: skip
        return {n: getattr(self, n) for n in names}

    def context_config(self) -> ScanContextConfig:
        """The descriptor configuration (no threshold is applied by the pipelines: tau = 0)."""
        return ScanContextConfig(**self._context_fields(), tau=0.0)


@dataclass(frozen=True)
class GaussianPlaceRecognitionConfig(PlaceRecognitionConfig):
    """Plus the GSC parameters (section 5.2.3: ``alpha = 2``, ``delta = 1`` m).

    Attributes:
        alpha: variance weight of eq. (4.28). delta_m: Huber threshold of eq. (4.31), m.
        intensity_scale: intensity byte to binned value (``gsc-intensity``).
        component_cells: compute only the statistics eq. (4.28) reads (the mean and variance of
            z or psi; :class:`ComponentGaussianScanContext`), the same numbers as the full
            4 x 4 covariance of :func:`~exobench.perception.place_recognition.gaussian_scan_context.bin_gaussians`
            at a quarter of the work; False: the full reference computation.
    """

    alpha: float = 2.0
    delta_m: float = 1.0
    intensity_scale: float = 1.0 / 255.0
    component_cells: bool = True

    def context_config(self, variant: str = "huber") -> GaussianScanContextConfig:  # type: ignore[override]
        return GaussianScanContextConfig(
            **self._context_fields(), tau=0.0, variant=variant, alpha=self.alpha, delta_m=self.delta_m,
            intensity_scale=self.intensity_scale,
        )  # fmt: skip


class ComponentGaussianScanContext(GaussianScanContext):
    """GSC whose cells compute only what eq. (4.28) reads: per bin the (Huber-weighted) mean and
    variance of the one component (z, or psi for ``"intensity"``).

    The same statistics as the ``[c]`` / ``[c, c]`` entries of
    :func:`~exobench.perception.place_recognition.gaussian_scan_context.bin_gaussians` (eq. 4.26-4.27, or the
    residual over x, y, z to the plain mean, eq. 4.29, the weight of eq. 4.31 and eq. 4.32-4.33),
    equal to rounding (the residual's norm is summed axis by axis); the other 15 covariance
    entries are not formed (the thesis' own remedy for GSC's overhead, section 5.2.3).
    """

    def _cells(self, p4: np.ndarray, flat_bin: np.ndarray, n_bins: int) -> np.ndarray:
        from .gaussian_scan_context import huber_weights

        cfg = self.config
        c = 3 if cfg.variant == "intensity" else 2
        p = np.asarray(p4, dtype=float)
        v = p[:, 3] * cfg.intensity_scale if c == 3 else p[:, 2]
        b = np.asarray(flat_bin, dtype=np.int64)
        counts_all = np.bincount(b, minlength=n_bins)
        bins = np.flatnonzero(counts_all)
        dense = np.full(n_bins, -1, dtype=np.int64)
        dense[bins] = np.arange(len(bins))
        k = dense[b]
        K = len(bins)
        counts = counts_all[bins].astype(float)
        ones = np.ones(len(p))
        sw = np.bincount(k, weights=ones, minlength=K)
        if cfg.variant == "huber":
            r2 = np.zeros(len(p))
            for j in range(3):  # eq. (4.29): squared distance to the plain mean, axis by axis
                dj = p[:, j] - (np.bincount(k, weights=p[:, j], minlength=K) / sw)[k]
                r2 += dj * dj
            w = huber_weights(np.sqrt(r2), cfg.delta_m)  # eq. (4.31)
            sw = np.bincount(k, weights=w, minlength=K)
            denom = sw  # eq. (4.33)
        else:
            w = ones
            denom = counts - 1.0  # eq. (4.27)
        mu = np.bincount(k, weights=w * v, minlength=K) / sw  # eq. (4.26) / (4.32)
        d = v - mu[k]
        S = np.bincount(k, weights=w * d * d, minlength=K)
        with np.errstate(invalid="ignore", divide="ignore"):
            var = np.where(denom > 0, S / denom, 0.0)
        C = np.zeros(n_bins)
        C[bins] = mu + cfg.alpha * var  # eq. (4.28)
        return C


def remove_ceiling(points_level: np.ndarray, config: PlaceRecognitionConfig) -> tuple[np.ndarray, float]:
    """Mask of the points kept and the cut height above the sensor (inf: nothing removed).

    ``points_level`` (N, 3) in a level sensor-centred frame (z up, sensor at 0).
    """
    z = np.asarray(points_level, dtype=float).reshape(-1, 3)[:, 2]
    if config.ceiling == "none" or len(z) == 0:
        return np.ones(len(z), dtype=bool), math.inf
    if config.ceiling == "fixed":
        cut = float(config.ceiling_above_sensor_m)
        return z <= cut, cut
    above = z[z > config.ceiling_search_above_m]
    if len(above) == 0:
        return np.ones(len(z), dtype=bool), math.inf
    b = np.floor(above / config.ceiling_bin_m).astype(np.int64)
    counts = np.bincount(b - b.min())
    peak = int(np.argmax(counts))
    if counts[peak] < config.ceiling_min_share * len(above):
        return np.ones(len(z), dtype=bool), math.inf
    cut = (peak + b.min()) * config.ceiling_bin_m - config.ceiling_margin_m
    return z <= cut, float(cut)


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
        self._n_nonfinite = 0
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
        lidars = calibration.mounts_of_kind("lidar")
        lidar = None
        if self.config.lidar_id:
            lidar = calibration.mount(self.config.lidar_id)
        elif lidars:
            lidar = lidars[0]
        imus = calibration.mounts_of_kind("imu")
        if lidar is not None:
            self._lidar_id = lidar.sensor_id
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
        if isinstance(frame, ImuSample):
            if not self._imu_id or frame.sensor_id == self._imu_id:
                q = np.asarray(frame.quat_wxyz, dtype=float)
                if q.shape == (4,) and np.all(np.isfinite(q)) and np.linalg.norm(q) > 0:
                    self._imu_t.append(float(frame.stamp_s))
                    self._imu_R.append(quat_wxyz_to_matrix(q / np.linalg.norm(q)))
            return None
        if not isinstance(frame, LidarScan) or (self._lidar_id and frame.sensor_id != self._lidar_id):
            return None
        t0 = time.perf_counter()
        pts = np.asarray(frame.points_xyz, dtype=float).reshape(-1, 3)
        inten = np.asarray(frame.intensity, dtype=float).reshape(-1)
        if len(inten) != len(pts):  # a broken intensity channel: the geometry is still usable
            self._bad_intensity += 1
            inten = np.zeros(len(pts))
        ok = np.all(np.isfinite(pts), axis=1) & np.isfinite(inten)
        self._n_nonfinite += int(np.count_nonzero(~ok))
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
            "nonfinite_points": self._n_nonfinite,
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
