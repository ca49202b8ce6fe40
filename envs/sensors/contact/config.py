"""Configuration of the heel and toe insole force pads."""

from __future__ import annotations

from dataclasses import dataclass

from exobench.core import check_range

from ..common import check_timing


@dataclass(frozen=True)
class ContactConfig:
    """Insole force pads under heel and toe, from the geometric contact of the feet.

    Output: :class:`~exobench.core.ContactSample` per pad (``contact_{l,r}_{heel,toe}``): normal
    force, N, and ``in_contact``. Sources: docs/sensor-reference.md; [A] marks an assumption.

    Attributes:
        rate_hz: sampling rate, Hz [A: 100].
        latency_s: delivery delay after the measurement, s [A: 0].
        dropout_prob: probability a frame is lost [A: 0].
        noise_n: force noise standard deviation, N [A: 2].
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
        check_timing("contact", self.rate_hz, self.latency_s, self.dropout_prob)
        check_range("contact.noise_n", self.noise_n, 0.0, 1000.0)
        check_range("contact.threshold_n", self.threshold_n, 0.0, 5000.0)
        check_range("contact.contact_tol_m", self.contact_tol_m, 0.0, 0.05)
