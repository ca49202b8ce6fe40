"""The ToF sensor inside the simulation core: ray casts at every ``k / rate_hz``, one truth per reading."""

from __future__ import annotations

from typing import Any

import numpy as np

from ..adapter import BaseAdapter, MountedSensor, RecordContext, SensorOutput
from ..common import sample_times
from .model import ToFSensor


class ToFAdapter(BaseAdapter):
    calibration_shared = True
    streams = True  # noise and dropout are drawn reading by reading, in time order

    def __init__(self, sensor: MountedSensor, ctx: RecordContext) -> None:
        super().__init__(sensor, ctx)
        self.model = ToFSensor(sensor.sensor_id, sensor.config, ctx.model, ctx.seed)

    def instants(self) -> np.ndarray:
        return sample_times(self.config.rate_hz, self.ctx.duration_s)

    def observe(self, model: Any, data: Any, t: float) -> None:
        self.model.observe(model, data, t)

    def finish(self) -> SensorOutput:
        pairs = self.model.frames(self.ctx.model, self.ctx.scene_truth)
        return SensorOutput([f for f, _ in pairs], [t for _, t in pairs])

    def take(self) -> SensorOutput:
        return self.finish()  # the sensor turns only the observations since its last call into frames

    @staticmethod
    def calibration_params(sensor: MountedSensor) -> dict[str, Any]:
        t = sensor.config
        return {
            "rate_hz": t.rate_hz, "min_range_m": t.min_range_m, "max_range_m": t.max_range_m,
            "noise_sigma_m": t.noise_m, "fov_deg": t.fov_deg, "n_cone_rays": t.n_cone_rays,
            "resolution_m": t.resolution_m, "latency_s": t.latency_s,
        }  # fmt: skip
