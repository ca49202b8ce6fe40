"""IMU preintegration for D-VIO on gtsam (seeds/002 eq. 7-9, the ``C_B`` term of eq. 15).

The preintegration measurement ``z = {alpha, beta, gamma}`` of eq. (7) between two keyframes is
gtsam's ``PreintegratedCombinedMeasurements`` (``deltaPij``, ``deltaVij``, ``deltaRij``): the
combined variant carries the bias random walk, i.e. the last two rows of eq. (7), in the factor
itself (``CombinedImuFactor``), so the window needs no separate bias-between factors.

Noise comes from the calibration's IMU mount (kalibr conventions, docs/sensor-reference.md "IMU"): continuous
noise densities (per sqrt(Hz)) and random walks, which gtsam takes as continuous-time covariances
(density squared) and discretises with the sample interval itself.

Samples are integrated over each interval with the mean of its two end samples, the end one
rotated into the attitude at the interval's start (VINS-Mono's midpoint rule, which the paper's
D-VIO inherits): the error is second order in the sample interval, where holding the first sample
(or averaging the raw samples while the body turns) is first order. A sample with a non-finite value, or a
stamp not after the previous one (repeated or out of order), is skipped and counted in
:attr:`ImuPreintegrator.skipped`, never raised on: a dropped or faulty sample widens one interval.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import gtsam
import numpy as np

from exobench.core.errors import check_range

__all__ = ["GRAVITY_MPS2", "ImuNoise", "ImuPreintegrator", "combined_factor"]

#: Standard gravity, m/s^2; the gravity-aligned frame G has +z up (gtsam ``MakeSharedU``).
GRAVITY_MPS2 = 9.80665

# Longest interval integrated as one step: a gap beyond it (the IMU stream stopped) is not
# bridged by a constant-rate assumption, the samples after it start a new hold.
_MAX_GAP_S = 0.5


@dataclass(frozen=True)
class ImuNoise:
    """Continuous-time IMU noise (kalibr conventions).

    Attributes:
        gyro_noise_density: rad/s/sqrt(Hz).
        gyro_random_walk: rad/s^2/sqrt(Hz).
        accel_noise_density: m/s^2/sqrt(Hz).
        accel_random_walk: m/s^3/sqrt(Hz).
        integration_sigma: m/s^2/sqrt(Hz)-like term of gtsam for the position integration error
            (VINS and gtsam's examples use about 1e-4).
        gravity_mps2: magnitude of gravity in G.
    """

    gyro_noise_density: float = 1.027e-4
    gyro_random_walk: float = 1.11e-6
    accel_noise_density: float = 1.038e-3
    accel_random_walk: float = 4.13e-5
    integration_sigma: float = 1e-4
    gravity_mps2: float = GRAVITY_MPS2

    def __post_init__(self) -> None:
        for name in ("gyro_noise_density", "gyro_random_walk", "accel_noise_density", "accel_random_walk",
                     "integration_sigma"):
            # gtsam needs invertible covariances: a density of exactly 0 is refused.
            check_range(f"imu.{name}", getattr(self, name), 0.0, 1.0, low_open=True)
        check_range("imu.gravity_mps2", self.gravity_mps2, 9.0, 10.5)

    @classmethod
    def from_params(cls, params: Mapping[str, Any]) -> ImuNoise:
        """Noise of an IMU mount's ``params`` (the calibration's names; missing ones default)."""
        names = ("gyro_noise_density", "gyro_random_walk", "accel_noise_density", "accel_random_walk")
        return cls(**{n: float(params[n]) for n in names if n in params})

    def gtsam_params(self) -> gtsam.PreintegrationCombinedParams:
        p = gtsam.PreintegrationCombinedParams.MakeSharedU(self.gravity_mps2)
        eye = np.eye(3)
        p.setGyroscopeCovariance(self.gyro_noise_density**2 * eye)
        p.setAccelerometerCovariance(self.accel_noise_density**2 * eye)
        p.setBiasOmegaCovariance(self.gyro_random_walk**2 * eye)
        p.setBiasAccCovariance(self.accel_random_walk**2 * eye)
        p.setIntegrationCovariance(self.integration_sigma**2 * eye)
        return p


class ImuPreintegrator:
    """Preintegrates IMU samples since the last :meth:`reset` (the last keyframe).

    ``add(stamp_s, accel_mps2, gyro_radps)`` takes one sample in the IMU frame; :meth:`integrate_to`
    extends the integration to a frame time by holding the last sample, so a keyframe boundary
    between two samples splits that interval exactly.
    """

    def __init__(self, noise: ImuNoise, bias: gtsam.imuBias.ConstantBias | None = None) -> None:
        self.noise = noise
        self._params = noise.gtsam_params()
        self.pim = gtsam.PreintegratedCombinedMeasurements(
            self._params, bias if bias is not None else gtsam.imuBias.ConstantBias())
        self._last: tuple[float, np.ndarray, np.ndarray] | None = None
        self._start_s: float | None = None
        self.skipped = 0

    @property
    def start_s(self) -> float | None:
        """Stamp the current preintegration starts at (None before the first sample)."""
        return self._start_s

    @property
    def end_s(self) -> float | None:
        """Stamp integrated up to (the last sample or :meth:`integrate_to` time)."""
        return None if self._last is None else self._last[0]

    def reset(self, stamp_s: float | None = None, bias: gtsam.imuBias.ConstantBias | None = None) -> None:
        """Start a new preintegration at ``stamp_s`` (default: the last integrated time), with
        ``bias`` as the linearisation point (default: the current one). The last sample is kept
        as the hold for the next interval."""
        self.pim.resetIntegrationAndSetBias(bias if bias is not None else self.pim.biasHat())
        self._start_s = stamp_s if stamp_s is not None else self.end_s

    def add(self, stamp_s: float, accel_mps2: np.ndarray, gyro_radps: np.ndarray) -> bool:
        """Integrate up to the sample at ``stamp_s``; False (and counted) if it is skipped."""
        acc = np.asarray(accel_mps2, dtype=float).reshape(3)
        gyr = np.asarray(gyro_radps, dtype=float).reshape(3)
        if not (math.isfinite(stamp_s) and np.all(np.isfinite(acc)) and np.all(np.isfinite(gyr))):
            self.skipped += 1
            return False
        if self._last is None:
            self._last = (stamp_s, acc, gyr)
            if self._start_s is None:
                self._start_s = stamp_s
            return True
        t0, a0, w0 = self._last
        dt = stamp_s - t0
        if dt <= 0.0:
            self.skipped += 1
            return False
        if dt <= _MAX_GAP_S:
            w_mid = 0.5 * (w0 + gyr)
            # gtsam rotates the step's acceleration with the attitude at the step's start; the
            # end sample is brought into that frame first, so the step is VINS-Mono's midpoint
            # (trapezoid in G) rather than an average of two differently oriented vectors.
            b = self.pim.biasHat()
            turn = gtsam.Rot3.Expmap((w_mid - b.gyroscope()) * dt).matrix()
            a_mid = 0.5 * (a0 + turn @ (acc - b.accelerometer()) + b.accelerometer())
            self.pim.integrateMeasurement(a_mid, w_mid, dt)
        self._last = (stamp_s, acc, gyr)
        return True

    def integrate_to(self, stamp_s: float) -> None:
        """Extend the integration to ``stamp_s`` (a frame time after the last sample) with the
        last sample held; a time at or before the last one changes nothing."""
        if self._last is None or not math.isfinite(stamp_s):
            return
        t0, a0, w0 = self._last
        dt = stamp_s - t0
        if 0.0 < dt <= _MAX_GAP_S:
            self.pim.integrateMeasurement(a0, w0, dt)
            self._last = (stamp_s, a0, w0)

    def predict(self, nav: gtsam.NavState, bias: gtsam.imuBias.ConstantBias | None = None) -> gtsam.NavState:
        """The state at :attr:`end_s` from ``nav`` at :attr:`start_s` (IMU-rate propagation)."""
        return self.pim.predict(nav, bias if bias is not None else self.pim.biasHat())


def combined_factor(pose_i: int, vel_i: int, pose_j: int, vel_j: int, bias_i: int, bias_j: int,
                    pim: gtsam.PreintegratedCombinedMeasurements) -> gtsam.CombinedImuFactor:
    """The IMU factor of eq. (7) between keyframes i and j (keys of poses, velocities, biases)."""
    return gtsam.CombinedImuFactor(pose_i, vel_i, pose_j, vel_j, bias_i, bias_j, pim)
