"""Configuration of the calf time-of-flight sensors (ST VL53L1X)."""

from __future__ import annotations

from dataclasses import dataclass

from exobench.core import check_int, check_range

from ..common import check_timing


@dataclass(frozen=True)
class ToFConfig:
    """ST VL53L1X single-beam ranging.

    Output: :class:`~exobench.core.ToFReading`, the range along the sensor site's +z axis, m.
    Sources: ST VL53L1X data sheet and ULD API (docs/sensor-reference.md); [A] marks an assumption.

    Attributes:
        rate_hz: ranging rate, Hz (50).
        latency_s: delivery delay after the measurement, s [A: 0].
        dropout_prob: probability a frame is lost [A: 0].
        noise_m: standard deviation of the static range noise, m (1.5e-3, the paper's).
        min_range_m / max_range_m: valid range, m (0.04 / 4.0); outside: NaN, OUT_OF_BOUNDS.
        fov_deg: full cone angle, deg (27). n_cone_rays: 1 = the central ray only (the paper's
            model); more = a cone of sub-rays mixed by return strength (cos(incidence) / r^2).
        resolution_m: output quantisation, m (1e-3: the ULD API reports millimetres; 0 = off).
        sigma_limit_m: with a cone, readings whose sub-ranges spread more than this are flagged
            SIGMA_FAIL (the range is still reported) [A: 0.05].
    """

    rate_hz: float = 50.0
    latency_s: float = 0.0
    noise_m: float = 1.5e-3
    dropout_prob: float = 0.0
    min_range_m: float = 0.04
    max_range_m: float = 4.0
    fov_deg: float = 27.0
    n_cone_rays: int = 1
    resolution_m: float = 1e-3
    sigma_limit_m: float = 0.05

    def __post_init__(self) -> None:
        check_timing("tof", self.rate_hz, self.latency_s, self.dropout_prob)
        check_range("tof.noise_m", self.noise_m, 0.0, 0.1)
        check_range("tof.min_range_m", self.min_range_m, 0.0, 1.0)
        check_range("tof.max_range_m", self.max_range_m, self.min_range_m, 100.0, low_open=True)
        check_range("tof.fov_deg", self.fov_deg, 0.0, 90.0)
        object.__setattr__(self, "n_cone_rays", check_int("tof.n_cone_rays", self.n_cone_rays, 1, 256))
        check_range("tof.resolution_m", self.resolution_m, 0.0, 0.05)
        check_range("tof.sigma_limit_m", self.sigma_limit_m, 0.0, 1.0, low_open=True)
