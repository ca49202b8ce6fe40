"""Walking a route: the footsteps, turns and stops of the walker, planned on the true terrain.

The exoskeleton walks stop-and-go (every swing is rest to rest, then a short double support),
as lower-limb exoskeletons do. Each step the heading turns towards a look-ahead point of the
route (at most ``max_turn_deg``, the stance foot pivoting about its ankle) and the swing foot
is placed ``a`` ahead of the stance ankle along the new heading, one hip width beside it.

Progress along the route is an arc length that never decreases: the walker's position is
projected onto the polyline only within a window ahead of the current arc length (and never
past the next sharp corner), so routes that pass a place twice (a corridor walked out and back,
a loop that closes) are followed in order. A corner sharper than ``turn_in_place_deg`` is a
stop: the walker steps up to it, then turns on the spot (steps with ``a = 0``, at most
``max_turn_deg`` each) until it faces the next segment, and walks on; any heading error larger
than ``max_turn_deg`` is turned away on the spot the same way, so 90 and 180 degree turns work
with any ``max_turn_deg``. At the end the feet are brought together and, if ``end_yaw_deg`` is
given, the walker turns on the spot to that heading (a closed loop ends in its start pose).

Where each foot lands follows the foothold rule of :mod:`exobench.envs.motion.footholds`
(with the approach regulation before transitions); each step is planned by
:func:`exobench.envs.motion.step.plan_step` (heel rises on stairs; forefoot landings on steep
descents, tried only when the flat landings fail, so gentler stairs are planned as before). The
swing apex keeps ``clearance_m`` over nosings (see
:func:`exobench.envs.motion.swing.swing_apex_m`, sampled with the exact inverse of the
minimum-jerk progress so that a toe pitched down near lift-off or touch-down is checked too).
The footstep of a forefoot landing records the foot flat on the tread (its ``touchdown_s`` is
when the heel is down, when the insoles' heel pads touch).
"""

from __future__ import annotations

import numpy as np

from exobench.core import ConfigError, SceneTruth
from exobench.models.exo_spec import ExoSpec

from .footholds import Foot, Footholds, approach_step, choose_footholds
from .kinematics import STAND_KNEE_RAD, GaitError, leg_length_for_knee
from .motion import Footstep, Motion, Segment, check_feasible
from .route import Polyline, Route, wrap_angle
from .step import (
    DESCENT_KNEE_DEEP_RAD,
    DESCENT_KNEE_MAX_RAD,
    HEEL_DROP_S,
    TOE_FIRST_RAD,
    StepPlan,
    StepStart,
    heel_rises,
    plan_step,
)
from .swing import heel_drop_segment, still_segment


