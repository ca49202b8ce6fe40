"""Footstep planning along a route: level ground, stairs up and down, ramps and turns.

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
given, the walker turns on the spot to that heading (a closed loop ends in its start pose). A
placement is a *foothold* when the sole from the ankle to the toe rests on one walkable surface
(the heel may overhang a lower one, as on stairs) with the foot pitched along it and no roll; only
when no such foothold can be reached, the toes beyond the ball of the foot (``BALL_FRACTION``) may
overhang a lower one too (treads shorter than the foot, on the way down).
On level ground and ramps the nominal step is kept when it is a foothold at about the same
level; otherwise (a riser or a slope change ahead) the foot goes to the next surface ahead,
centred on it if it is a tread, at the nominal length clamped into it otherwise. ``step-over``
puts each foot on the next tread; ``step-to`` brings the trailing foot beside the leading one
before the next tread. The swing apex keeps ``clearance_m`` over nosings (see
:func:`exobench.envs.gait.swing_apex_m`, sampled with the exact inverse of the minimum-jerk
progress so that a toe pitched down near lift-off or touch-down is checked too).

On the way up and down stairs the trailing (stance) foot may rise on its toes (``HEEL_RISE_RAD``).
Steep descents (risers 0.20-0.25 m), where no flat landing is within reach, are walked as people
walk them: the leading foot reaches down toes first (``TOE_FIRST_RAD``), touches the tread with
its toe tip, and lowers its heel in the double support (at least ``HEEL_DROP_S``; the pelvis
comes down meanwhile) while the trailing foot stays on its toes (up to 40 deg); the stance knee
may then flex to ``DESCENT_KNEE_DEEP_RAD`` instead of ``DESCENT_KNEE_MAX_RAD``. These are tried
only when the flat landings fail, so gentler stairs are planned as before. The footstep of a
forefoot landing records the foot flat on the tread (its ``touchdown_s`` is when the heel is
down, when the insoles' heel pads touch). Heel rises and forefoot landings turn the foot about
its toe tip, also when the toes overhang a nosing (an approximation: the real pivot is then the
nosing under the ball of the foot).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from exobench.core import ConfigError, SceneTruth, check_range
from exobench.models.exo_spec import ExoSpec

from .gait import (
    CLIMB_LEAN_RAD,
    STANCE_KNEE_MAX_RAD,
    STAND_KNEE_RAD,
    SWING_SHAPES,
    Footstep,
    GaitError,
    Motion,
    Segment,
    _SwingPlan,
    check_feasible,
    end_pelvis_options,
    heel_drop_segment,
    leg_length_for_knee,
    still_segment,
    swing_apex_m,
    toe_pivot,
)
from .terrain import Terrain, sole_grid_f

STAIR_MODES = ("step-over", "step-to")
DESCENT_KNEE_MAX_RAD = np.radians(100.0)  # stair descent flexes the stance knee to about 90 deg (SENSORS.md)
HEEL_RISE_RAD = tuple(np.radians([15.0, 25.0, 5.0, 0.0, 35.0]))  # trailing heel rises tried on stairs [A]
# Steep stairs down (risers 0.20-0.25 m), tried only when no flat landing works. The leading foot
# lands forefoot first, as people do on stairs of every inclination (Riener et al., Gait Posture
# 15 (2002) 32-44, 24-42 deg stairs), toes down by TOE_FIRST_RAD [A: within the model's 40 deg
# plantarflexion], and lowers its heel in the double support (at least HEEL_DROP_S). The stance
# knee may then flex to DESCENT_KNEE_DEEP_RAD: 15 deg beyond the ~100 deg of ordinary stairs
# (SENSORS.md), for risers 40-50 % higher than the 0.17 m ones those figures come from (young
# adults descend 0.255 m risers: Foster et al., Gait Posture 73 (2019) 305-314); still 15 deg
# inside the model's 130 deg knee range [A].
DESCENT_KNEE_DEEP_RAD = np.radians(115.0)
TOE_FIRST_RAD = tuple(np.radians([20.0, 30.0, 40.0]))
BALL_FRACTION = 0.73  # ball of the foot (metatarsal heads) from the heel, fraction of the foot length [A]
HEEL_DROP_S = 0.1  # shortest heel lowering after a forefoot landing, s [A]
HEEL_RISE_DEEP_RAD = HEEL_RISE_RAD + (np.radians(40.0),)  # with forefoot landings the trailing heel may rise 40 deg [A]
# Approach regulation (Route.approach_steps, see _approach_step) [A]
APPROACH_RANGE = (0.75, 1.25)  # regulated step lengths, fractions of the nominal step
APPROACH_DOWN_MAX = 1.1  # ... at most this onto a ramp going down
ONTO_MARGIN_M = 0.10  # the first foot on a ramp, landing or floor lands this far beyond its first foothold if it can
EDGE_BAND_M = 0.05  # before a flight (up or down) the last foot on the level lands with its toes this close to the edge
TREAD_RUN_M = 0.25  # a run of footholds shorter than this is a tread: the foot is centred on it


@dataclass(frozen=True)
class Route:
    """Where and how to walk.

    Attributes:
        waypoints_xy: polyline (x, y) the body follows, m; it starts at the first point with the
            feet beside it, facing the second (or ``start_yaw_deg``).
        step_length_m: nominal step length on level ground, m (the foot lands this far ahead of
            the other). swing_s / double_support_s: duration of a swing / of the pause after it, s.
        stairs: ``"step-over"`` or ``"step-to"``. max_turn_deg: heading change per step, deg.
        still_s: standing still at the start and at the end, s. clearance_m: toe clearance, m.
        start_yaw_deg: initial heading, deg (default: towards the second waypoint).
        end_yaw_deg: heading turned to on the spot at the end, deg (default: none).
        turn_in_place_deg: waypoints where the route turns by more than this are walked to and
            turned at on the spot, deg. max_steps: steps allowed (GaitError beyond).
        approach_steps: over how many steps before a transition (stairs, a ramp's start or end)
            the walker regulates its step length so that the transition step lands where it
            should (see :func:`_approach_step`); 0 keeps the nominal step up to the transition.
    """

    waypoints_xy: tuple[tuple[float, float], ...]
    step_length_m: float = 0.35
    swing_s: float = 0.8
    double_support_s: float = 0.2
    stairs: str = "step-over"
    max_turn_deg: float = 25.0
    still_s: float = 0.3
    clearance_m: float = 0.04
    start_yaw_deg: float | None = None
    max_steps: int = 200
    end_yaw_deg: float | None = None
    turn_in_place_deg: float = 45.0
    approach_steps: int = 0

    def __post_init__(self) -> None:
        pts = np.asarray(self.waypoints_xy, dtype=float)
        if pts.ndim != 2 or pts.shape[1] != 2 or len(pts) < 2 or not np.all(np.isfinite(pts)):
            raise ConfigError("route.waypoints_xy", self.waypoints_xy, "at least two finite (x, y) points")
        if np.any(np.linalg.norm(np.diff(pts, axis=0), axis=1) < 1e-6):
            raise ConfigError("route.waypoints_xy", self.waypoints_xy, "distinct consecutive points")
        check_range("route.step_length_m", self.step_length_m, 0.1, 0.8)
        check_range("route.swing_s", self.swing_s, 0.3, 5.0)
        check_range("route.double_support_s", self.double_support_s, 0.0, 5.0)
        if self.stairs not in STAIR_MODES:
            raise ConfigError("route.stairs", self.stairs, " or ".join(STAIR_MODES))
        check_range("route.max_turn_deg", self.max_turn_deg, 0.0, 60.0)
        check_range("route.still_s", self.still_s, 0.0, 10.0)
        check_range("route.clearance_m", self.clearance_m, 0.0, 0.2)
        if self.start_yaw_deg is not None:
            check_range("route.start_yaw_deg", self.start_yaw_deg, -360.0, 360.0)
        check_range("route.max_steps", self.max_steps, 1, 10000)
        if self.end_yaw_deg is not None:
            check_range("route.end_yaw_deg", self.end_yaw_deg, -360.0, 360.0)
        check_range("route.turn_in_place_deg", self.turn_in_place_deg, 1.0, 180.0)
        if isinstance(self.approach_steps, bool) or not isinstance(self.approach_steps, (int, np.integer)) \
                or not 0 <= self.approach_steps <= 6:
            raise ConfigError("route.approach_steps", self.approach_steps, "an integer in [0, 6]")


class _Polyline:
    def __init__(self, pts: np.ndarray) -> None:
        self.p = pts
        self.seg = np.diff(pts, axis=0)
        self.len = np.linalg.norm(self.seg, axis=1)
        self.cum = np.concatenate([[0.0], np.cumsum(self.len)])
        self.total = float(self.cum[-1])

    def project(self, q: np.ndarray, lo: float = 0.0, hi: float = np.inf) -> float:
        """Arc length of the point of the polyline between arc lengths ``lo`` and ``hi`` nearest to ``q``."""
        lo, hi = max(float(lo), 0.0), min(float(hi), self.total)
        hi = max(hi, lo)
        best, best_d = lo, np.inf
        for i in range(len(self.seg)):
            a, b = float(self.cum[i]), float(self.cum[i + 1])
            if b < lo - 1e-12 or a > hi + 1e-12:
                continue
            u0, u1 = (max(lo, a) - a) / self.len[i], (min(hi, b) - a) / self.len[i]
            u = float(np.clip((q - self.p[i]) @ self.seg[i] / self.len[i] ** 2, u0, u1))
            d = float(np.linalg.norm(self.p[i] + u * self.seg[i] - q))
            if d < best_d:
                best, best_d = a + u * float(self.len[i]), d
        return best

    def point(self, s: float, seg: int | None = None) -> np.ndarray:
        """Point at arc length ``s``; beyond the end the last segment is extended. With ``seg``,
        the point on that segment's line (extended beyond its ends)."""
        s = max(float(s), 0.0)
        i = int(np.clip(np.searchsorted(self.cum, s, side="right") - 1, 0, len(self.seg) - 1)) if seg is None else seg
        return self.p[i] + (s - self.cum[i]) / self.len[i] * self.seg[i]

    def stops(self, min_turn_rad: float) -> list[tuple[float, int]]:
        """(arc length, incoming segment) of every vertex turning by more than ``min_turn_rad``, and of the end."""
        out = []
        for j in range(1, len(self.p) - 1):
            a0 = np.arctan2(self.seg[j - 1][1], self.seg[j - 1][0])
            a1 = np.arctan2(self.seg[j][1], self.seg[j][0])
            if abs(_wrap(float(a1 - a0))) > min_turn_rad:
                out.append((float(self.cum[j]), j - 1))
        out.append((self.total, len(self.seg) - 1))
        return out


def _wrap(a: float) -> float:
    return float((a + np.pi) % (2.0 * np.pi) - np.pi)


@dataclass
class _Foot:
    ankle: np.ndarray  # world (3,)
    pitch: float
    surface: int


class _Planner:
    def __init__(self, exo: ExoSpec, truth: SceneTruth, route: Route) -> None:
        self.exo, self.truth, self.route = exo, truth, route
        self.terrain = Terrain(truth)
        self.grid = sole_grid_f(exo)
        self.front = self.grid[:, 0] >= 0.0
        # with ``overhang`` only the sole from the ankle to the ball of the foot must rest on the surface
        self.to_ball = self.front & (self.grid[:, 0] <= BALL_FRACTION * exo.foot_m - exo.heel_to_ankle_m + 1e-9)
        self.w = exo.hip_width_m
        self.normals = {s.surface_id: s.normal_w for s in truth.surfaces}
        self._points = {s.surface_id: s.point_w for s in truth.surfaces}
        self._coplanar: dict[tuple[int, int], bool] = {}

    def plane_z(self, surface: int, xy: np.ndarray) -> float:
        """Height of a surface's plane (extended beyond its edges) at (x, y)."""
        n, p = self.normals[surface], self._points[surface]
        return float(p[2] - (n[0] * (xy[0] - p[0]) + n[1] * (xy[1] - p[1])) / n[2])

    def coplanar(self, a: int, b: int) -> bool:
        """Whether surfaces ``a`` and ``b`` lie in one plane (one walkable surface split into
        several geoms, e.g. a floor): normals within 1 deg, offsets within 1 cm."""
        if a == b:
            return True
        key = (min(a, b), max(a, b))
        if key not in self._coplanar:
            na, nb = self.normals[a], self.normals[b]
            self._coplanar[key] = bool(float(na @ nb) >= np.cos(np.radians(1.0))
                                       and abs(float(na @ (self._points[b] - self._points[a]))) <= 0.01)
        return self._coplanar[key]

    def foothold(self, sole_xy: np.ndarray, yaw: float, overhang: bool = False) -> tuple[_Foot, float] | None:
        """The foot placed with its sole point at ``sole_xy`` and heading ``yaw``, or None.

        ``overhang``: only placements whose toes overhang a lower surface (or nothing) beyond the
        ball of the foot, the rest of the sole from the ankle on the surface.
        """
        z, sid = self.terrain.query(sole_xy[None, :])
        if sid[0] < 0:
            return None
        n = self.normals[int(sid[0])]
        x = np.array([np.cos(yaw), np.sin(yaw), 0.0])
        y = np.array([-np.sin(yaw), np.cos(yaw), 0.0])
        if abs(float(n @ y)) > np.sin(np.radians(3.0)):
            return None  # the foot cannot roll
        pitch = float(np.arctan2(-(n @ x), n[2]))
        zf = np.array([-np.sin(pitch) * x[0], -np.sin(pitch) * x[1], np.cos(pitch)])
        xf = np.array([np.cos(pitch) * x[0], np.cos(pitch) * x[1], np.sin(pitch)])
        sole = np.array([sole_xy[0], sole_xy[1], z[0]])
        pts = sole + np.outer(self.grid[:, 0], xf) + np.outer(self.grid[:, 1], y)
        tz, tid = self.terrain.query(pts[:, :2])
        if np.any(np.isfinite(tz) & (tz > pts[:, 2] + 1e-6)):
            return None
        whole = not np.any(tid[self.front] != sid[0])
        if whole == overhang or (overhang and np.any(tid[self.to_ball] != sid[0])):
            return None
        ankle = sole + self.exo.sole_height_m * zf
        return _Foot(ankle, pitch, int(sid[0])), float(z[0])

    def place(self, A: np.ndarray, sg: float, yaw: float, a: float, overhang: bool = False) -> tuple[_Foot, float] | None:
        x = np.array([np.cos(yaw), np.sin(yaw)])
        y = np.array([-np.sin(yaw), np.cos(yaw)])
        return self.foothold(A[:2] + a * x - sg * self.w * y, yaw, overhang)


def plan_walk(exo: ExoSpec, truth: SceneTruth, route: Route) -> Motion:
    """Plan and return the motion of walking ``route`` in the world of ``truth``."""
    pl = _Planner(exo, truth, route)
    path = _Polyline(np.asarray(route.waypoints_xy, dtype=float))
    d0 = path.p[1] - path.p[0]
    yaw = np.radians(route.start_yaw_deg) if route.start_yaw_deg is not None else float(np.arctan2(d0[1], d0[0]))
    w = exo.hip_width_m
    feet: dict[str, _Foot] = {}
    for side, s in (("l", 1.0), ("r", -1.0)):
        y = np.array([-np.sin(yaw), np.cos(yaw)])
        got = pl.foothold(path.p[0] + s * 0.5 * w * y, yaw)
        if got is None:
            raise ConfigError("route.waypoints_xy", route.waypoints_xy, f"a start where foot_{side} stands on one walkable surface")
        feet[side] = got[0]
    h_stand = leg_length_for_knee(exo, STAND_KNEE_RAD)
    pelvis = 0.5 * (feet["l"].ankle + feet["r"].ankle)
    pelvis[2] = min(feet["l"].ankle[2], feet["r"].ankle[2]) + h_stand
    pitch = 0.0
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
        err = _wrap(float(np.arctan2(look[1], look[0])) - yaw) if np.linalg.norm(look) > 1e-6 else 0.0
        if arrived:
            err = 0.0 if end_yaw is None else _wrap(end_yaw - yaw)
        turn = float(np.clip(err, -max_turn, max_turn))
        yaw1 = yaw + turn
        in_place = abs(err) > max_turn + 1e-9  # turn on the spot first
        final = arrived and not in_place
        a_nom = 0.0 if (arrived or in_place) else min(route.step_length_m, remaining)
        a_reg, reg_next = a_nom, None
        if not (arrived or in_place) and a_nom == route.step_length_m:
            a_reg, reg_next = _approach_step(pl, route, A, sg, yaw1, a_nom, feet, stance, swing, reg)
        sw = feet[swing]
        x0 = np.array([np.cos(yaw), np.sin(yaw), 0.0])
        x1 = np.array([np.cos(yaw1), np.sin(yaw1), 0.0])
        beta0 = feet[stance].pitch
        a0 = float((sw.ankle - A) @ x0)
        f0, h0 = float((pelvis - A) @ x0), float(pelvis[2] - A[2])
        found = None
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
            options = _choose(pl, route, A, sg, yaw1, a_try, feet, stance, swing, final, overhang)
            n_options += len(options)
            for pw, knee_down in variants:
                for new, _a in options:  # the first foothold the legs can reach and swing to
                    dz0 = float(new.ankle[2] - A[2])
                    if pw and dz0 >= -0.05:
                        continue
                    land = new.ankle
                    if pw:  # the ankle of the foot on its toe tip, heel up (it lowers in the double support)
                        land = toe_pivot(exo, new.ankle, x1[None, :], np.array([new.pitch]), np.array([new.pitch - pw]))[0]
                    # on stairs the trailing (stance) foot rises on its toes (only on straight steps)
                    rises = (HEEL_RISE_RAD if not pw else HEEL_RISE_DEEP_RAD) if abs(dz0) > 0.05 and straight else (0.0,)
                    for rise in rises:
                        A_end = toe_pivot(exo, A, x1[None, :], np.array([beta0]), np.array([beta0 - rise]))[0] if rise else A
                        a1, dz = float((land - A_end) @ x1), float(land[2] - A_end[2])
                        pitch1 = CLIMB_LEAN_RAD if dz > 0.05 else np.radians(2.0)
                        knee_max = knee_down if dz < -0.05 else STANCE_KNEE_MAX_RAD
                        pelvis_opts = end_pelvis_options(exo, a1, dz, pitch1, (beta0 - rise, new.pitch - pw), knee_max)
                        if not pelvis_opts:
                            continue
                        plan = _SwingPlan(
                            stance=stance, A=A.copy(), stance_pitch=(beta0, beta0 - rise), yaw=(yaw, yaw1),
                            pitch=(pitch, pitch1), f=(f0, 0.0), h=(h0, 0.0), a=(a0, a1),
                            z=(float(sw.ankle[2]), float(land[2])), swing_pitch=(sw.pitch, new.pitch - pw),
                        )  # fmt: skip
                        drop = None
                        if pw:  # where the pelvis goes while the heel lowers: a double stance on the flat foot
                            a2, dz2 = float((new.ankle - A_end) @ x1), float(new.ankle[2] - A_end[2])
                            flat_opts = end_pelvis_options(exo, a2, dz2, pitch1, (beta0 - rise, new.pitch), knee_max)
                            if not flat_opts:
                                continue
                            drop = (float(new.pitch), flat_opts[:8])
                        for lag, dip in SWING_SHAPES:
                            plan.lag, plan.dip = lag, dip
                            apex = swing_apex_m(exo, pl.terrain, plan, clearance_m=route.clearance_m, exact_progress=True)
                            found = _first_feasible(exo, plan, apex, f0, h0, pelvis_opts[:8], drop)
                            if found:
                                f1, h1, fh2 = found
                                found = (new, A_end, beta0 - rise, f1, h1, pitch1, plan, apex, drop, fh2)
                                a_used = a_try
                                break
                        if found:
                            break
                    if found:
                        break
                if found:
                    break
            if found:
                break
        if not n_options:
            raise GaitError(f"no foothold for foot_{swing} ahead of ({A[0]:.2f}, {A[1]:.2f}) at t={t:.2f} s")
        if found is None:
            raise GaitError(f"no reachable foothold for foot_{swing} ahead of ({A[0]:.2f}, {A[1]:.2f}) at t={t:.2f} s")
        new, A_end, beta1, f1, h1, pitch1, plan, apex, drop, fh2 = found
        reg = reg_next if a_used == a_reg else None  # a regulated approach goes on only if this step kept to it
        if first_plan is None:
            first_plan = plan
            if route.still_s > 0:
                segs.append(still_segment(exo, plan, 0.0, route.still_s, at_end=False))
                t = route.still_s
        segs.append(plan.segment(t, t + route.swing_s, apex))
        sole = new.ankle - exo.sole_height_m * np.array([-np.sin(new.pitch) * x1[0], -np.sin(new.pitch) * x1[1], np.cos(new.pitch)])
        liftoff = t
        t += route.swing_s
        hold = route.double_support_s if not final else route.still_s
        if drop is not None:  # forefoot landing: the heel lowers in the double support, the pelvis comes down
            hold = max(hold, HEEL_DROP_S)
            f1, h1 = fh2
            segs.append(heel_drop_segment(exo, plan, t, t + hold, to_pitch=drop[0], f=f1, h=h1))
            t += hold
        elif hold > 0:
            segs.append(still_segment(exo, plan, t, t + hold, at_end=True))
            t += hold
        # touch-down: the foot flat on its support (after the heel lowering of a forefoot landing)
        steps.append(Footstep(swing, liftoff, t if drop is not None else liftoff + route.swing_s, sole, float(yaw1), new.surface))
        ylat = np.array([-np.sin(yaw1), np.cos(yaw1), 0.0])
        pelvis = A_end + f1 * x1 - sg * 0.5 * w * ylat
        pelvis[2] = A_end[2] + h1
        feet[stance] = _Foot(A_end, beta1, feet[stance].surface)
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


def _first_feasible(
    exo: ExoSpec, plan: _SwingPlan, apex: float, f0: float, h0: float, options: list[tuple[float, float]],
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


def _choose(
    pl: _Planner, route: Route, A: np.ndarray, sg: float, yaw: float, a_nom: float,
    feet: dict[str, _Foot], stance: str, swing: str, final: bool, overhang: bool = False,
) -> list[tuple[_Foot, float]]:  # fmt: skip
    """Footholds for the swing foot with their distance ``a`` ahead of the stance ankle, best first
    (with ``overhang``: only those with the toes over a lower surface, see :meth:`_Planner.foothold`)."""
    S_A = feet[stance].surface
    z_A = float(A[2])
    trailing_low = abs(float(feet[swing].ankle[2]) - z_A) > 0.05
    if not final and not (route.stairs == "step-to" and trailing_low):
        got = pl.place(A, sg, yaw, a_nom, overhang)  # the nominal step, when it lands at about the same level
        if got is not None and abs(got[0].ankle[2] - z_A) <= 0.03 + abs(a_nom) * np.tan(np.radians(25.0)):
            return [(got[0], a_nom)]
    grid = np.round(np.arange(-0.15, max(0.8, 2.0 * route.step_length_m) + 1e-9, 0.01), 6)
    cands: list[tuple[float, _Foot]] = []
    for a in grid:
        got = pl.place(A, sg, yaw, float(a), overhang)
        if got is not None and abs(got[0].ankle[2] - z_A) <= 0.35:
            cands.append((float(a), got[0]))

    def nearest(target: float, pool: list[tuple[float, _Foot]]) -> list[tuple[_Foot, float]]:
        if not pool:
            return []
        a, f = min(pool, key=lambda c: abs(c[0] - target))
        return [(f, a)]

    same_level = [c for c in cands if abs(c[1].ankle[2] - z_A) <= 0.03 + abs(c[0]) * np.tan(np.radians(25.0))]
    # step-to: the trailing foot joins the leading one on its step
    if final or (route.stairs == "step-to" and trailing_low):
        return nearest(0.0, [c for c in cands if c[1].surface == S_A])
    nominal = nearest(a_nom, same_level)
    if nominal and abs(nominal[0][1] - a_nom) < 0.005:
        return nominal
    out: list[tuple[_Foot, float]] = []
    ahead = [c for c in cands if c[0] > 0.05 and c[1].surface != S_A]
    if ahead:
        target = ahead[0][1].surface
        run = [c for c in ahead if c[1].surface == target]
        lo, hi = run[0][0], run[-1][0]
        if hi - lo < TREAD_RUN_M:  # a tread: centre the foot on it
            out += nearest(0.5 * (lo + hi), run)
        else:
            out += nearest(float(np.clip(a_nom, lo + 0.05, hi)), run)
    # or a shorter step up to the edge, when the next surface is out of reach
    short = [c for c in same_level if 0.05 < c[0] <= a_nom + 1e-9]
    if short:
        out += [(short[-1][1], short[-1][0])]
    return out


def _approach_step(
    pl: _Planner, route: Route, A: np.ndarray, sg: float, yaw: float, a_nom: float,
    feet: dict[str, _Foot], stance: str, swing: str, under_way: tuple[int, int] | None = None,
) -> tuple[float, tuple[int, int] | None]:  # fmt: skip
    """The step length regulated towards the next transition ahead (module docstring), or ``a_nom``,
    and the approach it starts or continues: (next surface, number of steps to it incl. this one),
    None when not regulated.

    Only while both feet stand on one plane (level ground, a ramp, a landing): the footholds of
    the swing foot are scanned along the heading up to (``approach_steps`` + 0.5) nominal steps
    ahead. Where they leave the stance foot's plane is the *edge* (the last foothold on it at
    ``a_edge``); the first foothold beyond it on another surface starts the *next surface*
    (footholds from ``a_lo`` to ``a_hi``). With n equal steps of length a from here:

    - before a flight (the next surface more than 5 cm above or below this plane extended under
      it), the n-th step is the last on this level, with the toes within :data:`EDGE_BAND_M` of
      the edge (people put the last foot close to the first riser, or with the toes at the edge
      before a step down); the step onto the flight is then the planner's usual one (a tread's
      centre);
    - otherwise (a ramp's start or end, a landing, the floor) the n-th step is the first on the
      next surface, :data:`ONTO_MARGIN_M` beyond its first foothold if that fits, else anywhere
      on it, with the foot before it still on this plane ((n - 1) a <= ``a_edge``).

    On a slope a pitched foot's ankle lies d = sole height x sin(pitch) behind its sole point, so
    the n-th foot lands n a - (n - 1) d ahead of the stance ankle. Of the n <= ``approach_steps``
    and a within :data:`APPROACH_RANGE` of the nominal step (at
    most :data:`APPROACH_DOWN_MAX` of it onto a ramp going down: the kinematic walker reaches no
    farther) that do, the a closest to the nominal is taken (the nominal itself when it fits):
    the steps before a transition change only as much as they must, evenly over the last ones,
    as people regulate their steps over the last two or three strides before a target [A: Lee,
    Lishman & Thomson, J. Exp. Psychol. HPP 8 (1982) 448-459; de Rugy et al., Biol. Cybern. 87
    (2002) 141-150]. An approach ``under_way`` (the previous step's, towards the same surface)
    goes on with one step fewer if that still fits (the executed steps differ from the plan by
    millimetres to centimetres: a heel rising on a slope), so the walker keeps to its count
    instead of re-choosing it every step.
    """
    n_max = int(route.approach_steps)
    S = feet[stance].surface
    if n_max <= 0 or a_nom <= 0.0 or not pl.coplanar(S, feet[swing].surface):
        return a_nom, None
    grid = np.round(np.arange(0.02, (n_max + 0.5) * a_nom + 0.5, 0.01), 6)
    got = [pl.place(A, sg, yaw, float(a)) for a in grid]
    on = [g is not None and pl.coplanar(g[0].surface, S) for g in got]
    if all(on) or not on[0]:
        return a_nom, None  # no transition within reach, or standing at one already
    k = on.index(False)
    a_edge = float(grid[k - 1])
    j = next((i for i in range(k, len(grid)) if got[i] is not None), None)
    if j is None or on[j]:
        return a_nom, None  # nothing walkable beyond the edge (a wall), or a gap in the same plane
    nxt = got[j][0].surface
    end = j
    while end + 1 < len(grid) and got[end + 1] is not None and pl.coplanar(got[end + 1][0].surface, nxt):
        end += 1
    a_lo, a_hi = float(grid[j]), float(grid[end])
    # a flight up or down: the next surface more than 5 cm off this plane extended under it
    xy_j = A[:2] + a_lo * np.array([np.cos(yaw), np.sin(yaw)]) - sg * pl.w * np.array([-np.sin(yaw), np.cos(yaw)])
    level_change = abs(float(got[j][1]) - pl.plane_z(S, xy_j)) > 0.05
    lo_f, hi_f = APPROACH_RANGE
    x = np.array([np.cos(yaw), np.sin(yaw), 0.0])
    if not level_change and float(pl.normals[nxt] @ x) > 0.02:
        hi_f = min(hi_f, APPROACH_DOWN_MAX)  # a long step onto a ramp down is out of reach
    # a foot pitched on this plane has its ankle d behind its sole point, so each step lands a
    # ahead of the ankle but its sole point only a - d ahead of the last one: the n-th step's
    # sole point is n a - (n - 1) d ahead of the stance ankle (the footholds were scanned as one step)
    d = float(pl.exo.sole_height_m * np.sin(feet[stance].pitch))

    def fit(n: int) -> float | None:
        """The step closest to the nominal with which the n-th step is the last one before a
        flight (``level_change``) or the first one on the next surface (else)."""
        windows = [(a_edge - EDGE_BAND_M, a_edge)] if level_change else \
            [(a_lo + ONTO_MARGIN_M, a_hi), (a_lo, a_hi)]  # clear of the crease, else just past it
        for lo, hi in windows:
            lo, hi = (lo + (n - 1) * d) / n, (hi + (n - 1) * d) / n
            if not level_change and n > 1:
                hi = min(hi, (a_edge + (n - 2) * d) / (n - 1))  # the foot before it on this plane
            lo, hi = max(lo, lo_f * a_nom), min(hi, hi_f * a_nom)
            if lo <= hi + 1e-9:
                return float(np.clip(a_nom, lo, hi))
        return None

    if under_way is not None and under_way[0] == nxt and under_way[1] > 1:
        a = fit(under_way[1] - 1)  # keep counting down, if that still fits
        if a is not None:
            return a, (nxt, under_way[1] - 1)
    fits = [(a, n) for n in range(1, n_max + 1) if (a := fit(n)) is not None]
    if not fits:
        return a_nom, None
    a, n = min(fits, key=lambda c: (abs(c[0] - a_nom), c[1]))
    return a, (nxt, n)
