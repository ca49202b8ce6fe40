"""Dimensions of the exoskeleton with its user, and its sensor mounts.

One dataclass, :class:`ExoSpec`, is the single source of every length, mass and mount pose;
the MuJoCo model, the URDF that estimators load with pinocchio, and the gait driver all read
it, so they agree by construction (a test checks MuJoCo's and pinocchio's kinematics agree).

Segment lengths and masses are fractions of the user's height and mass from de Leva (1996)
(thigh 0.2425, shank 0.2493, foot 0.1482 of height; masses 0.1416, 0.0433, 0.0137 of body mass,
male) and Winter (2009) (ankle height 0.039, hip height 0.530, shoulder 0.818, head top 1.0 of
height). Values marked [A] are assumptions with no source.

Frames (all bodies): x forward, y left, z up when the user stands straight. Sagittal joints
rotate about the lateral axis with these signs: hip flexion +, knee flexion +, ankle
dorsiflexion (toes up) +. The zero posture is standing straight with both feet flat.
"""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np

from exobench.core.errors import check_range
from exobench.core.transforms import make_T, rot_x, rot_y, rot_z

# joint name -> (parent body, child body); the order is the encoder order
LEG_JOINTS = ("hip_l", "knee_l", "ankle_l", "hip_r", "knee_r", "ankle_r")
NECK_JOINTS = ("neck_yaw", "neck_pitch")
TOF_IDS = ("tof_l_med", "tof_l_lat", "tof_r_med", "tof_r_lat")
CONTACT_IDS = ("contact_l_heel", "contact_l_toe", "contact_r_heel", "contact_r_toe")
CONTACT_PADS = {"contact_l_heel": ("l", "heel"), "contact_l_toe": ("l", "toe"), "contact_r_heel": ("r", "heel"),
                "contact_r_toe": ("r", "toe")}  # fmt: skip
"""Insole pad id -> (foot side, pad): what the calibration says of each pad."""
RGBD_IDS = ("rgbd_head", "rgbd_chest", "rgbd_thigh_l", "rgbd_thigh_r")

# sagittal joint axes in the child body frame (see the module docstring for the signs)
HIP_AXIS = np.array([0.0, -1.0, 0.0])
KNEE_AXIS = np.array([0.0, 1.0, 0.0])
ANKLE_AXIS = np.array([0.0, -1.0, 0.0])
# neck joints of the head body: yaw + turns the face to the left, pitch + looks down
NECK_YAW_AXIS = np.array([0.0, 0.0, 1.0])
NECK_PITCH_AXIS = np.array([0.0, 1.0, 0.0])

# joint ranges, rad [A: normal human range of motion, trimmed to what the device allows]
JOINT_RANGES_RAD = {
    "hip": (np.radians(-30.0), np.radians(120.0)),
    "knee": (np.radians(-5.0), np.radians(130.0)),
    "ankle": (np.radians(-40.0), np.radians(30.0)),
    "neck_yaw": (np.radians(-80.0), np.radians(80.0)),
    "neck_pitch": (np.radians(-40.0), np.radians(60.0)),
}


def _camera_optical(pitch_down_rad: float) -> np.ndarray:
    """Rotation body <- optical frame (z forward, x right, y down) pitched down by ``pitch``."""
    # optical axes expressed in a forward-looking body frame: z_opt = +x, x_opt = -y, y_opt = -z
    R0 = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
    return rot_y(pitch_down_rad) @ R0


