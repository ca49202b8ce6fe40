"""Worlds of the course scenario (the locomotion track): stair, ramp and side-by-side courses, the
walker's route in pieces, and the locomotion mode of every step.

Courses (seeds/002 section III-B) are :func:`exobench.models.worlds.build_course` profiles along
+x starting at the origin: ``stairs`` = level, a flight up, a landing, a flight down, level
(LG SA LG SD LG); ``ramp`` = level, ramp up, landing, ramp down, level (LG RA LG RD LG).
``parallel`` puts the two courses side by side (lane centres ``width_m`` + two wall thicknesses
apart): lane a (the ``parallel_first`` course) runs along world +y (built with yaw 90 deg; the
walk planner mishandles headings near +-180 deg) and lane b, turned by 180 deg, runs back along
-y; the walker walks lane a, makes a U-turn on the floor beyond its end and walks back along lane b
(the multi-direction test of Fig. 3(b)). Lane b's geoms are copied into lane a's spec with the
prefix ``b_`` (its floor plane is left out: lane a's floor covers both lanes) and its surfaces are
appended with ids offset past lane a's (``scene.params["lane_b"]``).

Walks are planned in pieces (:func:`plan_pieces`): the walker stops before every transition from
level ground to stairs or a ramp and restarts from standing; the motions are joined by a short
settle segment (:func:`join_motions`).

The exoskeleton, its camera rig and pedestrians are added by :func:`exobench.envs.sim.compose.compose_rig`.

Step modes (:func:`step_truths`): the mode of a step is that of the terrain under its landing
footprint relative to where the same foot stood before: on a ramp surface RA if the ramp rises
along the walking heading, else RD; on a flat surface SA / SD if the foot landed more than
:data:`STAIR_DZ_M` higher / lower than it was and did not come from a ramp, else LG (stepping off
a ramp onto its landing or the floor is level walking).
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Any

import numpy as np

from exobench.core import SceneTruth, StepTruth
from exobench.core.transforms import make_T, matrix_to_quat_wxyz, rot_z
from exobench.core.truth import PlanarSurface
from exobench.models.exo_spec import ExoSpec
from exobench.models.terrain import WALL_THICKNESS_M
from exobench.models.world_params import CourseParams
from exobench.models.worlds import BuiltWorld, build_course

from ...motion import Footstep, GaitError, Motion, Route, Segment, check_feasible, plan_walk

STAIR_DZ_M = 0.05  # a foot landing this much higher/lower than it stood climbs/descends stairs
RAMP_MIN_DEG = 2.0  # a surface tilted more than this is a ramp
LANE_PREFIX = "b_"
U_TURN_M = 1.2  # the U-turn of the parallel course runs this far beyond the first lane's end
START_INSET_M = 0.4  # the walk starts / ends this far inside the level ends of a course
JOIN_SETTLE_S = 0.3  # pause between two planned pieces of a walk
STOP_SHIFTS_M = (0.0, 0.1, 0.2, 0.3)
MIN_STOP_FLAT_M = 0.6
PARALLEL_YAW_DEG = 90.0
STOP_TOE_GAP_M = 0.08  # toes this far before the edge at a standing stop [A]
MAX_PLANS = 40  # planner calls before a course is declared unwalkable
APPROACH_STEPS = 4  # the walker regulates its last steps before a transition (exobench.envs.motion.Route.approach_steps)
PARALLEL_EXTRA_APPROACH_M = 1.0  # more level floor in each lane of the parallel course, to straighten up after the U-turn


def stairs_segments(riser_m: float, tread_m: float, n_steps: int, landing_m: float) -> tuple:
    s = {"n_steps": n_steps, "riser_m": riser_m, "tread_m": tread_m, "nosing_m": 0.0}
    return (("stairs", {"direction": "up", **s}), ("level", {"length_m": landing_m}), ("stairs", {"direction": "down", **s}))


def ramp_segments(slope_deg: float, length_m: float, landing_m: float) -> tuple:
    r = {"slope_deg": slope_deg, "length_m": length_m}
    return (("ramp", {"direction": "up", **r}), ("level", {"length_m": landing_m}), ("ramp", {"direction": "down", **r}))


def course_length(world: BuiltWorld) -> float:
    """Local x where the course's exit floor ends."""
    return float(world.truth.params["profile"][-1]["x1"])


