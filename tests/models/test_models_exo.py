"""The exoskeleton model: MuJoCo and pinocchio (from the URDF + Calibration) agree on every pose."""

from __future__ import annotations

import mujoco
import numpy as np
import pinocchio as pin
import pytest

from exobench.core.errors import UnknownNameError
from exobench.core.transforms import make_T, quat_wxyz_to_matrix
from exobench.models.exo import R_OPTICAL_MJCAMERA, add_exo, exo_calibration, exo_urdf
from exobench.models.exo_spec import CONTACT_IDS, LEG_JOINTS, NECK_JOINTS, RGBD_IDS, TOF_IDS, ExoSpec

BODIES = ("pelvis", "thigh_l", "shank_l", "foot_l", "thigh_r", "shank_r", "foot_r", "head")
SENSORS = (*TOF_IDS, "imu_trunk", "lidar_trunk", *RGBD_IDS, *CONTACT_IDS)


def _compiled(exo: ExoSpec) -> tuple[mujoco.MjModel, mujoco.MjData]:
    spec = mujoco.MjSpec()
    add_exo(spec, exo)
    model = spec.compile()
    return model, mujoco.MjData(model)


def _random_rotation(rng: np.random.Generator) -> np.ndarray:
    q = rng.normal(size=4)
    return quat_wxyz_to_matrix(q / np.linalg.norm(q))


@pytest.mark.parametrize("height_m", [1.60, 1.90])
def test_pinocchio_fk_of_every_mount_equals_mujoco_site(height_m: float) -> None:
    exo = ExoSpec(user_height_m=height_m, user_mass_kg=70.0)
    model, data = _compiled(exo)
    calib = exo_calibration(exo)
    pm = pin.buildModelFromXML(calib.robot_urdf)
    pd = pm.createData()
    rng = np.random.default_rng(7)
    joints = (*LEG_JOINTS, *NECK_JOINTS)
    for _ in range(20):
        angles = {j: rng.uniform(-1.2, 1.6) for j in joints}
        R_wp, p_wp = _random_rotation(rng), rng.uniform(-3.0, 3.0, size=3)
        # MuJoCo: free joint (position, quaternion wxyz) then the hinges by address
        qpos = np.zeros(model.nq)
        qpos[:3] = p_wp
        mujoco.mju_mat2Quat(quat := np.zeros(4), R_wp.ravel())
        qpos[3:7] = quat
        for j, a in angles.items():
            qpos[model.joint(j).qposadr[0]] = a
        data.qpos[:] = qpos
        mujoco.mj_kinematics(model, data)
        # pinocchio: fixed pelvis root; compose the base pose ourselves
        q = np.zeros(pm.nq)
        for j, a in angles.items():
            q[pm.joints[pm.getJointId(j)].idx_q] = a
        pin.forwardKinematics(pm, pd, q)
        pin.updateFramePlacements(pm, pd)
        T_wp = make_T(R_wp, p_wp)

        def T_world_link(link: str, T_wp: np.ndarray = T_wp) -> np.ndarray:
            return T_wp @ pd.oMf[pm.getFrameId(link, pin.BODY)].homogeneous

        for b in BODIES:
            T = T_world_link(b)
            np.testing.assert_allclose(data.body(b).xpos, T[:3, 3], atol=1e-9)
            np.testing.assert_allclose(data.body(b).xmat.reshape(3, 3), T[:3, :3], atol=1e-9)
        for sid in SENSORS:
            m = calib.mount(sid)
            T = T_world_link(m.parent_link) @ m.T_parent_sensor
            site = data.site(sid)
            np.testing.assert_allclose(site.xpos, T[:3, 3], atol=1e-9, err_msg=sid)
            np.testing.assert_allclose(site.xmat.reshape(3, 3), T[:3, :3], atol=1e-9, err_msg=sid)
        for side in ("l", "r"):  # sole and toe sites: on the sole plane of the foot, below the ankle / at the toe tip
            T_foot = T_world_link(f"foot_{side}")
            below = T_foot[:3, :3] @ np.array([0.0, 0.0, -exo.sole_height_m]) + T_foot[:3, 3]
            np.testing.assert_allclose(data.site(f"sole_{side}").xpos, below, atol=1e-9)
            toe = T_foot[:3, :3] @ np.array([exo.foot_m - exo.heel_to_ankle_m, 0.0, -exo.sole_height_m]) + T_foot[:3, 3]
            np.testing.assert_allclose(data.site(f"toe_{side}").xpos, toe, atol=1e-9)


