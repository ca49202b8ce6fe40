"""The sliding window's parameters (:class:`WindowConfig`), checked on construction; the window
itself is :mod:`.window`."""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

from exobench.core.errors import ConfigError, check_int, check_range

from .factors import KERNELS
from .failure import FailureBounds

__all__ = ["SOLVERS", "WindowConfig"]

SOLVERS = {"cholesky": "MULTIFRONTAL_CHOLESKY", "qr": "MULTIFRONTAL_QR"}
"""The smoother's linear solvers by ``WindowConfig.linear_solver`` name: gtsam's ordering names."""


@dataclass(frozen=True)
class WindowConfig:
    """Back-end parameters (VINS-Mono's values where it has them).

    Attributes:
        window: keyframes in the window (the paper and VINS-Mono: 10).
        init_keyframes: keyframes the initialisation takes (at most ``window``).
        pixel_sigma_px: reprojection sigma, px (VINS-Mono: 1.5 at 460 px focal length).
        kernel / kernel_k: robust kernel of every visual and depth factor and its scale.
        depth_factors: host and projection depth factors on (``dvio``) or off (``dvio-no-depth``).
        max_iterations: Levenberg-Marquardt iterations per keyframe (VINS-Mono: 8).
        min_features: fewer tracked features than this is a tracking loss.
        min_landmarks: a new keyframe that observes fewer of the window's landmarks than this is a
            tracking loss (VINS-Mono's "little feature" bound, ``last_track_num < 2``): its pose,
            and once the window's last landmarks age out the whole window, would rest on the IMU
            alone, an optimisation whose system gtsam's Cholesky finds indeterminate.
        max_speed_mps / max_accel_bias / max_gyro_bias / max_update_speed_mps /
            max_update_climb_mps / update_slack_m / max_update_turn_deg / max_depth_misfit /
            max_init_tilt_deg / max_init_gyro_bias: the failure detection's bounds on the newest
            state after a window update and on an initialisation (:class:`.failure.FailureBounds`:
            VINS-Mono's, adapted to a walker, and three of this estimator's).
        linear_solver: the smoother's linear solver, "cholesky" (gtsam's default, multifrontal
            Cholesky on the normal equations) or "qr" (multifrontal QR on the Jacobian; docs/dvio.md
            "Long walks" for why it is not the default).
        bias_sigma_acc / bias_sigma_gyro: prior sigma of the initial biases (m/s^2, rad/s).
        depth_gate_px: a landmark whose reprojections miss by more than this on average (px),
            started from its host depth when it is made or at the estimate after a window
            update, has its depths dropped for good (0: never): a depth that is not
            the feature's (glass in front of it, a depth edge) otherwise holds the landmark off
            its rays and bends the window's poses (docs/dvio.md "Drift"). VINS-Fusion's
            ``outliersRejection`` drops such features (3 px at its 460 px focal length); here
            the feature stays, on its reprojections alone.
        tilt_sigma_rad: prior sigma of the roll and pitch of an initialisation's first pose, rad.
            The alignment's gravity is a least-squares fit to double-differenced SfM positions
            over about a second: off by 2-14 deg on a walk (docs/dvio.md "Drift"), which the
            window's IMU factors correct unless the prior holds it. VINS-Mono holds none. 0.02 rad
            [A] (0.1 before): a window of few or wrong landmarks, started after a loss in a hard
            stretch, otherwise follows them 12-90 deg off the vertical within a frame (the
            MH03-like walk, docs/dvio.md "Drift after a loss"; most of that was the new segment's
            velocity left in the wrong yaw, since fixed: "The re-anchored velocity"); a window of
            many still levels a 13 deg alignment to within 1 deg about 1 s later (the prior leaves
            with the first keyframe).
    """

    window: int = 10
    init_keyframes: int = 10
    pixel_sigma_px: float = 1.5
    kernel: str = "cauchy"
    kernel_k: float = 1.0
    depth_factors: bool = True
    max_iterations: int = 8
    min_features: int = 10
    min_landmarks: int = 2
    max_speed_mps: float = 8.0
    max_accel_bias: float = 2.5
    max_gyro_bias: float = 1.0
    max_update_speed_mps: float = 4.0
    max_update_climb_mps: float = 1.0
    update_slack_m: float = 0.5
    max_update_turn_deg: float = 50.0
    max_depth_misfit: float = 100.0
    max_init_tilt_deg: float = 5.0
    max_init_gyro_bias: float = 0.05
    linear_solver: str = "cholesky"
    bias_sigma_acc: float = 0.2
    bias_sigma_gyro: float = 0.02
    depth_gate_px: float = 3.0
    tilt_sigma_rad: float = 0.02

    def __post_init__(self) -> None:
        check_int("window", self.window, 3, 50)
        check_int("init_keyframes", self.init_keyframes, 3, self.window)
        check_range("pixel_sigma_px", self.pixel_sigma_px, 0.0, 50.0, low_open=True)
        if self.kernel not in KERNELS:
            raise ConfigError("kernel", self.kernel, "one of " + ", ".join(KERNELS))
        check_range("kernel_k", self.kernel_k, 0.0, 100.0, low_open=True)
        check_int("max_iterations", self.max_iterations, 1, 100)
        check_int("min_features", self.min_features, 0, 1000)
        check_int("min_landmarks", self.min_landmarks, 0, 1000)
        self.failure_bounds()  # its own checks name the field and its range
        if self.linear_solver not in SOLVERS:
            raise ConfigError("linear_solver", self.linear_solver, "one of " + ", ".join(SOLVERS))
        check_range("bias_sigma_acc", self.bias_sigma_acc, 0.0, 10.0, low_open=True)
        check_range("bias_sigma_gyro", self.bias_sigma_gyro, 0.0, 1.0, low_open=True)
        check_range("depth_gate_px", self.depth_gate_px, 0.0, 1000.0)
        check_range("tilt_sigma_rad", self.tilt_sigma_rad, 0.0, math.pi, low_open=True)

    def failure_bounds(self) -> FailureBounds:
        # by name, so a bound added to FailureBounds cannot be passed in the wrong place
        return FailureBounds(**{f.name: getattr(self, f.name) for f in fields(FailureBounds)})
