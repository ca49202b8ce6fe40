"""The D-VIO pipelines (issue 27): ``dvio`` (seeds/002 II-C) and ``dvio-no-depth`` (its ablation
without the window's depth factors, Table IV's VINS-Mono-like row), on the core pipeline protocol.

Input: the RGB-D frames of the calibration's camera (``extra["camera"]``, else the first
``rgbd`` mount) and the samples of its IMU (``extra["camera_imu"]``, else the first ``imu``
mount); other frames are counted as ignored. From the calibration: the camera's intrinsics,
baseline and disparity noise (the depth noise model), the IMU's noise densities (kalibr names),
``extra["T_camera_imu"]`` (the IMU's pose in the optical frame; identity when absent) and
``extra["timeshift_cam_imu_s"]`` (``t_imu = t_cam + shift``; 0 when absent).

A frame is processed once the IMU has reached its time (IMU latency and clock offset make the
samples arrive after it), or after ``max_wait_s`` of frames when the IMU is silent.

Output (:meth:`DvioPipeline.finalize`): a :class:`~exobench.core.estimates.TrajectoryEstimate`
with the camera optical frame's pose ``T_world_sensor`` in the gravity-aligned frame G at every
RGB-D frame used, and its status: ``"ok"``; ``"initialising"`` before the first initialisation;
``"lost"`` after a tracking loss until re-initialised. A frame without a pose has a NaN pose
(never a made-up one). ``time_per_scan_s`` is each frame's processing time (tracking and
estimation, with the IMU samples handled since the previous frame). ``process`` of an IMU sample
returns the IMU-rate pose (:class:`ImuRatePose`) while tracking.

Faults are counted (:mod:`exobench.core.counters`) and survived: repeated or out-of-order
frames and samples are refused by the counters, gaps count as dropped, NaN depth pixels and
non-finite IMU samples as NaN, depth pixels beyond what the camera can report
(:func:`exobench.core.limits.max_depth_m`) and IMU samples no IMU reports
(:func:`exobench.core.limits.imu_absurd`) as absurd; an absurd IMU sample is skipped, and a
depth of 0, NaN or absurd at a feature gives no depth factor.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, fields
from typing import Any, ClassVar

import numpy as np

from exobench.core.calibration import Calibration, SensorMount
from exobench.core.counters import StreamCounters, nan_values
from exobench.core.errors import ConfigError, check_range
from exobench.core.estimates import TrajectoryEstimate
from exobench.core.frames import Frame, ImuSample, RgbdFrame
from exobench.core.limits import absurd_depth, imu_absurd
from exobench.core.limits import max_depth_m as reportable_depth_m
from exobench.core.pipeline import check_frame

from .factors import KERNELS, DepthNoise, Extrinsics
from .imu import ImuNoise
from .tracker import FeatureTracker, TrackerConfig, normalised
from .window import SlidingWindow, WindowConfig

# Largest relative spread of the four depths around a feature that is still one surface [A]: a
# floor seen at 60 deg from its normal at 1.5 m changes by about 1 % per pixel.
_EDGE_REL = 0.05

__all__ = ["DvioConfig", "DvioNoDepthConfig", "DvioNoDepthPipeline", "DvioPipeline", "ImuRatePose"]


@dataclass(frozen=True)
class DvioConfig:
    """Parameters of D-VIO (front end: VINS-Mono's; back end: :class:`.window_config.WindowConfig`).

    Attributes:
        window: keyframes in the sliding window.
        init_keyframes: keyframes of the initialisation (at most ``window``).
        max_features / min_distance_px / keyframe_parallax_px: KLT front end (:class:`.tracker.TrackerConfig`).
        equalize: CLAHE on each grey image before tracking (VINS-Mono's ``equalize``, :mod:`.tracker`).
        pixel_sigma_px: reprojection sigma, px.
        kernel / kernel_k: robust kernel ("cauchy", "huber", "none") and its scale.
        depth_factors: the host and projection depth factors (eq. 11-14) on.
        max_iterations: Levenberg-Marquardt iterations per keyframe.
        min_features: fewer tracked features is a tracking loss.
        min_landmarks: a keyframe observing fewer window landmarks is a tracking loss.
        max_speed_mps / max_accel_bias / max_gyro_bias / max_update_speed_mps /
            max_update_climb_mps / update_slack_m / max_update_turn_deg / max_depth_misfit /
            max_init_tilt_deg / max_init_gyro_bias: the failure detection's bounds on a window
            update and on an initialisation (:class:`.failure.FailureBounds`).
        linear_solver: the window smoother's linear solver ("cholesky" or "qr").
        max_wait_s: longest a frame waits for the IMU to reach its time, s.
        camera_id / imu_id: streams to read ("" = the calibration's camera and its IMU).
    """

    window: int = 10
    init_keyframes: int = 10
    max_features: int = 150
    # VINS-Mono's 30 px is for EuRoC's 752x480 images; at 424x240 the same spacing is 17 px.
    min_distance_px: float = 20.0
    keyframe_parallax_px: float = 10.0
    equalize: bool = True
    pixel_sigma_px: float = 1.5
    kernel: str = "cauchy"
    kernel_k: float = 1.0
    depth_factors: bool = True
    max_iterations: int = 8
    min_features: int = 10
    min_landmarks: int = 2
    max_speed_mps: float = 8.0
    max_accel_bias: float = 2.5
    max_gyro_bias: float = 1.0
    max_update_speed_mps: float = 4.0
    max_update_climb_mps: float = 1.0
    update_slack_m: float = 0.5
    max_update_turn_deg: float = 50.0
    max_depth_misfit: float = 100.0
    max_init_tilt_deg: float = 5.0
    max_init_gyro_bias: float = 0.05
    linear_solver: str = "cholesky"
    max_wait_s: float = 0.5
    camera_id: str = ""
    imu_id: str = ""

    def __post_init__(self) -> None:
        if self.kernel not in KERNELS:
            raise ConfigError("kernel", self.kernel, "one of " + ", ".join(KERNELS))
        check_range("max_wait_s", self.max_wait_s, 0.0, 10.0)
        self.tracker()  # their own checks name the field and its range
        self.window_config()

    def tracker(self) -> TrackerConfig:
        return TrackerConfig(max_features=self.max_features, min_distance_px=self.min_distance_px,
                             keyframe_parallax_px=self.keyframe_parallax_px, equalize=self.equalize)

    def window_config(self) -> WindowConfig:
        # every window field this config also declares, by name (a bound added to both cannot be
        # left out); the window's own (bias and tilt sigmas, the depth gate) keep their defaults
        return WindowConfig(**{f.name: getattr(self, f.name) for f in fields(WindowConfig) if hasattr(self, f.name)})


@dataclass(frozen=True)
class DvioNoDepthConfig(DvioConfig):
    """:class:`DvioConfig` with the window's depth factors off by default."""

    depth_factors: bool = False


@dataclass(frozen=True, eq=False)
class ImuRatePose:
    """The IMU's pose ``T_world_imu`` (4x4) in G at ``stamp_s`` (camera clock)."""

    stamp_s: float
    T_world_imu: np.ndarray


def _param(mount: SensorMount, name: str, default: float | None, low: float, high: float) -> float:
    value = mount.params.get(name, default)
    if value is None:
        raise ConfigError(f"{mount.sensor_id}.{name}", None, f"a number in [{low}, {high}]")
    return check_range(f"{mount.sensor_id}.{name}", value, low, high)


class DvioPipeline:
    """D-VIO (see the module docstring)."""

    name: ClassVar[str] = "dvio"
    track: ClassVar[str] = "vio"
    Config: ClassVar[type] = DvioConfig

    def __init__(self, config: DvioConfig | None = None) -> None:
        self.config = config if config is not None else self.Config()
        self._reset_done = False
        self._counters = StreamCounters()

    def reset(self, calibration: Calibration) -> None:
        c = self.config
        extra = calibration.extra or {}
        cams = calibration.mounts_of_kind("rgbd")
        imus = calibration.mounts_of_kind("imu")
        cam_id = c.camera_id or extra.get("camera") or (cams[0].sensor_id if cams else "")
        imu_id = c.imu_id or extra.get("camera_imu") or (imus[0].sensor_id if imus else "")
        if not cam_id:
            raise ConfigError("calibration.camera", None, "an rgbd mount")
        cam = calibration.mount(cam_id)
        self._K = np.array([_param(cam, n, None, 1.0, 1e5) for n in ("fx_px", "fy_px", "cx_px", "cy_px")])
        self._depth = DepthNoise(focal_px=float(self._K[0]), baseline_m=_param(cam, "baseline_m", 0.095, 1e-3, 1.0),
                                 subpixel=_param(cam, "subpixel", 0.08, 1e-4, 10.0),
                                 min_depth_m=_param(cam, "min_depth_m", 0.4, 0.0, 100.0),
                                 max_depth_m=_param(cam, "max_depth_m", 6.0, 0.0, 100.0))
        imu_noise = ImuNoise.from_params(calibration.mount(imu_id).params) if imu_id else ImuNoise()
        T_cam_imu = np.asarray(extra.get("T_camera_imu", np.eye(4)), dtype=float)
        if T_cam_imu.shape != (4, 4) or not np.all(np.isfinite(T_cam_imu)):
            raise ConfigError("calibration.extra.T_camera_imu", T_cam_imu.tolist(), "a finite 4x4 rigid transform")
        R = T_cam_imu[:3, :3]
        if not np.allclose(R @ R.T, np.eye(3), atol=1e-4) or abs(np.linalg.det(R) - 1.0) > 1e-4:
            raise ConfigError("calibration.extra.T_camera_imu", T_cam_imu.tolist(), "a rotation block with det 1")
        self._ext = Extrinsics.from_T_imu_camera(np.linalg.inv(T_cam_imu))
        self._shift = check_range("calibration.extra.timeshift_cam_imu_s", extra.get("timeshift_cam_imu_s", 0.0),
                                  -0.1, 0.1)
        self._cam_id, self._imu_id = cam_id, imu_id
        self._depth_hi_m = reportable_depth_m(cam)  # beyond it a depth is absurd (core.limits)
        self._counters = StreamCounters.of(calibration)
        self._tracker = FeatureTracker(self.config.tracker())
        self._window = SlidingWindow(c.window_config(), self._ext, imu_noise, self._depth, float(self._K[0]))
        self._queue: list[RgbdFrame] = []
        self._imu_time = -math.inf
        self._imu_cost_s = 0.0
        self._stamps: list[float] = []
        self._poses: list[np.ndarray] = []
        self._status: list[str] = []
        self._times: list[float] = []
        self._n_features: list[int] = []
        self._no_depth_frames = 0
        self._first_stamp: float | None = None
        self._reset_done = True

    def process(self, frame: Frame) -> ImuRatePose | None:
        check_frame(self, frame, self._reset_done)
        if isinstance(frame, ImuSample):
            c = self._counters.admit(frame, consumed=frame.sensor_id == self._imu_id)
            if c is None:
                return None
            if nan_values(frame):
                c.add_nan(nan_values(frame))
                return None
            if imu_absurd(frame):  # a rate or force no IMU reports: skipped, as a NaN one
                c.add_absurd()
                return None
            t0 = time.perf_counter()
            if not self._window.add_imu(float(frame.stamp_s) - self._shift, frame.accel_m_s2, frame.gyro_rad_s):
                c.add_nan(nan_values(frame))
                return None
            c.used += 1
            self._imu_time = float(frame.stamp_s) - self._shift
            pose = self._window.imu_pose()
            self._imu_cost_s += time.perf_counter() - t0
            self._flush(self._imu_time)
            return None if pose is None else ImuRatePose(pose[0], pose[1])
        c = self._counters.admit(frame, consumed=isinstance(frame, RgbdFrame) and frame.sensor_id == self._cam_id)
        if c is None:
            return None
        c.add_nan(nan_values(frame))
        c.add_absurd(self._absurd_pixels(frame.depth_m))
        c.used += 1
        self._queue.append(frame)
        # A silent IMU must not hold images without bound: the oldest goes after max_wait_s.
        self._flush(max(self._imu_time, float(frame.stamp_s) - self.config.max_wait_s))
        return None

    def _flush(self, until_s: float) -> None:
        while self._queue and float(self._queue[0].stamp_s) <= until_s:
            self._handle(self._queue.pop(0))

    def _handle(self, frame: RgbdFrame) -> None:
        t0 = time.perf_counter()
        stamp = float(frame.stamp_s)
        if self._first_stamp is None:
            self._first_stamp = stamp
        tracked = self._tracker.track(stamp, frame.rgb)
        status, T = "lost", None
        n = 0
        if tracked is not None:
            n = len(tracked.ids)
            fx, fy, cx, cy = self._K
            u = normalised(tracked.pts_px, fx, fy, cx, cy)
            depth = self._depth_at(frame.depth_m, tracked.pts_px)
            status, T = self._window.add_frame(stamp, tracked.ids.tolist(), u, depth, tracked.is_keyframe)
        self._stamps.append(stamp)
        self._poses.append(T if T is not None else np.full((4, 4), np.nan))
        self._status.append(status)
        self._n_features.append(n)
        self._times.append(time.perf_counter() - t0 + self._imu_cost_s)
        self._imu_cost_s = 0.0

    def _absurd_pixels(self, depth: object) -> int:
        """How many depth pixels no camera of this mount can report (0 if unreadable); they are
        left out of the features' depths by :meth:`_depth_at`."""
        try:
            return int(np.count_nonzero(absurd_depth(np.asarray(depth, dtype=float), self._depth_hi_m)))
        except (TypeError, ValueError):
            return 0

    def _depth_at(self, depth_m: np.ndarray, pts_px: np.ndarray) -> np.ndarray:
        """Depth at each feature, bilinear between the four pixels around it; NaN where one of
        them has no depth or they differ by more than ``_EDGE_REL`` (a corner on a depth edge:
        its depth is the foreground's or the background's, not the feature's)."""
        d = np.asarray(depth_m, dtype=float)
        if d.ndim != 2 or len(pts_px) == 0 or min(d.shape) < 2:
            self._no_depth_frames += 1
            return np.full(len(pts_px), np.nan)
        h, w = d.shape
        x = np.clip(pts_px[:, 0], 0.0, w - 1.001)
        y = np.clip(pts_px[:, 1], 0.0, h - 1.001)
        x0, y0 = np.floor(x).astype(int), np.floor(y).astype(int)
        fx, fy = x - x0, y - y0
        q = np.stack([d[y0, x0], d[y0, x0 + 1], d[y0 + 1, x0], d[y0 + 1, x0 + 1]], axis=1)
        wts = np.stack([(1 - fx) * (1 - fy), fx * (1 - fy), (1 - fx) * fy, fx * fy], axis=1)
        with np.errstate(invalid="ignore"):
            good = np.all(np.isfinite(q) & (q > 0.0) & (q <= self._depth_hi_m), axis=1)
            good &= (q.max(axis=1) - q.min(axis=1)) <= _EDGE_REL * q.min(axis=1)
        out = np.where(good, np.sum(np.where(np.isfinite(q), q, 0.0) * wts, axis=1), np.nan)
        if not np.any(np.isfinite(out)):
            self._no_depth_frames += 1
        return out

    def frame_results(self, start: int = 0) -> list[tuple[float, np.ndarray, str]]:
        """(stamp, camera pose in G or NaN, status) of each RGB-D frame handled so far, from the
        ``start``-th on: what a pipeline built on D-VIO reads as the frames are handled (a frame
        waits for the IMU to reach its time, so a result comes after its frame)."""
        return list(zip(self._stamps[start:], self._poses[start:], self._status[start:]))

    def window_poses(self) -> list[tuple[float, np.ndarray]]:
        """(stamp, camera pose in G) of the keyframes in the window now: right after a first pose,
        those of the initialisation window, instants its frames' results leave without a pose."""
        return self._window.keyframe_poses() if self._reset_done else []

    def imu_pose(self) -> ImuRatePose | None:
        """The newest IMU-rate pose (None when not tracking)."""
        pose = self._window.imu_pose() if self._reset_done else None
        return None if pose is None else ImuRatePose(pose[0], pose[1])

    def propagation(self) -> tuple[float, np.ndarray, float, np.ndarray] | None:
        """While lost, the last good state's IMU propagation (:meth:`SlidingWindow.propagation`)."""
        return self._window.propagation()

    def finalize(self) -> TrajectoryEstimate:
        if not self._reset_done:
            return TrajectoryEstimate(np.zeros(0), np.zeros((0, 4, 4)), np.zeros(0))
        self._flush(math.inf)
        w = self._window
        init_s = (w.init_time_s - self._first_stamp if w.init_time_s is not None and self._first_stamp is not None
                  else math.nan)
        stats: dict[str, Any] = {
            **w.stats, "init_s": init_s, "frames_without_depth": self._no_depth_frames,
            "features_tracked_mean": float(np.mean(self._n_features)) if self._n_features else 0.0,
            "lost_frames": self._status.count("lost"), "initialising_frames": self._status.count("initialising"),
            "imu_skipped": self._counters.kind("imu").nan, "loss_reasons": dict(w.loss_reasons),
            "depth_factors": self.config.depth_factors,
        }
        return TrajectoryEstimate(
            stamps_s=np.array(self._stamps, dtype=float),
            T_world_sensor=np.array(self._poses, dtype=float).reshape(-1, 4, 4),
            time_per_scan_s=np.array(self._times, dtype=float),
            status=tuple(self._status), stats=stats, counts=self._counters.snapshot())


class DvioNoDepthPipeline(DvioPipeline):
    """``dvio-no-depth``: D-VIO without the window's depth factors (module docstring)."""

    name: ClassVar[str] = "dvio-no-depth"
    Config: ClassVar[type] = DvioNoDepthConfig

