"""Heel-strike shock transients in a body-worn accelerometer.

The IMU is derived from the planned kinematic motion, whose feet touch down with smooth
(minimum-jerk) trajectories, so it has no impact. A real foot strike sends a short shock up the
skeleton; wearable visual-inertial odometry meets it as spikes of several m/s^2 at every step.

Peaks (docs/vio-realism.md): Light, McLellan and Klenerman (1980), "Skeletal transients on heel
strike in normal walking with different footwear", J. Biomech. 13(6):477-480, measured the
transient simultaneously at the tibia and the skull in normal walking: about 5 g at the tibia and
0.5 g at the skull with hard heels; resilient heels halved both. The thigh and the trunk lie
between; with no simultaneous figure of the same study for them, the attenuation is split
equally (in dB) over the three joints the shock crosses (knee, hip and spine up to the trunk,
neck up to the head): a factor 10 ** (-1 / 3) = 0.464 each, so thigh 2.32 g and trunk 1.08 g [D].
A sensor on the other leg than the striking foot receives the shock through the pelvis: the
trunk figure [A].

Shape [A]: a damped oscillation along the world vertical (the shock of the ground travels up the
skeleton), ``a(s) = A exp(-s / tau) sin(2 pi f s) / n`` for s >= 0 after the touchdown, with
f = 25 Hz and tau = 12 ms (the transient is over within about 50 ms, before the loading peak of
the ground reaction force) and ``n`` the maximum of ``exp(-s / tau) sin(2 pi f s)`` so the
waveform's peak is ``A``. The delay of the travelling wave up the body (a few ms) is not modelled.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

G_M_S2 = 9.80665
TIBIA_PEAK_G = 5.0  # Light et al. (1980), normal walking, hard heels
HEAD_PEAK_G = 0.5  # same study, skull
JOINT_ATTENUATION = (HEAD_PEAK_G / TIBIA_PEAK_G) ** (1.0 / 3.0)  # [D] equal per joint: knee, hip, neck
PEAK_G: dict[str, float] = {
    "shank": TIBIA_PEAK_G,
    "thigh": TIBIA_PEAK_G * JOINT_ATTENUATION,
    "trunk": TIBIA_PEAK_G * JOINT_ATTENUATION**2,
    "head": HEAD_PEAK_G,
}
FREQ_HZ = 25.0  # [A]
TAU_S = 0.012  # [A]
DURATION_S = 8.0 * TAU_S  # exp(-8) < 4e-4 of the peak: later samples get nothing


def _peak_of_shape() -> float:
    # the maximum of exp(-s/tau) sin(w s): where tan(w s) = w tau
    w = 2.0 * np.pi * FREQ_HZ
    s = np.arctan(w * TAU_S) / w
    return float(np.exp(-s / TAU_S) * np.sin(w * s))


_NORM = _peak_of_shape()


def waveform(s: np.ndarray) -> np.ndarray:
    """The unit transient at times ``s`` after the touchdown (0 before it and after DURATION_S)."""
    s = np.asarray(s, dtype=float)
    on = (s >= 0.0) & (s < DURATION_S)
    sc = np.where(on, s, 0.0)
    return np.where(on, np.exp(-sc / TAU_S) * np.sin(2.0 * np.pi * FREQ_HZ * sc) / _NORM, 0.0)


def body_level(body: str) -> tuple[str, str | None]:
    """(level, leg side or None) of an exoskeleton body: shank (and foot), thigh, trunk
    (pelvis, the chest rig) or head."""
    for prefix, level in (("shank_", "shank"), ("foot_", "shank"), ("thigh_", "thigh")):
        if body.startswith(prefix):
            return level, body[len(prefix):]
    if body == "head":
        return "head", None
    return "trunk", None


def peak_m_s2(level: str, side: str | None, strike_side: str) -> float:
    """Peak of the transient at a sensor on ``level`` (of leg ``side``) when foot ``strike_side`` lands."""
    if side is not None and side != strike_side:
        return PEAK_G["trunk"] * G_M_S2
    return PEAK_G[level] * G_M_S2


def impact_accel_world(t: np.ndarray, strikes: Sequence[tuple[float, str]], body: str, scale: float) -> np.ndarray:
    """World-frame acceleration (N, 3) the heel strikes ``(touchdown_s, side)`` add at times ``t``
    to a sensor rigid with ``body``, ``scale`` times the published peaks."""
    t = np.asarray(t, dtype=float)
    out = np.zeros((len(t), 3))
    level, side = body_level(body)
    for t_hs, strike_side in strikes:
        out[:, 2] += scale * peak_m_s2(level, side, strike_side) * waveform(t - t_hs)
    return out
