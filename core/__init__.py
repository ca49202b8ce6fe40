"""Shared contracts of exobench: poses, frames, calibration, ground truth, estimates, errors.

numpy and the standard library only. Everything else in exobench builds on these types.
"""

from .calibration import Calibration, SensorMount
from .episode import Episode, EpisodeTruth
from .errors import (
    ConfigError,
    ExobenchError,
    RenderError,
    SessionError,
    UnknownNameError,
    check_int,
    check_range,
)
from .estimates import (
    LOCOMOTION_MODES,
    FilterEstimate,
    LocomotionEstimate,
    ModePrediction,
    PlaceRecognitionEstimate,
    PlaneEstimate,
    PointAssignment,
    StaircaseEstimate,
    TrajectoryEstimate,
)
from .frames import (
    FRAME_TYPES,
    ContactSample,
    Frame,
    ImuSample,
    JointState,
    LidarScan,
    OdometrySample,
    RgbdFrame,
    StreamStats,
    ToFReading,
    TofStatus,
    frame_kind,
)
from .pipeline import Pipeline, coerce_like, config_from_dict
from .truth import SURFACE_KINDS, PlanarSurface, SceneTruth, StepTruth, ToFTruth, height_at

__all__ = [
    "Calibration",
    "ConfigError",
    "ContactSample",
    "Episode",
    "FilterEstimate",
    "LOCOMOTION_MODES",
    "LocomotionEstimate",
    "ModePrediction",
    "OdometrySample",
    "PlaceRecognitionEstimate",
    "StepTruth",
    "TrajectoryEstimate",
    "EpisodeTruth",
    "ExobenchError",
    "FRAME_TYPES",
    "Frame",
    "ImuSample",
    "JointState",
    "LidarScan",
    "RgbdFrame",
    "Pipeline",
    "PlanarSurface",
    "PlaneEstimate",
    "PointAssignment",
    "RenderError",
    "SURFACE_KINDS",
    "SceneTruth",
    "SensorMount",
    "SessionError",
    "StaircaseEstimate",
    "StreamStats",
    "ToFReading",
    "ToFTruth",
    "TofStatus",
    "UnknownNameError",
    "check_int",
    "check_range",
    "coerce_like",
    "config_from_dict",
    "frame_kind",
    "height_at",
]
