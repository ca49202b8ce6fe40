"""D-VIO inside a locomotion pipeline (``terrain-recon.odometry = "dvio"``, issue 27).

The paper's system places the footprints with D-VIO's pose (seeds/002 II-C, eq. 16-18), not
with a given odometry. :class:`DvioOdometry` runs a :class:`~exobench.mapping.odometry.dvio.
pipeline.DvioPipeline` (its config nested as ``dvio``) on the pipeline's camera and the camera's
IMU (``dvio.imu_id``, else ``calibration.extra["camera_imu"]``, else the first IMU mount), and
holds the camera frames and insole contacts back, in their arrival order, until D-VIO has
handled each frame: D-VIO handles a frame once the IMU has reached its time, so a contact that
arrives after a frame and before its pose is released after that frame's prediction, as it
arrived. A frame's pose is D-VIO's camera pose in its gravity-aligned frame G (origin and yaw
of its own); a frame without one (``initialising``, ``lost``) is released with None.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Iterator
from dataclasses import replace
from typing import Any

import numpy as np

from exobench.core import Calibration, ConfigError, Frame, RgbdFrame
from exobench.mapping.odometry.dvio.pipeline import DvioConfig, DvioPipeline

__all__ = ["DvioOdometry", "camera_imu_of"]


def camera_imu_of(config: DvioConfig, calibration: Calibration) -> str:
    """The IMU D-VIO reads, as :class:`DvioPipeline` picks it ("" without one)."""
    imus = calibration.mounts_of_kind("imu")
    named = (calibration.extra or {}).get("camera_imu")
    return config.imu_id or (named if isinstance(named, str) else "") or (imus[0].sensor_id if imus else "")


class DvioOdometry:
    """D-VIO's poses for the camera frames of a locomotion pipeline (module docstring).

    Args:
        config: D-VIO's config (``camera_id`` "" or the pipeline's camera).
        calibration: the episode's calibration.
        camera_id: the pipeline's camera.
    """

    def __init__(self, config: DvioConfig, calibration: Calibration, camera_id: str) -> None:
        if config.camera_id and config.camera_id != camera_id:
            # the footprints are placed with the pose of the camera whose depth built the map
            raise ConfigError("dvio.camera_id", config.camera_id, f"'' or the pipeline's camera {camera_id!r}")
        self.imu_id = camera_imu_of(config, calibration)
        self._dvio = DvioPipeline(replace(config, camera_id=camera_id, imu_id=self.imu_id))
        self._dvio.reset(calibration)
        self._pending: deque[tuple[Frame, Any, float]] = deque()  # (frame, its counters, arrival time)
        self._n_results = 0
        # frames released without a pose, by D-VIO's status (or never handled by it)
        self.n_without_pose = {"initialising": 0, "lost": 0, "unhandled": 0}

    def feed(self, frame: Frame) -> None:
        """Give D-VIO an IMU sample or a camera frame."""
        self._dvio.process(frame)

    def hold(self, frame: Frame, counts: Any, t0: float) -> None:
        """Queue a camera frame or a contact until the frames before it have their pose."""
        self._pending.append((frame, counts, t0))

    def idle(self) -> bool:
        """Whether nothing is held back (a contact can then be used at once)."""
        return not self._pending

    def released(self) -> Iterator[tuple[Frame, Any, float, np.ndarray | None]]:
        """The held frames now ready, in arrival order, each camera frame with its pose (None
        without one; None for a contact)."""
        for stamp, T, status in self._dvio.frame_results(self._n_results):
            self._n_results += 1
            while self._pending:
                frame, counts, t0 = self._pending.popleft()
                if not isinstance(frame, RgbdFrame):
                    yield frame, counts, t0, None
                    continue
                if float(frame.stamp_s) != stamp:  # never handled by D-VIO: no pose
                    self.n_without_pose["unhandled"] = self.n_without_pose.get("unhandled", 0) + 1
                    yield frame, counts, t0, None
                    continue
                ok = T is not None and bool(np.all(np.isfinite(T)))
                if not ok:
                    self.n_without_pose[status] = self.n_without_pose.get(status, 0) + 1
                yield frame, counts, t0, np.asarray(T, dtype=float) if ok else None
                break
        while self._pending and not isinstance(self._pending[0][0], RgbdFrame):
            frame, counts, t0 = self._pending.popleft()
            yield frame, counts, t0, None

    def window_poses(self, before_s: float) -> list[tuple[float, np.ndarray]]:
        """(stamp, camera pose in G) of the keyframes in D-VIO's window stamped before
        ``before_s``, from its estimate now (none while it has no estimate). Read at D-VIO's first
        pose after a gap, these are the keyframes of the initialisation window: instants before
        that pose which D-VIO's first optimisation has placed (D-VIO's results leave those frames
        without a pose: they were handled while it was initialising)."""
        return [(t, T) for t, T in self._dvio.window_poses() if t < before_s]

    def finish(self) -> dict[str, Any]:
        """Let D-VIO handle every frame still waiting for the IMU (then :meth:`released` gives
        them); D-VIO's numeric statistics."""
        est = self._dvio.finalize()
        return {k: v for k, v in (est.stats or {}).items() if isinstance(v, (bool, int, float))}
