"""One step of the walker: from a double support to the next, given where the swing foot lands.

:func:`plan_step` is the walker's public step planner; the walk planner
(:mod:`exobench.envs.motion.walk`) and the gymnasium environment ``exobench/StairClimb-v0`` both
plan their steps with it. Given the double support a step starts from (:class:`StepStart`), the
landing foothold and the heading after the step, it chooses the trailing heel's rise, the trunk
lean, the pelvis pose of the next double support and the swing's shape (lag, toe-down dip, apex
clearing ``clearance_m`` over the given terrain): the first of these, in the order tried, whose
whole swing the legs can follow.

On the way up and down stairs the trailing (stance) foot may rise on its toes
(:data:`HEEL_RISE_RAD`, :func:`heel_rises`). Steep descents (risers 0.20-0.25 m), where no flat
landing is within reach, are walked as people walk them: the leading foot reaches down toes first
(``toes_down_rad``, one of :data:`TOE_FIRST_RAD`), touches the tread with its toe tip, and lowers
its heel in the double support (at least :data:`HEEL_DROP_S`; the pelvis comes down meanwhile)
while the trailing foot stays on its toes (up to 40 deg); the stance knee may then flex to
:data:`DESCENT_KNEE_DEEP_RAD` instead of :data:`DESCENT_KNEE_MAX_RAD`. Heel rises and forefoot
landings turn the foot about its toe tip, also when the toes overhang a nosing (an
approximation: the real pivot is then the nosing under the ball of the foot).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from exobench.models.exo_spec import ExoSpec

from ..terrain import Terrain
from .kinematics import (
    CLIMB_LEAN_RAD,
    LEVEL_LEAN_RAD,
    STANCE_KNEE_MAX_RAD,
    GaitError,
    end_pelvis_options,
    toe_pivot,
)
from .motion import Motion, Segment
from .swing import SWING_SHAPES, SwingPlan, heel_drop_segment, swing_apex_m

DESCENT_KNEE_MAX_RAD = np.radians(100.0)  # stair descent flexes the stance knee to about 90 deg (docs/sensor-reference.md)
HEEL_RISE_RAD = tuple(np.radians([15.0, 25.0, 5.0, 0.0, 35.0]))  # trailing heel rises tried on stairs [A]
# Steep stairs down (risers 0.20-0.25 m), tried only when no flat landing works. The leading foot
# lands forefoot first, as people do on stairs of every inclination (Riener et al., Gait Posture
# 15 (2002) 32-44, 24-42 deg stairs), toes down by TOE_FIRST_RAD [A: within the model's 40 deg
# plantarflexion], and lowers its heel in the double support (at least HEEL_DROP_S). The stance
# knee may then flex to DESCENT_KNEE_DEEP_RAD: 15 deg beyond the ~100 deg of ordinary stairs
# (docs/sensor-reference.md), for risers 40-50 % higher than the 0.17 m ones those figures come from (young
# adults descend 0.255 m risers: Foster et al., Gait Posture 73 (2019) 305-314); still 15 deg
# inside the model's 130 deg knee range [A].
DESCENT_KNEE_DEEP_RAD = np.radians(115.0)
TOE_FIRST_RAD = tuple(np.radians([20.0, 30.0, 40.0]))
HEEL_DROP_S = 0.1  # shortest heel lowering after a forefoot landing, s [A]
HEEL_RISE_DEEP_RAD = HEEL_RISE_RAD + (np.radians(40.0),)  # with forefoot landings the trailing heel may rise 40 deg [A]


@dataclass(frozen=True, eq=False)
class StepStart:
    """The double support a step starts from (world frame, angles in rad).

    ``stance`` (``"l"`` or ``"r"``) is the leg that stays; its ankle ``stance_ankle_w`` and
    toes-up sole pitch ``stance_pitch``; the other (swing) foot's ankle and pitch; the pelvis
    origin ``pelvis_w``, the trunk's forward lean ``trunk_pitch`` and the heading ``yaw``.
    """

    stance: str
    stance_ankle_w: np.ndarray
    stance_pitch: float
    swing_ankle_w: np.ndarray
    swing_pitch: float
    pelvis_w: np.ndarray
    trunk_pitch: float
    yaw: float


@dataclass(frozen=True, eq=False)
class StepPlan:
    """A planned step: the swing (``plan`` with its apex ``apex_m``) and the double support it
    ends in: the stance foot (``stance_ankle_w``, ``stance_pitch``: its heel risen), the pelvis
    ``f_m`` ahead of and ``h_m`` above the stance ankle along the new heading, the trunk lean.
    ``heel_drop`` after a forefoot landing: (pitch of the flat foot, f, h of the pelvis once the
    heel is down), for :func:`~exobench.envs.motion.swing.heel_drop_segment`; else None."""

    plan: SwingPlan
    apex_m: float
    stance_ankle_w: np.ndarray
    stance_pitch: float
    f_m: float
    h_m: float
    trunk_pitch: float
    heel_drop: tuple[float, float, float] | None = None

    def segment(self, t0: float, t1: float) -> Segment:
        """The swing segment from ``t0`` to ``t1``."""
        return self.plan.segment(t0, t1, self.apex_m)


def heel_rises(dz_m: float, straight: bool, forefoot: bool = False) -> tuple[float, ...]:
    """Rises of the trailing heel to try, rad, for a landing ``dz_m`` above the stance ankle: on
    stairs (|dz| > 5 cm) of a straight step the heel may rise (up to 40 deg before a forefoot
    landing), else it stays down."""
    if abs(dz_m) > 0.05 and straight:
        return HEEL_RISE_DEEP_RAD if forefoot else HEEL_RISE_RAD
    return (0.0,)


def plan_step(
    exo: ExoSpec,
    terrain: Terrain,
    start: StepStart,
    land_ankle_w: np.ndarray,
    land_pitch: float,
    yaw1: float,
    *,
    rises: tuple[float, ...],
    clearance_m: float,
    toes_down_rad: float = 0.0,
    knee_down_rad: float = DESCENT_KNEE_MAX_RAD,
    shapes: tuple[tuple[float, float], ...] = SWING_SHAPES,
) -> StepPlan | None:
    """The first feasible step from ``start`` to a foot at rest with its ankle at ``land_ankle_w``
    and sole pitch ``land_pitch`` (the foothold), heading ``yaw1`` after the step; None if none.

    Tried in order: the trailing heel's ``rises``; the pelvis poses of
    :func:`~exobench.envs.motion.kinematics.end_pelvis_options` (the first 8; the stance knee
    flexes at most ``knee_down_rad`` on a step down, :data:`STANCE_KNEE_MAX_RAD` otherwise); the
    swing ``shapes`` (lag, toe-down dip; :data:`~exobench.envs.motion.swing.SWING_SHAPES`, or
    :data:`~exobench.envs.motion.swing.SWING_SHAPES_DEEP_DIP`), each with the lowest apex
    keeping ``clearance_m`` over ``terrain``. The trunk leans :data:`CLIMB_LEAN_RAD` on a step up
    (> 5 cm), :data:`LEVEL_LEAN_RAD` otherwise. ``toes_down_rad`` > 0: a forefoot landing (the foot
    touches down on its toe tip pitched down by it, then lowers its heel: ``heel_drop``).
    """
    stance = start.stance
    A = start.stance_ankle_w
    beta0 = start.stance_pitch
    x0 = np.array([np.cos(start.yaw), np.sin(start.yaw), 0.0])
    x1 = np.array([np.cos(yaw1), np.sin(yaw1), 0.0])
    a0 = float((start.swing_ankle_w - A) @ x0)
    f0, h0 = float((start.pelvis_w - A) @ x0), float(start.pelvis_w[2] - A[2])
    pw = toes_down_rad
    land = land_ankle_w
    if pw:  # the ankle of the foot on its toe tip, heel up (it lowers in the double support)
        land = toe_pivot(exo, land_ankle_w, x1[None, :], np.array([land_pitch]), np.array([land_pitch - pw]))[0]
    for rise in rises:
        A_end = toe_pivot(exo, A, x1[None, :], np.array([beta0]), np.array([beta0 - rise]))[0] if rise else A
        a1, dz = float((land - A_end) @ x1), float(land[2] - A_end[2])
        pitch1 = CLIMB_LEAN_RAD if dz > 0.05 else LEVEL_LEAN_RAD
        knee_max = knee_down_rad if dz < -0.05 else STANCE_KNEE_MAX_RAD
        pelvis_opts = end_pelvis_options(exo, a1, dz, pitch1, (beta0 - rise, land_pitch - pw), knee_max)
        if not pelvis_opts:
            continue
        plan = SwingPlan(
            stance=stance, A=A.copy(), stance_pitch=(beta0, beta0 - rise), yaw=(start.yaw, yaw1),
            pitch=(start.trunk_pitch, pitch1), f=(f0, 0.0), h=(h0, 0.0), a=(a0, a1),
            z=(float(start.swing_ankle_w[2]), float(land[2])), swing_pitch=(start.swing_pitch, land_pitch - pw),
        )  # fmt: skip
        drop = None
        if pw:  # where the pelvis goes while the heel lowers: a double stance on the flat foot
            a2, dz2 = float((land_ankle_w - A_end) @ x1), float(land_ankle_w[2] - A_end[2])
            flat_opts = end_pelvis_options(exo, a2, dz2, pitch1, (beta0 - rise, land_pitch), knee_max)
            if not flat_opts:
                continue
            drop = (float(land_pitch), flat_opts[:8])
        for lag, dip in shapes:
            plan.lag, plan.dip = lag, dip
            apex = swing_apex_m(exo, terrain, plan, clearance_m=clearance_m, exact_progress=True)
            found = _first_feasible(exo, plan, apex, f0, h0, pelvis_opts[:8], drop)
            if found:
                f1, h1, fh2 = found
                heel_drop = None if drop is None or fh2 is None else (drop[0], fh2[0], fh2[1])
                return StepPlan(plan, apex, A_end, beta0 - rise, f1, h1, pitch1, heel_drop)
    return None


def _first_feasible(
    exo: ExoSpec, plan: SwingPlan, apex: float, f0: float, h0: float, options: list[tuple[float, float]],
    heel_drop: tuple[float, list[tuple[float, float]]] | None = None,
) -> tuple[float, float, tuple[float, float] | None] | None:
    """The first pelvis end pose (f, h) whose whole swing the legs can follow. After a forefoot
    landing (``heel_drop`` = (pitch of the flat foot, pelvis poses over it)) also the first pose
    the pelvis can move to while the heel lowers: (f, h, (f2, h2)); else (f, h, None)."""
    for f1, h1 in options:
        plan.f, plan.h = (f0, f1), (h0, h1)
        try:
            Motion(exo, [plan.segment(0.0, 1.0, apex)]).state(np.linspace(0.0, 1.0, 101))
        except GaitError:
            continue
        if heel_drop is None:
            return f1, h1, None
        for f2, h2 in heel_drop[1]:
            seg = heel_drop_segment(exo, plan, 0.0, 1.0, to_pitch=heel_drop[0], f=f2, h=h2)
            try:
                Motion(exo, [seg]).state(np.linspace(0.0, 1.0, 51))
            except GaitError:
                continue
            return f1, h1, (f2, h2)
    return None
