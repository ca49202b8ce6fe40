"""Estimate types that pipelines return and scorers compare with ground truth."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .counters import FrameCounts


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
        scatter: ``sum (p - centroid)(p - centroid)^T`` of the plane's points, shape (3, 3), when
            the estimator fits a general plane and keeps it (None otherwise): lets a read-out
            pool the points of several planes (``riser_at="parallel"``).
    """

    index: int
    normal: np.ndarray
    centroid: np.ndarray
    n_points: dict[str, int]
    sigma_m: float
    reliable: bool
    reliable_stamp_s: float | None = None
    scatter: np.ndarray | None = None


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
        stats: diagnostics (no-return readings, readings before any state, the algorithm's own).
        compute_time_s: processing time spent per used point (s), one entry per point.
        counts: the input counters by frame kind (:mod:`exobench.core.counters`).
    """

    planes: tuple[PlaneEstimate, ...]
    riser_height_m: float
    tread_depth_m: float
    assignments: tuple[PointAssignment, ...] = ()
    stats: dict[str, Any] = field(default_factory=dict)
    compute_time_s: np.ndarray = field(default_factory=lambda: np.zeros(0))
    frame_id: str = "stance_ground"
    counts: dict[str, FrameCounts] = field(default_factory=dict)

    def plane(self, index: int) -> PlaneEstimate | None:
        for p in self.planes:
            if p.index == index:
                return p
        return None


LOCOMOTION_MODES = ("LG", "SA", "SD", "RA", "RD")  # level ground, stair/ramp ascent/descent


@dataclass(frozen=True, eq=False)
class ModePrediction:
    """The locomotion mode predicted for the next step, at one instant.

    Attributes:
        stamp_s: time of the input frame the prediction was made on, s.
        mode: one of :data:`LOCOMOTION_MODES`, or ``""`` when the pipeline has none yet.
        footprint_odom: predicted footprint of the next step in the odometry frame, (3,)
            (NaN when unknown).
        strike_index: number of heel strikes the pipeline had seen when it predicted (the
            prediction is for the step after the last of them).
        latency_s: compute time of this prediction (frame in -> mode out), s.
        status: ``"ok"``, or why the pipeline kept its last state (``"no_depth"``,
            ``"dropped"``, ``"no_odometry"``, ...).
        T_odom_camera: the camera pose the prediction was made with, in the odometry frame,
            (4, 4); None when it had none.
    """

    stamp_s: float
    mode: str
    footprint_odom: np.ndarray
    strike_index: int
    latency_s: float
    status: str = "ok"
    T_odom_camera: np.ndarray | None = None


@dataclass(frozen=True, eq=False)
class LocomotionEstimate:
    """Locomotion-mode predictions over an episode (track ``locomotion``).

    Attributes:
        predictions: one per processed camera frame, time-ordered.
        planes: the final plane set, each a dict with ``id``, ``normal``, ``centroid`` (odometry
            frame), ``kind`` and ``score`` (for reports and rerun).
        stats: diagnostics (statuses, strikes, ...).
        counts: the input counters by frame kind (:mod:`exobench.core.counters`).
        odometry: the frame of the footprints and planes: ``"given"``, the odometry stream's of
            the episode; any other name (e.g. ``"dvio"``), the pipeline's own odometry's, known
            to a scorer only through the predictions' ``T_odom_camera``.
    """

    predictions: tuple[ModePrediction, ...]
    planes: tuple[dict[str, Any], ...] = ()
    stats: dict[str, Any] = field(default_factory=dict)
    counts: dict[str, FrameCounts] = field(default_factory=dict)
    odometry: str = "given"


@dataclass(frozen=True, eq=False)
class TrajectoryEstimate:
    """An estimated sensor trajectory (track ``odometry``, and ``lidar-filter`` through odometry).

    Attributes:
        stamps_s: time of each pose, s, (N,) (the scan's ``sweep_start_s`` for LiDAR).
        T_world_sensor: poses of the sensor in the estimator's world frame (its first pose is
            usually the identity), (N, 4, 4).
        time_per_scan_s: processing time of each input scan, s, (N,).
        loop_edges: detected loop closures, pairs of pose indices ``(i, j)`` (may be empty).
        status: per-pose status (``"ok"``, ``"empty_scan"``, ``"lost"``, ...), length N.
        stats: diagnostics (failures, keyframes, submaps, ...).
        map_points: the final (corrected) map in the estimator frame, (M, 3), optional.
        counts: the input counters by frame kind (:mod:`exobench.core.counters`).
    """

    stamps_s: np.ndarray
    T_world_sensor: np.ndarray
    time_per_scan_s: np.ndarray
    loop_edges: tuple[tuple[int, int], ...] = ()
    status: tuple[str, ...] = ()
    stats: dict[str, Any] = field(default_factory=dict)
    map_points: np.ndarray | None = None
    counts: dict[str, FrameCounts] = field(default_factory=dict)


@dataclass(frozen=True, eq=False)
class FilterEstimate:
    """What an intensity filter kept of each scan (track ``lidar-filter``).

    Attributes:
        stamps_s: the scan stamps, (N,).
        keep: one boolean mask per scan over its points, in the scan's point order.
        time_per_scan_s: processing time of each scan, s, (N,).
        stats: the filter's counters (empty scans, ...).
        counts: the input counters by frame kind (:mod:`exobench.core.counters`).
    """

    stamps_s: np.ndarray
    keep: tuple[np.ndarray, ...]
    time_per_scan_s: np.ndarray
    stats: dict[str, Any] = field(default_factory=dict)
    counts: dict[str, FrameCounts] = field(default_factory=dict)


@dataclass(frozen=True, eq=False)
class PlaceRecognitionEstimate:
    """Place-recognition results over the keyframes of an episode (track ``loop-closure``).

    Attributes:
        stamps_s: time of each keyframe (a scan, or the last scan of a submap), (K,).
        match_index: best database match of each keyframe among earlier, non-recent keyframes,
            -1 when there is none, (K,) int.
        distance: descriptor distance of that match (lower is more similar; inf when none), (K,).
        yaw_rad: relative yaw from the column-shift alignment, (K,).
        time_per_keyframe_s: description + query time per keyframe, s, (K,).
        stats: diagnostics.
        counts: the input counters by frame kind (:mod:`exobench.core.counters`).
    """

    stamps_s: np.ndarray
    match_index: np.ndarray
    distance: np.ndarray
    yaw_rad: np.ndarray
    time_per_keyframe_s: np.ndarray
    stats: dict[str, Any] = field(default_factory=dict)
    counts: dict[str, FrameCounts] = field(default_factory=dict)


@dataclass(frozen=True, eq=False)
class MultiSessionEstimate:
    """Sessions merged into one map, with the changes found between them (track ``multisession``).

    Attributes:
        sessions: session ids in episode order.
        days: the day of each session (from its mark).
        keyframe_stamps_s: per session, the stamps of its keyframes, (K_s,).
        T_map_cam: per session, its keyframes' camera poses in the frame of the map it belongs
            to, (K_s, 4, 4); the main map's frame is session ``sessions[0]``'s odometry frame.
        map_of_session: per session, the index of its map (0: the main map, anchored at the
            first session; others: sessions that overlap none of the main map's, or that no
            two agreeing inter-session edges join to it).
        separate_sessions: the sessions outside the main map (kept as their own maps, never
            forced into it).
        inter_edges: inter-session edges ``(session_a, keyframe_a, session_b, keyframe_b)``.
        change_pairs: ``(prior_last_session, session)`` of each change detection run: the
            session against the main map updated by the sessions before it.
        removed_points / added_points: per change pair, the points found removed (prior points
            where the session saw free space) and added (map frame, m), (N, 3) each.
        static_masks: per change pair, (N,) bool over ``map_points_no_change_detection``: the
            points of the updated map not flagged (a mask, not the points: the updated map of
            the k-th run holds k sessions, so copies would grow with the square of the sessions).
        merged_map_points: the final map after change detection (eq. 3), (N, 3) m.
        map_points_no_change_detection: every session's points of the main map at the merged
            poses, unfiltered, session after session.
        map_points_single_session: the last session of the main map alone, at its merged poses.
        merge_time_s: place recognition, merging and change detection, s (wall time).
        peak_memory_mb: the pipeline's peak traced allocations while merging, MB.
        stats: diagnostics (keyframes, edges, vocabulary size, ...).
        counts: the input counters by frame kind (:mod:`exobench.core.counters`).
    """

    sessions: tuple[int, ...]
    days: tuple[int, ...]
    keyframe_stamps_s: tuple[np.ndarray, ...]
    T_map_cam: tuple[np.ndarray, ...]
    map_of_session: tuple[int, ...]
    separate_sessions: tuple[int, ...] = ()
    inter_edges: tuple[tuple[int, int, int, int], ...] = ()
    change_pairs: tuple[tuple[int, int], ...] = ()
    removed_points: tuple[np.ndarray, ...] = ()
    added_points: tuple[np.ndarray, ...] = ()
    static_masks: tuple[np.ndarray, ...] = ()
    merged_map_points: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    map_points_no_change_detection: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    map_points_single_session: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    merge_time_s: float = float("nan")
    peak_memory_mb: float = float("nan")
    stats: dict[str, Any] = field(default_factory=dict)
    counts: dict[str, FrameCounts] = field(default_factory=dict)
