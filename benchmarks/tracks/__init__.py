"""The tracks of the benchmark: one folder per perception problem, found through a registry.

- ``spec``: the :class:`~exobench.benchmarks.tracks.spec.Track` protocol and its records.
- ``registry``: track names -> classes (built-ins and the ``exobench.tracks`` entry points);
  :func:`get_track` and :func:`track_names` are re-exported here.
- ``stairs/``, ``locomotion/``, ``lidar_filter/``, ``odometry/``, ``loop_closure/``: the tracks.
- ``office_walks``, ``lidar_trajectory``, ``office_recording``: what the three office LiDAR
  tracks share (scenario helpers and per-point truth, scoring of a LiDAR trajectory, rerun views).
"""

from __future__ import annotations

from .registry import get_track, track_names

__all__ = ["get_track", "track_names"]
