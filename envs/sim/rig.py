"""Sensor rigs: which sensors a scenario mounts, and named presets a user can add to any world.

A rig is a tuple of :class:`~exobench.envs.sensors.adapter.MountedSensor`; its order is the tie
order of frames with equal stamps (state before ranges and images, so a pipeline has the
encoders and IMU of an instant when a range or image of that instant arrives). Every scenario has
a default rig; ``extra_sensors`` (a scenario parameter, comma-separated :data:`PRESETS` names) or
the ``rig`` argument of a ``simulate_*`` function adds to or replaces it.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING

from exobench.core import ConfigError, SegmentationTruth, UnknownNameError
from exobench.models.exo_spec import CONTACT_IDS, TOF_IDS

from ..sensors import (
    ENCODER_ID,
    ContactConfig,
    EncoderConfig,
    ImuConfig,
    LidarConfig,
    RgbdConfig,
    SensorsConfig,
    ToFConfig,
)
from ..sensors.adapter import MountedSensor

if TYPE_CHECKING:
    from .recorder import Recording

Rig = tuple[MountedSensor, ...]
IMU_TRUNK = "imu_trunk"
LIDAR_TRUNK = "lidar_trunk"
CAMERA_KEYS = {"head": "head", "chest": "chest", "thigh": "thigh_r"}
CAMERA_IMU = ImuConfig()  # the D455's BMI055 at 200 Hz


def scalar_rig(config: SensorsConfig, *, tof: bool = True) -> Rig:
    """Encoders, the trunk IMU, the four insole pads and (with ``tof``) the four calf ToF sensors."""
    out = [
        MountedSensor(ENCODER_ID, "encoders", config.encoders),
        MountedSensor(IMU_TRUNK, "imu", config.imu),
        *(MountedSensor(pid, "contact", config.contact) for pid in CONTACT_IDS),
    ]
    if tof:
        out += calf_tof_rig(config.tof)
    return tuple(out)


def calf_tof_rig(config: ToFConfig) -> Rig:
    """The four calf ToF sensors (``tof_l_med, tof_l_lat, tof_r_med, tof_r_lat``), one config."""
    return tuple(MountedSensor(sid, "tof", config) for sid in TOF_IDS)


def camera_rig(mount: str, camera: RgbdConfig, imu: ImuConfig | None = CAMERA_IMU, odometry: object | None = None) -> Rig:
    """An RGB-D camera on ``mount`` (head, chest, thigh) with its IMU and odometry (each optional),
    in the order IMU, odometry, camera."""
    if mount not in CAMERA_KEYS:
        raise UnknownNameError("camera mount", mount, CAMERA_KEYS)
    k = CAMERA_KEYS[mount]
    cam = f"rgbd_{k}"
    out = []
    if imu is not None:
        out.append(MountedSensor(f"imu_{k}", "imu", imu, attached_to=cam))
    if odometry is not None:
        out.append(MountedSensor(f"odom_{k}", "odometry", odometry, attached_to=cam))
    out.append(MountedSensor(cam, "rgbd", camera))
    return tuple(out)


PRESETS: dict[str, Callable[[], Rig]] = {
    "lidar_trunk": lambda: (MountedSensor(LIDAR_TRUNK, "lidar", LidarConfig()),),
    "rgbd_head": lambda: camera_rig("head", RgbdConfig(width_px=424, height_px=240)),
    "rgbd_chest": lambda: camera_rig("chest", RgbdConfig(width_px=424, height_px=240)),
    "rgbd_thigh": lambda: camera_rig("thigh", RgbdConfig(width_px=424, height_px=240)),
    "imu_trunk": lambda: (MountedSensor(IMU_TRUNK, "imu", ImuConfig()),),
    "tof_calves": lambda: calf_tof_rig(ToFConfig()),
    "encoders": lambda: (MountedSensor(ENCODER_ID, "encoders", EncoderConfig()),),
    "contacts": lambda: tuple(MountedSensor(pid, "contact", ContactConfig()) for pid in CONTACT_IDS),
}
"""Sensor sets a scenario can add by name (``extra_sensors="rgbd_thigh,lidar_trunk"``): the trunk
VLP-16; a D455 at 424x240 on the head, chest or right thigh with its IMU; the trunk IMU; the calf
ToF sensors; the encoders; the insole pads."""


def preset_names(text: str) -> tuple[str, ...]:
    """The preset names of an ``extra_sensors`` value, checked."""
    names = tuple(n.strip() for n in text.split(",") if n.strip())
    for n in names:
        if n not in PRESETS:
            raise UnknownNameError("extra sensor preset", n, PRESETS)
    return names


def with_presets(rig: Sequence[MountedSensor], text: str) -> Rig:
    """``rig`` followed by the sensors of the presets named in ``text`` (refused if an id repeats)."""
    out = list(rig)
    for n in preset_names(text):
        for s in PRESETS[n]():
            if any(o.sensor_id == s.sensor_id for o in out):
                raise ConfigError("extra_sensors", text, f"sensors not already on the rig ({s.sensor_id!r} is)")
            out.append(s)
    return tuple(out)


def with_segmentation_truth(rig: Sequence[MountedSensor]) -> Rig:
    """``rig`` with every RGB-D camera keeping a segmentation truth of its frames
    (``RgbdConfig.segmentation_truth``); the other sensors unchanged."""
    return tuple(
        dataclasses.replace(s, config=dataclasses.replace(s.config, segmentation_truth=True)) if s.kind == "rgbd" else s
        for s in rig
    )


def segmentation_truths(rec: Recording, rig: Sequence[MountedSensor]) -> tuple[SegmentationTruth, ...]:
    """The segmentation truths of a recording (``Recording.frame_truth``) of the rig's cameras
    that keep one, in frame order."""
    cams = [s.sensor_id for s in rig if s.kind == "rgbd" and s.config.segmentation_truth]
    return rec.frame_truth(cams) if cams else ()