def plan_walk(exo: ExoSpec, truth: SceneTruth, route: Route) -> Motion:
    """Plan and return the motion of walking ``route`` in the world of ``truth``."""
    pl = Footholds(exo, truth)
    path = Polyline(np.asarray(route.waypoints_xy, dtype=float))
    d0 = path.p[1] - path.p[0]
    yaw = np.radians(route.start_yaw_deg) if route.start_yaw_deg is not None else float(np.arctan2(d0[1], d0[0]))
    w = exo.hip_width_m
    feet: dict[str, Foot] = {}
    for side, s in (("l", 1.0), ("r", -1.0)):
        y = np.array([-np.sin(yaw), np.cos(yaw)])
        got = pl.foothold(path.p[0] + s * 0.5 * w * y, yaw)
        if got is None:
            raise ConfigError("route.waypoints_xy", route.waypoints_xy, f"a start where foot_{side} stands on one walkable surface")
        feet[side] = got[0]
    h_stand = leg_length_for_knee(exo, STAND_KNEE_RAD)
    pelvis = 0.5 * (feet["l"].ankle + feet["r"].ankle)
    pelvis[2] = min(feet["l"].ankle[2], feet["r"].ankle[2]) + h_stand
    pitch = float(np.radians(route.start_lean_deg))
    segs: list[Segment] = []
    steps: list[Footstep] = []
    t = 0.0
    swing = "r"
    done = False
    first_plan = None
    stops = path.stops(np.radians(route.turn_in_place_deg))
    k_stop = 0  # the next stop (sharp corner or the end) not reached yet
    arrived = False
    s_prog = 0.0  # arc length reached by the walker; never decreases
    window = max(1.0, 3.0 * route.step_length_m)
    look_m = max(route.step_length_m, 0.5)
    max_turn = float(np.radians(route.max_turn_deg))
    end_yaw = None if route.end_yaw_deg is None else float(np.radians(route.end_yaw_deg))
    reg: tuple[int, int] | None = None  # regulated approach under way: (next surface, steps left to it)
    a_used = 0.0
    for _ in range(route.max_steps):
        stance = "l" if swing == "r" else "r"
        sg = 1.0 if stance == "l" else -1.0
        A = feet[stance].ankle
        mid = 0.5 * (feet["l"].ankle + feet["r"].ankle)[:2]
        while True:  # progress within the window ahead, up to the next stop; pass the stops reached
            s_stop, stop_seg = stops[k_stop]
            s_floor = stops[k_stop - 1][0] if k_stop else 0.0
            s_prog = max(s_prog, path.project(mid, s_prog, min(s_prog + window, s_stop)))
            s_A = path.project(A[:2], max(s_floor, s_prog - window), s_stop)
            remaining = s_stop - s_A
            if remaining >= 0.05 or k_stop == len(stops) - 1:
                break
            k_stop += 1
            s_prog = max(s_prog, s_stop)
        arrived = arrived or (k_stop == len(stops) - 1 and remaining < 0.05)  # stays so while turning at the end
        s_look = s_prog + look_m
        look = (path.point(s_look) if s_look <= s_stop else path.point(s_look, stop_seg)) - mid
        err = wrap_angle(float(np.arctan2(look[1], look[0])) - yaw) if np.linalg.norm(look) > 1e-6 else 0.0
        if arrived:
            err = 0.0 if end_yaw is None else wrap_angle(end_yaw - yaw)
        turn = float(np.clip(err, -max_turn, max_turn))
        yaw1 = yaw + turn
        in_place = abs(err) > max_turn + 1e-9  # turn on the spot first
        final = arrived and not in_place
        a_nom = 0.0 if (arrived or in_place) else min(route.step_length_m, remaining)
        a_reg, reg_next = a_nom, None
        if not (arrived or in_place) and a_nom == route.step_length_m:
            a_reg, reg_next = approach_step(pl, route, A, sg, yaw1, a_nom, feet, stance, swing, reg)
        sw = feet[swing]
        x1 = np.array([np.cos(yaw1), np.sin(yaw1), 0.0])
        start = StepStart(stance, A, feet[stance].pitch, sw.ankle, sw.pitch, pelvis, pitch, yaw)
        found: tuple[Foot, StepPlan] | None = None
        straight = yaw1 == yaw
        # pass 1: flat landings; pass 2 (straight steps down only): forefoot landings, the swing
        # foot touching down on its toe tip pitched down by pw, first with the usual stance knee
        # limit, then with the deeper one of steep stairs
        variants = [(0.0, DESCENT_KNEE_MAX_RAD)]
        if straight:
            variants += [(pw, knee) for knee in (DESCENT_KNEE_MAX_RAD, DESCENT_KNEE_DEEP_RAD) for pw in TOE_FIRST_RAD]
        n_options = 0
        # the regulated step first; the nominal one if no regulated foothold can be reached. The
        # toes may overhang a tread's nosing (on the way down, treads shorter than the foot)
        # only when no foothold of the whole foot works
        for a_try, overhang in [(a, o) for a in dict.fromkeys((a_reg, a_nom)) for o in (False, True)]:
            options = choose_footholds(pl, route, A, sg, yaw1, a_try, feet, stance, swing, final, overhang)
            n_options += len(options)
            for pw, knee_down in variants:
                for new, _a in options:  # the first foothold the legs can reach and swing to
                    dz0 = float(new.ankle[2] - A[2])
                    if pw and dz0 >= -0.05:
                        continue
                    # on stairs the trailing (stance) foot rises on its toes (only on straight steps)
                    step = plan_step(
                        exo, pl.terrain, start, new.ankle, new.pitch, yaw1, rises=heel_rises(dz0, straight, bool(pw)),
                        clearance_m=route.clearance_m, toes_down_rad=pw, knee_down_rad=knee_down,
                    )  # fmt: skip
                    if step is not None:
                        found = (new, step)
                        a_used = a_try
                        break
                if found:
                    break
            if found:
                break
        if not n_options:
            raise GaitError(f"no foothold for foot_{swing} ahead of ({A[0]:.2f}, {A[1]:.2f}) at t={t:.2f} s")
        if found is None:
            raise GaitError(f"no reachable foothold for foot_{swing} ahead of ({A[0]:.2f}, {A[1]:.2f}) at t={t:.2f} s")
        new, step = found
        A_end, beta1, f1, h1, pitch1 = step.stance_ankle_w, step.stance_pitch, step.f_m, step.h_m, step.trunk_pitch
        plan, drop = step.plan, step.heel_drop
        reg = reg_next if a_used == a_reg else None  # a regulated approach goes on only if this step kept to it
        if first_plan is None:
            first_plan = plan
            if route.still_s > 0:
                segs.append(still_segment(exo, plan, 0.0, route.still_s, at_end=False))
                t = route.still_s
        segs.append(step.segment(t, t + route.swing_s))
        sole = new.ankle - exo.sole_height_m * np.array([-np.sin(new.pitch) * x1[0], -np.sin(new.pitch) * x1[1], np.cos(new.pitch)])
        liftoff = t
        t += route.swing_s
        hold = route.double_support_s if not final else route.still_s
        if drop is not None:  # forefoot landing: the heel lowers in the double support, the pelvis comes down
            hold = max(hold, HEEL_DROP_S)
            to_pitch, f1, h1 = drop
            segs.append(heel_drop_segment(exo, plan, t, t + hold, to_pitch=to_pitch, f=f1, h=h1))
            t += hold
        elif hold > 0:
            segs.append(still_segment(exo, plan, t, t + hold, at_end=True))
            t += hold
        # touch-down: the foot flat on its support (after the heel lowering of a forefoot landing)
        steps.append(Footstep(swing, liftoff, t if drop is not None else liftoff + route.swing_s, sole, float(yaw1), new.surface))
        ylat = np.array([-np.sin(yaw1), np.cos(yaw1), 0.0])
        pelvis = A_end + f1 * x1 - sg * 0.5 * w * ylat
        pelvis[2] = A_end[2] + h1
        feet[stance] = Foot(A_end, beta1, feet[stance].surface)
        feet[swing], yaw, pitch = new, yaw1, pitch1
        swing = stance
        if final:
            done = True
            break
    if not done:
        raise GaitError(f"route not finished within route.max_steps={route.max_steps} steps")
    motion = Motion(
        exo, segs, events={"liftoff_s": steps[0].liftoff_s, "end_s": t}, footsteps=tuple(steps), stance_side="l"
    )
    check_feasible(motion)
    return motion
