"""Terrain from depth images (the ``locomotion`` track's perception): planes, their tracking, the
terrain they make up, and where the next foot lands.

- :mod:`.plane_extraction` (with :mod:`.ahc_math`): AHC planes of a depth image.
- :mod:`.plane_tracking`: the plane set updated by IoU with scores (eq. 23).
- :mod:`.terrain_description` (with :mod:`.terrain_types`): level ground, ramps and stairs from
  the plane set; the mode of the next step.
- :mod:`.footprint`: gait division by foot strikes and next-footprint prediction (eq. 16-18).
"""

from .footprint import FootprintConfig, GaitDivider, HeelStrike, predict_footprint
from .plane_extraction import AhcConfig, extract_planes, segment_depth
from .plane_tracking import DetectedPlane, PlaneSet, PlaneTrackingConfig
from .terrain_description import TerrainDescription, describe_terrain, predict_mode
from .terrain_types import TerrainConfig, plane_class, plane_height_at, slope_deg

__all__ = [
    "AhcConfig",
    "DetectedPlane",
    "FootprintConfig",
    "GaitDivider",
    "HeelStrike",
    "PlaneSet",
    "PlaneTrackingConfig",
    "TerrainConfig",
    "TerrainDescription",
    "describe_terrain",
    "extract_planes",
    "plane_class",
    "plane_height_at",
    "predict_footprint",
    "predict_mode",
    "segment_depth",
    "slope_deg",
]
