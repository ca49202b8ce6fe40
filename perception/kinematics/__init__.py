"""Forward kinematics of the exoskeleton's sensor mounts from encoders and the trunk IMU.

Shared by the problems whose estimators need a sensor's pose on the device: the stairs
pipelines (ToF beam hit points) and the ground-aware LiDAR filters (the footprint transform).
"""

from .tof_kinematics import ESTIMATOR_FRAME, TofKinematics

__all__ = ["ESTIMATOR_FRAME", "TofKinematics"]
