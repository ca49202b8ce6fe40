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

While D-VIO is lost it propagates its last good state with the IMU (the state the re-initialised
segment is anchored on, :mod:`~exobench.mapping.odometry.dvio.window`); :meth:`DvioOdometry.
dead_reckoned` reads that propagation's camera pose at a frame's time, for a short loss.
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

# A frame takes the propagated pose of the IMU sample nearest to it within this, moved on to the
# frame's time at the propagated velocity [A: ten periods of a 200 Hz IMU; a frame arrives after
# the samples of its time (its latency), and the first frame of a loss is handled before any
# sample is propagated from the loss's start]; the last 400 (2 s at 200 Hz) are kept.
_DEAD_RECKON_MATCH_S = 0.05
_DEAD_RECKON_KEEP = 400


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
        # (IMU time, camera pose in G, seconds since the last good state, velocity in G) of
        # D-VIO's IMU propagation through a loss, one a sample (and one after each frame); the
        # oldest dropped past _DEAD_RECKON_KEEP
        self._dead: deque[tuple[float, np.ndarray, float, np.ndarray]] = deque(maxlen=_DEAD_RECKON_KEEP)
        self._bounds = config.window_config().failure_bounds()
        self._last_pose: tuple[float, np.ndarray] | None = None  # (stamp, position) of D-VIO's last pose
        self._runaway = False  # the propagation of this loss has left D-VIO's bounds
        # frames released without a pose, by D-VIO's status (or never handled by it)
        self.n_without_pose = {"initialising": 0, "lost": 0, "unhandled": 0}

    def feed(self, frame: Frame) -> None:
        """Give D-VIO an IMU sample or a camera frame."""
        self._dvio.process(frame)
        self._note_dead_reckoning()

    def _note_dead_reckoning(self) -> None:
        """Keep D-VIO's IMU propagation of its last good state while it is lost (its
        ``propagation``, one per new IMU sample), so that a frame's pose can be read at its stamp."""
        p = self._dvio.propagation()
        if p is None or (self._dead and self._dead[-1][0] == p[0]):
            return
        self._dead.append(p)

    def dead_reckoned(self, stamp_s: float, max_age_s: float) -> np.ndarray | None:
        """The camera pose in G at ``stamp_s`` from D-VIO's IMU propagation of its last good
        state, if D-VIO was lost then, a propagated sample lies within ``_DEAD_RECKON_MATCH_S``
        of it, the propagation had run at most ``max_age_s`` and it has stayed within D-VIO's
        own bounds on a move since its last pose (its failure detection's speed and climb, with
        the slack, :mod:`~exobench.mapping.odometry.dvio.failure`: a propagation from a bad
        state runs away at metres a second); else None, for the rest of the loss once out."""
        best = min(self._dead, key=lambda d: abs(d[0] - stamp_s), default=None)
        if best is None or abs(best[0] - stamp_s) > _DEAD_RECKON_MATCH_S or best[2] > max_age_s \
                or self._last_pose is None or self._runaway:
            return None
        T = best[1].copy()
        T[:3, 3] += best[3] * (stamp_s - best[0])
        dt, move = stamp_s - self._last_pose[0], T[:3, 3] - self._last_pose[1]
        b = self._bounds
        if np.linalg.norm(move) > b.max_update_speed_mps * dt + b.update_slack_m \
                or abs(move[2]) > b.max_update_climb_mps * dt + b.update_slack_m:
            self._runaway = True
            return None
        return T

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
                else:
                    self._last_pose, self._runaway = (stamp, np.asarray(T, float)[:3, 3].copy()), False
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
