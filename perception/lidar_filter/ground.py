"""Ground tests of the ground-aware filters: heights above the footprint plane, the scan's floor plane.

The footprint ``f`` is the ground frame below the walker (z up, origin on the ground), given by
the caller as ``T_footprint_sensor`` from kinematics and trunk tilt. The thesis uses only the
translation ``^l z_f`` when the LiDAR is level and asks for the full transform when it is
tilted; ``use_full_transform=True`` (default) does that, ``False`` is eq. (4.16) literally.

The naive filter's ``ground_test``:

- ``"below"`` (naive-ground): eq. (4.16) as written, ``z_f < ground_margin_m``: *every* point
  below the footprint is ground, including the ghosts a polished floor mirrors below itself
  (the flaw the thesis names in section 5.2.2).
- ``"band"``: ``-ground_depth_m < z_f < ground_margin_m`` (a level-floor assumption; the depth
  covers the error of the kinematic footprint).
- ``"plane-band"`` (floor-ground): ``|z_f - plane| < plane_margin_m`` about the scan's own floor
  plane (:func:`fit_floor_plane`); ``"band"`` when no plane is found. It removes most of the
  ghosts mirrored just below the floor; ghosts *on* the floor plane (the floor mirrored in a
  vertical panel) remain, as no height test separates them.
"""

from __future__ import annotations

import math

import numpy as np


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


