"""Leg kinematics of the sagittal exoskeleton: inverse and forward kinematics within the joint
limits, the foot's sole footprint and toe pivot, and the pelvis poses of a double stance.

The legs are sagittal (hip, knee and ankle rotate about the lateral axis), so each ankle lies
in its hip's sagittal plane; angles follow :mod:`exobench.models.exo_spec` (hip and knee
flexion +, ankle dorsiflexion +, foot pitch toes-up +). Everything here is a pure function of
the body spec; the motions built on it live in :mod:`exobench.envs.motion.motion`.
"""

from __future__ import annotations

import numpy as np

from exobench.core import ExobenchError
from exobench.models.exo_spec import JOINT_RANGES_RAD, ExoSpec

KNEE_MIN_RAD = np.radians(2.0)  # never straighter: no hyperextension, no singular IK [A]
KNEE_MAX_RAD = float(JOINT_RANGES_RAD["knee"][1])
STAND_KNEE_RAD = np.radians(5.0)  # relaxed standing knee flexion [A]
TARGET_KNEE_RAD = np.radians(10.0)  # least knee flexion the planner aims for at touch-down [A]
STANCE_KNEE_MAX_RAD = np.radians(75.0)  # deepest stance knee flexion a planned step may need [A]
CLIMB_LEAN_RAD = np.radians(6.0)  # forward trunk lean while stepping up [A]
LEVEL_LEAN_RAD = np.radians(2.0)  # forward trunk lean after a level or downward step [A]


class GaitError(ExobenchError):
    """A planned motion cannot be executed by the legs (out of reach, knee limits)."""


def leg_length_for_knee(exo: ExoSpec, knee_rad: float) -> float:
    """Hip-to-ankle distance of a leg whose knee is flexed by ``knee_rad``."""
    T, S = exo.thigh_m, exo.shank_m
    return float(np.sqrt(T * T + S * S + 2.0 * T * S * np.cos(knee_rad)))


