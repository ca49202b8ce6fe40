"""What a sensor cannot have measured: the limits beyond which a value is absurd.

A value outside what the sensor can physically report is not noise but a broken driver, a unit
error or a flipped bit (a range of 1e308, 0 or 1e6 m, a LiDAR point at the origin). Pipelines
skip such values and count them in their stats. The limits come from the calibration a pipeline
receives in ``reset`` (the mount's ``params`` and the robot description); a limit the
calibration does not give falls back to a bound no real device reaches. Per frame kind:

- ToF range (status VALID, finite): not above 0, or more than ``margin`` outside the mount's
  ``[min_range_m, max_range_m]``, where ``margin`` = 6 ``noise_sigma_m`` + ``resolution_m`` (the
  noise is added after the sensor's own range check, so a good reading may lie a little
  outside); without limits in the calibration, ``(0, FALLBACK_MAX_RANGE_M]``;
- LiDAR point (finite): its distance from the sensor more than ``margin`` outside the mount's
  ``[min_range_m, max_range_m]`` (a point at the origin is absurd whenever ``min_range_m`` >
  ``margin``, and always when it is exactly 0: a return has a length); non-finite points are
  NaN points, counted apart;
- RGB-D depth pixel (finite): negative, or above the mount's ``max_depth_m`` + ``margin``
  (0 is the invalid value, not absurd);
- IMU sample: a non-finite value, a quaternion of norm outside ``(0.5, 1.5)``, an angular rate
  above :data:`MAX_GYRO_RAD_S` or a specific force above :data:`MAX_ACCEL_M_S2`;
- joint state: a non-finite angle, or one beyond its URDF ``<limit>`` by more than
  :data:`JOINT_LIMIT_MARGIN_RAD` (joints without a limit: only non-finite);
- contact sample (finite): a negative force or one above :data:`MAX_FORCE_N`;
- odometry sample (finite): a translation beyond :data:`FALLBACK_MAX_RANGE_M` on any axis.

A pipeline counts the frames it skips for such values as ``absurd`` and those with non-finite
values as ``nan`` (:mod:`exobench.core.counters`).
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from typing import Any

import numpy as np

from .calibration import Calibration, SensorMount
from .frames import ContactSample, ImuSample, JointState, OdometrySample

FALLBACK_MAX_RANGE_M = 1e4  # no ranging sensor of a wearable device reports 10 km
MAX_GYRO_RAD_S = 1e3  # ~57 000 deg/s; MEMS gyroscopes saturate below 100 rad/s
MAX_ACCEL_M_S2 = 1e4  # ~1000 g; MEMS accelerometers saturate below 2000 m/s^2
JOINT_LIMIT_MARGIN_RAD = 0.5
MAX_FORCE_N = 1e5  # ~10 t: no insole pad under a foot reports it
NOISE_SIGMAS = 6.0


def finite_rows(points_xyz: np.ndarray) -> np.ndarray:
    """(N,) bool: the rows of an (N, 3) array whose three values are all finite.

    ``np.all(np.isfinite(p), axis=1)`` gives the same mask, but a reduction along an axis of
    three is slow in numpy: 1 ms against 0.06 ms for a VLP-16 scan, and every pipeline of a
    LiDAR track takes it several times per scan."""
    p = np.asarray(points_xyz, dtype=float).reshape(-1, 3)
    return np.isfinite(p[:, 0]) & np.isfinite(p[:, 1]) & np.isfinite(p[:, 2])


def _param(mount: SensorMount | None, key: str, default: float) -> float:
    if mount is None:
        return default
    try:
        x = float(mount.params.get(key, default))
    except (TypeError, ValueError):
        return default
    return x if math.isfinite(x) else default


def _margin(mount: SensorMount | None) -> float:
    return NOISE_SIGMAS * max(_param(mount, "noise_sigma_m", 0.0), 0.0) + max(_param(mount, "resolution_m", 0.0), 0.0)


@dataclass(frozen=True)
class RangeLimits:
    """The ranges a ToF or LiDAR mount can report: ``low_m <= r <= high_m`` and ``r > 0``."""

    low_m: float = 0.0
    high_m: float = FALLBACK_MAX_RANGE_M

    @classmethod
    def of_mount(cls, mount: SensorMount | None) -> RangeLimits:
        """From the mount's ``min_range_m``, ``max_range_m``, ``noise_sigma_m`` and ``resolution_m``."""
        m = _margin(mount)
        hi = _param(mount, "max_range_m", math.nan)
        lo = _param(mount, "min_range_m", 0.0)
        return cls(low_m=lo - m, high_m=hi + m if math.isfinite(hi) and hi > 0 else FALLBACK_MAX_RANGE_M)

    def absurd(self, r: float) -> bool:
        """Whether a finite range ``r`` cannot have been measured (NaN is not absurd: it is NaN)."""
        return not (r > 0.0 and self.low_m <= r <= self.high_m) and r == r

    def absurd_points(self, points_xyz: np.ndarray) -> np.ndarray:
        """Mask of the finite points of an (N, 3) array whose distance from the sensor is absurd."""
        p = np.asarray(points_xyz, dtype=float).reshape(-1, 3)
        with np.errstate(over="ignore", invalid="ignore"):
            r = np.sqrt(np.einsum("ni,ni->n", p, p))
        finite = finite_rows(p)
        return finite & ~((r > 0.0) & (r >= self.low_m) & (r <= self.high_m))