def _transform_surface(s: PlanarSurface, T: np.ndarray, sid: int, prefix: str) -> PlanarSurface:
    R, t = T[:3, :3], T[:3, 3]
    return PlanarSurface(surface_id=sid, kind=s.kind, normal_w=R @ s.normal_w, point_w=R @ s.point_w + t,
                         polygon_w=s.polygon_w @ R.T + t, geom_names=tuple(prefix + g for g in s.geom_names))


def merge_lanes(a: BuiltWorld, b: BuiltWorld, T_b: np.ndarray) -> BuiltWorld:
    """Lane ``b`` (built at the origin) moved by ``T_b`` into lane ``a``'s spec and truth."""
    import mujoco

    spec = a.spec.copy()
    R, t = T_b[:3, :3], T_b[:3, 3]
    for g in b.spec.geoms:
        if g.name == "floor":
            continue
        Rg = np.empty(9)
        mujoco.mju_quat2Mat(Rg, np.asarray(g.quat, dtype=float))
        spec.worldbody.add_geom(name=LANE_PREFIX + g.name, type=g.type, pos=list(R @ np.asarray(g.pos) + t),
                                quat=list(matrix_to_quat_wxyz(R @ Rg.reshape(3, 3))), size=list(g.size),
                                material=g.material, group=g.group)
    ta, tb = a.truth, b.truth
    off = 1 + max(s.surface_id for s in ta.surfaces)
    surfaces = list(ta.surfaces)
    geom_surfaces = {k: list(v) for k, v in ta.geom_surfaces.items()}
    for s in tb.surfaces:
        if s.geom_names == ("floor",):
            continue
        ns = _transform_surface(s, T_b, off + s.surface_id, LANE_PREFIX)
        surfaces.append(ns)
        for g in ns.geom_names:
            geom_surfaces.setdefault(g, []).append(ns.surface_id)
    params = dict(ta.params)
    params["lane_b"] = {"T_world_lane": T_b.tolist(), "profile": tb.params["profile"], "surface_id_offset": off,
                        "geom_prefix": LANE_PREFIX, "segments": tb.params.get("segments")}
    truth = SceneTruth(surfaces=tuple(surfaces), geom_surfaces={k: tuple(v) for k, v in geom_surfaces.items()},
                       params=params, kind="course", geom_materials={**ta.geom_materials}, objects=ta.objects)
    return BuiltWorld(spec=spec, truth=truth, T_world_local=a.T_world_local)


def stop_points_x(world: BuiltWorld, toe_m: float, descents: bool = True) -> list[float]:
    """Local x of the standing stops of a course: on every level stretch at least
    :data:`MIN_STOP_FLAT_M` long that ends at a riser or a ramp (going up, or also down when
    ``descents``), with the toes :data:`STOP_TOE_GAP_M` before its edge (``toe_m``: ankle to toe)."""
    prof = world.truth.params["profile"]
    out = []
    for i, it in enumerate(prof[:-1]):
        nxt = prof[i + 1]
        if it["kind"] == "flat" and nxt["kind"] != "flat" and it["x1"] - it["x0"] >= MIN_STOP_FLAT_M:
            if descents or nxt["z1"] > nxt["z0"]:
                out.append(float(it["x1"] - toe_m - STOP_TOE_GAP_M))
    return out


