"""The LiDAR intensity filters (seeds/003 section 4.2.2, eq. 4.15-4.19) and the table of their names.

Each filter takes one cloud ``points_xyz`` (N, 3) in the LiDAR frame ``l`` with its
``intensity`` (N,) byte and returns a keep mask and the reason per point (:class:`FilterResult`);
it never modifies its input and never raises on data (empty clouds, clouds with only glass, a
missing transform are reported in ``FilterResult.status``). :data:`FILTERS` names them:

- ``"none"``: keeps every finite point.
- ``"threshold"``: the plain band filter of eq. (4.15): a point is removed when its intensity
  lies outside ``psi* = [psi*_min, psi*_max]``.
- ``"naive-ground"``: eq. (4.16): eq. (4.15), but a point that lies below the footprint is kept
  whatever its intensity.
- ``"normal-ground"``: eq. (4.17)-(4.19): eq. (4.15), but a point whose surface normal is
  parallel to the footprint's z axis is kept whatever its intensity.
- ``"floor-ground"`` (not in the thesis): eq. (4.15), but a point within ``plane_margin_m`` of
  the scan's own floor plane is kept whatever its intensity (:mod:`.ground`): the naive filter's
  idea without its flaw. On the track's 60 m corridor (VLP-16, seed 0) it keeps 99.5 % of the
  ground and removes 98.5 % of the spurious points (the naive filter: 98.8 % and 87.0 %).

Readings of the text (it does not parse literally):

- Eq. (4.15) writes ``psi not in psi* == (psi < psi*_min) & (psi > psi*_max)``; as a logical AND
  no value satisfies it. The text ("falls outside the specified boundary") means OR, which is
  what :func:`out_of_band` computes. ``psi*`` is the band that is *kept*.
- Eq. (4.16) and (4.19) define the set by the rescue condition only; the text makes the kept set
  ``in band OR ground``: an out-of-band point is removed unless the ground test rescues it.
- Eq. (4.17) applies a homogeneous transform to a direction: only its rotation acts on a normal.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import IntEnum
from typing import ClassVar

import numpy as np

from exobench.core.errors import ConfigError, UnknownNameError
from exobench.core.limits import finite_rows

from .config import (
    FloorGroundConfig,
    IntensityBandConfig,
    NaiveGroundConfig,
    NoFilterConfig,
    NormalGroundConfig,
)
from .ground import fit_floor_plane, footprint_heights_m
from .normals import estimate_normals, normal_cosines, range_image_normal_candidates

__all__ = [
    "FILTERS",
    "FilterReason",
    "FilterResult",
    "FloorGroundFilter",
    "IntensityThresholdFilter",
    "NaiveGroundFilter",
    "NoFilter",
    "NormalGroundFilter",
    "make_filter",
    "out_of_band",
]


class FilterReason(IntEnum):
    """Why a point was kept or removed (stored as uint8 per point)."""

    KEPT_IN_BAND = 0  # intensity inside psi*
    KEPT_GROUND = 1  # outside psi*, rescued by the ground test (eq. 4.16 / 4.19)
    KEPT_NO_FILTER = 2  # the "none" filter
    DROPPED_LOW_INTENSITY = 3  # psi < psi*_min and not ground
    DROPPED_HIGH_INTENSITY = 4  # psi > psi*_max and not ground
    DROPPED_INVALID = 5  # non-finite coordinates or intensity


@dataclass(frozen=True, eq=False)
class FilterResult:
    """Decision of one filter on one cloud.

    Attributes:
        keep: (N,) bool, True for the points in the filtered cloud ``^l P*``.
        reason: (N,) uint8 :class:`FilterReason` per point.
        status: ``"ok"``; ``"empty_input"`` (no point given); ``"all_removed"`` (points given,
            none kept, e.g. a scan with only glass); ``"no_transform"`` (the ground test could not
            run because ``T_footprint_sensor`` was missing or not finite: only the band was
            applied).
        normal_method: the normal estimate the normal filter used (``"range-image"`` or
            ``"knn"``; empty for the other filters and when no normals were computed).
        ground_plane: the plane the naive filter's ground test used: ``"refined"`` (the scan's
            own floor plane) or ``"footprint"`` (from kinematics); empty for the other filters
            and when the test did not run.
    """

    keep: np.ndarray
    reason: np.ndarray
    status: str
    normal_method: str = ""
    ground_plane: str = ""

    @property
    def n_kept(self) -> int:
        return int(np.count_nonzero(self.keep))

    def counts(self) -> dict[str, int]:
        """Number of points per :class:`FilterReason` name (all reasons listed)."""
        return {r.name.lower(): int(np.count_nonzero(self.reason == r)) for r in FilterReason}


# ---------------------------------------------------------------- pure functions of the equations


def out_of_band(intensity: np.ndarray, intensity_min: float, intensity_max: float) -> np.ndarray:
    """Eq. (4.15): ``psi < psi*_min or psi > psi*_max`` per point, (N,) bool."""
    psi = np.asarray(intensity, dtype=float)
    return (psi < intensity_min) | (psi > intensity_max)


def _check_T(T_footprint_sensor: np.ndarray | None) -> np.ndarray | None:
    """The transform as a float (4, 4) array, or None when absent or not finite."""
    if T_footprint_sensor is None:
        return None
    T = np.asarray(T_footprint_sensor, dtype=float)
    if T.shape != (4, 4):
        raise ConfigError("T_footprint_sensor", T.shape, "a 4x4 homogeneous transform")
    return T if np.all(np.isfinite(T)) else None


# ------------------------------------------------------------------------------------- filters


def _prepare(points_xyz: np.ndarray, intensity: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    p = np.asarray(points_xyz, dtype=float).reshape(-1, 3)
    psi = np.asarray(intensity, dtype=float).reshape(-1)
    if len(psi) != len(p):
        raise ConfigError("intensity", psi.shape, f"one value per point ({len(p)})")
    finite = finite_rows(p) & np.isfinite(psi)
    return p, psi, finite


def _band_result(
    psi: np.ndarray, finite: np.ndarray, cfg: IntensityBandConfig, ground: np.ndarray | None, status: str
) -> FilterResult:
    low = psi < cfg.intensity_min
    high = psi > cfg.intensity_max
    reason = np.full(len(psi), FilterReason.KEPT_IN_BAND, dtype=np.uint8)
    reason[low] = FilterReason.DROPPED_LOW_INTENSITY
    reason[high] = FilterReason.DROPPED_HIGH_INTENSITY
    if ground is not None:
        reason[(low | high) & ground] = FilterReason.KEPT_GROUND
    reason[~finite] = FilterReason.DROPPED_INVALID
    keep = (reason == FilterReason.KEPT_IN_BAND) | (reason == FilterReason.KEPT_GROUND)
    return _finish(keep, reason, status)


def _finish(keep: np.ndarray, reason: np.ndarray, status: str) -> FilterResult:
    if len(keep) == 0:
        status = "empty_input"
    elif status == "ok" and not keep.any():
        status = "all_removed"
    return FilterResult(keep=keep, reason=reason, status=status)


class NoFilter:
    """The ``"none"`` filter: every finite point is kept.

    Every filter's ``apply`` takes the cloud, its intensities, ``T_footprint_sensor`` and the
    optional ``ring`` of each point (used by the range-image normals only).
    """

    name: ClassVar[str] = "none"
    Config: ClassVar[type] = NoFilterConfig

    def __init__(self, config: object | None = None) -> None:
        self.config = config if config is not None else self.Config()

    def apply(
        self,
        points_xyz: np.ndarray,
        intensity: np.ndarray,
        T_footprint_sensor: np.ndarray | None = None,
        ring: np.ndarray | None = None,
    ) -> FilterResult:
        _, _, finite = _prepare(points_xyz, intensity)
        reason = np.where(finite, FilterReason.KEPT_NO_FILTER, FilterReason.DROPPED_INVALID).astype(np.uint8)
        return _finish(finite.copy(), reason, "ok")


class IntensityThresholdFilter(NoFilter):
    """The plain band filter of eq. (4.15): keep ``psi in psi*``; the transform is not used."""

    name: ClassVar[str] = "threshold"
    Config: ClassVar[type] = IntensityBandConfig

    def apply(
        self,
        points_xyz: np.ndarray,
        intensity: np.ndarray,
        T_footprint_sensor: np.ndarray | None = None,
        ring: np.ndarray | None = None,
    ) -> FilterResult:
        _, psi, finite = _prepare(points_xyz, intensity)
        return _band_result(psi, finite, self.config, None, "ok")


class NaiveGroundFilter(NoFilter):
    """Eq. (4.16): keep ``psi in psi*`` or ground by ``config.ground_test`` (default ``"below"``:
    footprint height below ``ground_margin_m``, the text as written)."""

    name: ClassVar[str] = "naive-ground"
    Config: ClassVar[type] = NaiveGroundConfig

    def ground_mask_and_plane(self, points_xyz: np.ndarray, T_footprint_sensor: np.ndarray) -> tuple[np.ndarray, str]:
        """The ground test, (N,) bool, and the plane it used: ``"refined"`` (the scan's floor
        plane, ``"plane-band"``) or ``"footprint"`` (the footprint plane from kinematics)."""
        cfg = self.config
        p = np.asarray(points_xyz, dtype=float).reshape(-1, 3)
        z_f = footprint_heights_m(p, T_footprint_sensor, use_full_transform=cfg.use_full_transform)
        if cfg.ground_test == "below":
            return z_f < cfg.ground_margin_m, "footprint"
        if cfg.ground_test == "plane-band":
            if cfg.use_full_transform:
                T = np.asarray(T_footprint_sensor, dtype=float)
                xy = p @ T[:2, :3].T + T[:2, 3]
            else:
                xy = p[:, :2]
            plane = fit_floor_plane(xy, z_f, search_m=cfg.plane_search_m, margin_m=cfg.plane_margin_m)
            if plane is not None:
                a, b, c = plane
                return np.abs(z_f - (a * xy[:, 0] + b * xy[:, 1] + c)) < cfg.plane_margin_m, "refined"
        return (z_f < cfg.ground_margin_m) & (z_f > -cfg.ground_depth_m), "footprint"

    def apply(
        self,
        points_xyz: np.ndarray,
        intensity: np.ndarray,
        T_footprint_sensor: np.ndarray | None = None,
        ring: np.ndarray | None = None,
    ) -> FilterResult:
        p, psi, finite = _prepare(points_xyz, intensity)
        T = _check_T(T_footprint_sensor)
        if T is None:
            return _band_result(psi, finite, self.config, None, "no_transform")
        ground = np.zeros(len(p), dtype=bool)
        plane = ""
        if finite.any():
            ground[finite], plane = self.ground_mask_and_plane(p[finite], T)
        res = _band_result(psi, finite, self.config, ground, "ok")
        return FilterResult(res.keep, res.reason, res.status, ground_plane=plane)


class FloorGroundFilter(NaiveGroundFilter):
    """Eq. (4.16) with the ground test ``"plane-band"``: keep ``psi in psi*`` or within
    ``plane_margin_m`` of the scan's own floor plane (module docstring). Not in the thesis: a
    ground-aware filter that keeps the floor but not the ghosts a polished floor mirrors under it."""

    name: ClassVar[str] = "floor-ground"
    Config: ClassVar[type] = FloorGroundConfig


class NormalGroundFilter(NoFilter):
    """Eq. (4.19): keep ``psi in psi*`` or ``theta_eta > 1 - epsilon_eta``."""

    name: ClassVar[str] = "normal-ground"
    Config: ClassVar[type] = NormalGroundConfig

    def cosines_and_method(
        self, points_xyz: np.ndarray, T_footprint_sensor: np.ndarray, ring: np.ndarray | None = None
    ) -> tuple[np.ndarray, str]:
        """``theta_eta`` of eq. (4.18) per point (NaN without a normal), (N,), and the normal
        method that ran. Range image: the largest cosine of the point's one-sided normals (the
        crease reading of the module docstring)."""
        p = np.asarray(points_xyz, dtype=float).reshape(-1, 3)
        if self.config.normal_method == "range-image":
            cand = range_image_normal_candidates(p, ring, **self.config.range_image_params())
            if cand is not None:
                theta = normal_cosines(cand.reshape(-1, 3), T_footprint_sensor).reshape(-1, 4)
                defined = ~np.isnan(theta)
                # column by column: numpy's reductions along an axis of four are slow
                side = np.where(defined, theta, -np.inf).T
                best = np.maximum(np.maximum(side[0], side[1]), np.maximum(side[2], side[3]))
                d = defined.T
                return np.where(d[0] | d[1] | d[2] | d[3], best, np.nan), "range-image"
        normals = estimate_normals(p, self.config.normal_k, self.config.normal_radius_m)
        return normal_cosines(normals, T_footprint_sensor), "knn"

    def cosines(self, points_xyz: np.ndarray, T_footprint_sensor: np.ndarray, ring: np.ndarray | None = None) -> np.ndarray:
        """``theta_eta`` of eq. (4.18) per point (NaN without a normal), (N,)."""
        return self.cosines_and_method(points_xyz, T_footprint_sensor, ring)[0]

    def apply(
        self,
        points_xyz: np.ndarray,
        intensity: np.ndarray,
        T_footprint_sensor: np.ndarray | None = None,
        ring: np.ndarray | None = None,
    ) -> FilterResult:
        p, psi, finite = _prepare(points_xyz, intensity)
        T = _check_T(T_footprint_sensor)
        if T is None:
            return _band_result(psi, finite, self.config, None, "no_transform")
        ground = np.zeros(len(p), dtype=bool)
        method = ""
        if finite.any():
            r = None
            if ring is not None and np.asarray(ring).reshape(-1).shape == (len(p),):
                r = np.asarray(ring).reshape(-1)[finite]
            theta, method = self.cosines_and_method(p[finite], T, r)
            with np.errstate(invalid="ignore"):
                ground[finite] = theta > 1.0 - self.config.epsilon_eta
        res = _band_result(psi, finite, self.config, ground, "ok")
        return FilterResult(res.keep, res.reason, res.status, method)


FILTERS: dict[str, type[NoFilter]] = {
    cls.name: cls
    for cls in (NoFilter, IntensityThresholdFilter, NaiveGroundFilter, NormalGroundFilter, FloorGroundFilter)
}
"""The one table of filter names: name -> filter class (its config class is ``cls.Config``)."""


def make_filter(name: str, **params: object) -> NoFilter:
    """A filter by name (:data:`FILTERS`) with its config built from ``params``.

    Unknown names raise :class:`UnknownNameError`; unknown or invalid parameters
    :class:`ConfigError`.
    """
    if name not in FILTERS:
        raise UnknownNameError("intensity filter", name, FILTERS)
    cls = FILTERS[name]
    fields = set(cls.Config.__dataclass_fields__)
    for key in params:
        if key not in fields:
            raise ConfigError(f"{name}.{key}", params[key], f"one of {sorted(fields)}" if fields else "no parameters")
    return cls(cls.Config(**params))
