"""The configs of the scalar sensor streams mounted together (ToF, IMU, encoders, contact); a rig of
them is :func:`exobench.envs.sim.rig.scalar_rig`, what a pipeline knows of them the kinds' adapters say."""

from __future__ import annotations

from dataclasses import dataclass

from .contact.config import ContactConfig
from .encoders.config import EncoderConfig
from .imu.config import ImuConfig
from .tof.config import ToFConfig


@dataclass(frozen=True)
class SensorsConfig:
    """Configs of every simulated sensor stream."""

    tof: ToFConfig = ToFConfig()
    imu: ImuConfig = ImuConfig()
    encoders: EncoderConfig = EncoderConfig()
    contact: ContactConfig = ContactConfig()
