"""ToF beam points by forward kinematics (pinocchio) against an independent numpy chain."""

import numpy as np
import pytest

from exobench.core import Calibration, ImuSample, JointState, SensorMount
from exobench.perception.kinematics.tof_kinematics import TofKinematics


# --- independent rotations (not exobench's) -------------------------------------------------
def _rot(axis, a):
    k = np.asarray(axis, float) / np.linalg.norm(axis)
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + np.sin(a) * K + (1 - np.cos(a)) * K @ K


def _rpy(r, p, y):  # URDF convention: R = Rz(y) Ry(p) Rx(r)
    return _rot([0, 0, 1], y) @ _rot([0, 1, 0], p) @ _rot([1, 0, 0], r)


def _T(R, t):
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, t
    return T


def _quat_wxyz(R):
    w = np.sqrt(max(0.0, 1.0 + np.trace(R))) / 2.0
    if w > 1e-3:
        return np.array([w, (R[2, 1] - R[1, 2]) / (4 * w), (R[0, 2] - R[2, 0]) / (4 * w), (R[1, 0] - R[0, 1]) / (4 * w)])
    raise AssertionError("test rotation too close to 180 deg")


# --- a small two-legged robot written by hand ------------------------------------------------
# joint: (name, parent, child, xyz, rpy, axis, type)
JOINTS = [
    ("hip_l", "pelvis", "thigh_l", (0.01, 0.09, -0.02), (0.02, 0.0, 0.03), (0, -1, 0), "revolute"),
    ("knee_l", "thigh_l", "shank_l", (0.0, 0.0, -0.42), (0.0, 0.01, 0.0), (0, 1, 0), "continuous"),
    ("ankle_l", "shank_l", "foot_l", (0.0, 0.0, -0.43), (0.0, 0.0, 0.0), (0, -1, 0), "revolute"),
    ("hip_r", "pelvis", "thigh_r", (0.0, -0.09, 0.0), (0.0, 0.0, -0.02), (0, -1, 0), "revolute"),
    ("knee_r", "thigh_r", "shank_r", (0.005, 0.0, -0.42), (0.01, 0.0, 0.0), (0, 1, 0), "revolute"),
    ("ankle_r", "shank_r", "foot_r", (0.0, 0.0, -0.43), (0.0, 0.0, 0.0), (0, -1, 0), "revolute"),
]
SOLE_M = 0.07


def tiny_urdf(joints=JOINTS):
    links = ["pelvis"] + [j[2] for j in joints]
    out = ['<?xml version="1.0"?>', '<robot name="tiny">']
    for ln in links:
        out.append(
            f'<link name="{ln}"><inertial><origin xyz="0 0 0"/><mass value="1.0"/>'
            '<inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial></link>'
        )
    for name, parent, child, xyz, rpy, axis, kind in joints:
        limit = '<limit lower="-3" upper="3" effort="100" velocity="10"/>' if kind in ("revolute", "prismatic") else ""
        out.append(
            f'<joint name="{name}" type="{kind}"><parent link="{parent}"/><child link="{child}"/>'
            f'<origin xyz="{" ".join(map(repr, xyz))}" rpy="{" ".join(map(repr, rpy))}"/>'
            f'<axis xyz="{" ".join(map(str, axis))}"/>{limit}</joint>'
        )
    out.append("</robot>")
    return "\n".join(out)


def _tof_T(pitch_deg, yaw_deg, pos):
    """Mount whose +z (the beam) points forward, pitched down and yawed."""
    return _T(_rot([0, 0, 1], np.radians(yaw_deg)) @ _rot([0, 1, 0], np.radians(90 + pitch_deg)), pos)


MOUNTS = (
    SensorMount("tof_r_med", "tof", "shank_r", _tof_T(20, 4, (0.06, 0.04, -0.2))),
    SensorMount("tof_r_lat", "tof", "shank_r", _tof_T(20, -4, (0.06, -0.04, -0.2))),
    SensorMount("tof_l_med", "tof", "shank_l", _tof_T(25, -4, (0.06, -0.04, -0.2))),
    SensorMount("tof_l_lat", "tof", "shank_l", _tof_T(25, 4, (0.06, 0.04, -0.2))),
    SensorMount("imu_trunk", "imu", "pelvis", _T(_rpy(0.1, -0.2, 0.3), (-0.12, 0.0, 0.2))),
    SensorMount("imu_thigh", "imu", "thigh_r", _T(_rpy(0.0, 0.3, 0.0), (0.05, 0.0, -0.1))),
)


def tiny_calibration(joints=JOINTS, mounts=MOUNTS):
    return Calibration(
        robot_urdf=tiny_urdf(joints),
        base_link="pelvis",
        joint_names=tuple(j[0] for j in joints),
        mounts=mounts,
        sole_height_m=SOLE_M,
        foot_length_m=0.26,
        heel_to_ankle_m=0.065,
    )


