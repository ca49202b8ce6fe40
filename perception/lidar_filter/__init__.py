"""Ground-aware LiDAR intensity filters (the ``lidar-filter`` track; also a stage of odometry).

- :mod:`.config`: one config dataclass per filter, and :class:`FilterStageConfig`, a filter as
  a stage of another pipeline.
- :mod:`.filters`: the filters and :data:`FILTERS`, the one table of their names.
- :mod:`.ground` / :mod:`.normals`: the ground tests and the surface normals they use.
- :mod:`.footprint`: ``T_footprint_sensor`` from the exoskeleton's kinematics.
- :mod:`.pipelines`: the pipelines ``filter-<name>`` of the track.
"""

from .config import (
    FILTER_KINDS,
    FilterStageConfig,
    FloorGroundConfig,
    IntensityBandConfig,
    NaiveGroundConfig,
    NoFilterConfig,
    NormalGroundConfig,
)
from .filters import (
    FILTERS,
    FilterReason,
    FilterResult,
    FloorGroundFilter,
    IntensityThresholdFilter,
    NaiveGroundFilter,
    NoFilter,
    NormalGroundFilter,
    make_filter,
)
from .footprint import FootprintKinematics
from .pipelines import (
    FILTER_PIPELINES,
    FilterFloorGround,
    FilterNaiveGround,
    FilterNone,
    FilterNormalGround,
    FilterThreshold,
    filter_pipeline,
)

__all__ = [
    "FILTERS",
    "FILTER_KINDS",
    "FILTER_PIPELINES",
    "FilterFloorGround",
    "FilterNaiveGround",
    "FilterNone",
    "FilterNormalGround",
    "FilterReason",
    "FilterResult",
    "FilterStageConfig",
    "FilterThreshold",
    "FloorGroundConfig",
    "FloorGroundFilter",
    "FootprintKinematics",
    "IntensityBandConfig",
    "IntensityThresholdFilter",
    "NaiveGroundConfig",
    "NaiveGroundFilter",
    "NoFilter",
    "NoFilterConfig",
    "NormalGroundConfig",
    "NormalGroundFilter",
    "filter_pipeline",
    "make_filter",
]
