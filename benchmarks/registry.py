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

An entry may depend on an optional extra: ``requires`` names the module the pipeline needs at
run time (``"pyorbslam3"``) and ``extra`` the extra that installs it (``"orbslam3"``). Without the
module the entry stays listed, marked unavailable with the line that installs it
(:meth:`PipelineRegistry.unavailable`); a run that names it is refused at plan time and a run of
all the track's pipelines leaves it out and says so (:func:`exobench.benchmarks.runner.plan_run`).
Finding the module does not import it (:func:`module_available`), so an entry whose module is a
separate process's business (ORB-SLAM3, GPL) costs nothing. ``setup`` names a function
``setup(config)`` run once before a run's episodes (e.g. building a resource the pipeline reads).
"""

from __future__ import annotations

import dataclasses
import functools
import importlib.util
import sys
from dataclasses import dataclass
from typing import Any

from exobench.core.errors import ConfigError
from exobench.core.pipeline import Pipeline, config_from_dict

from .entry_points import EntryPointRegistry

ENTRY_POINT_GROUP = "exobench.pipelines"

# ORB-SLAM3 (GPL-3.0, optional extra `orbslam3`), run in a worker process: its entry point and
# needs (the module it requires, the extra that installs it, the setup that builds its vocabulary)
ORB_SLAM3_ENTRY_POINT = "exobench.mapping.odometry.orbslam3.adapter:OrbSlam3Pipeline"
ORB_SLAM3_NEEDS: dict[str, str] = {"requires": "pyorbslam3", "extra": "orbslam3",
                                   "setup": "exobench.benchmarks.orbvoc:setup_pipeline"}  # fmt: skip

# lt-exosense: the setup that renders and trains the other office's vocabulary (vocabulary=other)
LT_EXOSENSE_NEEDS: dict[str, str] = {"setup": "exobench.benchmarks.ltvoc:setup_pipeline"}

# name -> (entry point, track); the track tag lets `exobench run` pick a track's pipelines
# without importing them
# an optional third item: what the entry needs (``requires``, ``extra``, ``setup``; module docstring)
BUILTIN_PIPELINES: dict[str, tuple[Any, ...]] = {
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
    "terrain-recon-dvio": ("exobench.mapping.locomotion.pipelines:TerrainReconDvioPipeline", "locomotion"),
    "single-frame": ("exobench.mapping.locomotion.pipelines:SingleFramePipeline", "locomotion"),
    "dvio": ("exobench.mapping.odometry.dvio.pipeline:DvioPipeline", "vio"),
    "dvio-no-depth": ("exobench.mapping.odometry.dvio.pipeline:DvioNoDepthPipeline", "vio"),
    "orb-slam3": (ORB_SLAM3_ENTRY_POINT, "vio", ORB_SLAM3_NEEDS),
    "lt-exosense": ("exobench.mapping.multisession.pipeline:LtExosense", "multisession", LT_EXOSENSE_NEEDS),
    "lt-exosense-dufomap": ("exobench.mapping.multisession.pipeline:LtExosenseDufomap", "multisession",
                            LT_EXOSENSE_NEEDS),
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
    requires: str | None = None
    extra: str | None = None
    setup: str | None = None


def module_available(module: str) -> bool:
    """Whether ``module`` can be imported here, found without importing it (a module set to None
    in ``sys.modules`` is one that cannot, as ``import`` has it)."""
    if module in sys.modules:
        return sys.modules[module] is not None
    try:
        return importlib.util.find_spec(module) is not None
    except (ImportError, ValueError):
        return False


def install_line(extra: str) -> str:
    """The command that installs an optional extra of exobench."""
    return f"pip install 'exobench[{extra}]'"


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
        self._needs: dict[str, tuple[str | None, str | None, str | None]] = {}

    def register(self, name: str, entry_point: str | type, *, track: str | None = None, source: str = "user",
                 requires: str | None = None, extra: str | None = None, setup: str | None = None) -> None:  # fmt: skip
        """Add a pipeline under ``name``; refuse a name already taken. A class registered directly
        is tagged with its ``track`` attribute unless ``track`` is given. ``requires``, ``extra``
        and ``setup``: see the module docstring."""
        if isinstance(entry_point, type):
            track = track or getattr(entry_point, "track", None)
        if requires is not None and not extra:
            raise ConfigError(f"pipeline {name!r} extra", extra, "the optional extra that installs " + requires)
        super().register(name, entry_point, tags=(track,) if track else (), source=source)
        self._needs[name] = (requires, extra, setup)

    def unavailable(self, name: str) -> str | None:
        """Why ``name`` cannot run here (its module is missing, with the line that installs it),
        or None when it can."""
        requires, extra, _ = self._needs.get(self.entry(name).name, (None, None, None))
        if requires is None or module_available(requires):
            return None
        return f"needs the optional extra {extra!r} (module {requires} is not installed): {install_line(str(extra))}"

    def names(self, track: str | None = None) -> list[str]:
        """Registered names in registration order (built-ins first); with ``track``, only those
        serving it (untagged entries are imported to find out)."""
        if track is None:
            return super().names()
        return [n for n in super().names() if (self.spec(n).track or self._loaded_track(n)) == track]

    def _loaded_track(self, name: str) -> str | None:
        # an untagged entry whose module is missing cannot be imported to find its track
        return None if self.unavailable(name) else getattr(self.load(name), "track", None)

    def spec(self, name: str) -> PipelineSpec:
        entry = self.entry(name)
        requires, extra, setup = self._needs.get(name, (None, None, None))
        return PipelineSpec(entry.name, entry.entry_point, entry.tags[0] if entry.tags else None, entry.source,
                            requires, extra, setup)  # fmt: skip

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
    for name, (ep, track, *needs) in BUILTIN_PIPELINES.items():
        reg.register(name, ep, track=track, source="builtin", **(needs[0] if needs else {}))
    if entry_points:
        reg.add_group(ENTRY_POINT_GROUP)
    return reg


@functools.lru_cache(maxsize=1)
def default_registry() -> PipelineRegistry:
    """The process-wide registry (built once; ``default_registry.cache_clear()`` rebuilds it)."""
    return build_registry()