def chain_T(link, q, joints=JOINTS):
    """T_pelvis_link at joint angles q (dict) by composing the URDF joints in numpy.

    A floating joint stays at its neutral pose (the encoders do not report it).
    """
    by_child = {j[2]: j for j in joints}
    T = np.eye(4)
    while link != "pelvis":
        name, parent, _, xyz, rpy, axis, kind = by_child[link]
        if kind == "floating":
            motion = np.eye(4)
        elif kind == "prismatic":
            motion = _T(np.eye(3), q.get(name, 0.0) * np.asarray(axis, float))
        else:
            motion = _T(_rot(axis, q.get(name, 0.0)), np.zeros(3))
        T = _T(_rpy(*rpy), xyz) @ motion @ T
        link = parent
    return T


def expected_point(cal, q, R_world_imu, sensor_id, range_m, stance="l", imu_id="imu_trunk", joints=JOINTS):
    mounts = {m.sensor_id: m for m in cal.mounts}
    imu = mounts[imu_id]
    R_p_imu = (chain_T(imu.parent_link, q, joints) @ imu.T_parent_sensor)[:3, :3]
    R_w_p = R_world_imu @ R_p_imu.T
    m = mounts[sensor_id]
    T_p_s = chain_T(m.parent_link, q, joints) @ m.T_parent_sensor
    p_p_ankle = chain_T(f"foot_{stance}", q, joints)[:3, 3]  # the foot's origin is the ankle joint
    return R_w_p @ (T_p_s[:3, 3] + T_p_s[:3, :3] @ np.array([0.0, 0.0, range_m])) - R_w_p @ p_p_ankle + np.array([0.0, 0.0, cal.sole_height_m])


def _random_rotation(rng):
    return _rot(rng.normal(size=3), rng.uniform(0.0, 2.5))


@pytest.mark.parametrize("stance", ["l", "r"])
def test_point_equals_an_independent_chain(stance):
    cal = tiny_calibration()
    kin = TofKinematics(cal, stance_side=stance)
    rng = np.random.default_rng(11)
    for trial in range(25):
        names = [j[0] for j in JOINTS if rng.random() < 0.85]  # missing joints stay at 0
        q = {n: float(rng.uniform(-1.2, 1.2)) for n in names}
        R_wi = _random_rotation(rng)
        kin.update_joints(JointState(0.01 * trial, "encoders", tuple(q) + ("neck_yaw",), np.array([*q.values(), 0.7])))
        kin.update_imu(ImuSample(0.01 * trial, "imu_trunk", _quat_wxyz(R_wi), np.zeros(3), np.zeros(3)))
        for sid in ("tof_r_med", "tof_r_lat", "tof_l_med", "tof_l_lat"):
            r = float(rng.uniform(0.04, 2.0))
            np.testing.assert_allclose(kin.point(sid, r), expected_point(cal, q, R_wi, sid, r, stance), atol=1e-9, rtol=0)
        T = kin.T_estimator_sensor("tof_r_lat")
        np.testing.assert_allclose(T[:3, 3], expected_point(cal, q, R_wi, "tof_r_lat", 0.0, stance), atol=1e-9, rtol=0)


def test_imu_on_a_moving_link_and_zero_posture():
    cal = tiny_calibration()
    kin = TofKinematics(cal, stance_side="l", imu_sensor_id="imu_thigh")
    assert not kin.has_state
    rng = np.random.default_rng(5)
    q = {"hip_r": 0.4, "knee_r": 0.9}
    R_wi = _random_rotation(rng)
    kin.set_joints(q)
    kin.set_orientation(R_wi)
    np.testing.assert_allclose(kin.point("tof_r_med", 0.5), expected_point(cal, q, R_wi, "tof_r_med", 0.5, imu_id="imu_thigh"), atol=1e-9, rtol=0)
    # a later state without hip_r puts it back to 0
    kin.set_joints({"knee_r": 0.9})
    np.testing.assert_allclose(kin.point("tof_r_med", 0.5), expected_point(cal, {"knee_r": 0.9}, R_wi, "tof_r_med", 0.5, imu_id="imu_thigh"), atol=1e-9, rtol=0)


def test_level_pelvis_puts_the_stance_ankle_sole_height_above_the_origin():
    cal = tiny_calibration()
    kin = TofKinematics(cal, stance_side="l")
    kin.set_joints({})
    kin.set_orientation(MOUNTS[4].T_parent_sensor[:3, :3])  # the IMU reports its mount: pelvis level
    # zero range: the mount itself, relative to the ankle joint, lifted by the sole height
    mount = chain_T("shank_l", {}) @ np.array([0.06, -0.04, -0.2, 1.0])
    expected = mount[:3] - chain_T("foot_l", {})[:3, 3] + np.array([0.0, 0.0, SOLE_M])
    np.testing.assert_allclose(kin.point("tof_l_med", 0.0), expected, atol=1e-12)


