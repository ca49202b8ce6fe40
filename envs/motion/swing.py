"""Swing trajectories: the pieces of a step between two double supports.

A :class:`SwingPlan` holds the start and end of a swing (stance ankle, pelvis over it, swing
ankle, foot pitches, yaw) and its shape (lag of the forward motion, toe-down dip); it gives the
swing :class:`~exobench.envs.motion.motion.Segment` once the apex height is known.
:func:`swing_apex_m` finds the lowest apex keeping the swing sole clear of a terrain;
:func:`still_segment` and :func:`heel_drop_segment` hold or settle the pose around a swing.
The climbing step (:mod:`exobench.envs.motion.climb`) and the step planner of the walker
(:mod:`exobench.envs.motion.step`) build their motions from these.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from exobench.models.exo_spec import ExoSpec

from ..terrain import Terrain
from .kinematics import sole_grid_f, toe_pivot
from .motion import Motion, Segment, min_jerk


@dataclass
class SwingPlan:
    """Everything a swing segment needs apart from its apex height (fields as in :class:`Segment`;
    ``A`` is the stance ankle at the start, ``lag``/``dip`` the swing shape)."""

    stance: str
    A: np.ndarray
    stance_pitch: tuple[float, float]
    yaw: tuple[float, float]
    pitch: tuple[float, float]
    f: tuple[float, float]
    h: tuple[float, float]
    a: tuple[float, float]
    z: tuple[float, float]
    swing_pitch: tuple[float, float]
    lag: float = 0.0
    dip: float = 0.0

    def segment(self, t0: float, t1: float, apex_m: float) -> Segment:
        return Segment(
            t0, t1, self.stance, tuple(float(v) for v in self.A), self.stance_pitch,
            self.yaw, self.pitch, self.f, self.h, self.a, self.z, float(apex_m), self.swing_pitch,
            float(self.lag), float(self.dip),
        )  # fmt: skip


def still_segment(exo: ExoSpec, plan: SwingPlan, t0: float, t1: float, *, at_end: bool) -> Segment:
    """A segment holding the pose at the start (``at_end=False``) or end of a swing plan."""
    k = 1 if at_end else 0

    def hold(p: tuple[float, float]) -> tuple[float, float]:
        return (p[k], p[k])

    A = np.asarray(plan.A, dtype=float)
    if at_end and plan.stance_pitch[1] != plan.stance_pitch[0]:
        x_h = np.array([[np.cos(plan.yaw[1]), np.sin(plan.yaw[1]), 0.0]])
        A = toe_pivot(exo, A, x_h, np.array([plan.stance_pitch[0]]), np.array([plan.stance_pitch[1]]))[0]
    return Segment(
        t0, t1, plan.stance, tuple(float(v) for v in A), hold(plan.stance_pitch),
        hold(plan.yaw), hold(plan.pitch), hold(plan.f), hold(plan.h), hold(plan.a), hold(plan.z),
        0.0, hold(plan.swing_pitch),
    )  # fmt: skip


def heel_drop_segment(
    exo: ExoSpec, plan: SwingPlan, t0: float, t1: float, *, to_pitch: float, f: float, h: float
) -> Segment:
    """The double support after a forefoot landing: both feet stay, the landed foot turns about
    its toe tip from the swing plan's end pitch to ``to_pitch`` (its heel lowers onto the
    support; a ``swing_pivot`` segment) and the pelvis moves from the plan's end pose to
    ``(f, h)`` over the stance ankle (it comes down as the leading leg takes the body)."""
    seg = still_segment(exo, plan, t0, t1, at_end=True)
    return Segment(
        seg.t0, seg.t1, seg.stance, seg.ankle_w, seg.stance_pitch, seg.yaw, seg.pitch, (seg.f[0], float(f)),
        (seg.h[0], float(h)), seg.a, seg.z, 0.0, (seg.swing_pitch[0], float(to_pitch)), swing_pivot=True,
    )  # fmt: skip


def swing_apex_m(
    exo: ExoSpec,
    terrain: Terrain,
    plan: SwingPlan,
    *,
    clearance_m: float,
    min_apex_m: float = 0.03,
    ramp: float = 0.2,
    n: int = 241,
    exact_progress: bool = False,
) -> float:
    """Least parabola height ``H`` keeping the swing sole ``clearance_m`` above the terrain.

    The clearance asked for grows linearly from 0 at lift-off and touch-down to its full value
    at a fraction ``ramp`` of the path, so the foot can leave and reach its support. The path is
    sampled uniformly in progress ``u``. ``exact_progress=True`` (the walk planner) inverts the
    minimum-jerk profile exactly; the default keeps the original Newton inversion, which sends
    the first and last 5 % of ``u`` to the rest poses (harmless for a flat foot; the staircase
    track's climbing step and its reference results use it), but misses a toe pitched down near
    lift-off or touch-down.
    """
    seg = plan.segment(0.0, 1.0, 0.0)
    m = Motion(exo, [seg])
    u = np.linspace(0.0, 1.0, n)[1:-1]  # uniform in path progress, not in time
    t = _inverse_min_jerk_exact(u) if exact_progress else _inverse_min_jerk(u)
    st = m.state(t, solve_legs=False)
    swing = "r" if plan.stance == "l" else "l"
    pts = st.sole_points_w(swing, sole_grid_f(exo, nx=13, ny=3))
    ground = terrain.height(pts.reshape(-1, 3)[:, :2]).reshape(pts.shape[:2])
    need = np.minimum(1.0, np.minimum(u, 1.0 - u) / ramp) * clearance_m
    deficit = np.nanmax(ground - pts[:, :, 2], axis=1, initial=-np.inf) + need
    H = np.max(deficit / (4.0 * u * (1.0 - u)))
    return float(max(H, min_apex_m))


# swing shapes (lag, toe-down dip) the walk planner tries, plainest first
SWING_SHAPES = tuple((lag, np.radians(dip)) for dip in (0.0, 15.0, 30.0) for lag in (0.0, 0.15, 0.3))
# ... and with the toes down 45 deg mid-swing as a last resort: commanded steps onto high risers
# (the gymnasium environment's) that no plainer shape clears within the ankle's range
SWING_SHAPES_DEEP_DIP = SWING_SHAPES + tuple((lag, np.radians(45.0)) for lag in (0.0, 0.15, 0.3))


def _inverse_min_jerk_exact(u: np.ndarray) -> np.ndarray:
    """Times s in [0, 1] with min_jerk(s) = u (bisection; min_jerk is increasing on [0, 1])."""
    lo, hi = np.zeros_like(u), np.ones_like(u)
    for _ in range(52):
        mid = 0.5 * (lo + hi)
        below = min_jerk(mid) < u
        lo, hi = np.where(below, mid, lo), np.where(below, hi, mid)
    return 0.5 * (lo + hi)


def _inverse_min_jerk(u: np.ndarray) -> np.ndarray:
    s = u.copy()
    for _ in range(30):  # Newton on 10s^3-15s^4+6s^5 = u, monotone on [0, 1]
        f = min_jerk(s) - u
        df = 30.0 * s * s * (1.0 - s) ** 2
        s = np.clip(s - f / np.maximum(df, 1e-9), 0.0, 1.0)
    return s
