"""The configs of the scalar sensor streams a simulator mounts together (ToF, IMU, encoders, contact)."""

from __future__ import annotations

from dataclasses import dataclass

from .contact.config import ContactConfig
from .encoders.config import EncoderConfig
from .imu.config import ImuConfig
from .tof.config import ToFConfig


@dataclass(frozen=True)
class SensorsConfig:
    """Configs of every simulated sensor stream."""

    tof: ToFConfig = ToFConfig()
    imu: ImuConfig = ImuConfig()
    encoders: EncoderConfig = EncoderConfig()
    contact: ContactConfig = ContactConfig()

    def calibration_params(self) -> dict[str, dict]:
        """Per-kind parameters for :func:`exobench.models.exo.exo_calibration` (what a pipeline may know)."""
        t, i, c = self.tof, self.imu, self.contact
        return {
            "tof": {
                "rate_hz": t.rate_hz, "min_range_m": t.min_range_m, "max_range_m": t.max_range_m,
                "noise_sigma_m": t.noise_m, "fov_deg": t.fov_deg, "n_cone_rays": t.n_cone_rays,
                "resolution_m": t.resolution_m, "latency_s": t.latency_s,
            },
            "imu": {
                "rate_hz": i.rate_hz, "gyro_noise_density": i.noise_scale * i.gyro_noise_density,
                "gyro_random_walk": i.noise_scale * i.gyro_random_walk,
                "accel_noise_density": i.noise_scale * i.accel_noise_density,
                "accel_random_walk": i.noise_scale * i.accel_random_walk,
                "orientation_rms_deg": i.orientation_rms_deg, "latency_s": i.latency_s,
            },
            "contact": {"rate_hz": c.rate_hz, "threshold_n": c.threshold_n, "latency_s": c.latency_s},
        }  # fmt: skip