def build_locomotion_world(sc: Any, toe_m: float = 0.2, descents: bool = True) -> tuple[BuiltWorld, tuple]:
    """(world, route pieces) of a :class:`~exobench.envs.sim.scenarios.course.LocomotionScenario`.

    The route is a sequence of pieces, each a polyline of ``(x, y)`` waypoints walked from a
    standing start to a standing stop (see :func:`plan_pieces`). With ``sc.stops ==
    "transitions"`` the walker stops before every transition from level ground to stairs or a
    ramp (:func:`stop_points_x`; stop-and-go, as exoskeleton users often do) and, on the
    ``parallel`` course, on the second lane's level approach after the U-turn; ``descents=False``
    then leaves out the stops before stairs or ramps going down. With ``"none"`` (the default)
    a stairs or ramp course is one piece, walked through every transition as the paper's
    subjects did (the planner of :mod:`exobench.envs.motion.walk` places the transition steps; every
    terrain, pattern and user height of the generality grid plans); the parallel course keeps
    one stop, on the second lane's approach after the U-turn (walked through, the planner finds
    no foothold on the second lane).
    """
    stairs = stairs_segments(sc.riser_m, sc.tread_m, sc.n_steps, sc.landing_m)
    ramps = ramp_segments(sc.slope_deg, sc.ramp_length_m, sc.landing_m)

    def course(segs: tuple, exit_m: float, approach_m: float, yaw_deg: float = 0.0) -> BuiltWorld:
        return build_course(CourseParams(segments=segs, width_m=sc.width_m, approach_m=approach_m,
                                         exit_m=exit_m, walls=bool(sc.walls), yaw_deg=yaw_deg))

    if sc.terrain in ("stairs", "ramp"):
        w = course(stairs if sc.terrain == "stairs" else ramps, sc.approach_m, sc.approach_m)
        x0, x1 = -sc.approach_m + START_INSET_M, course_length(w) - START_INSET_M
        stops = stop_points_x(w, toe_m, descents) if sc.stops == "transitions" else []
        xs = [x0, *stops, x1]
        return w, tuple(((xs[i], 0.0), (xs[i + 1], 0.0)) for i in range(len(xs) - 1))
    first, second = (stairs, ramps) if sc.parallel_first == "stairs" else (ramps, stairs)
    ap = sc.approach_m + PARALLEL_EXTRA_APPROACH_M
    la0, lb0 = course_length(course(first, ap, ap)), course_length(course(second, ap, ap))
    # the shorter lane's exit is stretched so that both lanes are L long
    # the parallel course runs along world +y (lane a) and -y (lane b): the planner of
    # exobench.envs.motion.walk mishandles headings near +-180 deg, so neither lane runs along -x
    a = course(first, ap + max(0.0, lb0 - la0), ap, PARALLEL_YAW_DEG)
    b = course(second, ap + max(0.0, la0 - lb0), ap)
    L = course_length(a)
    gap = sc.width_m + (2.0 * WALL_THICKNESS_M if sc.walls else 0.3)
    T_wa = np.asarray(a.T_world_local, dtype=float)
    # lane b turned by 180 deg in lane a's frame: its start (local x = -ap) at x = L, its centre at y = -gap
    T_b = T_wa @ make_T(rot_z(math.pi), np.array([L - ap, -gap, 0.0]))
    world = merge_lanes(a, b, T_b)
    turn_x = L + U_TURN_M
    x0 = -ap + START_INSET_M
    stops = sc.stops == "transitions"
    xa = [x0, *(stop_points_x(a, toe_m, descents) if stops else [])]
    xb = [float(L - ap - x) for x in stop_points_x(b, toe_m, descents)]
    if not stops:  # one stop only: after the U-turn, where the planner needs a standing start
        xb = xb[:1]
    local = [[(xa[i], 0.0), (xa[i + 1], 0.0)] for i in range(len(xa) - 1)]
    local.append([(xa[-1], 0.0), (turn_x - 0.6, 0.0), (turn_x, -0.5 * gap), (turn_x - 0.6, -gap), (xb[0], -gap)])
    xb.append(x0)
    local += [[(xb[i], -gap), (xb[i + 1], -gap)] for i in range(len(xb) - 1)]
    R = T_wa[:2, :2]
    pieces = tuple(tuple(tuple(map(float, R @ np.asarray(q))) for q in piece) for piece in local)
    return world, pieces


