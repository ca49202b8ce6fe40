"""Place recognition on LiDAR scans and submaps (the ``loop-closure`` track).

- :mod:`.scan_context`: the Scan Context grid, keys and shift similarity (eq. 4.20-4.25).
- :mod:`.recognizer`: descriptors and their database (SC++); :mod:`.gaussian_scan_context`:
  Gaussian Scan Context (eq. 4.26-4.33); :mod:`.component_gsc`: its cells, the fast way.
- :mod:`.config`: the pipelines' configs and ceiling removal.
- :mod:`.pipelines`: the pipelines ``sc++``, ``gsc-height``, ``gsc-huber``, ``gsc-intensity``.
"""

from .config import GaussianPlaceRecognitionConfig, PlaceRecognitionConfig, remove_ceiling
from .gaussian_scan_context import GaussianScanContext, GaussianScanContextConfig
from .pipelines import (
    GscHeightPipeline,
    GscHuberPipeline,
    GscIntensityPipeline,
    PlaceRecognitionPipeline,
    ScanContextPPPipeline,
)
from .recognizer import ContextDatabase, PlaceRecognizer, ScanContextPP
from .scan_context import ScanContextConfig

__all__ = [
    "ContextDatabase",
    "GaussianPlaceRecognitionConfig",
    "GaussianScanContext",
    "GaussianScanContextConfig",
    "GscHeightPipeline",
    "GscHuberPipeline",
    "GscIntensityPipeline",
    "PlaceRecognitionConfig",
    "PlaceRecognitionPipeline",
    "PlaceRecognizer",
    "ScanContextConfig",
    "ScanContextPP",
    "ScanContextPPPipeline",
    "remove_ceiling",
]