def test_cameras_are_optical_frames_turned_to_mujoco_convention() -> None:
    model, data = _compiled(ExoSpec())
    data.qpos[7:] = np.linspace(-0.5, 0.8, model.nq - 7)
    mujoco.mj_kinematics(model, data)
    mujoco.mj_camlight(model, data)
    for sid in RGBD_IDS:
        R_site = data.site(sid).xmat.reshape(3, 3)
        R_cam = data.cam(sid).xmat.reshape(3, 3)
        np.testing.assert_allclose(data.cam(sid).xpos, data.site(sid).xpos, atol=1e-12)
        np.testing.assert_allclose(R_cam, R_site @ R_OPTICAL_MJCAMERA, atol=1e-12)
        # the MuJoCo camera looks along its -z, which is the optical +z axis
        np.testing.assert_allclose(-R_cam[:, 2], R_site[:, 2], atol=1e-12)


def test_zero_posture_stands_with_soles_on_the_floor() -> None:
    exo = ExoSpec(user_height_m=1.80)
    model, data = _compiled(exo)
    mujoco.mj_kinematics(model, data)
    for side in ("l", "r"):
        assert abs(data.site(f"sole_{side}").xpos[2]) < 1e-12
        # the foot plate's underside is the sole: z = 0, from the heel to the toe
        g = data.geom(f"exo_footplate_{side}")
        half = model.geom(f"exo_footplate_{side}").size
        corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]) * half
        pts = corners @ g.xmat.reshape(3, 3).T + g.xpos
        ankle = data.body(f"foot_{side}").xpos
        assert abs(pts[:, 2].min()) < 1e-12
        np.testing.assert_allclose(pts[:, 0].min() - ankle[0], -exo.heel_to_ankle_m, atol=1e-12)
        np.testing.assert_allclose(pts[:, 0].max() - ankle[0], exo.foot_m - exo.heel_to_ankle_m, atol=1e-12)
    np.testing.assert_allclose(data.body("pelvis").xpos[2], exo.thigh_m + exo.shank_m + exo.sole_height_m, atol=1e-12)


def test_masses_and_inertias_are_the_same_in_mujoco_and_urdf() -> None:
    exo = ExoSpec(user_mass_kg=82.0, exo_mass_kg=20.0)
    model, _ = _compiled(exo)
    pm = pin.buildModelFromXML(exo_urdf(exo))
    assert model.body_mass.sum() == pytest.approx(82.0 + 20.0, abs=1e-9)
    # pinocchio fixes the root link to the universe and keeps its inertia in inertias[0]
    assert sum(i.mass for i in pm.inertias) == pytest.approx(82.0 + 20.0, abs=1e-9)
    for b in BODIES:
        inert = pm.inertias[pm.frames[pm.getFrameId(b, pin.BODY)].parentJoint]
        if b == "pelvis":
            inert = pm.inertias[0]
        assert model.body(b).mass[0] == pytest.approx(inert.mass, abs=1e-12)
        np.testing.assert_allclose(model.body(b).ipos, inert.lever, atol=1e-12)
        np.testing.assert_allclose(np.diag(inert.inertia), model.body(b).inertia, rtol=1e-12)


def test_exo_geoms_are_visual_only_in_group_2() -> None:
    model, _ = _compiled(ExoSpec())
    assert model.ngeom > 20
    for g in range(model.ngeom):
        assert model.geom_group[g] == 2
        assert model.geom_contype[g] == 0 and model.geom_conaffinity[g] == 0


def test_calibration_lists_every_mount_with_parameters() -> None:
    exo = ExoSpec()
    calib = exo_calibration(exo, {"tof": {"rate_hz": 25.0}, "tof_r_lat": {"noise_sigma_m": 0.003}})
    assert calib.base_link == "pelvis" and calib.joint_names == LEG_JOINTS
    assert {m.sensor_id for m in calib.mounts} == set(SENSORS)
    assert calib.mount("tof_r_lat").params["rate_hz"] == 25.0
    assert calib.mount("tof_r_lat").params["noise_sigma_m"] == 0.003
    assert calib.mount("tof_l_med").params["noise_sigma_m"] == 0.0015
    assert calib.sole_height_m == exo.sole_height_m and calib.foot_length_m == exo.foot_m
    # the ToF beam (+z) points forward and down from the shin
    for sid in TOF_IDS:
        z = calib.mount(sid).T_parent_sensor[:3, 2]
        assert z[0] > 0.5 and z[2] < 0.0
    with pytest.raises(UnknownNameError):
        exo_calibration(exo, {"tof_x": {}})


def test_model_compiles_without_warnings() -> None:
    model, data = _compiled(ExoSpec())
    mujoco.mj_forward(model, data)
    assert data.warning.number.sum() == 0
