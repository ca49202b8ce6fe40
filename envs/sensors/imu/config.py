"""Configuration of the trunk IMU (BMI055-class MEMS with an AHRS orientation output)."""

from __future__ import annotations

from dataclasses import dataclass

from exobench.core import check_range

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

    def __post_init__(self) -> None:
        check_timing("imu", self.rate_hz, self.latency_s, self.dropout_prob)
        for name in ("gyro_noise_density", "gyro_random_walk", "accel_noise_density", "accel_random_walk"):
            check_range(f"imu.{name}", getattr(self, name), 0.0, 1.0)
        check_range("imu.noise_scale", self.noise_scale, 0.0, 100.0)
        check_range("imu.orientation_rms_deg", self.orientation_rms_deg, 0.0, 30.0)
        check_range("imu.orientation_tau_s", self.orientation_tau_s, 0.0, 1e4, low_open=True)
