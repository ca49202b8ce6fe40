"""Estimate types that pipelines return and scorers compare with ground truth."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np


@dataclass(frozen=True, eq=False)
class PlaneEstimate:
    """One estimated staircase surface S_id.

    Attributes:
        index: the paper's surface index (0 ground, odd risers, even treads).
        normal: unit normal, shape (3,), in the estimator frame (see StaircaseEstimate).
        centroid: centroid of the points assigned to it, shape (3,).
        n_points: points assigned from each sensor (sensor_id -> count).
        sigma_m: standard deviation of the point-to-plane distances, m.
        reliable: the paper's ``ok`` flag.
        reliable_stamp_s: time the surface first became reliable, s, or None.
    """

    index: int
    normal: np.ndarray
    centroid: np.ndarray
    n_points: dict[str, int]
    sigma_m: float
    reliable: bool
    reliable_stamp_s: float | None = None


@dataclass(frozen=True, eq=False)
class PointAssignment:
    """What the estimator did with one ToF reading.

    ``surface_index`` is the surface it ended in at the end of the episode, -1 if discarded
    (rejected by Assign, removed by SurfUpdate and not re-assigned, or never leaving the queue),
    -2 if the reading was not used (no return, NaN, no kinematic state).
    """

    stamp_s: float
    sensor_id: str
    point: np.ndarray
    surface_index: int


@dataclass(frozen=True, eq=False)
class StaircaseEstimate:
    """A staircase reconstruction.

    Coordinates are in the estimator frame ``frame_id`` = ``"stance_ground"``: axes parallel to
    the gravity-aligned world of the trunk IMU, origin on the ground directly below the ankle
    joint of the stance foot (the paper's inertial frame on the supporting foot).

    Attributes:
        planes: estimated surfaces, by index.
        riser_height_m / tread_depth_m: read-out of the geometry (NaN when unknown).
        assignments: one entry per ToF reading, in arrival order.
        stats: faulty-input counters and other diagnostics.
        compute_time_s: processing time spent per used point (s), one entry per point.
    """

    planes: tuple[PlaneEstimate, ...]
    riser_height_m: float
    tread_depth_m: float
    assignments: tuple[PointAssignment, ...] = ()
    stats: dict[str, Any] = field(default_factory=dict)
    compute_time_s: np.ndarray = field(default_factory=lambda: np.zeros(0))
    frame_id: str = "stance_ground"

    def plane(self, index: int) -> PlaneEstimate | None:
        for p in self.planes:
            if p.index == index:
                return p
        return None
