"""An episode: the frames a pipeline sees, and apart from them the ground truth the harness keeps."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .calibration import Calibration
from .frames import Frame
from .truth import LidarTruth, SceneTruth, StepTruth, ToFTruth


@dataclass(frozen=True, eq=False)
class EpisodeTruth:
    """Ground truth of one simulated episode.

    Attributes:
        scene: static truth of the world (surfaces, geom map, builder parameters).
        tof: one entry per emitted ToF frame, in the same order as the ToF frames.
        T_world_estimator: pose in the world of the staircase estimator's frame
            (``"stance_ground"``: origin on the ground below the stance ankle, world-parallel axes).
        stance_side: ``"l"`` or ``"r"``, the supporting foot during the climbing step.
        touchdown_w: the climbing foot's sole point below the ankle at touch-down, world, (3,).
        foot_track_w: climbing foot's sole point over time, (N, 4) rows ``[t, x, y, z]``.
        body_tracks: link poses over time for visualisation, name -> (N, 8) rows
            ``[t, x, y, z, qw, qx, qy, qz]``.
        max_penetration_m: deepest foot-world penetration seen over the episode (0 if none).
        events: named times, s (e.g. ``"liftoff_s"``, ``"touchdown_s"``).
        lidar: one :class:`LidarTruth` per emitted LiDAR scan, in the same order as the LiDAR
            frames (empty when the episode has no LiDAR).
        trajectory_w: LiDAR sensor pose at the start of each emitted scan, (N, 8) rows
            ``[t, x, y, z, qw, qx, qy, qz]`` (empty when the episode has no LiDAR).
        steps: every step of the walk with its locomotion mode (empty when not relevant).
        extra: track-specific truth (e.g. pedestrian tracks, camera poses), plain values/arrays.
    """

    scene: SceneTruth
    tof: tuple[ToFTruth, ...]
    T_world_estimator: np.ndarray
    stance_side: str
    touchdown_w: np.ndarray
    foot_track_w: np.ndarray
    body_tracks: dict[str, np.ndarray] = field(default_factory=dict)
    max_penetration_m: float = 0.0
    events: dict[str, float] = field(default_factory=dict)
    lidar: tuple[LidarTruth, ...] = ()
    trajectory_w: np.ndarray = field(default_factory=lambda: np.zeros((0, 8)))
    steps: tuple[StepTruth, ...] = ()
    extra: dict[str, Any] = field(default_factory=dict)


@dataclass(frozen=True, eq=False)
class Episode:
    """A complete episode.

    Attributes:
        scenario: validated scenario parameters (plain values), e.g. riser_m, yaw_deg.
        seed: the scenario seed every random stream was derived from.
        calibration: what pipelines may know about the device.
        frames: every frame, time-ordered (ties broken by a fixed sensor order).
        truth: ground truth, for the harness only.
    """

    scenario: dict[str, Any]
    seed: int
    calibration: Calibration
    frames: tuple[Frame, ...]
    truth: EpisodeTruth
