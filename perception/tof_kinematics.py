"""Points hit by the ToF beams, from encoders, the trunk IMU and the range (seeds/004, Sec. II).

The paper computes the beam's hit point by forward kinematics in an inertial frame on the
supporting foot. Here that frame is ``stance_ground``: axes parallel to the IMU's
gravity-aligned world, origin on the ground right below the stance ankle joint (foot flat, so
``sole_height_m`` below the joint). With the base link (pelvis) frame ``b``::

    R_world_b = R_world_imu @ R_b_imu^T
    p = R_world_b @ (p_b_sensor + R_b_sensor @ [0, 0, range] - p_b_ankle) + [0, 0, sole_height_m]

``p_b_*``/``R_b_*`` come from the URDF in the calibration (loaded with pinocchio) at the latest
encoder angles (joints absent from the encoder state stay at 0) composed with the sensor mounts
of the calibration. Forward kinematics runs once per new encoder state; each point then costs a
few 3-vector operations.
"""

from __future__ import annotations

import numpy as np

from exobench.core.calibration import Calibration
from exobench.core.errors import ConfigError, UnknownNameError
from exobench.core.frames import ImuSample, JointState
from exobench.core.transforms import quat_wxyz_to_matrix

__all__ = ["ESTIMATOR_FRAME", "TofKinematics"]

ESTIMATOR_FRAME = "stance_ground"


