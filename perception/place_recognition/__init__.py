"""Place recognition on LiDAR scans and submaps (the ``loop-closure`` track)."""
from .pipelines import (
    GaussianPlaceRecognitionConfig,
    GscHeightPipeline,
    GscHuberPipeline,
    GscIntensityPipeline,
    PlaceRecognitionConfig,
    ScanContextPPPipeline,
    remove_ceiling,
)

__all__ = [
    "GaussianPlaceRecognitionConfig",
    "GscHeightPipeline",
    "GscHuberPipeline",
    "GscIntensityPipeline",
    "PlaceRecognitionConfig",
    "ScanContextPPPipeline",
    "remove_ceiling",
]
