"""The calibration's sensor mounts as the locomotion pipelines read them.

Which odometry stream tracks the camera (:func:`odometry_of`), a mount's delivery latency
(:func:`mount_latency_s`) and where a mount sits on the standing device, from the robot
description (:func:`tracked_point_neutral`).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from exobench.core import Calibration, ConfigError
from exobench.core.transforms import invert_T

__all__ = ["mount_latency_s", "odometry_of", "tracked_point_neutral"]


def mount_latency_s(params: dict[str, Any]) -> float:
    """A mount's delivery latency ``latency_s`` (0 when absent or not a finite number >= 0)."""
    try:
        x = float(params.get("latency_s", 0.0))
    except (TypeError, ValueError):
        return 0.0
    return x if math.isfinite(x) and x >= 0.0 else 0.0


def odometry_of(calibration: Calibration, camera_id: str) -> str:
    """The odometry stream that tracks the camera: the odometry mount whose ``tracks`` parameter
    names it, else the calibration's only odometry mount, else any odometry stream (``"*"``)."""
    odoms = calibration.mounts_of_kind("odometry")
    tracking = [m.sensor_id for m in odoms if m.params.get("tracks") == camera_id]
    if tracking:
        return tracking[0]
    if len(odoms) == 1:
        return odoms[0].sensor_id
    if odoms:
        raise ConfigError("odometry_sensor_id", "", f"the odometry tracking {camera_id!r}: one of {[m.sensor_id for m in odoms]}")
    return "*"


def tracked_point_neutral(calibration: Calibration, sensor_id: str, *, link_origin: bool = False) -> tuple[float, float] | None:
    """Where the mount ``sensor_id`` (``link_origin``: the origin of its parent link) sits in the
    robot description (URDF, loaded with pinocchio) at its neutral configuration (standing
    straight): (how far ahead of the base link (the pelvis) along its x axis (forward), how high
    above the soles (the feet: the parent links of the ``contact`` mounts, their origins
    ``sole_height_m`` above the sole)), m. None when the description or a link cannot be read."""
    try:
        import pinocchio as pin

        model = pin.buildModelFromXML(calibration.robot_urdf)
        data = model.createData()
        pin.framesForwardKinematics(model, data, pin.neutral(model))
        mount = calibration.mount(sensor_id)

        def placement(link: str) -> np.ndarray:
            return np.asarray(data.oMf[model.getFrameId(link, pin.BODY)].homogeneous, dtype=float)

        T_w_point = placement(mount.parent_link) @ (np.eye(4) if link_origin else np.asarray(mount.T_parent_sensor, dtype=float))
        x = float((invert_T(placement(calibration.base_link)) @ T_w_point)[0, 3])
        feet = {m.parent_link for m in calibration.mounts_of_kind("contact")}
        sole = min(float(placement(f)[2, 3]) for f in feet) - float(calibration.sole_height_m)
        h = float(T_w_point[2, 3]) - sole
    except Exception:  # no usable description: the caller falls back
        return None
    return (x, h) if math.isfinite(x) and math.isfinite(h) else None
