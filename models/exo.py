"""The exoskeleton with its user: MuJoCo bodies (through ``mujoco.MjSpec``), a URDF and a Calibration.

All three are generated from one :class:`~exobench.models.exo_spec.ExoSpec` and one body table
(:func:`body_table`), so MuJoCo's kinematics, pinocchio's (from :func:`exo_urdf`) and the sensor
mounts of :func:`exo_calibration` agree by construction; ``tests/models/test_models_exo.py`` checks it.
See ``models/README.md`` for sources, frames and joint signs.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from exobench.core.calibration import Calibration, SensorMount
from exobench.core.errors import UnknownNameError
from exobench.core.transforms import matrix_to_quat_wxyz

from .exo_spec import (
    ANKLE_AXIS,
    CONTACT_IDS,
    CONTACT_PADS,
    HIP_AXIS,
    JOINT_RANGES_RAD,
    KNEE_AXIS,
    LEG_JOINTS,
    NECK_PITCH_AXIS,
    NECK_YAW_AXIS,
    RGBD_IDS,
    TOF_IDS,
    ExoSpec,
)

if TYPE_CHECKING:
    import mujoco

EXO_GEOM_GROUP = 2
# MuJoCo cameras look along their -z with +y up; optical frames look along +z with +y down.
R_OPTICAL_MJCAMERA = np.diag([1.0, -1.0, -1.0])
SENSOR_KINDS = ("tof", "imu", "lidar", "rgbd", "contact")


@dataclass(frozen=True)
class BodyDef:
    """One rigid body of the exoskeleton+user tree.

    ``pos_parent`` is the body origin in the parent frame at zero joint angles (the frames are
    parallel then); ``joints`` are (name, unit axis in the body frame, (low, high) rad), applied
    in order. ``segment`` names the mass table entry of :meth:`ExoSpec.segment_mass_kg`.
    """

    name: str
    parent: str | None
    pos_parent: np.ndarray
    joints: tuple[tuple[str, np.ndarray, tuple[float, float]], ...]
    segment: str


def body_table(exo: ExoSpec) -> tuple[BodyDef, ...]:
    """The body tree, parents first. The pelvis's ``pos_parent`` is its standing pose in the world."""
    r = JOINT_RANGES_RAD
    out = [BodyDef("pelvis", None, np.array([0.0, 0.0, exo.leg_m]), (), "pelvis")]
    for s in ("l", "r"):
        out += [
            BodyDef(f"thigh_{s}", "pelvis", exo.hip_offset(s), ((f"hip_{s}", HIP_AXIS, r["hip"]),), "thigh"),
            BodyDef(f"shank_{s}", f"thigh_{s}", np.array([0.0, 0.0, -exo.thigh_m]), ((f"knee_{s}", KNEE_AXIS, r["knee"]),), "shank"),
            BodyDef(f"foot_{s}", f"shank_{s}", np.array([0.0, 0.0, -exo.shank_m]), ((f"ankle_{s}", ANKLE_AXIS, r["ankle"]),), "foot"),
        ]
    neck = (("neck_yaw", NECK_YAW_AXIS, r["neck_yaw"]), ("neck_pitch", NECK_PITCH_AXIS, r["neck_pitch"]))
    out.append(BodyDef("head", "pelvis", exo.neck_offset, neck, "head"))
    return tuple(out)


def sensor_mounts(exo: ExoSpec) -> tuple[tuple[str, str, str, np.ndarray], ...]:
    """Every sensor as (sensor_id, kind, parent body, T_parent_sensor)."""
    out: list[tuple[str, str, str, np.ndarray]] = []
    for sid in TOF_IDS:
        out.append((sid, "tof", *exo.tof_mount(sid)))
    out.append(("imu_trunk", "imu", *exo.imu_mount()))
    out.append(("lidar_trunk", "lidar", *exo.lidar_mount()))
    for sid in RGBD_IDS:
        out.append((sid, "rgbd", *exo.rgbd_mount(sid)))
    for sid in CONTACT_IDS:
        out.append((sid, "contact", *exo.contact_mount(sid)))
    return tuple(out)