class TofKinematics:
    """Forward kinematics of the ToF beams into the ``stance_ground`` frame.

    Args:
        calibration: robot URDF, base link, sensor mounts and ``sole_height_m``.
        stance_side: ``"l"`` or ``"r"``, the supporting foot whose ankle joint
            (``ankle_<side>``, else the origin of link ``foot_<side>``) anchors the frame.
        imu_sensor_id: the mount of the IMU that reports ``R_world_imu``.
    """

    def __init__(self, calibration: Calibration, stance_side: str = "l", imu_sensor_id: str = "imu_trunk") -> None:
        import pinocchio as pin

        if stance_side not in ("l", "r"):
            raise ConfigError("stance_side", stance_side, "'l' or 'r'")
        self._pin = pin
        self.calibration = calibration
        self.stance_side = stance_side
        self.model = pin.buildModelFromXML(calibration.robot_urdf)
        self.data = self.model.createData()
        self._q = self._zero_q()
        self._q_index: dict[str, tuple[int, int]] = {}
        for j in range(1, self.model.njoints):
            jm = self.model.joints[j]
            if jm.nq in (1, 2):
                self._q_index[self.model.names[j]] = (jm.idx_q, jm.nq)
        self._base_fid = self._body_frame(calibration.base_link)
        ankle = f"ankle_{stance_side}"
        if self.model.existJointName(ankle):
            self._ankle = ("joint", self.model.getJointId(ankle))
        else:
            self._ankle = ("frame", self._body_frame(f"foot_{stance_side}"))
        self._mounts = {m.sensor_id: m for m in calibration.mounts}
        if imu_sensor_id not in self._mounts:
            raise UnknownNameError("IMU sensor", imu_sensor_id, [m.sensor_id for m in calibration.mounts_of_kind("imu")])
        self._imu_id = imu_sensor_id
        self._mount_fids = {sid: self._body_frame(m.parent_link) for sid, m in self._mounts.items()}
        self._parent_fids = sorted(set(self._mount_fids.values()))
        self._R_world_imu: np.ndarray | None = None
        self._have_joints = False
        self._fk_dirty = True
        self._sensor_cache: dict[str, tuple[np.ndarray, np.ndarray]] = {}  # base frame: (p, beam)
        self._p_b_ankle = np.zeros(3)
        self._R_world_b: np.ndarray | None = None
        self.joint_stamp_s = float("-inf")
        self.imu_stamp_s = float("-inf")

    def _zero_q(self) -> np.ndarray:
        """Configuration with every joint at angle 0 (continuous joints as cos 1, sin 0)."""
        q = np.array(self._pin.neutral(self.model), dtype=float)
        for j in range(1, self.model.njoints):
            jm = self.model.joints[j]
            if jm.nq == 2:
                q[jm.idx_q : jm.idx_q + 2] = (1.0, 0.0)
            elif jm.nq == 1:
                q[jm.idx_q] = 0.0
        return q

    def _body_frame(self, link: str) -> int:
        if not self.model.existBodyName(link):
            names = [f.name for f in self.model.frames if f.type == self._pin.FrameType.BODY]
            raise UnknownNameError("URDF link", link, names)
        return self.model.getFrameId(link, self._pin.FrameType.BODY)

    # --- state ---
    @property
    def has_state(self) -> bool:
        """True once both an encoder state and an IMU orientation were received."""
        return self._have_joints and self._R_world_imu is not None

    def set_joints(self, positions_rad: dict[str, float]) -> None:
        """Set encoder angles by joint name; unknown names are ignored, missing ones keep 0."""
        q = self._zero_q()
        for name, value in positions_rad.items():
            idx = self._q_index.get(name)
            if idx is None:
                continue
            i, nq = idx
            if nq == 1:
                q[i] = value
            else:
                q[i : i + 2] = (np.cos(value), np.sin(value))
        self._q = q
        self._have_joints = True
        self._fk_dirty = True

    def update_joints(self, state: JointState) -> None:
        """Take the encoder angles of a :class:`JointState`."""
        self.set_joints(dict(zip(state.names, np.asarray(state.position_rad, dtype=float).ravel(), strict=False)))
        self.joint_stamp_s = float(state.stamp_s)

    def set_orientation(self, R_world_imu: np.ndarray) -> None:
        """Set the IMU orientation ``R_world_imu`` (3x3)."""
        self._R_world_imu = np.asarray(R_world_imu, dtype=float).reshape(3, 3)
        self._R_world_b = None

    def update_imu(self, sample: ImuSample) -> None:
        """Take the orientation of an :class:`ImuSample` (``quat_wxyz`` is ``R_world_imu``)."""
        self.set_orientation(quat_wxyz_to_matrix(sample.quat_wxyz))
        self.imu_stamp_s = float(sample.stamp_s)

    # --- kinematics ---
    def _forward(self) -> None:
        pin = self._pin
        pin.forwardKinematics(self.model, self.data, self._q)
        pin.updateFramePlacements(self.model, self.data)
        base = self.data.oMf[self._base_fid]
        R_ob, p_ob = np.array(base.rotation), np.array(base.translation)  # universe <- base
        self._T_b_parent = {}
        for fid in self._parent_fids:
            T = np.eye(4)
            T[:3, :3] = R_ob.T @ self.data.oMf[fid].rotation
            T[:3, 3] = R_ob.T @ (self.data.oMf[fid].translation - p_ob)
            self._T_b_parent[fid] = T
        kind, idx = self._ankle
        p_o = self.data.oMi[idx].translation if kind == "joint" else self.data.oMf[idx].translation
        self._p_b_ankle = R_ob.T @ (np.asarray(p_o) - p_ob)
        self._sensor_cache = {}
        self._R_world_b = None
        self._fk_dirty = False

    def T_base_sensor(self, sensor_id: str) -> np.ndarray:
        """Pose (4x4) of a sensor mount in the base link frame at the current encoder angles."""
        if sensor_id not in self._mounts:
            raise UnknownNameError("sensor", sensor_id, self._mounts)
        if self._fk_dirty:
            self._forward()
        m = self._mounts[sensor_id]
        return self._T_b_parent[self._mount_fids[sensor_id]] @ np.asarray(m.T_parent_sensor, dtype=float)

    def R_world_base(self) -> np.ndarray:
        """``R_world_b = R_world_imu @ R_b_imu^T`` at the current state."""
        if self._R_world_imu is None:
            raise ValueError("no IMU orientation yet")
        if self._fk_dirty:
            self._forward()
        if self._R_world_b is None:
            R_b_imu = self.T_base_sensor(self._imu_id)[:3, :3]
            self._R_world_b = self._R_world_imu @ R_b_imu.T
        return self._R_world_b

    def T_estimator_sensor(self, sensor_id: str) -> np.ndarray:
        """Pose (4x4) of a sensor in the ``stance_ground`` frame."""
        R = self.R_world_base()
        T_bs = self.T_base_sensor(sensor_id)
        T = np.eye(4)
        T[:3, :3] = R @ T_bs[:3, :3]
        T[:3, 3] = R @ (T_bs[:3, 3] - self._p_b_ankle) + np.array([0.0, 0.0, self.calibration.sole_height_m])
        return T

    def point(self, sensor_id: str, range_m: float) -> np.ndarray:
        """Point hit by the beam of ``sensor_id`` at ``range_m``, in ``stance_ground``, (3,)."""
        if not self.has_state:
            raise ValueError("no encoder or IMU state yet")
        R = self.R_world_base()
        cached = self._sensor_cache.get(sensor_id)
        if cached is None:
            T_bs = self.T_base_sensor(sensor_id)
            cached = (T_bs[:3, 3] - self._p_b_ankle, T_bs[:3, 2].copy())
            self._sensor_cache[sensor_id] = cached
        p_b, beam_b = cached
        p = R @ (p_b + float(range_m) * beam_b)
        p[2] += self.calibration.sole_height_m
        return p
