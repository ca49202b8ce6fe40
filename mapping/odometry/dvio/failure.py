"""D-VIO's failure detection after a window update (VINS-Mono's ``Estimator::failureDetection``).

VINS-Mono (vins_estimator/src/estimator.cpp, commit 90dabb5) checks the newest state after every
window optimisation and, on a failure, clears the estimator and initialises again: an accelerometer
bias norm above 2.5 m/s^2, a gyroscope bias norm above 1.0 rad/s, the newest position more than
5 m from the newest position after the previous optimisation, or more than 1 m from it vertically.
It also computes the rotation between the two and logs it above 50 deg (the ``return`` is
commented out), and logs a newest frame tracking fewer than 2 features (also not a failure there;
here that check is ``WindowConfig.min_landmarks``, made before the smoother runs).

VINS-Mono's translation bounds are a drone's, checked at every image (10-20 Hz on EuRoC): 5 m per
update is 50-100 m/s, so they only catch an estimate that has exploded. A walker moves little
between two updates: on the recorded MH04-like jog (head camera, 30 Hz frames, a keyframe every
2 frames) the true head speed over the interval between two window updates peaks at 3.4 m/s
(99.9th percentile 3.1 m/s; 2 m/s at 30 Hz is 7 cm a frame), and the true vertical step of an
update is at most 2.3 cm. Keyframes come by parallax, so the interval between two updates varies
(33 ms to about 0.5 s on that walk, longer when the walker stands): the translation bounds here
are speeds over that interval, with a slack for the window's correction of the newest pose:

- ``max_update_speed_mps`` 4.0: above the head's 3.4 m/s peak [A];
- ``max_update_climb_mps`` 1.0: a jogger's head bobs at about 0.5 m/s peak and stairs climb at
  0.2-0.5 m/s [A];
- ``update_slack_m`` 0.5: room for the window's correction of the newest pose. On the recorded
  MH04-like walk (Cholesky) the translation of an update exceeds 4 m/s over its interval by at
  most 0.01 m, but for a few updates: 0.14-0.22 m at the first update after a re-initialisation
  (0.35 m in 33 ms, a window 25 deg off the vertical), and 0.21 m where a good window pulled its
  newest pose 0.4 m back onto its landmarks after drifting (65.9 s: 0.53 m in 67 ms, the segment
  then ended 0.05 m off; with a 0.05 m slack that correction was declared a failure and the
  walk's ATE went 0.69 -> 0.80 m). A correction is one step; a window that runs away does so at a
  few m/s over many updates, which only the speed bound below sees, once past it (docs/dvio.md
  "Failure detection": too late to make QR pay on that walk);
- ``max_update_turn_deg`` 50: VINS-Mono's, now a failure; the head turned at most 7.3 deg between
  two updates on that jog (keyframes come by parallax, which a turn raises quickly);
- ``max_speed_mps`` 8.0 (the velocity state; a walking person's bound [A]: the head's true speed
  peaks at 3.4 m/s on that jog, a thigh camera's swing is faster), ``max_accel_bias`` 2.5 and
  ``max_gyro_bias`` 1.0 (VINS-Mono's).

Three checks VINS-Mono does not have, for what the paper suite's ring loop showed passing all of the
above (docs/dvio.md "The ring loop's two stretches"):

- ``max_depth_misfit`` 100: the window's depth misfit (:func:`depth_misfit`), the median over every
  depth measurement of the window's landmarks, the gated ones included, of its residual at the
  estimate in sigmas of the depth noise model. Depth measures metric scale: a window that runs off
  along the walk keeps its reprojections (its landmarks move with it) but not its depths. The
  depth gate (``WindowConfig.depth_gate_px``) then drops those depths as wrong one by one, so the
  misfit only shows when the gated ones are counted. Replayed: a healthy window 0.4-0.5 (median),
  at most 36.7 (ring loop) and 40.9 (MH04-like) in short stretches that recovered; the windows that
  ran off 100-3800 for seconds (the ring loop's 2.78 m segment, MH04-like's segment at 5.4-9.4 s);
- ``max_init_gyro_bias`` 0.05 rad/s: an initialisation whose gyroscope bias (from the SfM's
  rotations) no gyroscope has: a D455's IMU is specified within 1 deg/s (0.017 rad/s) [A]; the
  replayed walks' good alignments gave 0.5-45 mrad/s, alignments over a third of a second of
  keyframes 110-207 (their segments ran away or carried that bias into the next loss);
- ``max_init_tilt_deg`` 5: a re-initialisation's first keyframe's vertical (its alignment's
  gravity) against the last good state's, propagated by the gyroscope through the loss (the
  anchor of the new segment): the gyroscope keeps the vertical over a short loss, an alignment
  over 0.3 s of keyframes does not (the ring loop: 10.6 deg off the truth, 10.9 deg off the
  carried vertical). The window checks it within the first half of the dead reckoning's 3 s only,
  so a refused segment still starts on a propagated anchor.

Both refuse the initialisation (counted in ``stats["inits_refused_<reason>"]``), not a window
update; the next keyframe tries again.

The window (:mod:`.window`) discards a window that fails any of them and re-initialises as after a
solver failure, from the state before that update.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import gtsam
import numpy as np

from exobench.core.errors import check_range

__all__ = ["REASONS", "FailureBounds", "depth_misfit", "diverged", "init_refused", "tilt_between_deg"]

# Reasons in the order they are checked; ``stats["failures_<reason with _>"]`` counts each.
REASONS = ("not finite", "speed", "accel bias", "gyro bias", "jump", "vertical jump", "turn", "depth misfit")
# Fewer depth measurements in the window than this give no misfit (a median of a handful is noise).
_MIN_MISFIT_DEPTHS = 20


@dataclass(frozen=True)
class FailureBounds:
    """Bounds on the newest state after a window update (module docstring for the sources)."""

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

    def __post_init__(self) -> None:
        check_range("max_speed_mps", self.max_speed_mps, 0.0, 100.0, low_open=True)
        check_range("max_accel_bias", self.max_accel_bias, 0.0, 50.0, low_open=True)
        check_range("max_gyro_bias", self.max_gyro_bias, 0.0, 10.0, low_open=True)
        check_range("max_update_speed_mps", self.max_update_speed_mps, 0.0, 100.0, low_open=True)
        check_range("max_update_climb_mps", self.max_update_climb_mps, 0.0, 100.0, low_open=True)
        check_range("update_slack_m", self.update_slack_m, 0.0, 100.0)
        check_range("max_update_turn_deg", self.max_update_turn_deg, 0.0, 180.0, low_open=True)
        check_range("max_depth_misfit", self.max_depth_misfit, 0.0, 1e9, low_open=True)
        check_range("max_init_tilt_deg", self.max_init_tilt_deg, 0.0, 180.0, low_open=True)
        check_range("max_init_gyro_bias", self.max_init_gyro_bias, 0.0, 10.0, low_open=True)


def depth_misfit(residuals: Sequence[float]) -> float:
    """The window's depth misfit: the median of its depth measurements' residuals at the estimate,
    each ``|depth of the landmark at the estimate - measured depth|`` over the measurement's sigma
    (NaN for fewer than ``_MIN_MISFIT_DEPTHS`` of them)."""
    r = np.asarray(residuals, dtype=float)
    r = r[np.isfinite(r)]
    return float(np.median(r)) if len(r) >= _MIN_MISFIT_DEPTHS else math.nan


def tilt_between_deg(R_a: np.ndarray, R_b: np.ndarray) -> float:
    """Angle (deg) between the vertical of the attitude ``R_a`` (body to a gravity-aligned frame,
    z up) and that of ``R_b``, each seen in the body's axes: their yaws do not count."""
    up_a = np.asarray(R_a, dtype=float).T @ np.array([0.0, 0.0, 1.0])
    up_b = np.asarray(R_b, dtype=float).T @ np.array([0.0, 0.0, 1.0])
    return math.degrees(math.acos(float(np.clip(up_a @ up_b, -1.0, 1.0))))