def site_poses(exo: ExoSpec) -> tuple[tuple[str, str, np.ndarray], ...]:
    """Every MuJoCo site as (name, parent body, T_parent_site): the sensors plus soles and toes."""
    out = [(sid, parent, T) for sid, _, parent, T in sensor_mounts(exo)]
    for s in ("l", "r"):
        out.append((f"sole_{s}", *exo.sole_mount(s)))
        out.append((f"toe_{s}", *exo.toe_tip(s)))
    return tuple(out)


def default_sensor_params(kind: str) -> dict[str, Any]:
    """Nominal parameters per sensor kind (SI units; see docs/sensor-reference.md for sources)."""
    if kind == "tof":  # ST VL53L1X as used by the staircase paper
        return {"rate_hz": 50.0, "min_range_m": 0.04, "max_range_m": 4.0, "noise_sigma_m": 0.0015, "fov_deg": 27.0}
    if kind == "imu":
        return {"rate_hz": 200.0}
    if kind == "lidar":  # Velodyne VLP-16
        return {"rate_hz": 10.0, "channels": 16, "min_elevation_deg": -15.0, "max_elevation_deg": 15.0,
                "azimuth_step_deg": 0.2, "min_range_m": 0.9, "max_range_m": 100.0}
    if kind == "rgbd":  # Intel RealSense D455 depth stream at 848x480
        w, h, fovy = 848, 480, 58.0
        f = 0.5 * h / np.tan(np.radians(0.5 * fovy))
        return {"rate_hz": 30.0, "width_px": w, "height_px": h, "fovy_deg": fovy, "fx_px": float(f),
                "fy_px": float(f), "cx_px": 0.5 * (w - 1), "cy_px": 0.5 * (h - 1), "min_depth_m": 0.4,
                "max_depth_m": 6.0}
    if kind == "contact":
        return {"rate_hz": 100.0, "threshold_n": 20.0}
    raise UnknownNameError("sensor kind", kind, SENSOR_KINDS)


# --- MuJoCo ---------------------------------------------------------------------------------


def _add_materials(spec: mujoco.MjSpec) -> None:
    looks = {
        "exo_frame": ((0.22, 0.24, 0.27, 1.0), 0.6),
        "exo_cuff": ((0.08, 0.08, 0.09, 1.0), 0.2),
        "exo_sensor": ((0.85, 0.45, 0.10, 1.0), 0.3),
        "user_skin": ((0.80, 0.62, 0.50, 1.0), 0.1),
        "user_shirt": ((0.25, 0.40, 0.60, 1.0), 0.05),
        "user_trousers": ((0.18, 0.20, 0.26, 1.0), 0.05),
        "user_shoe": ((0.12, 0.10, 0.09, 1.0), 0.3),
        "user_hair": ((0.20, 0.14, 0.10, 1.0), 0.1),
    }
    for name, (rgba, spec_) in looks.items():
        spec.add_material(name=name, rgba=list(rgba), specular=spec_, shininess=0.4 * spec_)


def _visual(body: mujoco.MjsBody, name: str, gtype: str, material: str, *, size: list[float],
            pos: np.ndarray | list[float] | None = None, fromto: list[float] | None = None,
            R: np.ndarray | None = None) -> None:
    import mujoco

    kw: dict[str, Any] = {"name": name, "type": getattr(mujoco.mjtGeom, f"mjGEOM_{gtype.upper()}"),
                          "size": size + [0.0] * (3 - len(size)), "material": material,
                          "group": EXO_GEOM_GROUP, "contype": 0, "conaffinity": 0, "mass": 0.0}
    if fromto is not None:
        kw["fromto"] = fromto
    else:
        kw["pos"] = list(pos if pos is not None else (0.0, 0.0, 0.0))
        if R is not None:
            kw["quat"] = list(matrix_to_quat_wxyz(R))
    body.add_geom(**kw)


