"""Scanning LiDAR by MuJoCo ray casting, with ground truth per point.

- :mod:`.config`: :class:`LidarConfig` (noise, detection, optics switches, casting options);
- :mod:`.pattern`: :class:`LidarPattern`, which rays a sweep fires, where and when;
- :mod:`.model`: :class:`LidarSensor`, one sweep -> a :class:`~exobench.core.LidarScan` and its
  :class:`~exobench.core.LidarTruth`;
- :mod:`.cast` and :mod:`.ray_scene`: the batched ``mj_multiRay`` casting of the primary rays;
- :mod:`.optics`: glass, mirrors and return strength; :mod:`.labels`: surface labels of hits.
"""

from exobench.core import LidarTruth, ReturnKind

from .config import INTENSITY_MODES, LidarConfig
from .model import LidarSensor, PoseFn
from .pattern import LidarPattern, RayTable

__all__ = [
    "INTENSITY_MODES",
    "LidarConfig",
    "LidarPattern",
    "LidarSensor",
    "LidarTruth",
    "PoseFn",
    "RayTable",
    "ReturnKind",
]
