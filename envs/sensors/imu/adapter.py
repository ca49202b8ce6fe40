"""The IMU inside the simulation core: measured where the state carries the motion's accelerations.

Truth (``SensorOutput.truth``): ``pose_rows``, the IMU site's true pose at every measurement
instant, rows ``[t, x, y, z, qw, qx, qy, qz]`` (the instants of the samples before any drop,
clock offset or latency: ``t`` is the measurement time)."""

from __future__ import annotations

from typing import Any

import numpy as np

from ..adapter import BaseAdapter, MountedSensor, RecordContext, SensorOutput
from ..common import sample_times
from .model import ImuSensor


class ImuAdapter(BaseAdapter):
    needs_dynamics = True
    calibration_shared = True

    def __init__(self, sensor: MountedSensor, ctx: RecordContext) -> None:
        super().__init__(sensor, ctx)
        strikes = ()
        if sensor.config.heel_strike_scale > 0.0:
            strikes = tuple((float(f.touchdown_s), f.side) for f in ctx.motion.footsteps)
        self.model = ImuSensor(sensor.sensor_id, sensor.config, ctx.model, ctx.seed, strikes)

    def instants(self) -> np.ndarray:
        return sample_times(self.config.rate_hz, self.ctx.duration_s)

    def observe(self, model: Any, data: Any, t: float) -> None:
        self.model.observe(model, data, t)

    def finish(self) -> SensorOutput:
        return SensorOutput(list(self.model.frames()), None, {"pose_rows": self.model.pose_rows()})

    @staticmethod
    def calibration_params(sensor: MountedSensor) -> dict[str, Any]:
        i = sensor.config
        out = {
            "rate_hz": i.rate_hz, "gyro_noise_density": i.noise_scale * i.gyro_noise_density,
            "gyro_random_walk": i.noise_scale * i.gyro_random_walk,
            "accel_noise_density": i.noise_scale * i.accel_noise_density,
            "accel_random_walk": i.noise_scale * i.accel_random_walk,
            "orientation_rms_deg": i.orientation_rms_deg, "latency_s": i.latency_s,
        }  # fmt: skip
        if i.time_offset_s != 0.0:  # only then, so that calibrations of before are unchanged
            out["time_offset_s"] = i.time_offset_s
        return out
