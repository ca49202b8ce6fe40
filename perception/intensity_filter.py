"""Ground-aware LiDAR intensity filters (seeds/003 section 4.2.2, eq. 4.15-4.19).

Four filters over one cloud ``points_xyz`` (N, 3) in the LiDAR frame ``l`` with its
``intensity`` (N,) byte: each returns a keep mask and the reason per point
(:class:`FilterResult`), never modifies its input and never raises on data (empty clouds,
clouds with only glass, a missing transform are reported in ``FilterResult.status``).

- ``"none"``: keeps every finite point.
- ``"intensity"``: the plain band filter of eq. (4.15): a point is removed when its intensity
  lies outside ``psi* = [psi*_min, psi*_max]``.
- ``"naive-ground"``: eq. (4.16): eq. (4.15), but a point that lies below the footprint is kept
  whatever its intensity.
- ``"normal-ground"``: eq. (4.17)-(4.19): eq. (4.15), but a point whose surface normal is
  parallel to the footprint's z axis is kept whatever its intensity.

Readings of the text (documented because it does not parse literally):

- Eq. (4.15) writes ``psi not in psi* == (psi < psi*_min) & (psi > psi*_max)``; as a logical AND
  no value satisfies it. The text around it ("falls outside the specified boundary") means OR,
  which is what :func:`out_of_band` computes. ``psi*`` is the band that is *kept*.
- Eq. (4.16) and (4.19) define the set by the rescue condition only. The text ("retains all
  points located below the footprint", "similar to the naive approach, the normal filter checks
  whether the intensity lies outside the boundaries and whether the point belongs to the
  ground") makes the kept set ``in band OR ground``; an out-of-band point is removed unless the
  ground test rescues it.
- The footprint ``f`` is the ground frame below the walker (z up, origin on the ground), given by
  the caller as ``T_footprint_sensor`` from kinematics and trunk tilt. The thesis uses only the
  translation ``^l z_f`` when the LiDAR is level and asks for the full transform when it is
  tilted (the exoskeleton's trunk always is, a little); ``use_full_transform=True`` (default)
  does that: ``(T_footprint_sensor p)_z < margin``. ``use_full_transform=False`` is eq. (4.16)
  literally: ``p_z < ^l z_f + margin`` with ``^l z_f`` the z of the footprint origin in ``l``.
- ``ground_margin_m`` (default 0.05 m, not in the text): the thesis' footprint comes from foot
  frames that sit above the contact surface; here the footprint lies *on* the ground, so points
  of the ground itself scatter around z = 0 by the range noise (VLP-16: +-3 cm) and a strict
  ``< 0`` would drop half of them. ``ground_margin_m=0`` gives the strict inequality.
- Eq. (4.17) applies a homogeneous transform to a direction: only its rotation acts on a normal.
- Normals (step 1 of the normal filter): PCA of the ``normal_k`` nearest neighbours (the query
  point included) within ``normal_radius_m``, as PCL's ``NormalEstimation``: the eigenvector of
  the smallest eigenvalue of the neighbourhood covariance, flipped towards the viewpoint (the
  sensor origin), so the ground seen from above has ``theta = +1`` and a ceiling ``-1`` (the
  text: "typically normalized to 0 for parallel surfaces"). A point with fewer than 3
  neighbours, or with collinear neighbours (a lone ring of a sparse LiDAR), has no normal and is
  never rescued -- the sparsity limitation section 5.2.2 reports.

Defaults: ``psi*_min = 16``: the thesis' experiment removes ``[0, 15]`` of the 0-255 byte
(section 5.2.2). ``psi*_max = 100``: the text leaves the upper bound open; 100 is the top of the
diffuse range of the calibrated intensity byte (core/frames.py), so specular glass glints and
blooming retro-reflectors are removed. ``epsilon_eta = 0.03`` (normals within 14 deg of the
footprint z axis), ``normal_k = 10``, ``normal_radius_m = 0.5``: open in the text.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import IntEnum

import numpy as np

from exobench.core.errors import ConfigError, UnknownNameError, check_range
from exobench.core.frames import LidarScan

__all__ = [
    "FILTERS",
    "FilterReason",
    "FilterResult",
    "IntensityBandConfig",
    "IntensityThresholdFilter",
    "NaiveGroundConfig",
    "NaiveGroundFilter",
    "NoFilter",
    "NormalGroundConfig",
    "NormalGroundFilter",
    "estimate_normals",
    "footprint_heights_m",
    "make_filter",
    "normal_cosines",
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
    """

    keep: np.ndarray
    reason: np.ndarray
    status: str

    @property
    def n_kept(self) -> int:
        return int(np.count_nonzero(self.keep))

    def counts(self) -> dict[str, int]:
        """Number of points per :class:`FilterReason` name (all reasons listed)."""
        return {r.name.lower(): int(np.count_nonzero(self.reason == r)) for r in FilterReason}


