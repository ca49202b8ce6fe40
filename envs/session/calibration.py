"""``calibration.json`` of a session: sensor mounts, encoder joint names, robot description."""

from __future__ import annotations

from typing import Any

from exobench.core import Calibration, SensorMount
from exobench.models.exo_spec import CONTACT_PADS

from .store import dec_array, enc_array, plain


def calibration_to_dict(c: Calibration) -> dict[str, Any]:
    return {
        "robot_urdf": c.robot_urdf,
        "base_link": c.base_link,
        "joint_names": list(c.joint_names),
        "sole_height_m": c.sole_height_m,
        "foot_length_m": c.foot_length_m,
        "heel_to_ankle_m": c.heel_to_ankle_m,
        "extra": plain(c.extra),
        "mounts": [
            {
                "sensor_id": m.sensor_id,
                "kind": m.kind,
                "parent_link": m.parent_link,
                "T_parent_sensor": enc_array(m.T_parent_sensor),
                "params": plain(m.params),
            }
            for m in c.mounts
        ],
    }


def _params(m: dict[str, Any]) -> dict[str, Any]:
    """A mount's parameters; an insole pad of a session recorded before pads said their foot and
    pad gets them from the device's table (:data:`exobench.models.exo_spec.CONTACT_PADS`)."""
    params = dict(m["params"])
    if m["kind"] == "contact" and "side" not in params and m["sensor_id"] in CONTACT_PADS:
        params["side"], params["pad"] = CONTACT_PADS[m["sensor_id"]]
    return params


def calibration_from_dict(d: dict[str, Any]) -> Calibration:
    mounts = tuple(
        SensorMount(m["sensor_id"], m["kind"], m["parent_link"], dec_array(m["T_parent_sensor"]), _params(m))
        for m in d["mounts"]
    )
    return Calibration(
        robot_urdf=d["robot_urdf"],
        base_link=d["base_link"],
        joint_names=tuple(d["joint_names"]),
        mounts=mounts,
        sole_height_m=float(d["sole_height_m"]),
        foot_length_m=float(d["foot_length_m"]),
        heel_to_ankle_m=float(d["heel_to_ankle_m"]),
        extra=dict(d.get("extra", {})),
    )
