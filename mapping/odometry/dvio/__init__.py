"""Building blocks of D-VIO, the RGB-D-inertial odometry of seeds/002 section II-C (issue 27).

- :mod:`.imu`: IMU preintegration and bias handling on gtsam (eq. 7, 9).
- :mod:`.factors`: the inverse-depth reprojection factor (eq. 8) and the host and projection
  depth factors (eq. 11-14) weighted by the stereo depth noise model.
- :mod:`.grouped`: the same residuals of all the landmarks a keyframe hosts as one factor (the
  window's), and the SfM's per landmark (the initialisation's): one Python callback each.
- :mod:`.tracker`: the KLT front end (OpenCV) and keyframe choice by parallax.
- :mod:`.init`: the depth-enhanced SfM initialisation (eq. 1-5), the gyroscope bias and the
  visual-inertial alignment.
- :mod:`.window`: the sliding-window estimator (eq. 6-15) with marginalisation.
- :mod:`.pipeline`: the ``dvio`` and ``dvio-no-depth`` pipelines on the core protocol.

The ``vio`` track and the pipelines' registration are not here.
This package never imports the simulator (tests/test_import_rule.py).
"""

from .factors import (
    DepthNoise,
    Extrinsics,
    host_depth_factor,
    landmark_in_camera,
    projection_depth_factor,
    reprojection_factor,
)
from .imu import GRAVITY_MPS2, ImuNoise, ImuPreintegrator, combined_factor
from .init import (
    InitResult,
    KeyframeObs,
    align_visual_inertial,
    corrected_deltas,
    depth_sfm,
    initialise,
    solve_gyro_bias,
)
from .tracker import FeatureTracker, TrackedFrame, TrackerConfig, normalised
from .window import SlidingWindow, WindowConfig

__all__ = [
    "GRAVITY_MPS2",
    "DepthNoise",
    "Extrinsics",
    "FeatureTracker",
    "ImuNoise",
    "ImuPreintegrator",
    "InitResult",
    "KeyframeObs",
    "SlidingWindow",
    "TrackedFrame",
    "TrackerConfig",
    "WindowConfig",
    "align_visual_inertial",
    "combined_factor",
    "corrected_deltas",
    "depth_sfm",
    "host_depth_factor",
    "initialise",
    "landmark_in_camera",
    "normalised",
    "projection_depth_factor",
    "reprojection_factor",
    "solve_gyro_bias",
]