def _add_visuals(bodies: dict[str, mujoco.MjsBody], exo: ExoSpec) -> None:
    """Geoms for looks and for ground-truth contact checks; they carry no mass (see BodyDef)."""
    H = exo.user_height_m
    t = exo.trunk_m
    p = bodies["pelvis"]
    _visual(p, "exo_pelvis", "box", "user_trousers", size=[0.09, 0.5 * exo.hip_width_m + 0.06, 0.08], pos=[0.0, 0.0, 0.03])
    _visual(p, "exo_torso", "box", "user_shirt", size=[0.10, 0.17, 0.36 * t], pos=[0.0, 0.0, 0.56 * t])
    _visual(p, "exo_shoulders", "capsule", "user_shirt", size=[0.06], fromto=[0, -0.16, 0.9 * t, 0, 0.16, 0.9 * t])
    _visual(p, "exo_backpack", "box", "exo_frame", size=[0.04, 0.16, 0.09], pos=[-0.14, 0.0, 0.10])
    _visual(p, "exo_hipbar", "box", "exo_frame", size=[0.03, 0.5 * exo.hip_width_m + 0.08, 0.025], pos=[-0.06, 0.0, 0.0])
    if exo.lidar_height_m is None:  # the LiDAR's mast
        _visual(p, "exo_mast", "capsule", "exo_frame", size=[0.012], fromto=[-0.15, 0, 0.19, -0.15, 0, t + 0.11])
    _, T_lidar = exo.lidar_mount()
    _visual(p, "exo_lidar", "cylinder", "exo_cuff", size=[0.0515, 0.036], pos=T_lidar[:3, 3])
    for s, y in (("l", 0.20), ("r", -0.20)):  # arms hang forward to the crutch handles [A]
        elbow = [0.05, y * 1.08, 0.9 * t - 0.186 * H]
        _visual(p, f"exo_upperarm_{s}", "capsule", "user_shirt", size=[0.04], fromto=[0, y, 0.9 * t, *elbow])
        _visual(p, f"exo_forearm_{s}", "capsule", "user_skin", size=[0.032], fromto=[*elbow, 0.25, y * 1.1, elbow[2] - 0.03])
    for s in ("l", "r"):
        out = 1.0 if s == "l" else -1.0
        th, sh, ft = bodies[f"thigh_{s}"], bodies[f"shank_{s}"], bodies[f"foot_{s}"]
        r_th, r_sh = 0.040 * H, 0.028 * H
        _visual(th, f"exo_thigh_{s}", "capsule", "user_trousers", size=[r_th], fromto=[0, 0, -0.03, 0, 0, -exo.thigh_m + 0.04])
        _visual(th, f"exo_thigh_bar_{s}", "box", "exo_frame", size=[0.018, 0.008, 0.5 * exo.thigh_m - 0.03],
                pos=[0.0, out * (r_th + 0.012), -0.5 * exo.thigh_m])
        _visual(th, f"exo_thigh_cuff_{s}", "box", "exo_cuff", size=[0.03, r_th + 0.01, 0.03], pos=[0.0, 0.0, -0.55 * exo.thigh_m])
        _visual(th, f"exo_knee_motor_{s}", "cylinder", "exo_frame", size=[0.045, 0.02],
                pos=[0.0, out * (r_th + 0.025), -exo.thigh_m], R=np.array([[1, 0, 0], [0, 0, -1], [0, 1, 0.0]]))
        _visual(sh, f"exo_shank_{s}", "capsule", "user_trousers", size=[r_sh], fromto=[0, 0, -0.03, 0, 0, -exo.shank_m + 0.05])
        _visual(sh, f"exo_shank_bar_{s}", "box", "exo_frame", size=[0.016, 0.008, 0.5 * exo.shank_m - 0.04],
                pos=[0.0, out * (r_sh + 0.012), -0.5 * exo.shank_m])
        _visual(sh, f"exo_shank_cuff_{s}", "box", "exo_cuff", size=[0.025, r_sh + 0.01, 0.025], pos=[0.0, 0.0, -0.45 * exo.shank_m])
        for sid in TOF_IDS:
            if sid.startswith(f"tof_{s}_"):
                _, T = exo.tof_mount(sid)
                _visual(sh, f"exo_{sid}", "box", "exo_sensor", size=[0.012, 0.008, 0.006],
                        pos=T[:3, :3] @ np.array([0.0, 0.0, -0.006]) + T[:3, 3], R=T[:3, :3])
        heel, toe = -exo.heel_to_ankle_m, exo.foot_m - exo.heel_to_ankle_m
        plate = 0.008
        sole = -exo.sole_height_m
        _visual(ft, f"exo_footplate_{s}", "box", "exo_cuff", size=[0.5 * (toe - heel), 0.026 * H, 0.5 * plate],
                pos=[0.5 * (toe + heel), 0.0, sole + 0.5 * plate])
        top = 0.015
        _visual(ft, f"exo_shoe_{s}", "box", "user_shoe", size=[0.5 * (toe - heel) - 0.005, 0.024 * H, 0.5 * (top - sole - plate)],
                pos=[0.5 * (toe + heel) - 0.005, 0.0, 0.5 * (top + sole + plate)])
    hd = bodies["head"]
    r_head = 0.085
    _visual(hd, "exo_neck", "capsule", "user_skin", size=[0.045], fromto=[0, 0, 0.0, 0, 0, exo.head_m - 1.6 * r_head])
    _visual(hd, "exo_head", "sphere", "user_skin", size=[r_head], pos=[0.0, 0.0, exo.head_m - r_head])
    _visual(hd, "exo_hair", "ellipsoid", "user_hair", size=[r_head * 1.02, r_head * 1.02, 0.55 * r_head],
            pos=[-0.01, 0.0, exo.head_m - 0.55 * r_head])
    for sid in RGBD_IDS:  # D455 housing, 124 x 29 x 26 mm, behind the optical centre
        parent, T = exo.rgbd_mount(sid)
        _visual(bodies[parent], f"exo_{sid}", "box", "exo_cuff", size=[0.062, 0.0145, 0.013],
                pos=T[:3, :3] @ np.array([0.0, 0.0, -0.014]) + T[:3, 3], R=T[:3, :3])


