"""``orb-slam3``: ORB-SLAM3 (Campos et al. 2021) in its RGB-D-inertial mode, the established peer
of the ``vio`` track, through the ``pyorbslam3`` package in a separate process.

ORB-SLAM3 is GPL-3.0. It is an optional extra (``pip install 'exobench[orbslam3]'``) and no
module of exobench imports it: ``reset`` writes ORB-SLAM3's settings from the calibration
(:mod:`.settings`) into a temporary folder of the pipeline's own and starts the worker script
``orbslam3-worker.py`` with this interpreter (:mod:`.worker_client`); ``process`` sends it each
RGB-D frame of the camera with the camera IMU's samples since the previous frame, once the IMU has
reached the frame's time (an IMU clock offset or latency delivers a frame's last samples after the
frame), or after ``max_wait_s`` of frames when the IMU is silent.

Output: a :class:`~exobench.core.estimates.TrajectoryEstimate` of the camera optical frame's pose
at every RGB-D stamp used, with a status per frame: ``"ok"`` when ORB-SLAM3 tracked it (state OK),
``"initialising"`` before its map exists, ``"lost"`` when it has lost track (RECENTLY_LOST, LOST:
its pose then is an IMU prediction, not a tracked one) and ``"failed"`` after the worker failed.
Only ``"ok"`` frames carry a pose; the others carry NaN, so that no scorer can take them for good
ones.

The poses are ORB-SLAM3's own trajectory, as its authors evaluate it: ``finalize`` shuts it down
and reads its EuRoC export (``SaveTrajectoryEuRoC``: every frame of its largest map, re-expressed
through the final keyframe poses, in the frame of that map's first keyframe; IMU poses, turned
into camera poses with ``IMU.T_b_c1``). The poses ``track`` returns online are not used: ORB-SLAM3
moves its whole map when its IMU initialises and again at each of its two later inertial
refinements (gravity alignment, about 5 and 15 s on), so the online poses lie in frames that move
(measured on a 9 s ramp walk: an SE(3)-aligned ATE of 0.12-0.64 m over 3.4-3.9 m of one map's
online poses, where the export gives 0.06-0.09 m over 6.6 m). A frame tracked OK in a map ORB-SLAM3 later dropped
(it resets the active map when it loses track before its IMU is initialised, or finds too little
motion to initialise it) is not in the export: it becomes ``"lost"`` (``frames_in_other_maps``).
When the worker fails before the export, the online poses are kept as they are.

``stats``: the tracking states met (``states``), ``map_resets`` (ok or lost to initialising
again) and ``map_starts`` (the frame indices where they did), ``imu_initialised_s`` (first stamp with the IMU initialised), ``pose_source`` (``export``
or ``online``), ``frames_in_other_maps``, ``export_error`` (ORB-SLAM3 had no keyframe left to
export), ``worker_failed`` and ``failure`` (the reason) when the worker crashed, answered an error
or timed out; the estimate then holds what came before and the run goes on.

Input: the camera's :class:`~exobench.core.frames.RgbdFrame` (``camera_id``, else the
calibration's ``extra["camera"]``) and its IMU's :class:`~exobench.core.frames.ImuSample`
(``extra["camera_imu"]``), counted on ``counts`` (:mod:`exobench.core.counters`); other frames
are ignored. Non-finite or negative depth pixels are given to ORB-SLAM3 as 0 (no depth) and
counted; an IMU sample with a non-finite value is counted and left out. IMU stamps are moved to
the camera's clock (``t - timeshift_cam_imu_s``).
"""

from __future__ import annotations

import contextlib
import math
import shutil
import tempfile
import time
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from exobench.core.calibration import Calibration
from exobench.core.counters import StreamCounters, nan_values
from exobench.core.errors import ConfigError
from exobench.core.estimates import TrajectoryEstimate
from exobench.core.frames import Frame, ImuSample, RgbdFrame
from exobench.core.limits import absurd_depth, imu_absurd, max_depth_m
from exobench.core.pipeline import check_frame
from exobench.core.transforms import make_T, quat_wxyz_to_matrix

from .settings import (
    STATES_INITIALISING,
    STATES_OK,
    OrbSlam3Config,
    T_imu_camera,
    camera_mounts,
    settings_values,
    settings_yaml,
)
from .settings import timeshift_s as _timeshift_s
from .vocabulary import DEFAULT_PARAMS, vocabulary_path
from .worker_client import OrbSlam3Worker, WorkerError

NAN_POSE = np.full((4, 4), np.nan)
EXPORT_MATCH_S = 1e-4  # ORB-SLAM3 writes stamps in ns with 6 decimals: far below a frame period


