"""Configuration of the leg joint encoders."""

from __future__ import annotations

from dataclasses import dataclass

from exobench.core import check_int, check_range

from ..common import check_timing


@dataclass(frozen=True)
class EncoderConfig:
    """Joint encoders of the leg joints.

    Output: :class:`~exobench.core.JointState` (sensor id ``encoders``), joint angles in rad in
    the robot description's joint order. Sources: docs/sensor-reference.md; [A] marks an assumption.

    Attributes:
        rate_hz: sampling rate, Hz (200) [A: the device samples at 1 kHz; 200 Hz keeps sessions small].
        latency_s: delivery delay after the measurement, s [A: 0].
        dropout_prob: probability a frame is lost [A: 0].
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
        check_timing("encoders", self.rate_hz, self.latency_s, self.dropout_prob)
        check_range("encoders.noise_rad", self.noise_rad, 0.0, 0.5)
        object.__setattr__(
            self, "resolution_bits", check_int("encoders.resolution_bits", self.resolution_bits, 0, 32)
        )
        check_range("encoders.offset_std_rad", self.offset_std_rad, 0.0, 0.5)