def add_exo(spec: mujoco.MjSpec, exo: ExoSpec) -> None:
    """Add the exoskeleton with its user to ``spec``, standing at the world origin.

    Bodies, joints, sites and cameras are named as in the module contract (``pelvis`` with free
    joint ``root``; hinges ``hip_l knee_l ankle_l hip_r knee_r ankle_r neck_yaw neck_pitch``;
    one site per sensor id plus ``sole_*``/``toe_*``; one camera per RGB-D id). Masses and
    inertias are explicit (:meth:`ExoSpec.segment_inertial`); geoms are visual, in group 2,
    with collisions off (the motion is kinematic).
    """
    import mujoco

    _add_materials(spec)
    bodies: dict[str, Any] = {}
    for bd in body_table(exo):
        parent = spec.worldbody if bd.parent is None else bodies[bd.parent]
        com, inertia = exo.segment_inertial(bd.segment)
        body = parent.add_body(name=bd.name, pos=list(bd.pos_parent), explicitinertial=True,
                               mass=exo.segment_mass_kg(bd.segment), ipos=list(com), inertia=list(inertia))
        if bd.parent is None:
            body.add_freejoint(name="root")
        for jname, axis, (lo, hi) in bd.joints:
            body.add_joint(name=jname, type=mujoco.mjtJoint.mjJNT_HINGE, axis=list(axis),
                           range=[np.degrees(lo), np.degrees(hi)] if spec.compiler.degree else [lo, hi],
                           limited=mujoco.mjtLimited.mjLIMITED_TRUE)
        bodies[bd.name] = body
    for name, parent, T in site_poses(exo):
        bodies[parent].add_site(name=name, pos=list(T[:3, 3]), quat=list(matrix_to_quat_wxyz(T[:3, :3])),
                                size=[0.006, 0.0, 0.0], group=EXO_GEOM_GROUP + 1, rgba=[0.9, 0.2, 0.2, 1.0])
    rgbd = default_sensor_params("rgbd")
    for sid in RGBD_IDS:
        parent, T = exo.rgbd_mount(sid)
        bodies[parent].add_camera(name=sid, pos=list(T[:3, 3]), quat=list(matrix_to_quat_wxyz(T[:3, :3] @ R_OPTICAL_MJCAMERA)),
                                  fovy=rgbd["fovy_deg"], resolution=[rgbd["width_px"], rgbd["height_px"]])
    _add_visuals(bodies, exo)


# --- URDF -----------------------------------------------------------------------------------


def _f(x: float) -> str:
    return repr(float(x))


def _v(v: np.ndarray) -> str:
    return " ".join(_f(x) for x in v)


def _link(name: str, mass: float | None = None, com: np.ndarray | None = None, inertia: np.ndarray | None = None) -> str:
    if mass is None:
        return f'  <link name="{name}"/>'
    ixx, iyy, izz = inertia
    return (f'  <link name="{name}">\n    <inertial>\n      <origin xyz="{_v(com)}" rpy="0 0 0"/>\n'
            f'      <mass value="{_f(mass)}"/>\n'
            f'      <inertia ixx="{_f(ixx)}" ixy="0" ixz="0" iyy="{_f(iyy)}" iyz="0" izz="{_f(izz)}"/>\n'
            f'    </inertial>\n  </link>')


