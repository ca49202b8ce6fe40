"""Pipeline registry: names -> pipeline classes, found by string entry points.

An :class:`~exobench.benchmarks.entry_points.EntryPointRegistry` tagged by track: registering
imports nothing, a class is imported the first time it is asked for, a name can be registered
once only, and an unknown name raises :class:`UnknownNameError` listing the valid ones.
exobench's own pipelines are built in; any installed package adds its own through the
``exobench.pipelines`` entry-point group::

    [project.entry-points."exobench.pipelines"]
    my-stairs = "my_package.stairs:MyStairs"

A registered class must satisfy :class:`exobench.core.Pipeline` and carry a ``Config``
dataclass whose fields all have defaults.
"""

from __future__ import annotations

import dataclasses
import functools
from dataclasses import dataclass
from typing import Any

from exobench.core.errors import ConfigError
from exobench.core.pipeline import Pipeline, config_from_dict

from .entry_points import EntryPointRegistry

ENTRY_POINT_GROUP = "exobench.pipelines"

# name -> (entry point, track); the track tag lets `exobench run` pick a track's pipelines
# without importing them
BUILTIN_PIPELINES: dict[str, tuple[str, str]] = {
    "rtls": ("exobench.perception.stairs.rtls_pipeline:RtlsStairs", "stairs"),
    "rtls-htvr": ("exobench.perception.stairs.rtls_pipeline:RtlsHtvrStairs", "stairs"),
    "batch-ransac": ("exobench.perception.stairs.batch_ransac:BatchRansacStairs", "stairs"),
    "filter-none": ("exobench.perception.lidar_filter.pipelines:FilterNone", "lidar-filter"),
    "filter-threshold": ("exobench.perception.lidar_filter.pipelines:FilterThreshold", "lidar-filter"),
    "filter-naive-ground": ("exobench.perception.lidar_filter.pipelines:FilterNaiveGround", "lidar-filter"),
    "filter-normal-ground": ("exobench.perception.lidar_filter.pipelines:FilterNormalGround", "lidar-filter"),
    "filter-floor-ground": ("exobench.perception.lidar_filter.pipelines:FilterFloorGround", "lidar-filter"),
    "kiss-icp": ("exobench.mapping.odometry.kiss_icp:KissIcpPipeline", "odometry"),
    "leo-slam": ("exobench.mapping.odometry.leo_slam:LeoSlamPipeline", "odometry"),
    "sc++": ("exobench.perception.place_recognition.pipelines:ScanContextPPPipeline", "loop-closure"),
    "gsc-height": ("exobench.perception.place_recognition.pipelines:GscHeightPipeline", "loop-closure"),
    "gsc-huber": ("exobench.perception.place_recognition.pipelines:GscHuberPipeline", "loop-closure"),
    "gsc-intensity": ("exobench.perception.place_recognition.pipelines:GscIntensityPipeline", "loop-closure"),
    "terrain-recon": ("exobench.mapping.locomotion.pipelines:TerrainReconstructionPipeline", "locomotion"),
    "single-frame": ("exobench.mapping.locomotion.pipelines:SingleFramePipeline", "locomotion"),
    "lt-exosense": ("exobench.mapping.multisession.pipeline:LtExosense", "multisession"),
    "lt-exosense-dufomap": ("exobench.mapping.multisession.pipeline:LtExosenseDufomap", "multisession"),
}


@dataclass(frozen=True)
class PipelineSpec:
    """One registry entry.

    Attributes:
        name: registry name, e.g. ``"rtls"``.
        entry_point: ``"module:attribute"`` of the pipeline class.
        track: the track it serves if known without importing it, else None.
        source: ``"builtin"``, ``"entry-point"`` or ``"user"`` (registered in code).
    """

    name: str
    entry_point: str
    track: str | None = None
    source: str = "builtin"


def check_pipeline_class(name: str, cls: Any) -> type:
    """Raise ConfigError unless ``cls`` is a pipeline class with a defaulted ``Config``."""
    if not isinstance(cls, type) or not isinstance(cls, Pipeline):
        raise ConfigError(f"pipeline {name!r}", cls, "a class with name, track, reset, process, finalize")
    config = getattr(cls, "Config", None)
    if not (isinstance(config, type) and dataclasses.is_dataclass(config)):
        raise ConfigError(f"pipeline {name!r}.Config", config, "a dataclass")
    try:
        config()
    except TypeError as e:
        raise ConfigError(f"pipeline {name!r}.Config", config, f"every field with a default ({e})") from None
    return cls


class PipelineRegistry(EntryPointRegistry):
    """Pipelines by name, tagged with the track they serve. Entries are strings until first use."""

    def __init__(self) -> None:
        super().__init__("pipeline", check_pipeline_class)

    def register(self, name: str, entry_point: str | type, *, track: str | None = None, source: str = "user") -> None:
        """Add a pipeline under ``name``; refuse a name already taken. A class registered directly
        is tagged with its ``track`` attribute unless ``track`` is given."""
        if isinstance(entry_point, type):
            track = track or getattr(entry_point, "track", None)
        super().register(name, entry_point, tags=(track,) if track else (), source=source)

    def names(self, track: str | None = None) -> list[str]:
        """Registered names in registration order (built-ins first); with ``track``, only those
        serving it (untagged entries are imported to find out)."""
        if track is None:
            return super().names()
        return [n for n in super().names() if (self.spec(n).track or getattr(self.load(n), "track", None)) == track]

    def spec(self, name: str) -> PipelineSpec:
        entry = self.entry(name)
        return PipelineSpec(entry.name, entry.entry_point, entry.tags[0] if entry.tags else None, entry.source)

    def make_config(self, name: str, values: dict[str, Any] | None = None) -> Any:
        """The pipeline's ``Config`` from plain values (strings are converted), validated."""
        return config_from_dict(self.load(name).Config, dict(values or {}), prefix=f"{name}.")

    def make(self, name: str, config: Any | None = None) -> Any:
        """An instance of the pipeline with ``config`` (default config when None)."""
        cls = self.load(name)
        return cls(cls.Config() if config is None else config)


def build_registry(*, entry_points: bool = True) -> PipelineRegistry:
    """A registry with the built-in pipelines and those of the ``exobench.pipelines`` group."""
    reg = PipelineRegistry()
    for name, (ep, track) in BUILTIN_PIPELINES.items():
        reg.register(name, ep, track=track, source="builtin")
    if entry_points:
        reg.add_group(ENTRY_POINT_GROUP)
    return reg


@functools.lru_cache(maxsize=1)
def default_registry() -> PipelineRegistry:
    """The process-wide registry (built once; ``default_registry.cache_clear()`` rebuilds it)."""
    return build_registry()
