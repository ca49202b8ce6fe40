"""Forward kinematics of the exoskeleton's sensor mounts from encoders and the trunk IMU.

Shared by the problems whose estimators need a sensor's pose on the device: the stairs
pipelines (ToF beam hit points) and the ground-aware LiDAR filters (the footprint transform).

- :mod:`.tof_kinematics`: :class:`TofKinematics`, points and poses in the ``stance_ground`` frame.
- :mod:`.chain`: the model's joint chains compiled to plain-float Python (its fast path).
"""

from .tof_kinematics import ESTIMATOR_FRAME, TofKinematics

__all__ = ["ESTIMATOR_FRAME", "TofKinematics"]
