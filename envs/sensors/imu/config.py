"""Configuration of the trunk IMU (BMI055-class MEMS with an AHRS orientation output)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from exobench.core import ConfigError, check_range

from ..common import check_timing


@dataclass(frozen=True)
class ImuConfig:
    """Trunk IMU with an AHRS orientation output (kalibr noise conventions).

    Output: :class:`~exobench.core.ImuSample` in the IMU site's frame: ``quat_wxyz`` of
    ``R_world_imu`` (gravity-aligned world), ``gyro_rad_s`` (rad/s), ``accel_m_s2`` (specific
    force, m/s^2). Sources: docs/sensor-reference.md (BMI055 Allan figures of the OpenVINS rs_d455 kalibr files);
    [A] marks an assumption.

    Attributes:
        rate_hz: sampling rate, Hz (200).
        latency_s: delivery delay after the measurement, s [A: 0].
        dropout_prob: probability a frame is lost [A: 0].
        gyro_noise_density: rad/s/sqrt(Hz) (BMI055 Allan 1.027e-4); gyro_random_walk:
            rad/s^2/sqrt(Hz) (1.11e-6); accel_noise_density: m/s^2/sqrt(Hz) (1.038e-3);
            accel_random_walk: m/s^3/sqrt(Hz) (4.13e-5). Discrete: white sigma = ND / sqrt(dt),
            bias step = RW * sqrt(dt). noise_scale multiplies all four.
        orientation_rms_deg: rms angle of the AHRS orientation error [A: 0.2 deg], a first-order
            Gauss-Markov rotation error with correlation time orientation_tau_s [A: 1 s].
        extrinsics: pose of an IMU attached to a camera in the camera's optical frame,
            ``T_camera_imu`` (:data:`CAMERA_IMU_EXTRINSICS`): ``"identity"`` (the IMU at the
            optical frame, as before) or ``"d455"`` (a D455's BMI055 relative to its colour camera,
            docs/vio-realism.md). Ignored by an IMU not attached to a camera.
        time_offset_s: the IMU's clock minus the camera's (kalibr ``timeshift_cam_imu``:
            t_imu = t_cam + offset): every IMU stamp is its measurement time + ``latency_s`` +
            ``time_offset_s`` [0; a D455 calibration: 0.0025 s, docs/vio-realism.md].
        heel_strike_scale: heel-strike shock transients in the accelerometer (:mod:`.impact`),
            as a multiple of the published walking peaks (Light et al. 1980, hard heels; 0.5 is
            their resilient heels); 0: none (the kinematic motion alone, as before).
    """

    rate_hz: float = 200.0
    latency_s: float = 0.0
    dropout_prob: float = 0.0
    gyro_noise_density: float = 1.027e-4
    gyro_random_walk: float = 1.11e-6
    accel_noise_density: float = 1.038e-3
    accel_random_walk: float = 4.13e-5
    noise_scale: float = 1.0
    orientation_rms_deg: float = 0.2
    orientation_tau_s: float = 1.0
    extrinsics: str = "identity"
    time_offset_s: float = 0.0
    heel_strike_scale: float = 0.0

    def __post_init__(self) -> None:
        check_timing("imu", self.rate_hz, self.latency_s, self.dropout_prob)
        for name in ("gyro_noise_density", "gyro_random_walk", "accel_noise_density", "accel_random_walk"):
            check_range(f"imu.{name}", getattr(self, name), 0.0, 1.0)
        check_range("imu.noise_scale", self.noise_scale, 0.0, 100.0)
        check_range("imu.orientation_rms_deg", self.orientation_rms_deg, 0.0, 30.0)
        check_range("imu.orientation_tau_s", self.orientation_tau_s, 0.0, 1e4, low_open=True)
        if self.extrinsics not in CAMERA_IMU_EXTRINSICS:
            raise ConfigError("imu.extrinsics", self.extrinsics, "one of " + ", ".join(CAMERA_IMU_EXTRINSICS))
        check_range("imu.time_offset_s", self.time_offset_s, -MAX_TIME_OFFSET_S, MAX_TIME_OFFSET_S)
        check_range("imu.heel_strike_scale", self.heel_strike_scale, 0.0, 5.0)

    def T_camera_imu(self) -> np.ndarray:
        """The IMU's pose in the optical frame of the camera it is attached to (4x4)."""
        return np.array(CAMERA_IMU_EXTRINSICS[self.extrinsics], dtype=float)


# A D455's IMU relative to its colour camera's optical frame (z forward, x right, y down), kalibr
# ``T_cam_imu`` of the colour camera in OpenVINS' config/rs_d455/kalibr_imucam_chain.yaml (a
# kalibr calibration of a real D455 at 848x480; timeshift_cam_imu 0.002524 s): the IMU sits
# 27.5 mm to the left of the colour camera, 3.1 mm above it and 23.6 mm behind its optical
# centre, rotated by 0.48 deg.
_D455_T_CAMERA_IMU = (
    (0.9999654398038452, 0.007342326779113337, -0.003899927610975742, -0.027534314618518095),
    (-0.0073452195116216765, 0.9999727585590525, -0.0007279355223411334, -0.0030587146933711722),
    (0.0038944766308488753, 0.0007565561891287445, 0.9999921303062861, -0.023605118842939803),
    (0.0, 0.0, 0.0, 1.0),
)
CAMERA_IMU_EXTRINSICS: dict[str, tuple[tuple[float, ...], ...]] = {
    "identity": ((1.0, 0.0, 0.0, 0.0), (0.0, 1.0, 0.0, 0.0), (0.0, 0.0, 1.0, 0.0), (0.0, 0.0, 0.0, 1.0)),
    "d455": _D455_T_CAMERA_IMU,
}
D455_TIME_OFFSET_S = 0.002524  # the same calibration's timeshift_cam_imu (colour camera)
MAX_TIME_OFFSET_S = 0.1  # larger offsets are a wrong clock, not a calibration
