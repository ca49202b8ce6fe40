"""LiDAR odometry and SLAM (the ``odometry`` track).

- :mod:`.kiss_icp`: the ``kiss-icp`` package as the pipeline ``kiss-icp`` (with an optional
  intensity filter stage, ``KissConfig.filter``).
- :mod:`.leo_slam`: LEO-SLAM (seeds/003 4.2.1), the pipeline ``leo-slam``, built from
  :mod:`.preprocess`, :mod:`.gicp`, :mod:`.submaps`, :mod:`.loop_closure` and :mod:`.pose_graph`;
  its config (:class:`LeoSlamConfig`, also ``LeoSlamPipeline.Config``) is in :mod:`.leo_config`.
"""

from .gicp import GicpConfig
from .kiss_icp import KissConfig, KissIcpPipeline, run_kiss_icp
from .leo_config import LeoSlamConfig
from .leo_slam import LeoSlamPipeline
from .loop_closure import LoopDetectorConfig
from .pose_graph import PoseGraphConfig
from .preprocess import PreprocessConfig

__all__ = [
    "GicpConfig",
    "KissConfig",
    "KissIcpPipeline",
    "LeoSlamConfig",
    "LeoSlamPipeline",
    "LoopDetectorConfig",
    "PoseGraphConfig",
    "PreprocessConfig",
    "run_kiss_icp",
]
