"""Configuration of a camera's odometry stream (the tracker a VIO would run on the camera)."""

from __future__ import annotations

from dataclasses import dataclass

from exobench.core import check_range

from ..common import check_timing


@dataclass(frozen=True)
class OdometryConfig:
    """Odometry of the optical frame of the camera it is attached to.

    Output: :class:`~exobench.core.OdometrySample` at each camera measurement time (lost camera
    frames included), the pose of the optical frame in a gravity-aligned odometry frame whose
    origin and heading are the camera's at t = 0.

    Attributes:
        rate_hz: sampling rate, Hz (the camera's frame rate).
        drift_pct: translation error, percent of the horizontal distance travelled (1).
        yaw_drift_deg_per_m: heading error per metre travelled, deg/m (0.5).
    """

    rate_hz: float = 30.0
    drift_pct: float = 1.0
    yaw_drift_deg_per_m: float = 0.5

    def __post_init__(self) -> None:
        check_timing("odometry", self.rate_hz, 0.0, 0.0)
        check_range("odometry.drift_pct", self.drift_pct, 0.0, 100.0)
        check_range("odometry.yaw_drift_deg_per_m", self.yaw_drift_deg_per_m, 0.0, 180.0)