def _joint(name: str, parent: str, child: str, xyz: np.ndarray, axis: np.ndarray, rng: tuple[float, float]) -> str:
    return (f'  <joint name="{name}" type="revolute">\n    <parent link="{parent}"/>\n    <child link="{child}"/>\n'
            f'    <origin xyz="{_v(xyz)}" rpy="0 0 0"/>\n    <axis xyz="{_v(axis)}"/>\n'
            f'    <limit lower="{_f(rng[0])}" upper="{_f(rng[1])}" effort="300" velocity="10"/>\n  </joint>')


def exo_urdf(exo: ExoSpec) -> str:
    """URDF of the same body tree: links ``pelvis`` (root), thighs, shanks, feet, ``neck``, ``head``.

    The head's two joints need an extra massless link ``neck`` between ``neck_yaw`` and
    ``neck_pitch`` (MuJoCo puts both joints in the head body). No sensor links: the mounts
    are in the :class:`~exobench.core.calibration.Calibration`. Floats are written with
    ``repr`` so they round-trip exactly.
    """
    parts = ['<?xml version="1.0"?>', f'<robot name="exobench_exo_{exo.user_height_m:.2f}m">']
    for bd in body_table(exo):
        com, inertia = exo.segment_inertial(bd.segment)
        mass = exo.segment_mass_kg(bd.segment)
        parent = bd.parent
        xyz = bd.pos_parent
        for k, (jname, axis, rng) in enumerate(bd.joints):
            last = k == len(bd.joints) - 1
            child = bd.name if last else jname.rsplit("_", 1)[0]  # neck_yaw -> link "neck"
            if not last:
                parts.append(_link(child))
            parts.append(_joint(jname, parent, child, xyz, axis, rng))
            parent, xyz = child, np.zeros(3)
        parts.append(_link(bd.name, mass, com, inertia))
    parts.append("</robot>")
    return "\n".join(parts) + "\n"


# --- Calibration ----------------------------------------------------------------------------


def exo_calibration(exo: ExoSpec, sensor_params: dict[str, dict] | None = None) -> Calibration:
    """The device as a pipeline knows it: URDF, encoder joint order and every sensor mount.

    ``sensor_params`` overrides :func:`default_sensor_params`; keys are sensor kinds (apply to
    every sensor of that kind) or sensor ids (apply to one sensor, after the kind's).
    """
    mounts = sensor_mounts(exo)
    ids = [m[0] for m in mounts]
    overrides = dict(sensor_params or {})
    for key in overrides:
        if key not in ids and key not in SENSOR_KINDS:
            raise UnknownNameError("sensor or sensor kind", key, [*ids, *SENSOR_KINDS])
    out = []
    for sid, kind, parent, T in mounts:
        params = default_sensor_params(kind)
        params.update(overrides.get(kind, {}))
        params.update(overrides.get(sid, {}))
        if kind == "contact":  # which foot and which pad: pipelines read it here, not from the id
            params["side"], params["pad"] = CONTACT_PADS[sid]
        out.append(SensorMount(sensor_id=sid, kind=kind, parent_link=parent, T_parent_sensor=T.copy(), params=params))
    extra = {
        "exo": asdict(exo),
        "neck_joints": ("neck_yaw", "neck_pitch"),
        "thigh_m": exo.thigh_m,
        "shank_m": exo.shank_m,
        "hip_width_m": exo.hip_width_m,
        "leg_m": exo.leg_m,
    }
    return Calibration(robot_urdf=exo_urdf(exo), base_link="pelvis", joint_names=LEG_JOINTS, mounts=tuple(out),
                       sole_height_m=exo.sole_height_m, foot_length_m=exo.foot_m, heel_to_ankle_m=exo.heel_to_ankle_m,
                       extra=extra)


__all__ = [
    "EXO_GEOM_GROUP",
    "R_OPTICAL_MJCAMERA",
    "BodyDef",
    "add_exo",
    "body_table",
    "default_sensor_params",
    "exo_calibration",
    "exo_urdf",
    "sensor_mounts",
    "site_poses",
]