def test_unknown_names_raise_typed_errors():
    from exobench.core import ConfigError, UnknownNameError

    cal = tiny_calibration()
    with pytest.raises(UnknownNameError):
        TofKinematics(cal, imu_sensor_id="imu_nowhere")
    with pytest.raises(ConfigError):
        TofKinematics(cal, stance_side="x")
    kin = TofKinematics(cal)
    with pytest.raises(UnknownNameError):
        kin.T_base_sensor("tof_x")


def test_with_the_exoskeleton_calibration_of_models():
    from exobench.models import exo as exo_mod
    from exobench.models.exo_spec import ANKLE_AXIS, HIP_AXIS, KNEE_AXIS, ExoSpec

    spec = ExoSpec()
    cal = exo_mod.exo_calibration(spec)
    kin = TofKinematics(cal, stance_side="l")
    # the URDF of the models contract: thigh origin at the hip joint, knee at (0, 0, -thigh_m),
    # shank origin at the knee, ankle at (0, 0, -shank_m), foot origin at the ankle
    joints = []
    for side in ("l", "r"):
        joints += [
            (f"hip_{side}", "pelvis", f"thigh_{side}", tuple(spec.hip_offset(side)), (0, 0, 0), tuple(HIP_AXIS), "revolute"),
            (f"knee_{side}", f"thigh_{side}", f"shank_{side}", (0, 0, -spec.thigh_m), (0, 0, 0), tuple(KNEE_AXIS), "revolute"),
            (f"ankle_{side}", f"shank_{side}", f"foot_{side}", (0, 0, -spec.shank_m), (0, 0, 0), tuple(ANKLE_AXIS), "revolute"),
        ]
    rng = np.random.default_rng(3)
    for _ in range(10):
        q = {j[0]: float(rng.uniform(-1.0, 1.0)) for j in joints}
        R_wi = _random_rotation(rng)
        kin.set_joints(q)
        kin.set_orientation(R_wi)
        for sid in ("tof_r_med", "tof_r_lat"):
            r = float(rng.uniform(0.04, 2.0))
            np.testing.assert_allclose(kin.point(sid, r), expected_point(cal, q, R_wi, sid, r, "l", joints=joints), atol=1e-9, rtol=0)


def test_joint_types_without_a_compiled_chain_use_pinocchio():
    # the calf sensors ride on a floating joint: the float chains do not handle it
    joints = JOINTS + [("float_r", "shank_r", "calf_r", (0.0, 0.01, -0.1), (0.0, 0.02, 0.0), (0, 0, 1), "floating")]
    mounts = tuple(
        SensorMount(m.sensor_id, m.kind, "calf_r" if m.parent_link == "shank_r" else m.parent_link, m.T_parent_sensor)
        for m in MOUNTS
    )
    cal = tiny_calibration(joints, mounts)
    kin = TofKinematics(cal, stance_side="l")
    rng = np.random.default_rng(8)
    for _ in range(5):
        q = {j[0]: float(rng.uniform(-1.0, 1.0)) for j in JOINTS}
        R_wi = _random_rotation(rng)
        kin.set_joints(q)
        kin.set_orientation(R_wi)
        for sid in ("tof_r_med", "tof_l_lat"):
            r = float(rng.uniform(0.04, 2.0))
            want = expected_point(cal, q, R_wi, sid, r, "l", joints=joints)
            np.testing.assert_allclose(kin.point(sid, r), want, atol=1e-9, rtol=0)
            assert kin.point_xyz(sid, r) == tuple(kin.point(sid, r))


def test_points_follow_new_states_and_cover_every_mount():
    """Lazy kinematics: each new encoder or IMU state is used by the next point, for any mount."""
    cal = tiny_calibration()
    kin = TofKinematics(cal, stance_side="r")
    rng = np.random.default_rng(9)
    q = {j[0]: float(rng.uniform(-1.0, 1.0)) for j in JOINTS}
    R_wi = _random_rotation(rng)
    kin.set_joints(q)
    kin.update_imu(ImuSample(0.0, "imu_trunk", _quat_wxyz(R_wi), np.zeros(3), np.zeros(3)))
    for step in range(6):
        for sid in [m.sensor_id for m in MOUNTS]:  # the IMU mounts too: any mount's +z axis
            want = expected_point(cal, q, R_wi, sid, 0.3, "r")
            np.testing.assert_allclose(kin.point(sid, 0.3), want, atol=1e-9, rtol=0)
        if step % 2:
            q = dict(q, knee_r=q["knee_r"] + 0.1, hip_l=q["hip_l"] - 0.05)
            kin.update_joints(JointState(0.01 * step, "encoders", tuple(q), np.array(list(q.values()))))
        else:
            R_wi = _rot([0.0, 0.0, 1.0], 0.1) @ R_wi
            kin.update_imu(ImuSample(0.01 * step, "imu_trunk", _quat_wxyz(R_wi), np.zeros(3), np.zeros(3)))