@dataclass(frozen=True)
class IntensityBandConfig:
    """The kept intensity band ``psi* = [intensity_min, intensity_max]`` (bytes, inclusive)."""

    intensity_min: float = 16.0
    intensity_max: float = 100.0

    def __post_init__(self) -> None:
        lo = check_range("intensity_min", self.intensity_min, 0.0, 255.0)
        hi = check_range("intensity_max", self.intensity_max, 0.0, 255.0)
        if hi < lo:
            raise ConfigError("intensity_max", self.intensity_max, f"intensity_min ({lo}) <= intensity_max <= 255")


@dataclass(frozen=True)
class NaiveGroundConfig(IntensityBandConfig):
    """Naive ground-aware filter (eq. 4.16).

    Attributes:
        ground_margin_m: a point is ground when its footprint height is below this, m (0..0.5).
        use_full_transform: rotate into the footprint frame (True) or use only ``^l z_f``, the
            level-LiDAR form of eq. (4.16) (False).
    """

    ground_margin_m: float = 0.05
    use_full_transform: bool = True

    def __post_init__(self) -> None:
        super().__post_init__()
        check_range("ground_margin_m", self.ground_margin_m, 0.0, 0.5)
        if not isinstance(self.use_full_transform, bool):
            raise ConfigError("use_full_transform", self.use_full_transform, "True or False")


@dataclass(frozen=True)
class NormalGroundConfig(IntensityBandConfig):
    """Normal ground-aware filter (eq. 4.17-4.19).

    Attributes:
        epsilon_eta: a point is ground when ``theta_eta > 1 - epsilon_eta`` (0 < eps < 1).
        normal_k: neighbours (query point included) of the PCA normal, 3..100.
        normal_radius_m: neighbours farther than this are not used, m.
    """

    epsilon_eta: float = 0.03
    normal_k: int = 10
    normal_radius_m: float = 0.5

    def __post_init__(self) -> None:
        super().__post_init__()
        check_range("epsilon_eta", self.epsilon_eta, 0.0, 1.0, low_open=True, high_open=True)
        if not isinstance(self.normal_k, int) or isinstance(self.normal_k, bool) or not 3 <= self.normal_k <= 100:
            raise ConfigError("normal_k", self.normal_k, "an integer, 3 <= normal_k <= 100")
        check_range("normal_radius_m", self.normal_radius_m, 0.0, 10.0, low_open=True)


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


def footprint_heights_m(
    points_xyz: np.ndarray, T_footprint_sensor: np.ndarray, *, use_full_transform: bool = True
) -> np.ndarray:
    """Height of each point relative to the footprint plane, m, (N,).

    Full transform: ``(T_footprint_sensor p)_z``. Level form of eq. (4.16): ``p_z - ^l z_f``
    where ``^l z_f`` is the z of the footprint origin expressed in the LiDAR frame.
    """
    T = np.asarray(T_footprint_sensor, dtype=float)
    p = np.asarray(points_xyz, dtype=float).reshape(-1, 3)
    if use_full_transform:
        return p @ T[2, :3] + T[2, 3]
    l_z_f = -(T[:3, :3].T @ T[:3, 3])[2]  # translation of T_sensor_footprint = T^-1, z part
    return p[:, 2] - l_z_f