def scrub_points(points_xyz: np.ndarray, limits: RangeLimits) -> tuple[np.ndarray, int]:
    """``(points, n)``: the (N, 3) points with the ``n`` absurd ones set to NaN (the array as
    given, not copied, when there is none), so that a consumer drops them as it drops NaN."""
    bad = limits.absurd_points(points_xyz)
    n = int(np.count_nonzero(bad))
    if not n:
        return points_xyz, 0
    p = np.array(points_xyz, dtype=float).reshape(-1, 3)
    p[bad] = np.nan
    return p, n


def max_depth_m(mount: SensorMount | None) -> float:
    """The largest depth a camera mount can report (its ``max_depth_m`` plus margin)."""
    hi = _param(mount, "max_depth_m", math.nan)
    return hi + _margin(mount) if math.isfinite(hi) and hi > 0 else FALLBACK_MAX_RANGE_M


def absurd_depth(depth_m: np.ndarray, high_m: float) -> np.ndarray:
    """Mask of the finite pixels of a depth image that are negative or beyond ``high_m``."""
    d = np.asarray(depth_m)
    with np.errstate(invalid="ignore"):
        return np.isfinite(d) & ((d < 0) | (d > high_m))


def _floats(values: Any) -> list[float]:
    a = np.asarray(values, dtype=float)
    return a.ravel().tolist()


def imu_absurd(frame: ImuSample) -> bool:
    """Whether an IMU sample holds a non-finite value or one no IMU can report (module docstring)."""
    try:
        q, w, a = _floats(frame.quat_wxyz), _floats(frame.gyro_rad_s), _floats(frame.accel_m_s2)
    except (TypeError, ValueError):
        return True
    if len(q) != 4 or len(w) != 3 or len(a) != 3 or not all(map(math.isfinite, q + w + a)):
        return True
    return not 0.5 < math.hypot(*q) < 1.5 or math.hypot(*w) > MAX_GYRO_RAD_S or math.hypot(*a) > MAX_ACCEL_M_S2


def contact_absurd(frame: ContactSample) -> bool:
    """Whether a contact sample's finite force is negative or above :data:`MAX_FORCE_N`."""
    try:
        f = float(frame.force_n)
    except (TypeError, ValueError):
        return False
    return math.isfinite(f) and not 0.0 <= f <= MAX_FORCE_N


def odometry_absurd(frame: OdometrySample) -> bool:
    """Whether an odometry pose has a finite translation beyond :data:`FALLBACK_MAX_RANGE_M`."""
    try:
        p = np.asarray(frame.T_odom_body, dtype=float)[:3, 3]
    except (TypeError, ValueError, IndexError):
        return False
    return bool(np.all(np.isfinite(p)) and np.any(np.abs(p) > FALLBACK_MAX_RANGE_M))


def urdf_joint_limits(urdf: str) -> dict[str, tuple[float, float]]:
    """Joint name -> (lower, upper), rad, of the joints of a URDF with a ``<limit>`` (none if unreadable)."""
    out: dict[str, tuple[float, float]] = {}
    try:
        root = ET.fromstring(urdf)
    except (ET.ParseError, TypeError, ValueError):
        return out
    for j in root.iter("joint"):
        lim = j.find("limit")
        if lim is None or j.get("type") not in ("revolute", "prismatic") or "lower" not in lim.attrib:
            continue
        try:
            lo, hi = float(lim.get("lower", "nan")), float(lim.get("upper", "nan"))
        except ValueError:
            continue
        if math.isfinite(lo) and math.isfinite(hi) and lo <= hi:
            out[str(j.get("name"))] = (lo, hi)
    return out


class JointLimits:
    """The joint angles an encoder state can hold, from the calibration's URDF."""

    def __init__(self, calibration: Calibration | None) -> None:
        lim = urdf_joint_limits(calibration.robot_urdf) if calibration is not None else {}
        self._limits = {n: (lo - JOINT_LIMIT_MARGIN_RAD, hi + JOINT_LIMIT_MARGIN_RAD) for n, (lo, hi) in lim.items()}
        self._cache: tuple[tuple[str, ...], list[tuple[float, float]]] | None = None

    def _bounds(self, names: tuple[str, ...]) -> list[tuple[float, float]]:
        if self._cache is None or self._cache[0] != names:
            inf = math.inf
            self._cache = (names, [self._limits.get(n, (-inf, inf)) for n in names])
        return self._cache[1]

    def absurd(self, frame: JointState) -> bool:
        """Whether an encoder state has a non-finite angle or one beyond its joint's limit."""
        try:
            q = _floats(frame.position_rad)
        except (TypeError, ValueError):
            return True
        names = tuple(frame.names)
        if len(q) != len(names):
            return True
        return not all(math.isfinite(x) and lo <= x <= hi for x, (lo, hi) in zip(q, self._bounds(names)))