def init_refused(bounds: FailureBounds, R_init: np.ndarray, gyro_bias: np.ndarray,
                 R_carried: np.ndarray | None = None) -> str:
    """Why an initialisation is refused ("" if it is not): its gyroscope bias (rad/s) above
    ``max_init_gyro_bias`` ("gyro bias"), or its first keyframe's attitude ``R_init`` (its
    alignment's gravity) more than ``max_init_tilt_deg`` off ``R_carried``, the last good state's
    attitude propagated by the gyroscope through the loss to that keyframe ("tilt"; None: not
    checked)."""
    if not float(np.linalg.norm(gyro_bias)) <= bounds.max_init_gyro_bias:
        return "gyro bias"
    if R_carried is not None and tilt_between_deg(R_init, R_carried) > bounds.max_init_tilt_deg:
        return "tilt"
    return ""


def diverged(bounds: FailureBounds, before: gtsam.NavState, after: gtsam.NavState,
             bias: gtsam.imuBias.ConstantBias, dt_s: float, misfit: float = math.nan) -> str:
    """The first of :data:`REASONS` that the newest state ``after`` (with its ``bias``) fails,
    ``dt_s`` after the newest state of the previous update ``before``, with the window's depth
    ``misfit`` (:func:`depth_misfit`; NaN: not checked); "" when it fails none."""
    T0, T1 = before.pose(), after.pose()
    if not (np.all(np.isfinite(T1.matrix())) and np.all(np.isfinite(after.velocity()))
            and np.all(np.isfinite(bias.vector()))):
        return "not finite"
    if np.linalg.norm(after.velocity()) > bounds.max_speed_mps:
        return "speed"
    if np.linalg.norm(bias.accelerometer()) > bounds.max_accel_bias:
        return "accel bias"
    if np.linalg.norm(bias.gyroscope()) > bounds.max_gyro_bias:
        return "gyro bias"
    step = np.asarray(T1.translation()) - np.asarray(T0.translation())
    dt = max(float(dt_s), 0.0)
    if np.linalg.norm(step) > bounds.max_update_speed_mps * dt + bounds.update_slack_m:
        return "jump"
    if abs(float(step[2])) > bounds.max_update_climb_mps * dt + bounds.update_slack_m:
        return "vertical jump"
    turn = np.linalg.norm(gtsam.Rot3.Logmap(T0.rotation().between(T1.rotation())))
    if math.degrees(float(turn)) > bounds.max_update_turn_deg:
        return "turn"
    if math.isfinite(misfit) and misfit > bounds.max_depth_misfit:
        return "depth misfit"
    return ""
