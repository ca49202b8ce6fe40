"""The joint encoders inside the simulation core: read from the motion's joint angles, no MuJoCo state."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from ..adapter import BaseAdapter, MountedSensor, SensorOutput
from ..common import sample_times
from .model import EncoderSensor


class EncoderAdapter(BaseAdapter):
    has_mount = False

    def finish(self) -> SensorOutput:
        t = sample_times(self.config.rate_hz, self.ctx.duration_s)
        return SensorOutput(list(EncoderSensor(self.config, self.ctx.seed).frames(t, self.ctx.motion.state(t).joints)))

    @staticmethod
    def calibration_extra(sensor: MountedSensor, rig: Sequence[MountedSensor]) -> dict[str, Any]:
        c = sensor.config
        return {"encoders": {"rate_hz": c.rate_hz, "noise_rad": c.noise_rad, "resolution_bits": c.resolution_bits}}
