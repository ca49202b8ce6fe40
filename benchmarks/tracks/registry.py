"""Track registry: names -> track classes, found by string entry points, tagged by stream kind.

Built on :class:`~exobench.benchmarks.entry_points.EntryPointRegistry`, as the pipeline
registry is: registering imports nothing, a track is imported the first time it is asked for, a
name can be registered once only, an unknown name raises :class:`UnknownNameError` listing the
valid ones. exobench's own tracks are built in; any installed package adds its own through the
``exobench.tracks`` entry-point group::

    [project.entry-points."exobench.tracks"]
    my-track = "my_package.my_track:MyTrack"

A registered class must satisfy :class:`~exobench.benchmarks.tracks.spec.Track` and build with
no arguments; the harness uses one instance per track and process (:meth:`TrackRegistry.get`).
"""

from __future__ import annotations

import functools
from typing import Any

from exobench.core.errors import ConfigError

from ..entry_points import EntryPointRegistry
from .spec import Track

ENTRY_POINT_GROUP = "exobench.tracks"

# name -> (entry point, tags: the frame kinds its pipelines receive)
BUILTIN_TRACKS: dict[str, tuple[str, tuple[str, ...]]] = {
    "stairs": ("exobench.benchmarks.tracks.stairs:StairsTrack", ("tof", "imu", "joints", "contact")),
    "lidar-filter": ("exobench.benchmarks.tracks.lidar_filter:LidarFilterTrack", ("lidar", "imu", "joints", "contact")),
    "odometry": ("exobench.benchmarks.tracks.odometry:OdometryTrack", ("lidar", "imu", "joints", "contact")),
    "locomotion": ("exobench.benchmarks.tracks.locomotion:LocomotionTrack", ("rgbd", "imu", "contact", "odometry")),
    "loop-closure": ("exobench.benchmarks.tracks.loop_closure:LoopClosureTrack", ("lidar", "imu", "joints", "contact")),
    "vio": ("exobench.benchmarks.tracks.vio:VioTrack", ("rgbd", "imu")),
    "multisession": ("exobench.benchmarks.tracks.multisession:MultisessionTrack",
                     ("session", "place_label", "rgbd", "imu", "odometry")),
}


def track_members() -> tuple[str, ...]:
    """The members of the :class:`~.spec.Track` protocol: its attributes, then its methods."""
    attrs = [n for n in Track.__annotations__ if not n.startswith("_")]
    methods = [n for n, v in vars(Track).items() if callable(v) and not n.startswith("_") and n not in attrs]
    return (*attrs, *methods)


def check_track_class(name: str, cls: Any) -> type:
    """Raise ConfigError unless ``cls`` is a class with the members of the Track protocol; the
    message names the members it lacks."""
    allowed = "a class with the members of exobench.benchmarks.tracks.spec.Track"
    if not isinstance(cls, type):
        raise ConfigError(f"track {name!r}", cls, allowed)
    missing = [m for m in track_members() if not hasattr(cls, m)]
    if missing or not isinstance(cls, Track):
        raise ConfigError(f"track {name!r}", cls, f"{allowed}; it lacks {', '.join(missing)}")
    return cls


class TrackRegistry(EntryPointRegistry):
    """Tracks by name. Entries are strings until first use; one instance per track."""

    def __init__(self) -> None:
        super().__init__("track", check_track_class)
        self._instances: dict[str, Any] = {}

    def register(self, name: str, entry_point: str | type, *, tags: tuple[str, ...] | None = None, source: str = "user") -> None:
        """Add a track under ``name``; a class registered directly is tagged with its ``streams``
        unless ``tags`` is given."""
        if tags is None:
            tags = tuple(getattr(entry_point, "streams", ())) if isinstance(entry_point, type) else ()
        super().register(name, entry_point, tags=tags, source=source)

    def names(self, tag: str | None = None) -> list[str]:
        """Registered names in registration order; with ``tag``, only the tracks carrying it
        (untagged entries are imported to read their ``streams``)."""
        if tag is None:
            return super().names()
        return [n for n in super().names() if tag in (self.entry(n).tags or self.load(n).streams)]

    def get(self, name: str) -> Any:
        """The track instance called ``name`` (built on first use, then kept)."""
        if name not in self._instances:
            self._instances[name] = self.load(name)()
        return self._instances[name]


def build_track_registry(*, entry_points: bool = True) -> TrackRegistry:
    """A registry with the built-in tracks and those of the ``exobench.tracks`` group."""
    reg = TrackRegistry()
    for name, (ep, tags) in BUILTIN_TRACKS.items():
        reg.register(name, ep, tags=tags, source="builtin")
    if entry_points:
        reg.add_group(ENTRY_POINT_GROUP)
    return reg


@functools.lru_cache(maxsize=1)
def default_track_registry() -> TrackRegistry:
    """The process-wide track registry (built once; ``default_track_registry.cache_clear()`` rebuilds it)."""
    return build_track_registry()


def get_track(name: str) -> Any:
    """The track instance called ``name``; UnknownNameError lists the valid ones."""
    return default_track_registry().get(name)


def track_names(tag: str | None = None) -> list[str]:
    """Names of the registered tracks, sorted; with ``tag``, only those carrying it."""
    return sorted(default_track_registry().names(tag))
