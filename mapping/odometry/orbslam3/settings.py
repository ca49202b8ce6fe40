"""The ``orb-slam3`` adapter's config and the ORB-SLAM3 settings file it writes from the calibration.

ORB-SLAM3 reads an OpenCV YAML file (its ``Settings`` class, ``File.version: "1.0"``). The
adapter writes one per episode into its own temporary folder, from:

- the camera mount's intrinsics (``fx_px`` ... ``cy_px``, ``width_px``, ``height_px``,
  ``rate_hz``) and stereo baseline (``baseline_m``; ORB-SLAM3's ``Stereo.b``, whose multiple
  ``th_depth`` separates close points, trusted from one frame, from far ones); the images are
  rectified (no distortion);
- ``RGBD.DepthMapFactor`` 1: exobench's depth images are float metres already;
- ``IMU.T_b_c1``: the camera's pose in the IMU (body) frame. exobench's calibration gives the
  other direction, ``extra["T_camera_imu"]`` (the IMU's pose in the optical frame, kalibr's
  ``T_cam_imu``), so it is inverted; the identity when the calibration has none;
- the IMU's noise densities and random walks (kalibr conventions, as ORB-SLAM3's) and rate from
  the camera IMU's mount, unless the config sets them;
- ORB extraction parameters from the config.

ORB-SLAM3 has no camera-IMU time offset setting: the adapter applies ``timeshift_cam_imu_s``
(``t_imu = t_cam + shift``) to the IMU stamps itself; the file records the value it applied.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from exobench.core.calibration import Calibration, SensorMount
from exobench.core.errors import ConfigError, check_int, check_range
from exobench.core.transforms import invert_T

STATES_OK = ("OK",)
STATES_INITIALISING = ("SYSTEM_NOT_READY", "NO_IMAGES_YET", "NOT_INITIALIZED")


@dataclass(frozen=True)
class OrbSlam3Config:
    """Parameters of ORB-SLAM3 (its settings file) and of the adapter.

    Attributes:
        n_features: ``ORBextractor.nFeatures``, features per image (ORB-SLAM3's RGB-D examples:
            1000 at 640x480).
        scale_factor: ``ORBextractor.scaleFactor`` between pyramid levels.
        n_levels: ``ORBextractor.nLevels``.
        ini_th_fast / min_th_fast: ``ORBextractor.iniThFAST`` / ``minThFAST``, FAST thresholds
            (the second is tried in cells where the first finds nothing).
        th_depth: ``Stereo.ThDepth``, close points are nearer than this many baselines.
        gyro_noise_density, gyro_random_walk, accel_noise_density, accel_random_walk: IMU noise
            (``IMU.NoiseGyro``, ``IMU.GyroWalk``, ``IMU.NoiseAcc``, ``IMU.AccWalk``; kalibr units);
            0: the camera IMU's calibration value.
        camera_id: the RGB-D camera used (empty: the calibration's ``extra["camera"]``).
        vocabulary: path of an ``ORBvoc.txt`` (empty: exobench's vocabulary built from simulated
            images, :mod:`.vocabulary`, which the harness builds on first use).
        max_wait_s: longest a frame waits for the IMU to reach its time, s (an IMU stamped later
            than the camera, ``timeshift_cam_imu_s`` > 0 or a latency, delivers the samples of a
            frame's interval after the frame; a silent IMU must not hold frames without bound).
        init_timeout_s: time allowed to start ORB-SLAM3 and load the vocabulary, s.
        frame_timeout_s: time allowed for one frame, s; a worker slower than that is killed.
        close_timeout_s: time allowed to shut ORB-SLAM3 down and export its trajectory, s.

    """

    n_features: int = 2000
    scale_factor: float = 1.2
    n_levels: int = 8
    ini_th_fast: int = 4
    min_th_fast: int = 1
    th_depth: float = 40.0
    gyro_noise_density: float = 0.0
    gyro_random_walk: float = 0.0
    accel_noise_density: float = 0.0
    accel_random_walk: float = 0.0
    camera_id: str = ""
    vocabulary: str = ""
    max_wait_s: float = 0.5
    init_timeout_s: float = 300.0
    frame_timeout_s: float = 10.0
    close_timeout_s: float = 120.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "n_features", check_int("n_features", self.n_features, 50, 10000))
        check_range("scale_factor", self.scale_factor, 1.0, 2.0, low_open=True)
        object.__setattr__(self, "n_levels", check_int("n_levels", self.n_levels, 1, 16))
        object.__setattr__(self, "ini_th_fast", check_int("ini_th_fast", self.ini_th_fast, 1, 255))
        object.__setattr__(self, "min_th_fast", check_int("min_th_fast", self.min_th_fast, 1, self.ini_th_fast))
        check_range("th_depth", self.th_depth, 1.0, 1000.0)
        for name in ("gyro_noise_density", "gyro_random_walk", "accel_noise_density", "accel_random_walk"):
            check_range(name, getattr(self, name), 0.0, 10.0)
        check_range("max_wait_s", self.max_wait_s, 0.0, 10.0)
        check_range("init_timeout_s", self.init_timeout_s, 1.0, 3600.0)
        check_range("frame_timeout_s", self.frame_timeout_s, 0.1, 600.0)
        check_range("close_timeout_s", self.close_timeout_s, 1.0, 3600.0)



def camera_mounts(calibration: Calibration, camera_id: str) -> tuple[SensorMount, SensorMount | None]:
    """The RGB-D camera used (``camera_id``, else ``extra["camera"]``, else the first RGB-D mount)
    and its IMU (``extra["camera_imu"]`` when it belongs to that camera, else None)."""
    cams = calibration.mounts_of_kind("rgbd")
    cam_id = camera_id or calibration.extra.get("camera") or (cams[0].sensor_id if cams else "")
    if not cam_id:
        raise ConfigError("orb-slam3 camera", "none", "a calibration with an RGB-D camera")
    cam = calibration.mount(cam_id)
    if cam.kind != "rgbd":
        raise ConfigError("orb-slam3.camera_id", cam_id, "an RGB-D camera of the calibration")
    imu_id = calibration.extra.get("camera_imu") if cam_id == calibration.extra.get("camera") else None
    return cam, (calibration.mount(imu_id) if imu_id else None)


def T_imu_camera(calibration: Calibration) -> np.ndarray:
    """ORB-SLAM3's ``IMU.T_b_c1``: the camera in the IMU frame, the inverse of ``T_camera_imu``."""
    return invert_T(np.asarray(calibration.extra.get("T_camera_imu", np.eye(4)), dtype=float).reshape(4, 4))


def _number(params: dict[str, Any], key: str, field: str) -> float:
    try:
        x = float(params[key])
    except (KeyError, TypeError, ValueError):
        raise ConfigError(field, params.get(key), "a number in the calibration") from None
    return x


def settings_values(calibration: Calibration, config: OrbSlam3Config) -> dict[str, Any]:
    """The settings as ``{key: value}`` (matrices as 4x4 arrays), checked for ORB-SLAM3."""
    cam, imu = camera_mounts(calibration, config.camera_id)
    p = dict(cam.params)
    values: dict[str, Any] = {"Camera.type": '"PinHole"'}
    for key, name in (("fx_px", "fx"), ("fy_px", "fy"), ("cx_px", "cx"), ("cy_px", "cy")):
        values[f"Camera1.{name}"] = _number(p, key, f"{cam.sensor_id}.{key}")
    for name in ("k1", "k2", "p1", "p2"):
        values[f"Camera1.{name}"] = 0.0
    values["Camera.width"] = int(_number(p, "width_px", f"{cam.sensor_id}.width_px"))
    values["Camera.height"] = int(_number(p, "height_px", f"{cam.sensor_id}.height_px"))
    values["Camera.fps"] = int(round(_number(p, "rate_hz", f"{cam.sensor_id}.rate_hz")))
    values["Camera.RGB"] = 1  # exobench's colour images are RGB
    values["Stereo.ThDepth"] = float(config.th_depth)
    values["Stereo.b"] = float(p.get("baseline_m", 0.095))  # a D455's when the mount does not say
    values["RGBD.DepthMapFactor"] = 1.0
    ip = dict(imu.params) if imu is not None else {}
    values["IMU.T_b_c1"] = T_imu_camera(calibration)
    values["IMU.InsertKFsWhenLost"] = 0
    for key, name in (("gyro_noise_density", "IMU.NoiseGyro"), ("accel_noise_density", "IMU.NoiseAcc"),
                      ("gyro_random_walk", "IMU.GyroWalk"), ("accel_random_walk", "IMU.AccWalk")):  # fmt: skip
        given = float(getattr(config, key))
        value = given if given > 0 else float(ip.get(key, 0.0) or 0.0)
        if not value > 0:
            raise ConfigError(f"orb-slam3.{key}", value, "> 0 (set it, or give the camera IMU's in the calibration)")
        values[name] = value
    values["IMU.Frequency"] = float(ip.get("rate_hz", 200.0))
    values["IMU.TimeShiftCamImu"] = timeshift_s(calibration)  # not read by ORB-SLAM3: applied by the adapter
    values["ORBextractor.nFeatures"] = config.n_features
    values["ORBextractor.scaleFactor"] = float(config.scale_factor)
    values["ORBextractor.nLevels"] = config.n_levels
    values["ORBextractor.iniThFAST"] = config.ini_th_fast
    values["ORBextractor.minThFAST"] = config.min_th_fast
    # the viewer is never started, but ORB-SLAM3's Settings requires its keys
    values.update({"Viewer.KeyFrameSize": 0.05, "Viewer.KeyFrameLineWidth": 1.0, "Viewer.GraphLineWidth": 0.9,
                   "Viewer.PointSize": 2.0, "Viewer.CameraSize": 0.08, "Viewer.CameraLineWidth": 3.0,
                   "Viewer.ViewpointX": 0.0, "Viewer.ViewpointY": -0.7, "Viewer.ViewpointZ": -3.5,
                   "Viewer.ViewpointF": 500.0})  # fmt: skip
    return values


def timeshift_s(calibration: Calibration) -> float:
    """``t_imu - t_cam`` of the camera IMU (kalibr's ``timeshift_cam_imu``), 0 when not given."""
    return float(calibration.extra.get("timeshift_cam_imu_s", 0.0) or 0.0)


def settings_yaml(values: dict[str, Any]) -> str:
    """``values`` as an OpenCV YAML file (``%YAML:1.0``, matrices as ``!!opencv-matrix``)."""
    lines = ["%YAML:1.0", "---", 'File.version: "1.0"']
    for key, v in values.items():
        if isinstance(v, np.ndarray):
            data = ", ".join(f"{x:.17g}" for x in v.ravel())
            lines += [f"{key}: !!opencv-matrix", f"   rows: {v.shape[0]}", f"   cols: {v.shape[1]}", "   dt: f",
                      f"   data: [{data}]"]  # fmt: skip
        elif isinstance(v, float):
            lines.append(f"{key}: {v:.17g}" if v != int(v) or abs(v) >= 1e16 else f"{key}: {v:.1f}")
        else:
            lines.append(f"{key}: {v}")
    return "\n".join(lines) + "\n"
