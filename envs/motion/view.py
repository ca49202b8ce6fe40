"""Camera view motion of the locomotion track: the head's (neck) or chest rig's extra joint motion
added to a planned walk, with the looks down at terrain transitions.

A smooth random signal z(t) is a sum of :data:`N_PARTIALS` sinusoids with seeded frequencies in
0.15-1.2 Hz and phases, normalised over the episode to mean 0 and standard deviation 1 (so the
realised spread is the configured one; seeds/002 section IV-A 2, Fig. 4(b)). The head's camera
pitch below the horizon is ``mean + std * z(t)`` clipped to the paper's range -0.66..1.18 rad
(with ``gaze``, :class:`GazeDown`: plus looks down at each terrain transition, the mean and
spread of the random part reduced so that the episode keeps ``mean`` and ``std``); the neck
pitch is that minus the mount's pitch and the trunk's pitch of the gait, clipped to the neck's
joint range. Neck yaw is 0.15 rad * a second such signal. The chest rig sways with a third of
the head's spread around 0. ``unconventional`` (seeds/002 III-B 2) adds a slow excursion
(0.05-0.15 Hz) of up to +-:data:`UNCONV_YAW_RAD` yaw and +-0.35 rad pitch, the camera's pitch kept
in the paper's range; ``unconventional-wide`` is the harder excursion of +-60 deg yaw whose pitch
may leave that range. Derivatives for the IMU come from central differences of these analytic
signals (step :data:`DIFF_H_S`). Every limit is a smooth clamp (:func:`soft_clip`): a hard clip's
kink in the angle's rate read as one sample of ~50 g in the head IMU (a neck pitch reaching its
joint limit at 0.87 rad/s).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

N_PARTIALS = 8
DIFF_H_S = 2e-4
PITCH_RANGE_RAD = (-0.66, 1.18)  # paper Fig. 4(b)
NECK_YAW_STD_RAD = 0.15  # [A] ordinary looking around while walking
CHEST_SPREAD = 1.0 / 3.0  # [A] a chest bag sways much less than the head
# Gaze at terrain transitions (head mount, ``gaze="transitions"``): people walking over uneven
# terrain fixate the ground about two steps ahead and look at the transitions they approach
# (Marigold & Patla, Neuroscience 144 (2007) 302-313; stairs: Zietz & Hollands, J. Mot. Behav.
# 41 (2009) 357-365). The head pitches down by up to GAZE_DOWN_RAD [A: 0.45 rad, so the peak
# stays inside the paper's range with the 0.14 rad mean] over GAZE_WIDTH_STEPS step periods
# centred GAZE_STEPS_AHEAD steps before each step that changes the mode; the random part keeps
# the episode's mean and standard deviation (paper Fig. 4(b)), at least GAZE_MIN_SPREAD of it.
GAZE_DOWN_RAD = 0.45
GAZE_STEPS_AHEAD = 2
GAZE_WIDTH_STEPS = 2.5
GAZE_MIN_SPREAD = 0.5
# The unconventional-view trial (seeds/002 III-B 2, Fig. 3(a)): the wearer walks "with a large and
# changing view angle to the terrain", so that "the terrain is only partially captured" and "may
# only occupy a corner of the camera view", the side wall filling much of the image; the paper
# gives no angle. The terrain ahead stays in the image while the walking direction is inside its
# horizontal field of view: the excursion's peak is half the D455's 87 deg depth field of view
# (docs/sensor-reference.md), the walking direction then at the image's edge (the ordinary looking around adds
# its +-0.15 rad spread, as on every walk). The pitch excursion adds to the walk's pitch inside the
# paper's measured range (Fig. 4(b)). ``unconventional-wide`` [A: the first model of this trial]
# turns up to 60 deg (74 deg with the ordinary yaw: the walking direction 30 deg outside the
# image, the terrain ahead not seen for seconds) and pitches past that range.
UNCONV_YAW_RAD = np.radians(0.5 * 87.0)
UNCONV_WIDE_YAW_RAD = np.radians(60.0)
UNCONV_PITCH_RAD = 0.35
UNCONVENTIONAL_VIEWS = ("unconventional", "unconventional-wide")
# [A] width of the smooth clamp's bend on each side of a limit: a neck turning at 2 rad/s into its
# limit slows at most 0.75 * 2^2 / 0.1 = 30 rad/s^2, a few m/s^2 at the camera
SOFT_CLIP_BAND_RAD = 0.1
SOFT_CLIP_BAND_Z = 0.15  # the same in units of the excursion's normalised signal (clamped at +-1.5)


def soft_clip(x: np.ndarray, lo: float, hi: float, band: float) -> np.ndarray:
    """``x`` clamped to [lo, hi] with a C2 bend: the identity up to ``band`` inside a limit, the limit
    from ``band`` beyond it, ``g(s) = s - s^3/4 + s^4/16`` on the 2 ``band`` between (g(0) = 0,
    g'(0) = 1, g(2) = 1, g'(2) = g''(0) = g''(2) = 0; monotone, |g''| <= 0.75)."""
    x = np.asarray(x, dtype=float)

    def bend(s: np.ndarray) -> np.ndarray:
        s = np.clip(s, 0.0, 2.0)
        return s - s**3 / 4.0 + s**4 / 16.0

    y = np.clip(x, lo, hi)
    top, bottom = x > hi - band, x < lo + band
    y = np.where(top, hi - band + band * bend((x - (hi - band)) / band), y)
    return np.where(bottom, lo + band - band * bend(((lo + band) - x) / band), y)


class SmoothSignal:
    """z(t): a seeded sum of sinusoids normalised to mean 0, std 1 over [0, duration]."""

    def __init__(self, rng: np.random.Generator, duration_s: float, f_lo: float = 0.15, f_hi: float = 1.2) -> None:
        self.f = rng.uniform(f_lo, f_hi, N_PARTIALS)
        self.phi = rng.uniform(0.0, 2.0 * np.pi, N_PARTIALS)
        self.a = 1.0 / self.f  # lower frequencies carry more of the motion
        grid = np.linspace(0.0, max(duration_s, 1e-3), 2001)
        raw = self._raw(grid)
        self.mu, self.sd = float(raw.mean()), float(raw.std()) or 1.0

    def _raw(self, t: np.ndarray) -> np.ndarray:
        t = np.asarray(t, dtype=float)
        return np.sin(2.0 * np.pi * self.f * t[..., None] + self.phi) @ self.a

    def __call__(self, t: np.ndarray) -> np.ndarray:
        return (self._raw(t) - self.mu) / self.sd


@dataclass
class ViewMotion:
    """Extra joint angles of the camera mount over time (joint name -> function of t)."""

    joints: dict[str, object]

    def values(self, t: np.ndarray) -> dict[str, np.ndarray]:
        return {k: f(t) for k, f in self.joints.items()}  # type: ignore[operator]

    def derivatives(self, t: np.ndarray) -> dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]]:
        """name -> (q, qdot, qddot) at times t."""
        h = DIFF_H_S
        out = {}
        for k, f in self.joints.items():
            q0, qm, qp = f(t), f(t - h), f(t + h)  # type: ignore[operator]
            out[k] = (q0, (qp - qm) / (2 * h), (qp - 2 * q0 + qm) / (h * h))
        return out


class GazeDown:
    """g(t) >= 0: the extra downward head pitch of looking at terrain transitions, a raised-cosine
    bump of height :data:`GAZE_DOWN_RAD` and full width ``width_s`` centred on each time of
    ``looks_s``; ``mean`` and ``var`` over [0, duration]."""

    def __init__(self, looks_s: object, width_s: float, duration_s: float) -> None:
        self.looks = np.asarray(looks_s, dtype=float).reshape(-1)
        self.half = 0.5 * max(float(width_s), 1e-3)
        grid = self(np.linspace(0.0, max(duration_s, 1e-3), 4001))
        self.mean, self.var = float(grid.mean()), float(grid.var())

    def __call__(self, t: np.ndarray) -> np.ndarray:
        t = np.asarray(t, dtype=float)
        if self.looks.size == 0:
            return np.zeros_like(t)
        u = np.clip((t[..., None] - self.looks) / self.half, -1.0, 1.0)
        return GAZE_DOWN_RAD * (0.5 * (1.0 + np.cos(np.pi * u))).max(axis=-1)


def gaze_looks(step_modes: list[str], liftoffs_s: list[float], steps_ahead: int = GAZE_STEPS_AHEAD) -> list[float]:
    """Times the wearer looks down at a transition: the lift-off of the step ``steps_ahead``
    before each step whose mode differs from the previous step's (the first one if earlier)."""
    out = []
    for k in range(1, len(step_modes)):
        if step_modes[k] != step_modes[k - 1]:
            out.append(float(liftoffs_s[max(0, k - steps_ahead)]))
    return out


