"""Motions added to a planned walk for the locomotion track: camera view (neck / chest rig),
pedestrians, and the drifting odometry.

View motion (seeds/002 section IV-A 2, Fig. 4(b)): a smooth random signal z(t), a sum of
:data:`N_PARTIALS` sinusoids with seeded frequencies in 0.15-1.2 Hz and phases, normalised over
the episode to mean 0 and standard deviation 1 (so the realised spread is the configured one).
The head's camera pitch below the horizon is ``mean + std * z(t)`` clipped to the paper's range
-0.66..1.18 rad (with ``gaze``, :class:`GazeDown`: plus looks down at each terrain transition,
the mean and spread of the random part reduced so that the episode keeps ``mean`` and ``std``); the neck pitch is that minus the mount's pitch and the trunk's pitch of the gait,
clipped to the neck's joint range. Neck yaw is 0.15 rad * a second such signal. The chest rig
sways with a third of the head's spread around 0. ``unconventional`` adds a slow excursion
(0.05-0.15 Hz) of +-60 deg yaw and +-0.35 rad pitch. Derivatives for the IMU come from central
differences of these analytic signals (step :data:`DIFF_H_S`).

Pedestrians: straight constant-speed walks along the course near the walker that pass it at a
seeded time, drifting across the lane (so they cross the camera view); their height is the
terrain height under them.

Odometry (:func:`drift_odometry`): increments of the true camera position, rotated by a heading
error growing at ``yaw_deg_per_m`` per metre of horizontal travel, plus a translation error of
``pct`` % of the distance travelled along a seeded unit direction; orientation = heading error
@ true orientation. All in the gravity-aligned odometry frame of the true camera at t = 0.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from exobench.core.transforms import invert_T, make_T, rot_z

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
UNCONV_YAW_RAD = np.radians(60.0)
UNCONV_PITCH_RAD = 0.35


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
    unconv = view == "unconventional"

    def extra_pitch(t: np.ndarray) -> np.ndarray:
        return UNCONV_PITCH_RAD * np.clip(up(t), -1.5, 1.5) / 1.5 if unconv else np.zeros_like(np.asarray(t, float))

    def extra_yaw(t: np.ndarray) -> np.ndarray:
        return UNCONV_YAW_RAD * np.clip(uy(t), -1.5, 1.5) / 1.5 if unconv else np.zeros_like(np.asarray(t, float))

    if mount == "head":
        lo_p, hi_p = neck_range["neck_pitch"]
        lo_y, hi_y = neck_range["neck_yaw"]

        g = gaze if gaze is not None else GazeDown([], 1.0, duration_s)
        mu = pitch_mean - g.mean
        sd = float(np.sqrt(max(pitch_std**2 - g.var, (GAZE_MIN_SPREAD * pitch_std) ** 2)))

        def neck_pitch(t: np.ndarray) -> np.ndarray:
            cam = np.clip(mu + sd * zp(t) + g(t), *PITCH_RANGE_RAD) + extra_pitch(t)
            return np.clip(cam - mount_pitch - trunk_pitch(t), lo_p, hi_p)  # type: ignore[operator]

        def neck_yaw(t: np.ndarray) -> np.ndarray:
            return np.clip(NECK_YAW_STD_RAD * zy(t) + extra_yaw(t), lo_y, hi_y)

        return ViewMotion({"neck_pitch": neck_pitch, "neck_yaw": neck_yaw})
    if mount == "chest":
        s = CHEST_SPREAD * pitch_std

        def chest_pitch(t: np.ndarray) -> np.ndarray:
            return s * zp(t) + extra_pitch(t)

        def chest_yaw(t: np.ndarray) -> np.ndarray:
            return CHEST_SPREAD * NECK_YAW_STD_RAD * zy(t) + extra_yaw(t)

        return ViewMotion({"chest_pitch": chest_pitch, "chest_yaw": chest_yaw})
    return ViewMotion({})


@dataclass(frozen=True)
class PedestrianPath:
    """A straight walk: position (x, y) at time t = p0 + v t; height from the terrain."""

    p0_xy: np.ndarray
    v_xy: np.ndarray
    height_m: float

    def xy(self, t: np.ndarray) -> np.ndarray:
        return self.p0_xy[None, :] + np.asarray(t, dtype=float)[:, None] * self.v_xy[None, :]

    @property
    def yaw(self) -> float:
        return float(np.arctan2(self.v_xy[1], self.v_xy[0]))


def pedestrian_paths(n: int, walker_xy: object, heading: object, half_width_m: float, duration_s: float,
                     rng: np.random.Generator) -> list[PedestrianPath]:  # fmt: skip
    """``n`` people passing the walker: at a seeded time t_c a person is 1.2-2.5 m ahead of the
    walker, walking towards it or away from it at 0.8-1.4 m/s along its heading and drifting
    across the lane (lateral speed 0.15-0.35 m/s), so that it crosses the camera view."""
    out = []
    for _ in range(n):
        tc = float(rng.uniform(0.2, 0.8) * duration_s)
        ahead = float(rng.uniform(1.2, 2.5))
        speed = float(rng.uniform(0.8, 1.4)) * (1.0 if rng.random() < 0.5 else -1.0)
        lateral = float(rng.uniform(0.15, 0.35)) * (1.0 if rng.random() < 0.5 else -1.0)
        height = float(rng.uniform(1.6, 1.9))
        c = np.asarray(walker_xy(tc), dtype=float)  # type: ignore[operator]
        psi = float(heading(tc))  # type: ignore[operator]
        x, y = np.array([np.cos(psi), np.sin(psi)]), np.array([-np.sin(psi), np.cos(psi)])
        v = speed * x + lateral * y
        pc = c + ahead * x
        out.append(PedestrianPath(pc - tc * v, v, height))
    return out


def gravity_aligned(T_world_cam: np.ndarray) -> np.ndarray:
    """``T_world_odom``: origin at the camera, z up, x along the optical axis's horizontal heading."""
    z_opt = T_world_cam[:3, 2]
    yaw = float(np.arctan2(z_opt[1], z_opt[0]))
    return make_T(rot_z(yaw), T_world_cam[:3, 3].copy())