def estimate_normals(
    points_xyz: np.ndarray, k: int = 10, radius_m: float = 0.5, viewpoint_xyz: np.ndarray | None = None
) -> np.ndarray:
    """PCA normals (PCL ``NormalEstimation``), flipped towards the viewpoint; (N, 3), NaN if none.

    Neighbours: the ``k`` nearest points (the query point included) within ``radius_m``. A point
    with fewer than 3 neighbours, or whose neighbours are collinear (middle eigenvalue below
    1e-6 of the largest), gets NaN: its normal is undefined.
    """
    from scipy.spatial import cKDTree

    p = np.asarray(points_xyz, dtype=float).reshape(-1, 3)
    n = len(p)
    normals = np.full((n, 3), np.nan)
    if n < 3:
        return normals
    kk = min(k, n)
    dist, idx = cKDTree(p).query(p, k=kk, distance_upper_bound=radius_m)
    dist = dist.reshape(n, kk)
    idx = idx.reshape(n, kk)
    valid = np.isfinite(dist)
    count = valid.sum(axis=1)
    nbr = p[np.where(valid, idx, 0)]  # (n, kk, 3); invalid slots masked below
    w = valid[..., None].astype(float)
    mean = (nbr * w).sum(axis=1) / np.maximum(count, 1)[:, None]
    d = (nbr - mean[:, None, :]) * w
    cov = np.einsum("nki,nkj->nij", d, d) / np.maximum(count, 1)[:, None, None]
    evals, evecs = np.linalg.eigh(cov)  # ascending
    ok = (count >= 3) & (evals[:, 1] > 1e-6 * np.maximum(evals[:, 2], 1e-300))
    normal = evecs[:, :, 0]
    vp = np.zeros(3) if viewpoint_xyz is None else np.asarray(viewpoint_xyz, dtype=float)
    flip = np.einsum("ni,ni->n", normal, vp - p) < 0
    normal[flip] *= -1.0
    normals[ok] = normal[ok]
    return normals


def normal_cosines(normals_sensor: np.ndarray, T_footprint_sensor: np.ndarray) -> np.ndarray:
    """Eq. (4.17)-(4.18): cosine between each normal, rotated into ``f``, and ``f``'s z; (N,).

    NaN where the normal is undefined.
    """
    R = np.asarray(T_footprint_sensor, dtype=float)[:3, :3]
    eta_f = np.asarray(normals_sensor, dtype=float).reshape(-1, 3) @ R.T
    with np.errstate(invalid="ignore", divide="ignore"):
        return eta_f[:, 2] / np.linalg.norm(eta_f, axis=1)


# ------------------------------------------------------------------------------------- filters


