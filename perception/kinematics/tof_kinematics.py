"""Points hit by the ToF beams, from encoders, the trunk IMU and the range (seeds/004, Sec. II).

The paper computes the beam's hit point by forward kinematics in an inertial frame on the
supporting foot. Here that frame is ``stance_ground``: axes parallel to the IMU's
gravity-aligned world, origin on the ground right below the stance ankle joint (foot flat, so
``sole_height_m`` below the joint). With the base link (pelvis) frame ``b``::

    R_world_b = R_world_imu @ R_b_imu^T
    p = R_world_b @ (p_b_sensor + R_b_sensor @ [0, 0, range] - p_b_ankle) + [0, 0, sole_height_m]

``p_b_*``/``R_b_*`` come from the URDF in the calibration (loaded with pinocchio) at the latest
encoder angles (joints absent from the encoder state stay at 0) composed with the sensor mounts
of the calibration.

Speed: encoder states arrive faster than ToF readings, so the kinematics is lazy: a new encoder
state or IMU orientation is only stored, and the first point that needs it computes what that
point needs (cached until the next state), so the cost is paid per point, where the estimator's
timing sees it. The per-point path (:meth:`TofKinematics.point_xyz`) maps the vectors of the
point's sensor, the IMU and the stance ankle through kinematic chains compiled to plain Python
floats (:mod:`.chain`), checked against pinocchio when built; when a chain cannot be compiled
it falls back to pinocchio's forward kinematics. The pose methods
(:meth:`TofKinematics.T_base_sensor`, ...) use pinocchio.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np

from exobench.core.calibration import Calibration
from exobench.core.errors import ConfigError, UnknownNameError
from exobench.core.frames import ImuSample, JointState

from .chain import Step, chain_to_base, compile_chain

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
        self._sole_m = float(calibration.sole_height_m)
        self.model = pin.buildModelFromXML(calibration.robot_urdf)
        self.data = self.model.createData()
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
        # state: encoder angles by joint name, IMU orientation as a quaternion or a matrix
        self._angles: dict[str, float] = {}
        self._have_joints = False
        self._quat: tuple[float, float, float, float] | None = None
        self._R_wi: tuple[float, ...] | None = None  # R_world_imu, 9 floats row-major
        self.joint_stamp_s = float("-inf")
        self.imu_stamp_s = float("-inf")
        # pinocchio path (pose methods, fallback)
        self._fk_dirty = True
        self._sensor_cache: dict[str, tuple[np.ndarray, np.ndarray]] = {}
        self._p_b_ankle = np.zeros(3)
        self._R_world_b: np.ndarray | None = None
        # fast path: per-state caches, cleared by new states
        self._vec_cache: dict[str, tuple[float, ...]] = {}  # sensor -> p_b_sensor - p_b_ankle, beam_b
        self._ankle_b: tuple[float, ...] | None = None
        self._R_wb: tuple[float, ...] | None = None
        self._R_b_imu: tuple[float, ...] | None = None
        self._fast = self._build_chains()

    def _body_frame(self, link: str) -> int:
        if not self.model.existBodyName(link):
            names = [f.name for f in self.model.frames if f.type == self._pin.FrameType.BODY]
            raise UnknownNameError("URDF link", link, names)
        return self.model.getFrameId(link, self._pin.FrameType.BODY)

    # --- state ---
    @property
    def has_state(self) -> bool:
        """True once both an encoder state and an IMU orientation were received."""
        return self._have_joints and (self._quat is not None or self._R_wi is not None)

    def set_joints(self, positions_rad: dict[str, float]) -> None:
        """Set encoder angles by joint name; unknown names are ignored, missing ones keep 0."""
        known = self._q_index
        self._angles = {name: float(v) for name, v in positions_rad.items() if name in known}
        self._have_joints = True
        self._joints_changed()

    def update_joints(self, state: JointState) -> None:
        """Take the encoder angles of a :class:`JointState`."""
        pos = state.position_rad
        values = pos.ravel().tolist() if isinstance(pos, np.ndarray) else [float(v) for v in pos]
        self.set_joints(dict(zip(state.names, values, strict=False)))
        self.joint_stamp_s = float(state.stamp_s)

    def set_orientation(self, R_world_imu: np.ndarray) -> None:
        """Set the IMU orientation ``R_world_imu`` (3x3)."""
        self._R_wi = tuple(np.asarray(R_world_imu, dtype=float).reshape(9).tolist())
        self._quat = None
        self._imu_changed()

    def update_imu(self, sample: ImuSample) -> None:
        """Take the orientation of an :class:`ImuSample` (``quat_wxyz`` is ``R_world_imu``).

        Only stored: the rotation matrix is formed when a point needs it.
        """
        w, x, y, z = np.asarray(sample.quat_wxyz, dtype=float).reshape(4).tolist()
        self._quat = (w, x, y, z)
        self._R_wi = None
        self._imu_changed()
        self.imu_stamp_s = float(sample.stamp_s)

    def _joints_changed(self) -> None:
        self._fk_dirty = True
        self._vec_cache = {}
        self._ankle_b = None
        if self._imu_moves:
            self._R_wb = None
            self._R_b_imu = None

    def _imu_changed(self) -> None:
        self._R_world_b = None
        self._R_wb = None

    def _R_world_imu9(self) -> tuple[float, ...]:
        """``R_world_imu`` (9 floats) of the latest orientation (normalised quaternion)."""
        R = self._R_wi
        if R is None:
            w, x, y, z = self._quat  # type: ignore[misc]
            norm = math.sqrt(w * w + x * x + y * y + z * z)
            w, x, y, z = w / norm, x / norm, y / norm, z / norm
            R = self._R_wi = (
                1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y),
                2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x),
                2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y),
            )  # fmt: skip
        return R

    # --- chains of the fast path ---
    def _chain(self, joint: int) -> list[Step] | None:
        return chain_to_base(self.model, self._base_fid, joint)

    def _build_chains(self) -> bool:
        """Compile the chains of the IMU, the stance ankle and the ToF mounts; check them.

        Other mounts are compiled when a point of theirs is first asked for. False (use
        pinocchio for everything) when one of these chains cannot be compiled or disagrees with
        pinocchio.
        """
        model = self.model
        self._imu_moves = True
        self._mount_fn: dict[str, Callable[..., tuple[float, ...]] | None] = {}  # -> p_b_sensor, beam_b
        imu_frame = model.frames[self._mount_fids[self._imu_id]]
        chain = self._chain(imu_frame.parentJoint)
        if chain is None:
            return False
        T = imu_frame.placement.homogeneous @ np.asarray(self._mounts[self._imu_id].T_parent_sensor, dtype=float)
        self._imu_fn = compile_chain(chain, [], T[:3, :3].T.tolist())  # -> columns of R_b_imu
        self._imu_moves = any(step[0] != "c" for step in chain)
        kind, idx = self._ankle
        if kind == "joint":
            chain, leaf = self._chain(idx), [0.0, 0.0, 0.0]
        else:
            frame = model.frames[idx]
            chain, leaf = self._chain(frame.parentJoint), np.asarray(frame.placement.translation).tolist()
        if chain is None:
            return False
        self._ankle_fn = compile_chain(chain, [leaf], [])
        checks = [
            (lambda: self._ankle_fn(self._angles), lambda: self._p_b_ankle),
            (
                lambda: np.reshape(self._imu_fn(self._angles), (3, 3)).T.ravel(),
                lambda: self.T_base_sensor(self._imu_id)[:3, :3].ravel(),
            ),
        ]
        for sid in (m.sensor_id for m in self._mounts.values() if m.kind == "tof"):
            fn = self._mount_fn[sid] = self._compile_mount(sid)
            if fn is None:
                return False
            checks.append(self._mount_check(sid, fn))
        return self._agrees(checks)

    def _compile_mount(self, sensor_id: str) -> Callable[..., tuple[float, ...]] | None:
        """Chain of a mount's position and +z axis in the base frame, None if not compilable."""
        frame = self.model.frames[self._mount_fids[sensor_id]]
        chain = self._chain(frame.parentJoint)
        if chain is None:
            return None
        T = frame.placement.homogeneous @ np.asarray(self._mounts[sensor_id].T_parent_sensor, dtype=float)
        return compile_chain(chain, [T[:3, 3].tolist()], [T[:3, 2].tolist()])

    def _mount_check(self, sensor_id: str, fn: Callable[..., tuple[float, ...]]) -> tuple[Callable[[], Any], Callable[[], Any]]:
        def slow() -> list[float]:
            T = self.T_base_sensor(sensor_id)
            return [*T[:3, 3], *T[:3, 2]]

        return (lambda: fn(self._angles)), slow

    def _agrees(self, checks: list[tuple[Callable[[], Any], Callable[[], Any]]]) -> bool:
        """Whether each (compiled, pinocchio) pair agrees to 1e-9 at a few random configurations."""
        rng = np.random.default_rng(0)
        saved = (self._angles, self._have_joints)
        ok = True
        for _ in range(3):
            self.set_joints({name: float(rng.uniform(-1.0, 1.0)) for name in self._q_index})
            self._forward()
            ok = ok and all(np.allclose(fast(), slow(), rtol=0.0, atol=1e-9) for fast, slow in checks)
        self._angles, self._have_joints = saved
        self._joints_changed()
        return bool(ok)

    def _mount_function(self, sensor_id: str) -> Callable[..., tuple[float, ...]] | None:
        """The compiled chain of a mount (compiled and checked on first use); None: pinocchio."""
        try:
            return self._mount_fn[sensor_id]
        except KeyError:
            pass
        if sensor_id not in self._mounts:
            raise UnknownNameError("sensor", sensor_id, self._mounts)
        fn = self._compile_mount(sensor_id)
        if fn is not None and not self._agrees([self._mount_check(sensor_id, fn)]):
            fn = None
        self._mount_fn[sensor_id] = fn
        return fn

    def _ankle_vec(self) -> tuple[float, ...]:
        """``p_b_ankle`` at the current encoder angles (fast path, cached per state)."""
        a = self._ankle_b
        if a is None:
            a = self._ankle_b = self._ankle_fn(self._angles)
        return a

    def _R_world_base9(self) -> tuple[float, ...]:
        """``R_world_b = R_world_imu @ R_b_imu^T`` (9 floats, fast path, cached per state)."""
        R = self._R_wb
        if R is None:
            C = self._R_b_imu
            if C is None:
                # C[3k + j] = R_b_imu[j][k]: column k of R_b_imu is IMU axis k in the base frame
                C = self._R_b_imu = self._imu_fn(self._angles)
            a0, a1, a2, a3, a4, a5, a6, a7, a8 = self._R_world_imu9()
            c0, c1, c2, c3, c4, c5, c6, c7, c8 = C
            # (R_world_imu @ R_b_imu^T)[i][j] = sum_k R_world_imu[i][k] R_b_imu[j][k]
            R = self._R_wb = (
                a0 * c0 + a1 * c3 + a2 * c6, a0 * c1 + a1 * c4 + a2 * c7, a0 * c2 + a1 * c5 + a2 * c8,
                a3 * c0 + a4 * c3 + a5 * c6, a3 * c1 + a4 * c4 + a5 * c7, a3 * c2 + a4 * c5 + a5 * c8,
                a6 * c0 + a7 * c3 + a8 * c6, a6 * c1 + a7 * c4 + a8 * c7, a6 * c2 + a7 * c5 + a8 * c8,
            )  # fmt: skip
        return R

    def _sensor_vecs(self, sensor_id: str) -> tuple[float, ...]:
        """``p_b_sensor - p_b_ankle`` and the beam ``R_b_sensor[:, 2]`` (6 floats, cached per state)."""
        v = self._vec_cache.get(sensor_id)
        if v is None:
            fn = self._mount_function(sensor_id)
            if fn is None:
                px, py, pz, bx, by, bz = self._pin_vecs(sensor_id)
            else:
                px, py, pz, bx, by, bz = fn(self._angles)
            ax, ay, az = self._ankle_vec()
            v = self._vec_cache[sensor_id] = (px - ax, py - ay, pz - az, bx, by, bz)
        return v

    # --- kinematics (pinocchio) ---
    def _pin_q(self) -> np.ndarray:
        """Pinocchio configuration of the current angles (continuous joints as cos, sin)."""
        q = np.array(self._pin.neutral(self.model), dtype=float)
        for j in range(1, self.model.njoints):
            jm = self.model.joints[j]
            if jm.nq == 2:
                q[jm.idx_q : jm.idx_q + 2] = (1.0, 0.0)
            elif jm.nq == 1:
                q[jm.idx_q] = 0.0
        for name, value in self._angles.items():
            i, nq = self._q_index[name]
            if nq == 1:
                q[i] = value
            else:
                q[i : i + 2] = (np.cos(value), np.sin(value))
        return q

    def _forward(self) -> None:
        pin = self._pin
        pin.forwardKinematics(self.model, self.data, self._pin_q())
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
        if self._quat is None and self._R_wi is None:
            raise ValueError("no IMU orientation yet")
        if self._fk_dirty:
            self._forward()
        if self._R_world_b is None:
            R_b_imu = self.T_base_sensor(self._imu_id)[:3, :3]
            self._R_world_b = np.array(self._R_world_imu9()).reshape(3, 3) @ R_b_imu.T
        return self._R_world_b

    def T_estimator_sensor(self, sensor_id: str) -> np.ndarray:
        """Pose (4x4) of a sensor in the ``stance_ground`` frame."""
        R = self.R_world_base()
        T_bs = self.T_base_sensor(sensor_id)
        T = np.eye(4)
        T[:3, :3] = R @ T_bs[:3, :3]
        T[:3, 3] = R @ (T_bs[:3, 3] - self._p_b_ankle) + np.array([0.0, 0.0, self._sole_m])
        return T

    def _pin_vecs(self, sensor_id: str) -> list[float]:
        """``p_b_sensor`` and the beam ``R_b_sensor[:, 2]`` by pinocchio (6 floats)."""
        T = self.T_base_sensor(sensor_id)
        return [*T[:3, 3].tolist(), *T[:3, 2].tolist()]

    def _point_pin(self, sensor_id: str, range_m: float) -> np.ndarray:
        R = self.R_world_base()
        cached = self._sensor_cache.get(sensor_id)
        if cached is None:
            T_bs = self.T_base_sensor(sensor_id)
            cached = (T_bs[:3, 3] - self._p_b_ankle, T_bs[:3, 2].copy())
            self._sensor_cache[sensor_id] = cached
        p_b, beam_b = cached
        p = R @ (p_b + float(range_m) * beam_b)
        p[2] += self._sole_m
        return p

    # --- points ---
    def point_xyz(self, sensor_id: str, range_m: float) -> tuple[float, float, float]:
        """Point hit by the beam of ``sensor_id`` at ``range_m``, in ``stance_ground``, as floats."""
        if not self.has_state:
            raise ValueError("no encoder or IMU state yet")
        if not self._fast:
            x, y, z = self._point_pin(sensor_id, range_m).tolist()
            return x, y, z
        px, py, pz, bx, by, bz = self._sensor_vecs(sensor_id)
        r = float(range_m)
        vx, vy, vz = px + r * bx, py + r * by, pz + r * bz
        a0, a1, a2, a3, a4, a5, a6, a7, a8 = self._R_world_base9()
        return a0 * vx + a1 * vy + a2 * vz, a3 * vx + a4 * vy + a5 * vz, a6 * vx + a7 * vy + a8 * vz + self._sole_m

    def point(self, sensor_id: str, range_m: float) -> np.ndarray:
        """Point hit by the beam of ``sensor_id`` at ``range_m``, in ``stance_ground``, (3,)."""
        return np.array(self.point_xyz(sensor_id, range_m))
