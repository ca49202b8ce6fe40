"""Shared contracts of exobench: poses, frames, calibration, ground truth, estimates, errors.

numpy and the standard library only. Everything else in exobench builds on these types.
"""

from . import frame_kinds  # noqa: F401  (registers the shipped frame kinds)
from .calibration import Calibration, SensorMount
from .counters import FrameCounts, StreamCounters
from .episode import Episode, EpisodeTruth
from .errors import (
    ChangeScriptError,
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
    ContactSample,
    Frame,
    ImuSample,
    JointState,
    LidarScan,
    OdometrySample,
    RgbdFrame,
    ToFReading,
    TofStatus,
)
from .kinds import FRAME_TYPES, KINDS, FrameKind, frame_kind, kind_of, register_kind, unregister_kind
from .pipeline import Pipeline, coerce_like, config_from_dict
from .truth import (
    SURFACE_KINDS,
    LidarTruth,
    PlanarSurface,
    ReturnKind,
    SceneTruth,
    SegmentationTruth,
    StairTruth,
    StepTruth,
    ToFTruth,
    compact_truth,
    height_at,
)

__all__ = [
    "Calibration",
    "ChangeScriptError",
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
    "LidarTruth",
    "RgbdFrame",
    "Pipeline",
    "PlanarSurface",
    "PlaneEstimate",
    "PointAssignment",
    "RenderError",
    "ReturnKind",
    "SURFACE_KINDS",
    "SceneTruth",
    "SegmentationTruth",
    "StairTruth",
    "SensorMount",
    "SessionError",
    "StaircaseEstimate",
    "StreamCounters",
    "FrameCounts",
    "FrameKind",
    "KINDS",
    "kind_of",
    "register_kind",
    "unregister_kind",
    "ToFReading",
    "ToFTruth",
    "TofStatus",
    "UnknownNameError",
    "check_int",
    "check_range",
    "coerce_like",
    "compact_truth",
    "config_from_dict",
    "frame_kind",
    "height_at",
]