def step_truths(motion: Any, truth: SceneTruth, exo: ExoSpec) -> tuple[StepTruth, ...]:
    """One :class:`StepTruth` per footstep of a planned walk (modes: see the module docstring)."""
    st0 = motion.state(0.0)
    prev = {s: st0.sole_points_w(s, np.array([[0.0, 0.0, -exo.sole_height_m]]))[0, 0] for s in ("l", "r")}
    prev_kind = {"l": "flat", "r": "flat"}
    out = []
    for i, fs in enumerate(motion.footsteps):
        surf = truth.surface(int(fs.surface_id))
        heading = np.array([math.cos(fs.yaw_rad), math.sin(fs.yaw_rad), 0.0])
        tilt = math.degrees(math.acos(min(1.0, abs(float(surf.normal_w[2])))))
        dz = float(fs.sole_w[2] - prev[fs.side][2])
        if surf.kind == "ramp" and tilt > RAMP_MIN_DEG:
            mode = "RA" if float(surf.normal_w @ heading) < 0.0 else "RD"
        elif prev_kind[fs.side] != "ramp" and dz > STAIR_DZ_M:
            mode = "SA"
        elif prev_kind[fs.side] != "ramp" and dz < -STAIR_DZ_M:
            mode = "SD"
        else:
            mode = "LG"
        out.append(StepTruth(index=i, side=fs.side, liftoff_s=float(fs.liftoff_s), heel_strike_s=float(fs.touchdown_s),
                             footprint_w=np.asarray(fs.sole_w, dtype=float).copy(), terrain=surf.kind, mode=mode))
        prev[fs.side] = np.asarray(fs.sole_w, dtype=float)
        prev_kind[fs.side] = surf.kind if tilt > RAMP_MIN_DEG else "flat"
    return tuple(out)


def _shift_motion(motion: Motion, dt: float) -> tuple[list[Segment], list[Footstep]]:
    segs = [replace(s, t0=s.t0 + dt, t1=s.t1 + dt) for s in motion.segments]
    steps = [replace(f, liftoff_s=f.liftoff_s + dt, touchdown_s=f.touchdown_s + dt) for f in motion.footsteps]
    return segs, steps


def join_motions(exo: ExoSpec, first: Motion, second: Motion, settle_s: float = JOIN_SETTLE_S) -> Motion:
    """``first`` then ``second`` (which starts standing where ``first`` stopped), joined by a
    ``settle_s`` segment in which the feet stay and the pelvis moves from ``first``'s final pose
    to ``second``'s initial one (the planner's start pose differs from its stop pose by a few cm)."""
    T1 = first.duration_s
    s2 = second.segments[0]
    end = first.state(T1, solve_legs=False)
    P1, p1 = end.pelvis_w[0], float(end.pitch[0])
    A2 = np.asarray(s2.ankle_w, dtype=float)
    xh = np.array([math.cos(s2.yaw[0]), math.sin(s2.yaw[0]), 0.0])
    settle = Segment(
        t0=T1, t1=T1 + settle_s, stance=s2.stance, ankle_w=s2.ankle_w, stance_pitch=(s2.stance_pitch[0],) * 2,
        yaw=(s2.yaw[0],) * 2, pitch=(p1, s2.pitch[0]), f=(float((P1 - A2) @ xh), s2.f[0]),
        h=(float(P1[2] - A2[2]), s2.h[0]), a=(s2.a[0],) * 2, z=(s2.z[0],) * 2, apex_m=0.0,
        swing_pitch=(s2.swing_pitch[0],) * 2,
    )  # fmt: skip
    segs2, steps2 = _shift_motion(second, T1 + settle_s)
    events = dict(first.events)
    events["end_s"] = segs2[-1].t1
    events[f"join_{len(first.footsteps)}_s"] = T1
    motion = Motion(exo, [*first.segments, settle, *segs2], events=events,
                    footsteps=(*first.footsteps, *steps2), stance_side=first.stance_side)  # fmt: skip
    check_feasible(motion)
    return motion


