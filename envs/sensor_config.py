"""Sensor configurations (units, rates, latency, noise, dropout) and their random streams.

Each config is a frozen dataclass validated on construction (:class:`ConfigError` names the
field). Defaults come from ``SENSORS.md``; [A] marks an assumption. Every sensor draws from its
own generators, derived from ``np.random.SeedSequence([seed, stable_int_key(sensor_id)])``, so a
sensor's noise does not depend on which other sensors run, nor its dropout on its noise.
Timing: a sensor measures at ``k / rate_hz`` (k = 0, 1, ...); a frame is delivered (stamped) at
measurement time + ``latency_s`` and dropped with probability ``dropout_prob``.
"""

from __future__ import annotations

import zlib
from dataclasses import dataclass

import numpy as np

from exobench.core import ConfigError, check_range


def stable_int_key(name: str) -> int:
    """A stable 32-bit integer for a name (CRC-32; unlike ``hash`` it is the same in every run)."""
    return zlib.crc32(name.encode("utf-8"))


def sensor_rngs(seed: int, sensor_id: str) -> tuple[np.random.Generator, np.random.Generator]:
    """(noise, dropout) generators of one sensor for a scenario seed."""
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ConfigError("seed", seed, "an integer >= 0")
    noise, drop = np.random.SeedSequence([int(seed), stable_int_key(sensor_id)]).spawn(2)
    return np.random.default_rng(noise), np.random.default_rng(drop)


def sample_times(rate_hz: float, duration_s: float) -> np.ndarray:
    """Measurement times ``k / rate_hz`` in [0, duration_s] (exact multiples, so streams at
    commensurate rates share time stamps exactly)."""
    n = int(np.floor(duration_s * rate_hz + 1e-9)) + 1
    return np.arange(n) / rate_hz


def _common(prefix: str, rate_hz: float, latency_s: float, dropout_prob: float) -> None:
    check_range(f"{prefix}.rate_hz", rate_hz, 0.0, 10000.0, low_open=True)
    check_range(f"{prefix}.latency_s", latency_s, 0.0, 1.0)
    check_range(f"{prefix}.dropout_prob", dropout_prob, 0.0, 1.0, high_open=True)


def _int(field: str, value: object, low: int, high: int) -> int:
    x = check_range(field, value, low, high)  # type: ignore[arg-type]
    if x != int(x):
        raise ConfigError(field, value, f"an integer in [{low}, {high}]")
    return int(x)


@dataclass(frozen=True)
class ToFConfig:
    """ST VL53L1X single-beam ranging (SENSORS.md).

    Attributes:
        rate_hz: ranging rate, Hz (50). latency_s: delivery delay, s [A: 0].
        noise_m: standard deviation of the static range noise, m (1.5e-3, the paper's).
        dropout_prob: probability a frame is lost [A: 0].
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
        _common("tof", self.rate_hz, self.latency_s, self.dropout_prob)
        check_range("tof.noise_m", self.noise_m, 0.0, 0.1)
        check_range("tof.min_range_m", self.min_range_m, 0.0, 1.0)
        check_range("tof.max_range_m", self.max_range_m, self.min_range_m, 100.0, low_open=True)
        check_range("tof.fov_deg", self.fov_deg, 0.0, 90.0)
        object.__setattr__(self, "n_cone_rays", _int("tof.n_cone_rays", self.n_cone_rays, 1, 256))
        check_range("tof.resolution_m", self.resolution_m, 0.0, 0.05)
        check_range("tof.sigma_limit_m", self.sigma_limit_m, 0.0, 1.0, low_open=True)


@dataclass(frozen=True)
class ImuConfig:
    """Trunk IMU with an AHRS orientation output (kalibr noise conventions, SENSORS.md).

    Attributes:
        rate_hz: 200 Hz. latency_s [A: 0]. dropout_prob [A: 0].
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
        _common("imu", self.rate_hz, self.latency_s, self.dropout_prob)
        for name in ("gyro_noise_density", "gyro_random_walk", "accel_noise_density", "accel_random_walk"):
            check_range(f"imu.{name}", getattr(self, name), 0.0, 1.0)
        check_range("imu.noise_scale", self.noise_scale, 0.0, 100.0)
        check_range("imu.orientation_rms_deg", self.orientation_rms_deg, 0.0, 30.0)
        check_range("imu.orientation_tau_s", self.orientation_tau_s, 0.0, 1e4, low_open=True)


@dataclass(frozen=True)
class EncoderConfig:
    """Joint encoders of the leg joints (``JointState``, sensor id ``encoders``).

    Attributes:
        rate_hz: 200 Hz [A: the device samples at 1 kHz; 200 Hz keeps sessions small].
        noise_rad: white noise standard deviation, rad [A: 1e-4].
        resolution_bits: quantisation, bits per turn [A: 14]; 0 = off.
        offset_std_rad: standard deviation of a constant per-joint offset drawn once, rad [A: 0].
    """

    rate_hz: float = 200.0
    latency_s: float = 0.0
    dropout_prob: float = 0.0
    noise_rad: float = 1e-4
    resolution_bits: int = 14
    offset_std_rad: float = 0.0

    def __post_init__(self) -> None:
        _common("encoders", self.rate_hz, self.latency_s, self.dropout_prob)
        check_range("encoders.noise_rad", self.noise_rad, 0.0, 0.5)
        object.__setattr__(self, "resolution_bits", _int("encoders.resolution_bits", self.resolution_bits, 0, 32))
        check_range("encoders.offset_std_rad", self.offset_std_rad, 0.0, 0.5)


@dataclass(frozen=True)
class ContactConfig:
    """Insole force pads under heel and toe, from the geometric contact of the feet.

    Attributes:
        rate_hz: 100 Hz [A]. noise_n: force noise standard deviation, N [A: 2].
        threshold_n: ``in_contact`` when the force exceeds it, N (20, as the calibration says).
        contact_tol_m: a pad touches when within this distance of the terrain under it (2 mm).
    """

    rate_hz: float = 100.0
    latency_s: float = 0.0
    dropout_prob: float = 0.0
    noise_n: float = 2.0
    threshold_n: float = 20.0
    contact_tol_m: float = 2e-3

    def __post_init__(self) -> None:
        _common("contact", self.rate_hz, self.latency_s, self.dropout_prob)
        check_range("contact.noise_n", self.noise_n, 0.0, 1000.0)
        check_range("contact.threshold_n", self.threshold_n, 0.0, 5000.0)
        check_range("contact.contact_tol_m", self.contact_tol_m, 0.0, 0.05)


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
