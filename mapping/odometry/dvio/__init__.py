"""Building blocks of D-VIO, the RGB-D-inertial odometry of seeds/002 section II-C (issue 27).

- :mod:`.imu`: IMU preintegration and bias handling on gtsam (eq. 7, 9).

The sliding-window estimator, the ``vio`` track and the pipeline registration are not here yet.
This package never imports the simulator (tests/test_import_rule.py).
"""

from .imu import GRAVITY_MPS2, ImuNoise, ImuPreintegrator, combined_factor

__all__ = ["GRAVITY_MPS2", "ImuNoise", "ImuPreintegrator", "combined_factor"]
