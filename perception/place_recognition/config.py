"""Configs of the place-recognition pipelines, and the ceiling removal they configure.

Ceiling removal (the thesis removes the ceiling indoors): ``ceiling = "auto"`` finds the ceiling
as the most populated ``ceiling_bin_m`` height bin among the points more than
``ceiling_search_above_m`` above the sensor, when that bin holds at least ``ceiling_min_share``
of them, and removes every point above ``that height - ceiling_margin_m`` (no ceiling found:
nothing removed); ``"fixed"`` removes the points higher than ``ceiling_above_sensor_m`` above the
sensor; ``"none"`` keeps them.

Defaults not given by the text: ``exclude_recent = 40`` keyframes (20 s at 10 Hz with k = 5, the
track's recent window); ``ceiling_min_share = 0.1``: in a 1.8 m corridor a VLP-16 at head height
sees the ceiling only beyond about 3.6 m, so the ceiling layer is a small share of the points
above the sensor, but the densest 5 cm layer by far (walls spread over every height).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from exobench.core.errors import ConfigError, check_int, check_range

from .gaussian_scan_context import GaussianScanContextConfig
from .scan_context import ScanContextConfig

CEILING_MODES = ("auto", "fixed", "none")
ON_MODES = ("scan", "submap")


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
        object.__setattr__(self, "keyframe_every", check_int("keyframe_every", self.keyframe_every, 1, 10000))
        if self.on not in ON_MODES:
            raise ConfigError("on", self.on, " or ".join(ON_MODES))
        object.__setattr__(self, "submap_scans", check_int("submap_scans", self.submap_scans, 1, 1000))
        if self.ceiling not in CEILING_MODES:
            raise ConfigError("ceiling", self.ceiling, ", ".join(CEILING_MODES))
        check_range("ceiling_above_sensor_m", self.ceiling_above_sensor_m, 0.0, 100.0)
        check_range("ceiling_search_above_m", self.ceiling_search_above_m, 0.0, 100.0)
        check_range("ceiling_bin_m", self.ceiling_bin_m, 0.0, 10.0, low_open=True)
        check_range("ceiling_min_share", self.ceiling_min_share, 0.0, 1.0)
        check_range("ceiling_margin_m", self.ceiling_margin_m, 0.0, 10.0)
        object.__setattr__(self, "exclude_recent", check_int("exclude_recent", self.exclude_recent, 0, 10**9))
        object.__setattr__(self, "min_occupied_cells", check_int("min_occupied_cells", self.min_occupied_cells, 0, 10**9))
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