def read_euroc(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """ORB-SLAM3's EuRoC export: rows ``t_ns tx ty tz qx qy qz qw`` of the IMU (body) pose;
    returns the stamps in s (sorted) and the poses (N, 4, 4)."""
    rows = np.loadtxt(path, ndmin=2)
    if rows.size == 0:
        return np.zeros(0), np.zeros((0, 4, 4))
    if rows.shape[1] != 8:
        raise ValueError(f"{path}: {rows.shape[1]} columns, not 8")
    rows = rows[np.argsort(rows[:, 0])]
    T = np.array([make_T(quat_wxyz_to_matrix(np.array([r[7], r[4], r[5], r[6]])), r[1:4]) for r in rows])
    return rows[:, 0] * 1e-9, T


def default_vocabulary() -> Path:
    """The vocabulary the pipeline uses when its config names none (built by the harness)."""
    return vocabulary_path(DEFAULT_PARAMS)


def status_of(state: str) -> str:
    """exobench's status of an ORB-SLAM3 tracking state."""
    if state in STATES_OK:
        return "ok"
    if state in STATES_INITIALISING:
        return "initialising"
    return "lost"


class OrbSlam3Pipeline:
    """``orb-slam3``: ORB-SLAM3 RGB-D-inertial in a worker process (module docstring)."""

    name: ClassVar[str] = "orb-slam3"
    track: ClassVar[str] = "vio"
    # ORB-SLAM3 runs local mapping and loop closing in threads of its own, started by its System
    # constructor, with no setting (nor pyorbslam3 option) to run them in the tracking thread: what
    # the local mapping has done when a frame is tracked depends on the scheduler, so two runs
    # differ (docs/orbslam3.md).
    deterministic: ClassVar[bool] = False
    Config = OrbSlam3Config

    def __init__(self, config: OrbSlam3Config | None = None) -> None:
        self.config = config if config is not None else OrbSlam3Config()
        self._worker: OrbSlam3Worker | None = None
        self._folder: Path | None = None
        self._reset = False
        self._clear()

    def _clear(self) -> None:
        self._counters = StreamCounters()
        self._stamps: list[float] = []
        self._poses: list[np.ndarray] = []
        self._times: list[float] = []
        self._status: list[str] = []
        self._imu: list[tuple[float, ...]] = []
        self._imu_time = -math.inf
        self._queue: list[tuple[RgbdFrame, Any]] = []
        self._last_frame_s = -math.inf
        self._stats: dict[str, Any] = {"states": {}, "map_resets": 0, "map_starts": [], "worker_failed": False,
                                       "pose_source": "online"}  # fmt: skip
        self._failure: str = ""

    # ------------------------------------------------------------------ lifecycle

    def reset(self, calibration: Calibration) -> None:
        self._stop()
        self._clear()
        cam, imu = camera_mounts(calibration, self.config.camera_id)
        self._cam_id, self._imu_id = cam.sensor_id, (imu.sensor_id if imu is not None else "")
        self._max_depth = max_depth_m(cam)
        self._shift = _timeshift_s(calibration)
        self._T_body_camera = T_imu_camera(calibration)
        self._counters = StreamCounters.of(calibration)
        values = settings_values(calibration, self.config)
        vocab = Path(self.config.vocabulary) if self.config.vocabulary else default_vocabulary()
        if not vocab.is_file():
            raise ConfigError("orb-slam3.vocabulary", str(vocab),
                              "an ORBvoc.txt file (the default one is built by `exobench orbvoc` or on a run's start)")  # fmt: skip
        self._folder = Path(tempfile.mkdtemp(prefix="exobench-orbslam3-"))
        settings = self._folder / "settings.yaml"
        settings.write_text(settings_yaml(values))
        self._reset = True
        t0 = time.perf_counter()
        try:
            self._worker = OrbSlam3Worker(self._folder)
            self._worker.request({"op": "init", "vocabulary": str(vocab.resolve()), "settings": str(settings)},
                                 timeout_s=self.config.init_timeout_s)  # fmt: skip
        except (WorkerError, OSError) as e:
            self._fail(f"start: {e}")
        self._stats["start_s"] = time.perf_counter() - t0

    def process(self, frame: Frame) -> None:
        check_frame(self, frame, self._reset)
        if isinstance(frame, ImuSample) and frame.sensor_id == self._imu_id:
            c = self._counters.admit(frame)
            if c is None:
                return None
            row = (frame.stamp_s - self._shift, *np.asarray(frame.gyro_rad_s, float), *np.asarray(frame.accel_m_s2, float))
            if not all(math.isfinite(x) for x in row):
                c.add_nan()
            elif imu_absurd(frame):
                c.add_absurd()
            else:
                c.used += 1
                self._imu.append(row)
                self._imu_time = max(self._imu_time, row[0])
                self._flush(self._imu_time)
            return None
        if not (isinstance(frame, RgbdFrame) and frame.sensor_id == self._cam_id):
            self._counters.admit(frame, consumed=False)
            return None
        c = self._counters.admit(frame)
        if c is None:
            return None
        # ORB-SLAM3 integrates a frame's IMU interval once, when it tracks the frame: the frame
        # waits until the IMU (on the camera's clock) has reached its time, so that no sample of
        # the interval arrives too late to be given; a silent IMU holds it max_wait_s at most.
        self._queue.append((frame, c))
        self._flush(max(self._imu_time, float(frame.stamp_s) - self.config.max_wait_s))
        return None

    def _flush(self, until_s: float) -> None:
        while self._queue and float(self._queue[0][0].stamp_s) <= until_s:
            self._track(*self._queue.pop(0))

    def finalize(self) -> TrajectoryEstimate:
        self._flush(math.inf)
        if self._worker is not None and self._folder is not None:
            path = self._folder / "trajectory_euroc.txt"
            try:
                unsaved = self._worker.finish(path, timeout_s=self.config.close_timeout_s)
                if unsaved:  # every map was reset: ORB-SLAM3's trajectory holds no frame
                    self._stats["export_error"] = unsaved
                    self._use_export(np.zeros(0), np.zeros((0, 4, 4)))
                else:
                    self._use_export(*read_euroc(path))
            except (WorkerError, OSError, ValueError) as e:
                self._fail(f"trajectory export: {e}")
        self._stop()
        stats = dict(self._stats)
        stats["states"] = dict(stats["states"])
        stats["map_starts"] = list(stats["map_starts"])
        if self._failure:
            stats["failure"] = self._failure
        return TrajectoryEstimate(
            stamps_s=np.array(self._stamps, dtype=float),
            T_world_sensor=np.array(self._poses, dtype=float).reshape(-1, 4, 4),
            time_per_scan_s=np.array(self._times, dtype=float),
            status=tuple(self._status),
            stats=stats,
            counts=self._counters.snapshot(),
        )

    def __del__(self) -> None:  # a pipeline dropped without finalize must not leave its process behind
        with contextlib.suppress(Exception):  # interpreter shutdown: nothing left to report to
            self._stop()

    # ------------------------------------------------------------------ frames

    def _track(self, frame: RgbdFrame, c: Any) -> None:
        t = float(frame.stamp_s)
        depth = np.asarray(frame.depth_m, dtype=np.float32)
        bad_nan = nan_values(frame)
        absurd = absurd_depth(depth, self._max_depth)
        c.add_nan(bad_nan)
        c.add_absurd(int(absurd.sum()))
        if bad_nan or absurd.any():
            depth = np.where(np.isfinite(depth) & ~absurd, depth, 0.0).astype(np.float32)
        c.used += 1
        chunk = [r for r in self._imu if self._last_frame_s < r[0] <= t]
        self._imu = [r for r in self._imu if r[0] > t]
        self._last_frame_s = t
        t0 = time.perf_counter()
        status, pose = "failed", NAN_POSE
        if self._worker is not None:
            imu = np.array(chunk, dtype=np.float64).reshape(-1, 7)
            rgb = np.ascontiguousarray(frame.rgb, dtype=np.uint8)
            try:
                reply, arrays = self._worker.request({"op": "track", "t": t}, {"rgb": rgb, "depth": depth, "imu": imu},
                                                     timeout_s=self.config.frame_timeout_s)  # fmt: skip
            except WorkerError as e:
                self._fail(f"frame at {t:.3f} s: {e}")
            else:
                state = str(reply.get("state"))
                states = self._stats["states"]
                states[state] = states.get(state, 0) + 1
                status = status_of(state)
                if status == "ok" and "pose_wc" in arrays and np.all(np.isfinite(arrays["pose_wc"])):
                    pose = np.array(arrays["pose_wc"], dtype=float)
                elif status == "ok":
                    status = "lost"  # no usable pose came with it
                if status == "initialising" and self._status and self._status[-1] in ("ok", "lost"):
                    self._stats["map_resets"] += 1
                    self._stats["map_starts"].append(len(self._status))
                if reply.get("imu_initialised") and "imu_initialised_s" not in self._stats:
                    self._stats["imu_initialised_s"] = t
        self._stamps.append(t)
        self._poses.append(pose)
        self._status.append(status)
        self._times.append(time.perf_counter() - t0)

    def _use_export(self, stamps: np.ndarray, T_world_body: np.ndarray) -> None:
        """Replace the online poses of the frames tracked OK by ORB-SLAM3's export of its largest
        map (module docstring); a frame tracked OK but absent from it lay in a map left behind."""
        self._stats["pose_source"] = "export"
        other = 0
        for i, t in enumerate(self._stamps):
            if self._status[i] != "ok":
                continue
            j = int(np.searchsorted(stamps, t))
            near = [k for k in (j - 1, j) if 0 <= k < len(stamps) and abs(stamps[k] - t) <= EXPORT_MATCH_S]
            if near:
                self._poses[i] = T_world_body[near[0]] @ self._T_body_camera
            else:
                self._poses[i], self._status[i] = NAN_POSE, "lost"
                other += 1
        self._stats["frames_in_other_maps"] = other

    def _fail(self, reason: str) -> None:
        self._stats["worker_failed"] = True
        self._failure = self._failure or reason
        if self._worker is not None:
            self._worker.kill()
            self._worker.close(timeout_s=1.0)
        self._worker = None

    def _stop(self) -> None:
        if self._worker is not None:
            self._worker.close()
            self._worker = None
        if self._folder is not None:
            shutil.rmtree(self._folder, ignore_errors=True)
            self._folder = None
