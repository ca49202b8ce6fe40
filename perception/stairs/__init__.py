"""Staircase estimation from two calf ToF beams (the ``stairs`` track).

- :mod:`.rtls`: recursive total least squares planes (general and HTVR).
- :mod:`.staircase`: the paper's Algorithm 1 (Assign / SurfUpdate / Shift) over surfaces S0..S4.
- :mod:`.readout`: riser height and tread depth from the estimated planes.
- :mod:`.pipeline_base`: frame checks, ToF kinematics and bookkeeping shared by the pipelines.
- :mod:`.rtls_pipeline`: the pipelines ``rtls`` and ``rtls-htvr``.
- :mod:`.ransac` / :mod:`.batch_ransac`: connected sequential RANSAC, the pipeline ``batch-ransac``.
"""

from .batch_ransac import BatchRansacStairs
from .pipeline_base import sensor_flags
from .readout import riser_height_m, tread_depth_m
from .rtls import RtlsPlane
from .rtls_pipeline import RtlsHtvrStairs, RtlsStairs
from .staircase import StaircaseAlgorithm, StaircaseParams

__all__ = [
    "BatchRansacStairs",
    "RtlsHtvrStairs",
    "RtlsPlane",
    "RtlsStairs",
    "StaircaseAlgorithm",
    "StaircaseParams",
    "riser_height_m",
    "sensor_flags",
    "tread_depth_m",
]
