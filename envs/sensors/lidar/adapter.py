"""The LiDAR inside the simulation core.

Sweeps start at ``k / rate_hz`` (only sweeps that end within the recording). Each ray is cast
from the sensor pose at its firing block's time (the recording's exact pose function of a site
rigid with the pelvis); the legs, head and anything else the beams can hit are frozen at their
pose in the middle of the sweep, which is the instant the recorder gives the sensor. The stream's
delivery faults (:mod:`.faults`) apply to each sweep in turn; the output is in delivery order
(stamp), its ``truth["sweep_start_s"]`` the true start of each frame's sweep (of every frame
delivered, those already handed over by :meth:`LidarAdapter.take` first). Chunked: ``take``
hands over the frames delivered so far, in delivery order.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..adapter import BaseAdapter, MountedSensor, RecordContext, SensorOutput
from .faults import StreamFaults
from .model import LidarSensor


class LidarAdapter(BaseAdapter):
    chunked = True

    def __init__(self, sensor: MountedSensor, ctx: RecordContext) -> None:
        super().__init__(sensor, ctx)
        self.model = LidarSensor(sensor.sensor_id, sensor.config, ctx.model, ctx.seed)
        self.faults = StreamFaults(sensor.sensor_id, sensor.config, ctx.seed)
        self.pose_at = ctx.pose_fn(sensor.sensor_id)
        pat = sensor.config.pattern
        period = pat.sweep_period_s
        n = int(np.floor(ctx.duration_s / period + 1e-9))
        self.starts = [k / pat.rate_hz for k in range(n)]
        self.mid = {t0 + 0.5 * period: t0 for t0 in self.starts}
        self.frames: list[Any] = []
        self.truth: list[Any] = []
        self.taken_starts: list[float] = []  # true starts of the frames take() handed over

    def instants(self) -> np.ndarray:
        return np.array(sorted(self.mid))

    def observe(self, model: Any, data: Any, t: float) -> None:
        got = self.model.scan(model, data, self.pose_at, self.mid[t], self.ctx.scene_truth)
        for scan, truth in self.faults.deliver(got):
            self.frames.append(scan)
            self.truth.append(truth)

    def finish(self) -> SensorOutput:
        order = sorted(range(len(self.frames)), key=lambda i: self.frames[i].stamp_s)  # stable: duplicates keep their order
        first = len(self.taken_starts)
        starts = np.array(self.taken_starts + [self.faults.true_starts[first + i] for i in order])
        return SensorOutput([self.frames[i] for i in order], [self.truth[i] for i in order], {"sweep_start_s": starts})

    def take(self) -> SensorOutput:
        n = len(self.taken_starts)
        self.taken_starts += self.faults.true_starts[n : n + len(self.frames)]
        out = SensorOutput(self.frames, self.truth)
        self.frames, self.truth = [], []
        return out

    @staticmethod
    def calibration_params(sensor: MountedSensor) -> dict[str, Any]:
        return sensor.config.calibration_params()
