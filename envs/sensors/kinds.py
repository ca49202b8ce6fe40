"""The sensor kinds the simulation core can mount: kind name -> adapter class
(:class:`~exobench.envs.sensors.adapter.SensorAdapter`). A new kind adds its folder and one line here."""

from __future__ import annotations

from exobench.core import UnknownNameError

from .adapter import SensorAdapter
from .contact.adapter import ContactAdapter
from .encoders.adapter import EncoderAdapter
from .imu.adapter import ImuAdapter
from .lidar.adapter import LidarAdapter
from .odometry.adapter import OdometryAdapter
from .rgbd.adapter import RgbdAdapter
from .tof.adapter import ToFAdapter

ADAPTERS: dict[str, type[SensorAdapter]] = {
    "tof": ToFAdapter,
    "imu": ImuAdapter,
    "encoders": EncoderAdapter,
    "contact": ContactAdapter,
    "lidar": LidarAdapter,
    "rgbd": RgbdAdapter,
    "odometry": OdometryAdapter,
}


def adapter_class(kind: str) -> type[SensorAdapter]:
    """The adapter of a sensor kind; :class:`UnknownNameError` names the known kinds."""
    if kind not in ADAPTERS:
        raise UnknownNameError("sensor kind", kind, ADAPTERS)
    return ADAPTERS[kind]
