"""A test-only pipeline of the vio track: the camera never moves (the zero-motion baseline).

It returns the identity pose at every RGB-D frame it uses, ``"ok"``, or ``"lost"`` at every
``lost_every``-th frame (0: never), and counts its input in the common vocabulary
(:mod:`exobench.core.counters`): a frame repeated or out of order, a depth image with NaN or
pixels no camera of the mount can report, an IMU sample with NaN or absurd values. The vio track
has no registered pipeline until the D-VIO pipelines land; the tests register this one (as the
conformance tests register the toy track's) to run the track end to end. Its ATE is the spread of
the true camera path around its mean, which the tests check by hand.
"""

from __future__ import annotations

import dataclasses
import time
from typing import Any, ClassVar

import numpy as np

from exobench.core import Calibration
from exobench.core.counters import StreamCounters, nan_values
from exobench.core.estimates import TrajectoryEstimate
from exobench.core.frames import ImuSample, RgbdFrame
from exobench.core.limits import absurd_depth, imu_absurd, max_depth_m
from exobench.core.pipeline import check_frame


class StillCamera:
    """The zero-motion baseline (module docstring)."""

    name: ClassVar[str] = "vio-still"
    track: ClassVar[str] = "vio"

    @dataclasses.dataclass(frozen=True)
    class Config:
        lost_every: int = 0

    def __init__(self, config: Config | None = None) -> None:
        self.config = config or self.Config()
        self._ready = False

    def reset(self, calibration: Calibration) -> None:
        self._cam = calibration.extra.get("camera")  # the rig's camera and its IMU
        self._imus = {calibration.extra.get("camera_imu")}
        self._max_depth_m = max_depth_m(next((m for m in calibration.mounts if m.sensor_id == self._cam), None))
        self._counters = StreamCounters.of(calibration)
        self._stamps: list[float] = []
        self._status: list[str] = []
        self._times: list[float] = []
        self._ready = True

    def process(self, frame: Any) -> None:
        t0 = time.perf_counter()
        check_frame(self, frame, self._ready)
        if isinstance(frame, ImuSample):
            c = self._counters.admit(frame, frame.sensor_id in self._imus)
            if c is not None:
                c.judge(frame, imu_absurd(frame))
            return None
        c = self._counters.admit(frame, isinstance(frame, RgbdFrame) and frame.sensor_id == self._cam)
        if c is None:
            return None
        depth = np.asarray(frame.depth_m, dtype=float)
        c.add_absurd(int(np.count_nonzero(absurd_depth(depth, self._max_depth_m))))
        c.add_nan(nan_values(frame))
        c.used += 1
        k = len(self._stamps) + 1
        lost = self.config.lost_every > 0 and k % self.config.lost_every == 0
        self._stamps.append(float(frame.stamp_s))
        self._status.append("lost" if lost else "ok")
        self._times.append(time.perf_counter() - t0)
        return None

    def finalize(self) -> TrajectoryEstimate:
        n = len(self._stamps)
        return TrajectoryEstimate(np.asarray(self._stamps, dtype=float), np.tile(np.eye(4), (n, 1, 1)),
                                  np.asarray(self._times, dtype=float), status=tuple(self._status),
                                  counts=self._counters.snapshot())  # fmt: skip