@dataclass(frozen=True)
class ExoSpec:
    """The exoskeleton and its user. Every field is validated on construction.

    Attributes (SI units):
        user_height_m: user's standing height, 1.55-1.95 m (exoskeleton users 1.60-1.90).
        user_mass_kg: user's mass, 40-130 kg.
        exo_mass_kg: the device's mass, 5-30 kg (ReWalk 14-15 kg).
        tof_height_m: height of the calf ToF sensors above the ankle joint, m.
        tof_forward_m: their offset in front of the shank axis (on the shin), m.
        tof_separation_m: lateral distance between the two sensors of one calf, m.
        tof_pitch_deg: beam pitch below the shank's forward horizontal, deg.
        tof_toe_out_deg: each beam turned outwards (away from the other) by this yaw, deg.
        camera_pitch_deg: downward pitch of the chest and head camera mounts, deg [A].
        lidar_height_m: None: the trunk LiDAR on a backpack mast above the head (the default);
            else on the front of the pelvis frame at this height above the floor when standing,
            0.4-1.2 m (a VLP-16 on a Unitree B1, the robot of seeds/003's Table 5.4, is at about
            0.68 m).
    """

    user_height_m: float = 1.75
    user_mass_kg: float = 75.0
    exo_mass_kg: float = 14.0
    tof_height_m: float = 0.32
    tof_forward_m: float = 0.06
    tof_separation_m: float = 0.08
    tof_pitch_deg: float = 46.0
    tof_toe_out_deg: float = 4.0
    camera_pitch_deg: float = 30.0
    lidar_height_m: float | None = None

    def __post_init__(self) -> None:
        check_range("exo.user_height_m", self.user_height_m, 1.55, 1.95)
        check_range("exo.user_mass_kg", self.user_mass_kg, 40.0, 130.0)
        check_range("exo.exo_mass_kg", self.exo_mass_kg, 5.0, 30.0)
        check_range("exo.tof_height_m", self.tof_height_m, 0.05, 0.9 * self.shank_m)
        check_range("exo.tof_forward_m", self.tof_forward_m, 0.0, 0.15)
        check_range("exo.tof_separation_m", self.tof_separation_m, 0.01, 0.2)
        check_range("exo.tof_pitch_deg", self.tof_pitch_deg, -30.0, 80.0)
        check_range("exo.tof_toe_out_deg", self.tof_toe_out_deg, -20.0, 20.0)
        check_range("exo.camera_pitch_deg", self.camera_pitch_deg, -10.0, 80.0)
        if self.lidar_height_m is not None:
            check_range("exo.lidar_height_m", self.lidar_height_m, 0.4, 1.2)

    @classmethod
    def from_dict(cls, values: dict) -> ExoSpec:
        names = {f.name for f in fields(cls)}
        return cls(**{k: v for k, v in values.items() if k in names})

    # --- segment lengths (de Leva 1996; Winter 2009 for ankle, hip and head heights) ---
    @property
    def thigh_m(self) -> float:
        return 0.2425 * self.user_height_m

    @property
    def shank_m(self) -> float:
        return 0.2493 * self.user_height_m

    @property
    def foot_m(self) -> float:
        return 0.1482 * self.user_height_m

    @property
    def sole_height_m(self) -> float:
        """Ankle joint centre above the sole (Winter: 0.039 of height)."""
        return 0.039 * self.user_height_m

    @property
    def heel_to_ankle_m(self) -> float:
        """Horizontal distance from the heel to the ankle joint [A: 0.25 of the foot]."""
        return 0.25 * self.foot_m

    @property
    def hip_width_m(self) -> float:
        """Distance between the two hip joint centres [A: 0.10 of height]."""
        return 0.10 * self.user_height_m

    @property
    def leg_m(self) -> float:
        """Hip joint centre above the ground when standing straight."""
        return self.thigh_m + self.shank_m + self.sole_height_m

    @property
    def trunk_m(self) -> float:
        """Hip joint line to the neck (Winter: 0.818 - 0.530 of height, to the shoulders)."""
        return 0.288 * self.user_height_m

    @property
    def head_m(self) -> float:
        """Neck joint to the top of the head (1.0 - 0.870 of height, chin to vertex)."""
        return 0.130 * self.user_height_m

    # --- masses (de Leva, male; exo distribution [A]) ---
    def segment_mass_kg(self, segment: str) -> float:
        """Mass of a body (``pelvis``, ``thigh``, ``shank``, ``foot``, ``head``) with its exo share."""
        body = {"thigh": 0.1416, "shank": 0.0433, "foot": 0.0137, "head": 0.0694}
        exo = {"thigh": 0.15, "shank": 0.10, "foot": 0.05, "head": 0.0}
        if segment == "pelvis":  # trunk, arms and pelvis: the rest of the body
            rest = 1.0 - 2 * (body["thigh"] + body["shank"] + body["foot"]) - body["head"]
            return rest * self.user_mass_kg + 0.40 * self.exo_mass_kg
        return body[segment] * self.user_mass_kg + exo[segment] * self.exo_mass_kg

    def segment_inertial(self, segment: str) -> tuple[np.ndarray, np.ndarray]:
        """(centre of mass in the body frame, principal moments of inertia about x, y, z) of a body.

        Centre-of-mass positions and radii of gyration are de Leva's (1996, male): thigh CoM at
        0.4095 of its length from the hip, radii 0.329/0.329/0.149 (about x/y/z); shank 0.4459,
        0.255/0.249/0.103; foot 0.4415 from the heel, 0.124 about its long axis (x), 0.245
        about y, 0.257 about z; head+neck 0.5002 from the vertex, 0.303/0.315/0.261; trunk 0.5138
        from the neck, 0.328/0.306/0.169 (pelvis body: trunk, arms and pelvis lumped [A]). The
        exoskeleton's share of a segment is lumped with the same distribution [A].
        """
        m = self.segment_mass_kg(segment)
        if segment == "thigh":
            L = self.thigh_m
            com, r = np.array([0.0, 0.0, -0.4095 * L]), np.array([0.329, 0.329, 0.149]) * L
        elif segment == "shank":
            L = self.shank_m
            com, r = np.array([0.0, 0.0, -0.4459 * L]), np.array([0.255, 0.249, 0.103]) * L
        elif segment == "foot":
            L = self.foot_m
            com = np.array([0.4415 * L - self.heel_to_ankle_m, 0.0, -0.5 * self.sole_height_m])
            r = np.array([0.124, 0.245, 0.257]) * L
        elif segment == "head":
            L = self.head_m
            com, r = np.array([0.0, 0.0, (1.0 - 0.5002) * L]), np.array([0.303, 0.315, 0.261]) * L
        elif segment == "pelvis":
            L = self.trunk_m
            com, r = np.array([0.0, 0.0, (1.0 - 0.5138) * L]), np.array([0.328, 0.306, 0.169]) * L
        else:
            raise KeyError(segment)
        return com, m * r**2

    # --- body placement in the parent body's frame (zero posture) ---
    def hip_offset(self, side: str) -> np.ndarray:
        """Hip joint centre in the pelvis frame (pelvis origin: midway between the hips)."""
        return np.array([0.0, (0.5 if side == "l" else -0.5) * self.hip_width_m, 0.0])

    @property
    def neck_offset(self) -> np.ndarray:
        return np.array([0.0, 0.0, self.trunk_m])

    # --- sensor mounts: 4x4 poses in the parent body frame ---
    def tof_mount(self, sensor_id: str) -> tuple[str, np.ndarray]:
        """(parent body, T_parent_sensor) of a calf ToF sensor; the beam is the site's +z.

        The shank frame has its origin at the knee; the ankle is at (0, 0, -shank_m).
        ``med``/``lat`` are the medial and lateral sensors of a calf.
        """
        _, side, which = sensor_id.split("_")
        outward = 1.0 if side == "l" else -1.0  # +y is the left side
        lateral = outward * (0.5 if which == "lat" else -0.5) * self.tof_separation_m
        yaw = np.radians(self.tof_toe_out_deg) * np.sign(lateral)
        pitch = np.radians(self.tof_pitch_deg)
        beam = rot_z(yaw) @ np.array([np.cos(pitch), 0.0, -np.sin(pitch)])
        z = beam / np.linalg.norm(beam)
        x = np.cross(np.array([0.0, 1.0, 0.0]), z)
        x /= np.linalg.norm(x)
        y = np.cross(z, x)
        pos = np.array([self.tof_forward_m, lateral, -(self.shank_m - self.tof_height_m)])
        return f"shank_{side}", make_T(np.column_stack([x, y, z]), pos)

    def imu_mount(self) -> tuple[str, np.ndarray]:
        """Trunk IMU: on the back of the trunk, axes aligned with the pelvis [A]."""
        return "pelvis", make_T(np.eye(3), np.array([-0.12, 0.0, 0.45 * self.trunk_m]))

    def lidar_mount(self) -> tuple[str, np.ndarray]:
        """Trunk LiDAR, level, z up [A]: on a backpack mast 10 cm above the top of the head (lower,
        the user's head blocks a fifth of a VLP-16's beams); with ``lidar_height_m``, on the front
        of the pelvis frame, 0.20 m ahead of the hip joints (the legs, nearer than the VLP-16's 0.9 m
        minimum range, return nothing but shadow beams behind and below; the trunk and arms are on
        the LiDAR's own body, which its direct rays do not meet wherever it is mounted, though beams
        mirrored back by glass do)."""
        if self.lidar_height_m is not None:
            return "pelvis", make_T(np.eye(3), np.array([0.20, 0.0, self.lidar_height_m - self.leg_m]))
        return "pelvis", make_T(np.eye(3), np.array([-0.12, 0.0, self.trunk_m + self.head_m + 0.10]))

    def rgbd_mount(self, sensor_id: str) -> tuple[str, np.ndarray]:
        """Camera mounts, optical frame (z forward, x right, y down) [A]."""
        pitch = np.radians(self.camera_pitch_deg)
        if sensor_id == "rgbd_head":
            return "head", make_T(_camera_optical(0.5 * pitch), np.array([0.10, 0.0, 0.55 * self.head_m]))
        if sensor_id == "rgbd_chest":
            return "pelvis", make_T(_camera_optical(pitch), np.array([0.14, 0.0, 0.75 * self.trunk_m]))
        side = sensor_id[-1]
        pos = np.array([0.09, 0.0, -0.35 * self.thigh_m])
        return f"thigh_{side}", make_T(_camera_optical(np.radians(20.0)), pos)

    def contact_mount(self, sensor_id: str) -> tuple[str, np.ndarray]:
        """Insole pads under heel and toe; foot frame origin at the ankle joint."""
        side, where = CONTACT_PADS[sensor_id]
        x = -self.heel_to_ankle_m + 0.04 if where == "heel" else self.foot_m - self.heel_to_ankle_m - 0.04
        return f"foot_{side}", make_T(np.eye(3), np.array([x, 0.0, -self.sole_height_m]))

    def sole_mount(self, side: str) -> tuple[str, np.ndarray]:
        """Point on the sole right below the ankle joint."""
        return f"foot_{side}", make_T(np.eye(3), np.array([0.0, 0.0, -self.sole_height_m]))

    def toe_tip(self, side: str) -> tuple[str, np.ndarray]:
        """Tip of the toes on the sole."""
        return f"foot_{side}", make_T(np.eye(3), np.array([self.foot_m - self.heel_to_ankle_m, 0.0, -self.sole_height_m]))


def rot_about(axis: np.ndarray, angle: float) -> np.ndarray:
    """Rotation about one of the sagittal joint axes (+-y)."""
    return rot_y(angle * float(axis[1]))


__all__ = [
    "ANKLE_AXIS",
    "CONTACT_IDS",
    "ExoSpec",
    "HIP_AXIS",
    "JOINT_RANGES_RAD",
    "KNEE_AXIS",
    "LEG_JOINTS",
    "NECK_JOINTS",
    "NECK_PITCH_AXIS",
    "NECK_YAW_AXIS",
    "RGBD_IDS",
    "TOF_IDS",
    "rot_about",
    "rot_x",
]
