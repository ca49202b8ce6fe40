"""Tracks of the benchmark, by name (string entry points; a track is imported on first use)."""

from __future__ import annotations

import functools
from typing import Any

TRACKS: dict[str, str] = {
    "stairs": "exobench.benchmarks.tracks.stairs:StairsTrack",
    "lidar-filter": "exobench.benchmarks.tracks.lidar_filter:LidarFilterTrack",
    "odometry": "exobench.benchmarks.tracks.odometry:OdometryTrack",
    "locomotion": "exobench.benchmarks.tracks.locomotion:LocomotionTrack",
    "loop-closure": "exobench.benchmarks.tracks.loop_closure:LoopClosureTrack",
}


@functools.cache
def get_track(name: str) -> Any:
    """The track instance called ``name``; UnknownNameError lists the valid ones."""
    from exobench.benchmarks.registry import load_entry_point
    from exobench.core.errors import UnknownNameError

    if name not in TRACKS:
        raise UnknownNameError("track", name, TRACKS)
    return load_entry_point(TRACKS[name])()


def track_names() -> list[str]:
    return sorted(TRACKS)
