"""Pipeline registry: names -> pipeline classes, found by string entry points.

Like gymnasium's ``register(entry_point="pkg.mod:Cls")`` and dm_control's ``TaggedTasks``:
registering imports nothing, a class is imported the first time it is asked for, a name can be
registered once only, and an unknown name raises :class:`UnknownNameError` listing the valid
ones. exobench's own pipelines are built in; any installed package adds its own through the
``exobench.pipelines`` entry-point group::

    [project.entry-points."exobench.pipelines"]
    my-stairs = "my_package.stairs:MyStairs"

A registered class must satisfy :class:`exobench.core.Pipeline` and carry a ``Config``
dataclass whose fields all have defaults.
"""

from __future__ import annotations

import dataclasses
import functools
import importlib
import importlib.metadata
from dataclasses import dataclass
from typing import Any

from exobench.core.errors import ConfigError, UnknownNameError
from exobench.core.pipeline import Pipeline, config_from_dict

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


def load_entry_point(entry_point: str) -> Any:
    """Import ``"module:attr.sub"`` and return the attribute."""
    module_name, sep, attr = entry_point.partition(":")
    if not sep or not module_name or not attr:
        raise ConfigError("entry_point", entry_point, "'module:attribute'")
    obj: Any = importlib.import_module(module_name)
    for part in attr.split("."):
        obj = getattr(obj, part)
    return obj


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


class PipelineRegistry:
    """Pipelines by name. Entries are strings until first use."""

    def __init__(self) -> None:
        self._specs: dict[str, PipelineSpec] = {}
        self._classes: dict[str, type] = {}

    def register(self, name: str, entry_point: str | type, *, track: str | None = None, source: str = "user") -> None:
        """Add a pipeline under ``name``; refuse a name already taken."""
        if name in self._specs:
            taken = self._specs[name]
            raise ConfigError(
                "pipeline name", name, f"a name not yet registered (taken by {taken.entry_point}, {taken.source})"
            )
        if isinstance(entry_point, type):
            cls = check_pipeline_class(name, entry_point)
            self._classes[name] = cls
            entry_point = f"{cls.__module__}:{cls.__qualname__}"
            track = track or getattr(cls, "track", None)
        self._specs[name] = PipelineSpec(name, entry_point, track, source)

    def names(self, track: str | None = None) -> list[str]:
        """Registered names in registration order (built-ins first); with ``track``, only those
        serving it (untagged entries are imported to find out)."""
        if track is None:
            return list(self._specs)
        return [n for n, s in self._specs.items() if (s.track or getattr(self.load(n), "track", None)) == track]

    def spec(self, name: str) -> PipelineSpec:
        if name not in self._specs:
            raise UnknownNameError("pipeline", name, self._specs)
        return self._specs[name]

    def load(self, name: str) -> type:
        """The pipeline class, imported on first use."""
        spec = self.spec(name)
        if name not in self._classes:
            try:
                obj = load_entry_point(spec.entry_point)
            except (ImportError, AttributeError) as e:
                raise ConfigError(f"pipeline {name!r}", spec.entry_point, f"an importable class ({e})") from None
            self._classes[name] = check_pipeline_class(name, obj)
        return self._classes[name]

    def make_config(self, name: str, values: dict[str, Any] | None = None) -> Any:
        """The pipeline's ``Config`` from plain values (strings are converted), validated."""
        return config_from_dict(self.load(name).Config, dict(values or {}), prefix=f"{name}.")

    def make(self, name: str, config: Any | None = None) -> Any:
        """An instance of the pipeline with ``config`` (default config when None)."""
        cls = self.load(name)
        return cls(cls.Config() if config is None else config)

    def __contains__(self, name: object) -> bool:
        return name in self._specs


def build_registry(*, entry_points: bool = True) -> PipelineRegistry:
    """A registry with the built-in pipelines and those of the ``exobench.pipelines`` group."""
    reg = PipelineRegistry()
    for name, (ep, track) in BUILTIN_PIPELINES.items():
        reg.register(name, ep, track=track, source="builtin")
    if entry_points:
        for ep in importlib.metadata.entry_points(group=ENTRY_POINT_GROUP):
            reg.register(ep.name, ep.value, source="entry-point")
    return reg


@functools.lru_cache(maxsize=1)
def default_registry() -> PipelineRegistry:
    """The process-wide registry (built once; ``default_registry.cache_clear()`` rebuilds it)."""
    return build_registry()
