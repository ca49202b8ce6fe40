"""Time-of-flight ranging (ST VL53L1X): :class:`ToFConfig` and the ray-cast :class:`ToFSensor`."""

from .config import ToFConfig
from .model import ToFSensor, cone_directions

__all__ = ["ToFConfig", "ToFSensor", "cone_directions"]
