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
- ``"floor-ground"`` (not in the thesis): eq. (4.15), but a point within ``plane_margin_m`` of
  the scan's own floor plane, fitted near the footprint, is kept whatever its intensity (the
  ``"plane-band"`` ground test below): the naive filter's idea without its flaw.

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
- The ground test of the naive filter, ``ground_test`` (``"below"``, the default, is the text;
  the others are additions, and ``"plane-band"`` is the default of the ``"floor-ground"``
  filter, :class:`FloorGroundFilter`, our ground-aware filter beside the thesis's two):

  * ``"below"`` (naive-ground): eq. (4.16) as written, ``z_f < ground_margin_m``: *every* point below the
    footprint is ground. The thesis names the flaw (section 5.2.2: "it retains all the
    erroneously reflected points below the robot's height"): a polished floor mirrors the walls
    and furniture, and those ghosts appear below the floor, at any depth.
  * ``"band"``: ``-ground_depth_m < z_f < ground_margin_m``: nothing genuine is returned from
    under the floor the walker stands on (a level-floor assumption: a descending stair or ramp
    beyond ``ground_depth_m`` is lost, as any plane-based ground test loses it). The depth
    (0.1 m) covers the error of the kinematic footprint: on the simulated office walk the floor
    lies within -0.066 / +0.036 m of the footprint plane (0.5 / 99.5 percentiles), the scan's own
    floor varying by +-0.04 m from scan to scan (trunk height and tilt error) but only +-0.01 m
    around its own plane.
  * ``"plane-band"`` (floor-ground): the band about the scan's own floor plane
    (:func:`fit_floor_plane`: least squares on the points within ``plane_search_m`` of the
    footprint plane and 12 m of its origin, refitted on the points within 2 and 1
    ``plane_margin_m`` of the previous fit), ``|z_f - plane| < plane_margin_m`` (0.03 m: three
    times the floor's spread about its plane). The narrow band removes most of the ghosts that
    a polished floor mirrors just below itself (the foot of a wall, 1-10 cm under the floor).
    Without a plane (fewer than 30 supporting points, more than 3 deg of tilt or
    ``plane_search_m`` of offset from the footprint) the ``"band"`` test runs;
    :attr:`FilterResult.ground_plane` says which plane was used. Left: ghosts that lie *on* the
    floor plane, the floor mirrored in a vertical metal panel or pane, which no height test
    separates from the floor.

  Measured on the lidar-filter track (VLP-16, seed 0; ground kept / spurious removed, %):

  ============== ================ ================ ================
  ground test    quick (4 m)      corridor (60 m)  ring
  ============== ================ ================ ================
  below          99.9 / 40.4      98.8 / 87.0      99.5 / 92.5
  band           99.9 / 91.4      98.8 / 97.5      99.4 / 97.4
  plane-band     100.0 / 95.7     99.5 / 98.5      99.5 / 98.1
  ============== ================ ================ ================

  (normal filter, range image: 95.3 / 96.8, 91.1 / 98.3, 92.7 / 98.1: it loses the floor under
  walls, see below.)
- ``ground_margin_m`` (default 0.05 m, not in the text): the thesis' footprint comes from foot
  frames that sit above the contact surface; here the footprint lies *on* the ground, so points
  of the ground itself scatter around z = 0 by the range noise (VLP-16: +-3 cm) and a strict
  ``< 0`` would drop half of them. ``ground_margin_m=0`` gives the strict inequality.
- Eq. (4.17) applies a homogeneous transform to a direction: only its rotation acts on a normal.
- Normals (step 1 of the normal filter), ``normal_method``:

  * ``"knn"``: the thesis' method, PCA of the ``normal_k`` nearest neighbours (the query point
    included) within ``normal_radius_m``, as PCL's ``NormalEstimation``: the eigenvector of the
    smallest eigenvalue of the neighbourhood covariance, flipped towards the viewpoint (the
    sensor origin), so the ground seen from above has ``theta = +1`` and a ceiling ``-1`` (the
    text: "typically normalized to 0 for parallel surfaces"). A point with fewer than 3
    neighbours, or with collinear neighbours, has no normal and is never rescued. On a 16-ring
    LiDAR the k nearest points of a floor point all lie on its own ring (0.2 deg azimuth steps,
    2 deg between rings), so the "plane" is a line and its normal direction arbitrary: the
    sparsity limitation section 5.2.2 reports ("the alternative solution proved unusable").
  * ``"range-image"`` (default; a reading of step 1, not the thesis' PCL call): the scan is
    organised as a range image, rows = rings sorted by elevation, columns = azimuth
    (``atan2(y, x)`` in steps estimated from the scan), as practitioners do on spinning
    multi-beam LiDARs, and each point's normal is the cross product of an azimuth tangent
    (least-squares line through the point and its ``ri_col_halfwidth`` neighbours on one side;
    neighbours whose range differs by more than ``ri_azimuth_jump_rel`` of the point's are
    skipped) and a ring tangent (to the nearest return in the ring above / below, at most
    ``ri_max_ring_skip`` rows away, whose range is within a ratio ``1 + ri_ring_jump_rel`` of the
    point's: returns across a depth jump, such as a ghost behind glass or below a polished
    floor, are passed over), flipped towards the sensor. That gives four one-sided normals per point (left/right x
    up/down), NaN where a side has too few neighbours or straddles a depth jump. A point on a
    crease (floor meeting a wall, the top floor row below a wall) lies on both surfaces and a
    window across the crease mixes them, so eq. (4.19) is read as "some one-sided window of the
    point is parallel to the footprint plane": the point is ground when any of its one-sided
    normals passes eq. (4.18)-(4.19). :func:`estimate_range_image_normals` returns the single
    normal (the mean of the one-sided normals when they agree within 20 deg, NaN on a crease).
    Scans without a usable ring layout (no ``ring``, fewer than 2 rings, a non-spinning
    pattern) fall back to ``"knn"``; :attr:`FilterResult.normal_method` says which ran.

Defaults: ``psi*_min = 16``: the thesis' experiment removes ``[0, 15]`` of the 0-255 byte
(section 5.2.2). ``psi*_max = 100``: the text leaves the upper bound open; 100 is the top of the
diffuse range of the calibrated intensity byte (core/frames.py), so specular glass glints and
blooming retro-reflectors are removed. ``epsilon_eta = 0.05`` (normals within 18 deg of the
footprint z axis; open in the text): a floor normal from a VLP-16 range image has a few degrees
of noise (1.5 cm range noise over azimuth tangents of a few cm at 5 m) and the footprint
transform from kinematics a few more of tilt error, while ramps (< 5 deg) must pass and walls
(90 deg) stay far away. ``normal_k = 10``, ``normal_radius_m = 0.5``: open in the text.
Range-image windows: ``ri_col_halfwidth = 4`` columns (0.8 deg on a VLP-16: 6 cm at 4.5 m, where
the lowest ring meets the floor, long enough that the range noise tilts the tangent by a few
degrees only); ``ri_azimuth_jump_rel = 0.1`` (on a surface seen at 80 deg incidence the range
grows by 2 % per 0.2 deg column); ``ri_ring_jump_rel = 0.3``: adjacent rings 2 deg apart on a level
floor seen from 1.2-1.7 m have ranges in a ratio of 1.15-1.3 for the rings at -15..-7 deg
(floor within about 10 m, the extent of offices and corridors), while a ghost behind glass
next to the nearer genuine return it replaces jumps further; farther floor rings (-5 deg and
up: ratio 1.4 and more) read as depth jumps and are not rescued. The gate is set for the
VLP-16's uniform 2 deg rings: sensors with wider gaps between their lowest rings (VLP-32C:
-25 / -15.6 / -11.3 deg, floor ratios 1.4-1.55) need a larger value (0.6 on the office walk).
``ri_max_ring_skip = 2``: a
ring with no return there, or only one across a depth jump (a specular floor returning the
mirrored scene), is passed over.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import IntEnum

import numpy as np

from exobench.core.errors import ConfigError, UnknownNameError, check_range
from exobench.core.frames import LidarScan

__all__ = [
    "FILTERS",
    "GROUND_TESTS",
    "FilterReason",
    "FilterResult",
    "FloorGroundConfig",
    "FloorGroundFilter",
    "IntensityBandConfig",
    "IntensityThresholdFilter",
    "NaiveGroundConfig",
    "NaiveGroundFilter",
    "NoFilter",
    "NormalGroundConfig",
    "NormalGroundFilter",
    "estimate_normals",
    "estimate_range_image_normals",
    "fit_floor_plane",
    "range_image_index",
    "range_image_normal_candidates",
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


GROUND_TESTS = ("below", "band", "plane-band")


@dataclass(frozen=True)
class NaiveGroundConfig(IntensityBandConfig):
    """Naive ground-aware filter (eq. 4.16); see the module docstring for the ground tests.

    Attributes:
        ground_test: ``"below"`` (default, eq. 4.16 as written: footprint height below
            ``ground_margin_m``), ``"band"`` (footprint height in ``(-ground_depth_m,
            ground_margin_m)``) or ``"plane-band"`` (within ``plane_margin_m`` of the scan's own
            floor plane, found near the footprint plane; ``"band"`` when no plane is found; the
            default of :class:`FloorGroundFilter`).
        ground_margin_m: a point is ground when its footprint height is below this, m (0..0.5).
        ground_depth_m: ``"band"``: ... and above minus this, m (0..1].
        plane_margin_m: ``"plane-band"``: half-width of the band around the scan's floor plane, m
            (0..0.2].
        plane_search_m: ``"plane-band"``: the floor plane is fitted to the points within this of
            the footprint plane and may lie at most this far from it (at the footprint origin), m
            (0..0.5].
        use_full_transform: rotate into the footprint frame (True) or use only ``^l z_f``, the
            level-LiDAR form of eq. (4.16) (False).
    """

    ground_test: str = "below"
    ground_margin_m: float = 0.05
    ground_depth_m: float = 0.1
    plane_margin_m: float = 0.03
    plane_search_m: float = 0.1
    use_full_transform: bool = True

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.ground_test not in GROUND_TESTS:
            raise ConfigError("ground_test", self.ground_test, " or ".join(repr(m) for m in GROUND_TESTS))
        check_range("ground_margin_m", self.ground_margin_m, 0.0, 0.5)
        check_range("ground_depth_m", self.ground_depth_m, 0.0, 1.0, low_open=True)
        check_range("plane_margin_m", self.plane_margin_m, 0.0, 0.2, low_open=True)
        check_range("plane_search_m", self.plane_search_m, 0.0, 0.5, low_open=True)
        if not isinstance(self.use_full_transform, bool):
            raise ConfigError("use_full_transform", self.use_full_transform, "True or False")


@dataclass(frozen=True)
class FloorGroundConfig(NaiveGroundConfig):
    """The floor-plane ground-aware filter (:class:`FloorGroundFilter`): :class:`NaiveGroundConfig`
    with the ground test ``"plane-band"``."""

    ground_test: str = "plane-band"


NORMAL_METHODS = ("range-image", "knn")


@dataclass(frozen=True)
class NormalGroundConfig(IntensityBandConfig):
    """Normal ground-aware filter (eq. 4.17-4.19).

    Attributes:
        epsilon_eta: a point is ground when ``theta_eta > 1 - epsilon_eta`` (0 < eps < 1).
        normal_method: ``"range-image"`` (ring-organised scans; others fall back to knn) or
            ``"knn"`` (the thesis' PCL method); see the module docstring.
        normal_k: neighbours (query point included) of the knn PCA normal, 3..100.
        normal_radius_m: knn neighbours farther than this are not used, m.
        ri_col_halfwidth: range image: azimuth columns on each side of a point, 1..32.
        ri_azimuth_jump_rel: range image: an azimuth neighbour whose range differs by more than
            this fraction of the point's is skipped (0..1].
        ri_ring_jump_rel: range image: a ring neighbour whose range differs by more than this
            fraction of the nearer of the two ranges is across a depth jump, (0..2].
        ri_max_ring_skip: range image: rings without a return skipped to find the ring
            neighbour above / below, 1..4 (1 = only the adjacent ring).
    """

    epsilon_eta: float = 0.05
    normal_method: str = "range-image"
    normal_k: int = 10
    normal_radius_m: float = 0.5
    ri_col_halfwidth: int = 4
    ri_azimuth_jump_rel: float = 0.1
    ri_ring_jump_rel: float = 0.3
    ri_max_ring_skip: int = 2

    def __post_init__(self) -> None:
        super().__post_init__()
        check_range("epsilon_eta", self.epsilon_eta, 0.0, 1.0, low_open=True, high_open=True)
        if self.normal_method not in NORMAL_METHODS:
            raise ConfigError("normal_method", self.normal_method, " or ".join(repr(m) for m in NORMAL_METHODS))
        _check_int("normal_k", self.normal_k, 3, 100)
        check_range("normal_radius_m", self.normal_radius_m, 0.0, 10.0, low_open=True)
        _check_int("ri_col_halfwidth", self.ri_col_halfwidth, 1, 32)
        check_range("ri_azimuth_jump_rel", self.ri_azimuth_jump_rel, 0.0, 1.0, low_open=True)
        check_range("ri_ring_jump_rel", self.ri_ring_jump_rel, 0.0, 2.0, low_open=True)
        _check_int("ri_max_ring_skip", self.ri_max_ring_skip, 1, 4)

    def range_image_params(self) -> dict[str, float | int]:
        """Keyword arguments of :func:`range_image_normal_candidates`."""
        return {"col_halfwidth": self.ri_col_halfwidth, "azimuth_jump_rel": self.ri_azimuth_jump_rel,
                "ring_jump_rel": self.ri_ring_jump_rel, "max_ring_skip": self.ri_max_ring_skip}  # fmt: skip


def _check_int(field: str, value: object, low: int, high: int) -> None:
    if not isinstance(value, (int, np.integer)) or isinstance(value, bool) or not low <= value <= high:
        raise ConfigError(field, value, f"an integer, {low} <= {field} <= {high}")


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


PLANE_MAX_RANGE_M = 12.0  # floor-plane fit: points farther (horizontally) from the footprint are not used
PLANE_MAX_TILT_DEG = 3.0  # ... and a plane tilted more than this from the footprint plane is rejected
PLANE_MIN_POINTS = 30  # ... as is one supported by fewer inliers


def fit_floor_plane(
    xy_f: np.ndarray, z_f: np.ndarray, *, search_m: float = 0.1, margin_m: float = 0.03
) -> tuple[float, float, float] | None:
    """The scan's floor plane ``z = a x + b y + c`` in footprint coordinates, or None.

    Least squares on the points within ``search_m`` of the footprint plane (``|z_f| < search_m``)
    and ``PLANE_MAX_RANGE_M`` of its origin, refitted twice on the points within
    ``2 margin_m`` and then ``margin_m`` of the previous plane (so that a minority of points in
    the search band off the floor, such as ghosts mirrored just below it, does not pull the
    plane). None when fewer than ``PLANE_MIN_POINTS`` points support the last fit, or the plane
    is tilted more than ``PLANE_MAX_TILT_DEG`` or lies more than ``search_m`` from the footprint
    origin: the caller then uses the footprint plane itself.
    """
    xy = np.asarray(xy_f, dtype=float).reshape(-1, 2)
    z = np.asarray(z_f, dtype=float).reshape(-1)
    x, y = xy[:, 0], xy[:, 1]
    with np.errstate(invalid="ignore"):
        near = x * x + y * y < PLANE_MAX_RANGE_M**2
        m = near & (np.abs(z) < search_m)
    coef = None
    for tol in (2.0 * margin_m, margin_m, None):
        if np.count_nonzero(m) < PLANE_MIN_POINTS:
            return None
        A = np.column_stack([x[m], y[m], np.ones(np.count_nonzero(m))])
        coef, *_ = np.linalg.lstsq(A, z[m], rcond=None)
        if tol is not None:
            with np.errstate(invalid="ignore"):
                m = near & (np.abs(z - (coef[0] * x + coef[1] * y + coef[2])) < tol)
    a, b, c = (float(v) for v in coef)
    if math.hypot(a, b) > math.tan(math.radians(PLANE_MAX_TILT_DEG)) or abs(c) > search_m:
        return None
    return a, b, c


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


def range_image_index(points_xyz: np.ndarray, ring: np.ndarray | None) -> tuple[np.ndarray, float] | None:
    """Organise a spinning LiDAR scan as a range image of point indices.

    Rows are the rings sorted by their mean elevation (lowest first), columns the azimuth
    ``atan2(y, x)`` in steps of the scan's own azimuth resolution (the median gap between
    successive returns of a ring), with a per-ring phase so that rings fired at slightly
    different azimuths (interleaved lasers, per-laser offsets) still fall on whole columns.

    Returns ``(index, azimuth_step_rad)``: ``index`` (rows, columns) int64 with the point index
    of each cell, -1 where there is no return (two returns in one cell: the later one wins);
    None when the scan has no usable ring layout (no ring, mismatched length, fewer than two
    rings or than 8 columns, non-finite points only), so the caller falls back to knn.
    Non-finite points are left out.
    """
    p = np.asarray(points_xyz, dtype=float).reshape(-1, 3)
    if ring is None:
        return None
    ring_arr = np.asarray(ring).reshape(-1)
    if len(ring_arr) != len(p) or len(p) == 0:
        return None
    valid = np.all(np.isfinite(p), axis=1) & (np.einsum("ni,ni->n", p, p) > 1e-12)
    if ring_arr.dtype.kind == "f":
        valid &= np.isfinite(ring_arr)
    vi = np.flatnonzero(valid)
    if len(vi) < 4:
        return None
    _, rinv = np.unique(ring_arr[vi], return_inverse=True)
    rinv = rinv.reshape(-1)
    n_rows = int(rinv.max()) + 1
    if n_rows < 2:
        return None
    q = p[vi]
    az = np.arctan2(q[:, 1], q[:, 0])
    el = np.arctan2(q[:, 2], np.hypot(q[:, 0], q[:, 1]))
    mean_el = np.bincount(rinv, el, n_rows) / np.bincount(rinv, None, n_rows)  # a ring's elevation is fixed
    row_of_ring = np.empty(n_rows, dtype=np.int64)
    row_of_ring[np.argsort(mean_el, kind="stable")] = np.arange(n_rows)
    row = row_of_ring[rinv]
    o = np.argsort(row * 8.0 + az, kind="stable")  # by row, then azimuth (|az| <= pi < 4)
    gaps = np.diff(az[o])
    gaps = gaps[(row[o][1:] == row[o][:-1]) & (gaps > 1e-9)]
    if len(gaps) == 0:
        return None
    step = float(np.median(gaps))
    n_cols = int(round(2.0 * np.pi / step))
    if n_cols < 8 or n_cols > 1_000_000:
        return None
    u = az / step
    w = 2.0 * np.pi * u
    phase = np.arctan2(np.bincount(row, np.sin(w), n_rows), np.bincount(row, np.cos(w), n_rows)) / (2.0 * np.pi)
    col = np.rint(u - phase[row]).astype(np.int64) % n_cols
    index = np.full((n_rows, n_cols), -1, dtype=np.int64)
    index[row, col] = vi
    return index, step


def _unit(v: np.ndarray) -> np.ndarray:
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        return v / n


def range_image_normal_candidates(
    points_xyz: np.ndarray,
    ring: np.ndarray | None,
    *,
    col_halfwidth: int = 4,
    azimuth_jump_rel: float = 0.1,
    ring_jump_rel: float = 0.3,
    max_ring_skip: int = 2,
    min_neighbours: int = 2,
    min_sin: float = 0.2,
) -> np.ndarray | None:
    """The four one-sided range-image normals of each point, (N, 4, 3), NaN where undefined.

    Order: (left, up), (left, down), (right, up), (right, down). Side ``s`` of the azimuth
    tangent: the least-squares line through the point and its neighbours ``p[c + s j]``,
    ``j = 1..col_halfwidth``, whose range is within ``azimuth_jump_rel`` of the point's; at
    least ``min_neighbours`` such neighbours are needed. Ring tangent: to the nearest return in the ring above (below),
    in the same column or the next one on either side, at most ``max_ring_skip`` rings away,
    whose range ``r_n`` is within ``|r_n - r| <= ring_jump_rel * min(r_n, r)`` of the point's
    (returns across a depth jump are passed over); none when there is no such return.
    The normal ``t_az x t_ring`` is flipped towards the sensor (origin); NaN when the tangents
    are nearly parallel (sine of their angle below ``min_sin``). None when the scan is not
    ring-organised (:func:`range_image_index`).
    """
    p = np.asarray(points_xyz, dtype=float).reshape(-1, 3)
    organised = range_image_index(p, ring)
    if organised is None:
        return None
    index, _ = organised
    n_rows, n_cols = index.shape
    has = index >= 0
    pad = int(max_ring_skip)
    # the image in float32: half the memory traffic; a few mm of rounding at 100 m is far below range noise
    P = np.full((n_rows + 2 * pad, n_cols, 3), np.nan, dtype=np.float32)
    P[pad : pad + n_rows][has] = p[index[has]]
    rg = np.sqrt(np.einsum("rci,rci->rc", P, P))  # range image, NaN where empty
    Pc, rc = P[pad : pad + n_rows], rg[pad : pad + n_rows]

    cw = int(col_halfwidth)
    Pw = np.concatenate([Pc[:, n_cols - cw :], Pc, Pc[:, :cw]], axis=1)  # columns wrap round (360 deg)
    rw = np.concatenate([rc[:, n_cols - cw :], rc, rc[:, :cw]], axis=1)
    t_az = {}
    with np.errstate(invalid="ignore", divide="ignore"):
        tol = azimuth_jump_rel * rc
        for s in (-1, 1):
            # least-squares line through the point and its kept neighbours j on this side, in
            # coordinates relative to the point: direction sum_j (j - mean j) q_j = S_jq - S_j S_q / n
            s_q = np.zeros((n_rows, n_cols, 3), dtype=np.float32)
            s_jq = np.zeros((n_rows, n_cols, 3), dtype=np.float32)
            s_j = np.zeros((n_rows, n_cols), dtype=np.float32)
            k = np.zeros((n_rows, n_cols), dtype=np.float32)
            for j in range(1, cw + 1):
                lo = cw + s * j
                ok = np.abs(rw[:, lo : lo + n_cols] - rc) <= tol  # False where either is empty
                q = np.where(ok[..., None], Pw[:, lo : lo + n_cols] - Pc, np.float32(0.0))
                s_q += q
                s_jq += np.float32(j) * q
                s_j += np.float32(j) * ok
                k += ok
            t = s_jq - (s_j / (k + 1))[..., None] * s_q
            t[k < min_neighbours] = np.nan
            t_az[s] = s * t

        t_ring = {}
        Pr = np.concatenate([P[:, -1:], P, P[:, :1]], axis=1)  # one wrapped column each side
        rr = np.concatenate([rg[:, -1:], rg, rg[:, :1]], axis=1)
        for s in (1, -1):
            nb = np.full((n_rows, n_cols, 3), np.nan, dtype=np.float32)
            for k in range(pad, 0, -1):  # nearer rings overwrite farther ones
                r0 = pad + s * k
                for dc in (1, -1, 0):  # the same column overwrites its neighbours
                    qs = rr[r0 : r0 + n_rows, 1 + dc : 1 + dc + n_cols]
                    # a return, and no depth jump: range ratio within 1 + ring_jump_rel (False where empty)
                    m = np.abs(qs - rc) <= ring_jump_rel * np.fmin(qs, rc)
                    np.copyto(nb, Pr[r0 : r0 + n_rows, 1 + dc : 1 + dc + n_cols], where=m[..., None])
            d = s * (nb - Pc)
            t_ring[s] = d

        # the cells with a return only, as component arrays (cheaper than strided (.., 3) ops)
        idx = index[has]
        az_u = {k: _unit(v[has].astype(float)).T for k, v in t_az.items()}
        ring_u = {k: _unit(v[has].astype(float)).T for k, v in t_ring.items()}
        px, py, pz = p[idx].T
        out = np.empty((len(p), 4, 3))
        out.fill(np.nan)
        for c, (sa, sr) in enumerate(((-1, 1), (-1, -1), (1, 1), (1, -1))):
            (ax, ay, az), (bx, by, bz) = az_u[sa], ring_u[sr]
            nx, ny, nz = ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx
            sin = np.sqrt(nx * nx + ny * ny + nz * nz)
            # unit normal, NaN when the tangents are (nearly) parallel; towards the sensor: n . (0 - p) >= 0
            scale = np.where(sin > min_sin, 1.0, np.nan) / sin
            scale = np.where(nx * px + ny * py + nz * pz > 0, -scale, scale)
            out[idx, c, 0], out[idx, c, 1], out[idx, c, 2] = nx * scale, ny * scale, nz * scale
    return out


def estimate_range_image_normals(
    points_xyz: np.ndarray, ring: np.ndarray | None, *, max_spread_deg: float = 20.0, **params: float
) -> np.ndarray | None:
    """One range-image normal per point, (N, 3): the mean of the defined one-sided normals of
    :func:`range_image_normal_candidates` when they all lie within ``max_spread_deg`` of that
    mean, NaN otherwise (no side defined, or a crease / depth jump). None when the scan is not
    ring-organised."""
    cand = range_image_normal_candidates(points_xyz, ring, **params)
    if cand is None:
        return None
    defined = ~np.isnan(cand[..., 0])
    mean = _unit(np.where(defined[..., None], cand, 0.0).sum(axis=1))
    with np.errstate(invalid="ignore"):
        cos = np.einsum("nki,ni->nk", cand, mean)
        agree = np.all(~defined | (cos >= np.cos(np.radians(max_spread_deg))), axis=1) & defined.any(axis=1)
    mean[~agree] = np.nan
    return mean


def normal_cosines(normals_sensor: np.ndarray, T_footprint_sensor: np.ndarray) -> np.ndarray:
    """Eq. (4.17)-(4.18): cosine between each normal, rotated into ``f``, and ``f``'s z; (N,).

    NaN where the normal is undefined. ``(R eta)_z = R[2, :] . eta``: only the last row of the
    rotation is needed (computed without BLAS, whose idle threads cost more than the product).
    """
    r = np.asarray(T_footprint_sensor, dtype=float)[2, :3]
    eta = np.asarray(normals_sensor, dtype=float).reshape(-1, 3)
    with np.errstate(invalid="ignore", divide="ignore"):
        z = eta[:, 0] * r[0] + eta[:, 1] * r[1] + eta[:, 2] * r[2]
        return z / np.sqrt(np.einsum("ni,ni->n", eta, eta))


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
    """The ``"none"`` filter: every finite point is kept.

    Every filter's ``apply`` takes the cloud, its intensities, ``T_footprint_sensor`` and the
    optional ``ring`` of each point (used by the range-image normals only).
    """

    name = "none"

    def __init__(self, config: None = None) -> None:
        self.config = config

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

    def apply_scan(self, scan: LidarScan, T_footprint_sensor: np.ndarray | None = None) -> FilterResult:
        return self.apply(scan.points_xyz, scan.intensity, T_footprint_sensor, ring=scan.ring)


class IntensityThresholdFilter(NoFilter):
    """The plain band filter of eq. (4.15): keep ``psi in psi*``; the transform is not used."""

    name = "intensity"

    def __init__(self, config: IntensityBandConfig | None = None) -> None:
        self.config = config or IntensityBandConfig()

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

    name = "naive-ground"

    def __init__(self, config: NaiveGroundConfig | None = None) -> None:
        self.config = config or NaiveGroundConfig()

    def ground_mask(self, points_xyz: np.ndarray, T_footprint_sensor: np.ndarray) -> np.ndarray:
        """The ground test alone (eq. 4.16 read as ``ground_test`` says), (N,) bool."""
        return self.ground_mask_and_plane(points_xyz, T_footprint_sensor)[0]

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

    name = "floor-ground"

    def __init__(self, config: NaiveGroundConfig | None = None) -> None:
        super().__init__(config or FloorGroundConfig())


class NormalGroundFilter(NoFilter):
    """Eq. (4.19): keep ``psi in psi*`` or ``theta_eta > 1 - epsilon_eta``."""

    name = "normal-ground"

    def __init__(self, config: NormalGroundConfig | None = None) -> None:
        self.config = config or NormalGroundConfig()

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
                best = np.where(defined, theta, -np.inf).max(axis=1)
                return np.where(defined.any(axis=1), best, np.nan), "range-image"
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
    "none": NoFilter,
    "intensity": IntensityThresholdFilter,
    "naive-ground": NaiveGroundFilter,
    "normal-ground": NormalGroundFilter,
    "floor-ground": FloorGroundFilter,
}

_CONFIGS: dict[str, type | None] = {
    "none": None,
    "intensity": IntensityBandConfig,
    "naive-ground": NaiveGroundConfig,
    "normal-ground": NormalGroundConfig,
    "floor-ground": FloorGroundConfig,
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