def _prepare(points_xyz: np.ndarray, intensity: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    p = np.asarray(points_xyz, dtype=float).reshape(-1, 3)
    psi = np.asarray(intensity, dtype=float).reshape(-1)
    if len(psi) != len(p):
        raise ConfigError("intensity", psi.shape, f"one value per point ({len(p)})")
    finite = np.all(np.isfinite(p), axis=1) & np.isfinite(psi)
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
    """The ``"none"`` filter: every finite point is kept."""

    name = "none"

    def __init__(self, config: None = None) -> None:
        self.config = config

    def apply(
        self, points_xyz: np.ndarray, intensity: np.ndarray, T_footprint_sensor: np.ndarray | None = None
    ) -> FilterResult:
        _, _, finite = _prepare(points_xyz, intensity)
        reason = np.where(finite, FilterReason.KEPT_NO_FILTER, FilterReason.DROPPED_INVALID).astype(np.uint8)
        return _finish(finite.copy(), reason, "ok")

    def apply_scan(self, scan: LidarScan, T_footprint_sensor: np.ndarray | None = None) -> FilterResult:
        return self.apply(scan.points_xyz, scan.intensity, T_footprint_sensor)


class IntensityThresholdFilter(NoFilter):
    """The plain band filter of eq. (4.15): keep ``psi in psi*``; the transform is not used."""

    name = "intensity"

    def __init__(self, config: IntensityBandConfig | None = None) -> None:
        self.config = config or IntensityBandConfig()

    def apply(
        self, points_xyz: np.ndarray, intensity: np.ndarray, T_footprint_sensor: np.ndarray | None = None
    ) -> FilterResult:
        _, psi, finite = _prepare(points_xyz, intensity)
        return _band_result(psi, finite, self.config, None, "ok")


class NaiveGroundFilter(NoFilter):
    """Eq. (4.16): keep ``psi in psi*`` or ``footprint height < ground_margin_m``."""

    name = "naive-ground"

    def __init__(self, config: NaiveGroundConfig | None = None) -> None:
        self.config = config or NaiveGroundConfig()

    def ground_mask(self, points_xyz: np.ndarray, T_footprint_sensor: np.ndarray) -> np.ndarray:
        """The ground test of eq. (4.16) alone, (N,) bool."""
        z_f = footprint_heights_m(points_xyz, T_footprint_sensor, use_full_transform=self.config.use_full_transform)
        return z_f < self.config.ground_margin_m

    def apply(
        self, points_xyz: np.ndarray, intensity: np.ndarray, T_footprint_sensor: np.ndarray | None = None
    ) -> FilterResult:
        p, psi, finite = _prepare(points_xyz, intensity)
        T = _check_T(T_footprint_sensor)
        if T is None:
            return _band_result(psi, finite, self.config, None, "no_transform")
        with np.errstate(invalid="ignore"):
            ground = self.ground_mask(p, T)
        return _band_result(psi, finite, self.config, ground, "ok")


class NormalGroundFilter(NoFilter):
    """Eq. (4.19): keep ``psi in psi*`` or ``theta_eta > 1 - epsilon_eta``."""

    name = "normal-ground"

    def __init__(self, config: NormalGroundConfig | None = None) -> None:
        self.config = config or NormalGroundConfig()

    def cosines(self, points_xyz: np.ndarray, T_footprint_sensor: np.ndarray) -> np.ndarray:
        """``theta_eta`` of eq. (4.18) per point (NaN without a normal), (N,)."""
        p = np.asarray(points_xyz, dtype=float).reshape(-1, 3)
        normals = estimate_normals(p, self.config.normal_k, self.config.normal_radius_m)
        return normal_cosines(normals, T_footprint_sensor)

    def apply(
        self, points_xyz: np.ndarray, intensity: np.ndarray, T_footprint_sensor: np.ndarray | None = None
    ) -> FilterResult:
        p, psi, finite = _prepare(points_xyz, intensity)
        T = _check_T(T_footprint_sensor)
        if T is None:
            return _band_result(psi, finite, self.config, None, "no_transform")
        ground = np.zeros(len(p), dtype=bool)
        if finite.any():
            theta = self.cosines(p[finite], T)
            with np.errstate(invalid="ignore"):
                ground[finite] = theta > 1.0 - self.config.epsilon_eta
        return _band_result(psi, finite, self.config, ground, "ok")


FILTERS: dict[str, type[NoFilter]] = {
    "none": NoFilter,
    "intensity": IntensityThresholdFilter,
    "naive-ground": NaiveGroundFilter,
    "normal-ground": NormalGroundFilter,
}

_CONFIGS: dict[str, type | None] = {
    "none": None,
    "intensity": IntensityBandConfig,
    "naive-ground": NaiveGroundConfig,
    "normal-ground": NormalGroundConfig,
}


def make_filter(name: str, **params: object) -> NoFilter:
    """A filter by name (:data:`FILTERS`) with its config built from ``params``.

    Unknown names raise :class:`UnknownNameError`; unknown or invalid parameters
    :class:`ConfigError`.
    """
    if name not in FILTERS:
        raise UnknownNameError("intensity filter", name, FILTERS)
    cfg_type = _CONFIGS[name]
    if cfg_type is None:
        if params:
            raise ConfigError(f"{name}.{next(iter(params))}", params, "no parameters")
        return FILTERS[name]()
    fields = set(cfg_type.__dataclass_fields__)
    for key in params:
        if key not in fields:
            raise ConfigError(f"{name}.{key}", params[key], f"one of {sorted(fields)}")
    return FILTERS[name](cfg_type(**params))
