"""An episode: the frames a pipeline sees, and apart from them the ground truth the harness keeps."""

from __future__ import annotations

from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .calibration import Calibration
from .frames import Frame
from .truth import LidarTruth, SceneTruth, SegmentationTruth, StairTruth, StepTruth


@dataclass(frozen=True, eq=False)
class EpisodeTruth:
    """Ground truth of one simulated episode: what every walk has, and typed parts that an
    episode carries only when its world and sensors produce them.

    Attributes:
        scene: static truth of the world (surfaces, geom map, builder parameters).
        T_world_estimator: pose in the world of the frame the track's estimates are expressed in
            (stairs: ``"stance_ground"``, origin on the ground below the stance ankle with
            world-parallel axes; office walks: the LiDAR at t = 0; courses: the odometry frame).
        body_tracks: link and sensor poses over time, name -> (N, 8) rows
            ``[t, x, y, z, qw, qx, qy, qz]``.
        max_penetration_m: deepest foot-world penetration seen over the episode (0 if none).
        events: named times, s (e.g. ``"liftoff_s"``, ``"touchdown_s"``).
        stairs: the climbing step's truth (:class:`StairTruth`); None when the episode is not
            the staircase paper's climbing step.
        lidar: one :class:`LidarTruth` per emitted LiDAR scan, in the same order as the LiDAR
            frames (empty when the episode has no LiDAR).
        trajectory_w: pose of the track's reference sensor at each of its frames (the LiDAR at
            the start of each scan, the camera at each image), (N, 8) rows as ``body_tracks``
            (empty when the episode has none).
        steps: every step of the walk with its locomotion mode (empty when not labelled).
        segmentation: one :class:`SegmentationTruth` per emitted RGB-D frame of the cameras that
            record it (``RgbdConfig.segmentation_truth``; the scenarios' ``segmentation_truth``),
            in the same order as those frames (empty when no camera records it).
        extra: track-specific truth (e.g. pedestrian tracks, camera poses), plain values/arrays.
        lidar_scans: a streamed episode's LiDAR scans with their (compact) truth, in frame
            order, read back one at a time from where the harness spooled them (a sequence of
            ``(LidarScan, LidarTruth)``, see ``exobench.benchmarks.tracks.scan_spool``); None
            when ``Episode.frames`` and ``lidar`` hold them, or nothing scores them.
    """

    scene: SceneTruth
    T_world_estimator: np.ndarray
    body_tracks: dict[str, np.ndarray] = field(default_factory=dict)
    max_penetration_m: float = 0.0
    events: dict[str, float] = field(default_factory=dict)
    stairs: StairTruth | None = None
    lidar: tuple[LidarTruth, ...] = ()
    trajectory_w: np.ndarray = field(default_factory=lambda: np.zeros((0, 8)))
    steps: tuple[StepTruth, ...] = ()
    segmentation: tuple[SegmentationTruth, ...] = ()
    extra: dict[str, Any] = field(default_factory=dict)
    lidar_scans: Sequence[tuple[Any, Any]] | None = None


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


@dataclass(eq=False)
class EpisodeStream:
    """An episode whose frames are handed out as the simulation produces them (a long walk is
    never held whole).

    Attributes:
        scenario, seed, calibration: as in :class:`Episode`, known before the first frame.
        frames: every frame, time-ordered as :attr:`Episode.frames`; one pass.
        make_episode: called (by :meth:`finish`, once) when ``frames`` is exhausted: the
            :class:`Episode` with its truth (its ``frames`` holds only what the producer kept,
            usually nothing).
    """

    scenario: dict[str, Any]
    seed: int
    calibration: Calibration
    frames: Iterator[Frame]
    make_episode: Callable[[], Episode]
    _episode: Episode | None = field(default=None, repr=False)

    def finish(self) -> Episode:
        """The episode, once every frame has been read (the same object on every call)."""
        if self._episode is None:
            self._episode = self.make_episode()
        return self._episode