def plan_pieces(exo: ExoSpec, truth: SceneTruth, pieces: tuple, step_m: float, swing_s: float, ds_s: float,
                tries: tuple, approach_steps: int = APPROACH_STEPS) -> tuple[Motion, dict[str, float]]:  # fmt: skip
    """Plan a walk along ``pieces`` (polylines of ``(x, y)`` waypoints): piece k > 0 starts
    standing where piece k - 1 stopped, facing the same way, and the motions are joined
    (:func:`join_motions`). Each piece is tried with ``tries`` = (clearance, start shift (first
    piece only), step factor) in order; when no try of a piece works, the previous piece is
    planned again with its stop point moved back by the next of :data:`STOP_SHIFTS_M` (the
    stop-and-go walker's footholds depend on where it starts). At most :data:`MAX_PLANS` planner
    calls; raises :class:`GaitError` with the last planner error."""
    state = {"calls": 0, "err": "no plan tried"}
    used: list[dict[str, float]] = []

    def walk(k: int, start: np.ndarray | None, yaw: float | None) -> list[Motion] | None:
        wps = np.asarray(pieces[k], dtype=float).copy()
        d0 = (wps[1] - wps[0]) / np.linalg.norm(wps[1] - wps[0])
        if start is not None:
            # start where the last piece stopped, heading exactly along the piece (the planner's
            # footholds on ramps tolerate no roll: a heading off by 0.05 deg fails on them); the
            # piece is moved sideways by the stop's lateral offset (millimetres)
            off = np.asarray(start, dtype=float) - wps[0]
            lat = off - (off @ d0) * d0
            wps = wps + lat
            wps[0] = start
            yaw = float(np.degrees(np.arctan2(d0[1], d0[0])))
        last = k == len(pieces) - 1
        d1 = (wps[-1] - wps[-2]) / np.linalg.norm(wps[-1] - wps[-2])
        for stop in (0.0,) if last else STOP_SHIFTS_M:
            for clr, shift, fac in tries:
                if k > 0 and shift != 0.0:
                    continue
                if state["calls"] >= MAX_PLANS:
                    return None
                p = wps.copy()
                p[0] = wps[0] + shift * d0
                p[-1] = wps[-1] - stop * d1
                step = float(np.clip(step_m * fac, 0.1, 0.8))
                route = Route(tuple(map(tuple, p)), step_length_m=step, swing_s=swing_s, double_support_s=ds_s,
                              clearance_m=clr, max_turn_deg=45.0, max_steps=400, start_yaw_deg=yaw,
                              approach_steps=approach_steps)  # fmt: skip
                state["calls"] += 1
                try:
                    motion = plan_walk(exo, truth, route)
                except GaitError as err:
                    state["err"] = str(err)
                    continue
                used.append({"step_length_m": step, "clearance_m": clr, "start_shift_m": shift, "stop_shift_m": stop})
                if last:
                    return [motion]
                st = motion.state(motion.duration_s, solve_legs=False)
                mid = 0.5 * (st.ankle_w["l"][0] + st.ankle_w["r"][0])[:2]
                rest = walk(k + 1, mid, float(np.degrees(st.yaw[0])))
                if rest is not None:
                    return [motion, *rest]
                break  # the next piece cannot start from this stop: move the stop
        return None

    got = walk(0, None, None)
    if got is None:
        raise GaitError(f"{state['err']} (after {state['calls']} planner calls)")
    motion = got[0]
    for nxt in got[1:]:
        motion = join_motions(exo, motion, nxt)
    return motion, {**used[0], "planner_calls": float(state["calls"])}