def view_motion(mount: str, view: str, pitch_mean: float, pitch_std: float, mount_pitch: float,
                trunk_pitch: object, neck_range: dict[str, tuple[float, float]], duration_s: float,
                rng: np.random.Generator, gaze: GazeDown | None = None) -> ViewMotion:  # fmt: skip
    """The mount's extra joint motion (see the module docstring); ``trunk_pitch(t)`` from the gait;
    ``gaze``: looks down at transitions (head only; the random part's mean and spread are reduced
    so that the pitch keeps ``pitch_mean`` and ``pitch_std`` over the episode)."""
    zp, zy = SmoothSignal(rng, duration_s), SmoothSignal(rng, duration_s)
    up, uy = SmoothSignal(rng, duration_s, 0.05, 0.15), SmoothSignal(rng, duration_s, 0.05, 0.15)
    unconv = view in UNCONVENTIONAL_VIEWS
    yaw_amp = UNCONV_WIDE_YAW_RAD if view == "unconventional-wide" else UNCONV_YAW_RAD
    # the paper's excursion is clipped with the walk's pitch to the measured range, the wide one after it
    pitch_inside = view == "unconventional"

    def extra_pitch(t: np.ndarray) -> np.ndarray:
        return UNCONV_PITCH_RAD * soft_clip(up(t), -1.5, 1.5, SOFT_CLIP_BAND_Z) / 1.5 if unconv else np.zeros_like(np.asarray(t, float))

    def extra_yaw(t: np.ndarray) -> np.ndarray:
        return yaw_amp * soft_clip(uy(t), -1.5, 1.5, SOFT_CLIP_BAND_Z) / 1.5 if unconv else np.zeros_like(np.asarray(t, float))

    if mount == "head":
        lo_p, hi_p = neck_range["neck_pitch"]
        lo_y, hi_y = neck_range["neck_yaw"]

        g = gaze if gaze is not None else GazeDown([], 1.0, duration_s)
        mu = pitch_mean - g.mean
        sd = float(np.sqrt(max(pitch_std**2 - g.var, (GAZE_MIN_SPREAD * pitch_std) ** 2)))

        def neck_pitch(t: np.ndarray) -> np.ndarray:
            if pitch_inside:
                cam = soft_clip(mu + sd * zp(t) + g(t) + extra_pitch(t), *PITCH_RANGE_RAD, SOFT_CLIP_BAND_RAD)
            else:
                cam = soft_clip(mu + sd * zp(t) + g(t), *PITCH_RANGE_RAD, SOFT_CLIP_BAND_RAD) + extra_pitch(t)
            return soft_clip(cam - mount_pitch - trunk_pitch(t), lo_p, hi_p, SOFT_CLIP_BAND_RAD)  # type: ignore[operator]

        def neck_yaw(t: np.ndarray) -> np.ndarray:
            return soft_clip(NECK_YAW_STD_RAD * zy(t) + extra_yaw(t), lo_y, hi_y, SOFT_CLIP_BAND_RAD)

        return ViewMotion({"neck_pitch": neck_pitch, "neck_yaw": neck_yaw})
    if mount == "chest":
        s = CHEST_SPREAD * pitch_std

        def chest_pitch(t: np.ndarray) -> np.ndarray:
            return s * zp(t) + extra_pitch(t)

        def chest_yaw(t: np.ndarray) -> np.ndarray:
            return CHEST_SPREAD * NECK_YAW_STD_RAD * zy(t) + extra_yaw(t)

        return ViewMotion({"chest_pitch": chest_pitch, "chest_yaw": chest_yaw})
    return ViewMotion({})
