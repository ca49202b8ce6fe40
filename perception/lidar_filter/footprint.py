"""``T_footprint_sensor`` of a LiDAR from encoders, the trunk IMU and insole contacts.

The footprint frame ``f`` is the ground frame below the walker: ``stance_ground`` (gravity-aligned
axes, origin on the ground under the stance ankle; :mod:`exobench.perception.kinematics`) turned
about the vertical to the trunk's heading. The stance foot is the side whose insole pads report
contact when only one side does, otherwise the foot that is lower along gravity.
"""

from __future__ import annotations

import math

import numpy as np

from exobench.core.calibration import Calibration
from exobench.core.frames import ContactSample, Frame, ImuSample, JointState
from exobench.core.limits import JointLimits, imu_absurd
from exobench.perception.kinematics.tof_kinematics import TofKinematics

__all__ = ["FootprintKinematics", "footprint_from_stance"]


def footprint_from_stance(T_stance_sensor: np.ndarray, R_world_base: np.ndarray) -> np.ndarray:
    """``T_footprint_sensor`` from the sensor pose in ``stance_ground`` and the trunk rotation.

    The footprint frame is ``stance_ground`` rotated about its z axis by the heading of the base
    link's x axis (projected on the horizontal plane; identity when it is vertical).
    """
    x = np.asarray(R_world_base, dtype=float)[:, 0]
    yaw = math.atan2(x[1], x[0]) if math.hypot(x[0], x[1]) > 1e-9 else 0.0
    c, s = math.cos(yaw), math.sin(yaw)
    T_f_stance = np.eye(4)
    T_f_stance[:2, :2] = [[c, s], [-s, c]]  # Rz(-yaw)
    return T_f_stance @ np.asarray(T_stance_sensor, dtype=float)


class FootprintKinematics:
    """``T_footprint_sensor`` of one sensor from encoders, the trunk IMU and insole contacts.

    Args:
        calibration: URDF, mounts and ``sole_height_m`` of the device.
        sensor_id: the LiDAR mount.
        imu_sensor_id: the trunk IMU whose orientation is ``R_world_imu``.
    """

    def __init__(self, calibration: Calibration, sensor_id: str, imu_sensor_id: str = "imu_trunk") -> None:

        self.sensor_id = sensor_id
        self.imu_sensor_id = imu_sensor_id
        self._kin = {side: TofKinematics(calibration, side, imu_sensor_id) for side in ("l", "r")}
        self._kin["l"].T_base_sensor(sensor_id)  # unknown mount: UnknownNameError now, not per scan
        self._contact: dict[str, bool] = {}  # pad sensor id -> in contact
        self._joint_limits = JointLimits(calibration)
        self.stance_side: str | None = None

    @property
    def has_state(self) -> bool:
        return self._kin["l"].has_state

    def update(self, frame: Frame) -> None:
        """Take an encoder state, an IMU orientation of the trunk IMU or an insole contact."""
        if isinstance(frame, JointState):
            if self._joint_limits.absurd(frame):  # not finite or absurd (core.limits): the state is kept
                return
            for k in self._kin.values():
                k.update_joints(frame)
        elif isinstance(frame, ImuSample) and frame.sensor_id == self.imu_sensor_id:
            if imu_absurd(frame):
                return
            for k in self._kin.values():
                k.update_imu(frame)
        elif isinstance(frame, ContactSample):
            self._contact[frame.sensor_id] = bool(frame.in_contact)

    def _side_in_contact(self, side: str) -> bool | None:
        pads = [v for sid, v in self._contact.items() if sid.startswith(f"contact_{side}_")]
        return any(pads) if pads else None

    def T_footprint_sensor(self) -> np.ndarray | None:
        """The transform at the current state, None without a state or when not finite."""
        if not self.has_state:
            return None
        T = {side: k.T_estimator_sensor(self.sensor_id) for side, k in self._kin.items()}
        left, right = self._side_in_contact("l"), self._side_in_contact("r")
        if left and not right:
            side = "l"
        elif right and not left:
            side = "r"
        else:  # the stance foot is the lower one: the sensor is higher above it
            side = "l" if T["l"][2, 3] >= T["r"][2, 3] else "r"
        self.stance_side = side
        out = footprint_from_stance(T[side], self._kin[side].R_world_base())
        return out if np.all(np.isfinite(out)) else None
