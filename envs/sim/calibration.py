"""The one calibration builder: the device as a pipeline knows it, from the body spec and the rig.

:func:`build_calibration` starts from :func:`exobench.models.exo.exo_calibration` (robot
description, joint order and every mount the device has), gives each rig sensor on a device
mount its own parameters (and, for kinds whose adapter says ``calibration_shared``, the device's
unmounted sensors of that kind the parameters of the rig's first one), appends the mounts of rig
sensors the device does not have (a camera's IMU and odometry, in the camera's optical frame),
and adds each kind's calibration ``extra`` entries (``encoders``; ``camera``, ``camera_imu``,
``odometry``, ``T_camera_imu`` for the first RGB-D camera).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace
from typing import Any

from exobench.core import Calibration, SensorMount
from exobench.models.exo import exo_calibration, sensor_mounts
from exobench.models.exo_spec import ExoSpec

from ..sensors.adapter import MountedSensor
from ..sensors.kinds import adapter_class


def mount_of(exo: ExoSpec, sensor: MountedSensor) -> tuple[str, Any]:
    """(parent body, T_parent_sensor) of a rig sensor: its explicit mount, the camera it is
    attached to (an IMU there at ``T_camera_imu`` of its config's extrinsics), or the device's own
    mount of its id."""
    if sensor.mount is not None:
        return sensor.mount.parent, sensor.mount.T_parent_sensor()
    device = {sid: (parent, T) for sid, _, parent, T in sensor_mounts(exo)}
    key = sensor.attached_to or sensor.sensor_id
    if key not in device:
        from exobench.core import UnknownNameError

        raise UnknownNameError("sensor mount", key, device)
    parent, T = device[key]
    if sensor.attached_to is not None and sensor.kind == "imu" and sensor.config.extrinsics != "identity":
        return parent, T @ sensor.config.T_camera_imu()
    return parent, T


def build_calibration(exo: ExoSpec, rig: Sequence[MountedSensor]) -> Calibration:
    """The calibration of ``exo`` carrying ``rig`` (see the module docstring)."""
    device = {sid for sid, *_ in sensor_mounts(exo)}
    overrides: dict[str, dict[str, Any]] = {}
    for s in rig:
        ad = adapter_class(s.kind)
        if ad.has_mount and ad.calibration_shared and s.kind not in overrides:
            overrides[s.kind] = ad.calibration_params(s)
    for s in rig:
        ad = adapter_class(s.kind)
        if ad.has_mount and s.sensor_id in device and s.attached_to is None and s.mount is None:
            overrides[s.sensor_id] = ad.calibration_params(s)
    cal = exo_calibration(exo, overrides)
    extra_mounts = []
    for s in rig:
        ad = adapter_class(s.kind)
        if ad.has_mount and (s.sensor_id not in device or s.attached_to is not None or s.mount is not None):
            parent, T = mount_of(exo, s)
            extra_mounts.append(SensorMount(s.sensor_id, s.kind, parent, T.copy(), dict(ad.calibration_params(s))))
    extra = dict(cal.extra)
    for s in rig:
        extra.update(adapter_class(s.kind).calibration_extra(s, rig))
    return replace(cal, mounts=cal.mounts + tuple(extra_mounts), extra=extra)