def drift_odometry(t: np.ndarray, T_world_cam: np.ndarray, pct: float, yaw_deg_per_m: float,
                   rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:  # fmt: skip
    """(T_world_odom, T_odom_cam (N, 4, 4), v_odom (N, 3), distance travelled (N,)) of the drift model.

    ``T_world_cam`` are true optical-frame poses at times ``t``. Distance = cumulative horizontal
    path length of the camera. Translation error e(s) = pct/100 * s * u (u a seeded unit vector,
    its vertical part a third of the horizontal); heading error psi(s) = +-yaw_deg_per_m * s.
    """
    T_world_odom = gravity_aligned(T_world_cam[0])
    T_odom_w = invert_T(T_world_odom)
    T_true = np.einsum("ij,njk->nik", T_odom_w, T_world_cam)
    p = T_true[:, :3, 3]
    step = np.linalg.norm(np.diff(p[:, :2], axis=0), axis=1)
    s = np.concatenate([[0.0], np.cumsum(step)])
    u = rng.standard_normal(3)
    u[2] /= 3.0
    u /= np.linalg.norm(u)
    sign = 1.0 if rng.random() < 0.5 else -1.0
    psi = sign * np.radians(yaw_deg_per_m) * s
    e = (pct / 100.0) * s[:, None] * u[None, :]
    Rz = np.array([rot_z(a) for a in psi]).reshape(-1, 3, 3)
    dp = np.diff(p, axis=0)
    p_o = np.empty_like(p)
    p_o[0] = p[0]
    if len(p) > 1:
        p_o[1:] = p[0] + np.cumsum(np.einsum("nij,nj->ni", Rz[1:], dp), axis=0)
    p_o += e
    T = np.repeat(np.eye(4)[None], len(t), axis=0)
    T[:, :3, :3] = np.einsum("nij,njk->nik", Rz, T_true[:, :3, :3])
    T[:, :3, 3] = p_o
    v = np.gradient(p_o, t, axis=0) if len(t) > 1 else np.zeros((len(t), 3))
    return T_world_odom, T, v, s