def leg_ik(
    exo: ExoSpec, dx: np.ndarray, dz: np.ndarray, foot_pitch: np.ndarray, pelvis_pitch: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Joint angles (hip, knee, ankle) placing the ankle at (dx, dz) from the hip.

    ``dx`` (forward) and ``dz`` (up) are in the heading frame (yaw only), ``foot_pitch`` is the
    sole's toes-up angle in that frame and ``pelvis_pitch`` the pelvis' forward lean; signs as in
    :mod:`exobench.models.exo_spec`. The knee always flexes (the shank swings back). Raises
    :class:`GaitError` (with ``.index`` of the first bad sample) outside the knee limits.
    """
    T, S = exo.thigh_m, exo.shank_m
    D2 = dx * dx + dz * dz
    cos_k = (D2 - T * T - S * S) / (2.0 * T * S)
    bad = (cos_k > np.cos(KNEE_MIN_RAD) + 1e-12) | (cos_k < np.cos(KNEE_MAX_RAD) - 1e-12)
    if np.any(bad):
        i = int(np.argmax(bad))
        err = GaitError(
            f"leg out of reach: hip-ankle distance {np.sqrt(D2[i]):.3f} m outside "
            f"[{leg_length_for_knee(exo, KNEE_MAX_RAD):.3f}, {leg_length_for_knee(exo, KNEE_MIN_RAD):.3f}] m"
        )
        err.index = i  # type: ignore[attr-defined]
        raise err
    knee = np.arccos(np.clip(cos_k, -1.0, 1.0))
    D = np.sqrt(D2)
    gamma = np.arctan2(dx, -dz)  # hip-ankle line from the downward vertical, forward +
    delta = np.arccos(np.clip((T * T + D2 - S * S) / (2.0 * T * D), -1.0, 1.0))
    thigh = gamma + delta  # thigh ahead of the line, shank behind: the knee flexes forward
    hip = thigh + pelvis_pitch
    ankle = foot_pitch - thigh + knee
    for name, q in (("hip", hip), ("ankle", ankle)):
        lo, hi = JOINT_RANGES_RAD[name]
        bad = (q < lo - 1e-9) | (q > hi + 1e-9)
        if np.any(bad):
            i = int(np.argmax(bad))
            err = GaitError(
                f"{name} angle {np.degrees(q[i]):.1f} deg outside its range "
                f"[{np.degrees(lo):.0f}, {np.degrees(hi):.0f}] deg"
            )
            err.index = i  # type: ignore[attr-defined]
            raise err
    return hip, knee, ankle


def leg_fk(
    exo: ExoSpec, hip: np.ndarray, knee: np.ndarray, ankle: np.ndarray, pelvis_pitch: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Inverse of :func:`leg_ik`: ankle (dx, dz) from the hip and the foot pitch, heading frame."""
    thigh = hip - pelvis_pitch
    shank = thigh - knee
    dx = exo.thigh_m * np.sin(thigh) + exo.shank_m * np.sin(shank)
    dz = -exo.thigh_m * np.cos(thigh) - exo.shank_m * np.cos(shank)
    return dx, dz, ankle + thigh - knee


def rot_yaw_pitch(yaw: np.ndarray, pitch: np.ndarray) -> np.ndarray:
    """Rotations Rz(yaw) Ry(pitch), shape (N, 3, 3)."""
    cy, sy, cp, sp = np.cos(yaw), np.sin(yaw), np.cos(pitch), np.sin(pitch)
    R = np.empty((len(yaw), 3, 3))
    R[:, 0] = np.stack([cy * cp, -sy, cy * sp], axis=-1)
    R[:, 1] = np.stack([sy * cp, cy, sy * sp], axis=-1)
    R[:, 2] = np.stack([-sp, np.zeros_like(sp), cp], axis=-1)
    return R


def toe_pivot(exo: ExoSpec, ankle0: np.ndarray, x_h: np.ndarray, pitch0: np.ndarray, pitch: np.ndarray) -> np.ndarray:
    """Ankle (N, 3) of a foot turned about its toe tip from pitch ``pitch0`` to ``pitch``.

    ``ankle0`` is the ankle at ``pitch0``; ``x_h`` the heading's forward unit vectors (N, 3).
    """
    toe_x, sole_h = exo.foot_m - exo.heel_to_ankle_m, exo.sole_height_m
    z = np.array([0.0, 0.0, 1.0])

    def offset(b: np.ndarray) -> np.ndarray:  # ankle -> toe tip at pitch b
        b = np.atleast_1d(b)[:, None]
        return toe_x * (np.cos(b) * x_h + np.sin(b) * z) - sole_h * (-np.sin(b) * x_h + np.cos(b) * z)

    return ankle0 + offset(pitch0) - offset(pitch)



def foot_width_m(exo: ExoSpec) -> float:
    """Foot breadth [A: 0.055 of the user's height, Drillis and Contini anthropometry]."""
    return 0.055 * exo.user_height_m


def sole_grid_f(exo: ExoSpec, nx: int = 9, ny: int = 3) -> np.ndarray:
    """Points on the sole in the foot frame (origin at the ankle joint), shape (nx*ny, 3).

    A regular grid from heel to toe and across the foot breadth, including the four corners.
    """
    x = np.linspace(-exo.heel_to_ankle_m, exo.foot_m - exo.heel_to_ankle_m, nx)
    y = np.linspace(-0.5, 0.5, ny) * foot_width_m(exo)
    gx, gy = np.meshgrid(x, y, indexing="ij")
    return np.column_stack([gx.ravel(), gy.ravel(), np.full(gx.size, -exo.sole_height_m)])




def pelvis_height(exo: ExoSpec, f: float, swing_a: float, swing_dz: float, knee_rad: float) -> float:
    """Highest pelvis (above the stance ankle) with both knees flexed at least ``knee_rad``.

    ``f`` is the pelvis ahead of the stance ankle; the other ankle is ``swing_a`` ahead and
    ``swing_dz`` above the stance ankle; capped at the relaxed standing height.
    """
    D = leg_length_for_knee(exo, knee_rad)
    h = leg_length_for_knee(exo, STAND_KNEE_RAD)
    for dx, dz in ((f, 0.0), (swing_a - f, swing_dz)):
        if abs(dx) >= D:
            return float("nan")
        h = min(h, dz + np.sqrt(D * D - dx * dx))
    return float(h)


def end_pelvis(
    exo: ExoSpec,
    swing_a: float,
    swing_dz: float,
    pitch: float,
    foot_pitch: tuple[float, float] = (0.0, 0.0),
    max_knee_rad: float = STANCE_KNEE_MAX_RAD,
) -> tuple[float, float]:
    """The preferred of :func:`end_pelvis_options`, or (nan, nan) when there is none."""
    opts = end_pelvis_options(exo, swing_a, swing_dz, pitch, foot_pitch, max_knee_rad)
    return opts[0] if opts else (float("nan"), float("nan"))


def end_pelvis_options(
    exo: ExoSpec,
    swing_a: float,
    swing_dz: float,
    pitch: float,
    foot_pitch: tuple[float, float] = (0.0, 0.0),
    max_knee_rad: float = STANCE_KNEE_MAX_RAD,
) -> list[tuple[float, float]]:
    """Pelvis positions (f, h) over the stance ankle for a double stance, best first.

    The other ankle is ``swing_a`` ahead and ``swing_dz`` above the stance ankle. The pelvis
    stands at the highest height :func:`pelvis_height` allows; positions keeping every joint
    8 deg inside its range come first, nearest to 45 % of the way to the other foot, then the
    others by decreasing margin. Empty when no position keeps the knees below
    ``max_knee_rad`` and the joints in range.
    """
    D_deep = leg_length_for_knee(exo, max_knee_rad)
    cands = []
    for lam in np.linspace(0.15, 0.85, 57):
        f = lam * swing_a
        h = pelvis_height(exo, f, swing_a, swing_dz, TARGET_KNEE_RAD)
        if not np.isfinite(h) or np.hypot(f, h) < D_deep or np.hypot(swing_a - f, h - swing_dz) < D_deep:
            continue
        margin = np.inf
        for dx, dz, fp in ((-f, -h, foot_pitch[0]), (swing_a - f, swing_dz - h, foot_pitch[1])):
            try:
                q = leg_ik(exo, np.array([dx]), np.array([dz]), np.array([fp]), np.array([pitch]))
            except GaitError:
                margin = -np.inf
                break
            for name, v in zip(("hip", "knee", "ankle"), q):
                lo, hi = JOINT_RANGES_RAD[name]
                margin = min(margin, float(v[0] - lo), float(hi - v[0]))
        if margin > -np.inf:
            cands.append((lam, f, h, margin))
    good = sorted((c for c in cands if c[3] >= np.radians(8.0)), key=lambda c: abs(c[0] - 0.45))
    rest = sorted((c for c in cands if c[3] < np.radians(8.0)), key=lambda c: -c[3])
    return [(float(c[1]), float(c[2])) for c in good + rest]


