"""The staircase paper's climbing step (section V-A): one step from level ground onto the first
tread, planned from the true staircase and not updated by perception.

World convention of :func:`climb_step`: the exoskeleton starts at the origin facing +x, both
feet flat on level ground at z = 0 (ankles below the hips, knees 5 deg flexed [A]). The
staircase must be built with :func:`exobench.envs.sim.scenarios.stairs.staircase_params_for_case`.
"""

from __future__ import annotations

import numpy as np

from exobench.core import ConfigError, SceneTruth
from exobench.models.exo_spec import ExoSpec

from ..terrain import Terrain
from .kinematics import (
    CLIMB_LEAN_RAD,
    STAND_KNEE_RAD,
    GaitError,
    end_pelvis_options,
    leg_length_for_knee,
    sole_grid_f,
)
from .motion import Footstep, Motion, check_feasible
from .swing import SwingPlan, still_segment, swing_apex_m


def _riser_and_tread(truth: SceneTruth) -> tuple[object, object, object | None]:
    try:
        riser, tread = truth.surface(1), truth.surface(2)
    except KeyError:
        raise ConfigError("truth", truth.kind, "a staircase with surfaces 1 (riser) and 2 (tread)") from None
    if riser.kind != "riser" or tread.kind not in ("tread", "landing"):
        raise ConfigError("truth", truth.kind, "an ascending staircase (surface 1 a riser, 2 a tread)")
    nxt = None
    for s in truth.surfaces:
        if s.surface_id == 3 and s.kind == "riser":
            nxt = s
    return riser, tread, nxt


def climb_step(
    exo: ExoSpec,
    truth: SceneTruth,
    *,
    distance_m: float,
    yaw_deg: float,
    duration_s: float = 2.0,
    side: str = "r",
    still_s: float = 0.3,
    settle_s: float = 0.3,
    clearance_m: float = 0.04,
) -> Motion:
    """One climbing step of the staircase paper (section V-A), not updated by perception.

    The exoskeleton stands at the origin facing +x, feet flat on the ground; the staircase in
    ``truth`` must have its first riser at perpendicular distance ``distance_m`` from the swing
    foot's toe tip and be yawed by ``-yaw_deg`` (the exoskeleton turned by ``yaw_deg``
    counter-clockwise relative to the stairs), as
    :func:`exobench.envs.sim.scenarios.stairs.staircase_params_for_case` builds it. After ``still_s`` of
    standing, the ``side`` foot lifts off and follows a parabola (flat sole, minimum-jerk
    progress) to the first tread: the footprint is centred on the tread along the walking
    direction (toe 1 cm short of the next riser when the foot is longer than the tread), the
    apex is the lowest giving ``clearance_m`` over the terrain; the pelvis moves forward, down
    as needed and leans 6 deg. Touch-down is ``settle_s`` before the end.

    Events: ``liftoff_s``, ``touchdown_s``. Raises :class:`ConfigError` when the first tread is
    out of one step's reach or the staircase does not match ``distance_m``/``yaw_deg``.
    """
    if side not in ("l", "r"):
        raise ConfigError("side", side, "'l' or 'r'")
    if duration_s - still_s - settle_s < 0.5:
        raise ConfigError("duration_s", duration_s, f">= {still_s + settle_s + 0.5} s (still, swing >= 0.5 s, settle)")
    stance = "l" if side == "r" else "r"
    sg = 1.0 if stance == "l" else -1.0
    w = exo.hip_width_m
    sole_h = exo.sole_height_m
    toe_x = exo.foot_m - exo.heel_to_ankle_m
    y_sw = -sg * 0.5 * w
    toe = np.array([toe_x, y_sw, 0.0])
    riser, tread, nxt = _riser_and_tread(truth)
    d = -riser.normal_w  # up the stairs, horizontal
    dist = float((riser.point_w - toe) @ d)
    if abs(dist - distance_m) > 1e-6:
        raise ConfigError("distance_m", distance_m, f"the staircase's first riser is {dist:.4f} m from the toe tip")
    yaw_st = np.degrees(np.arctan2(d[1], d[0]))
    if abs(((yaw_st + yaw_deg) + 180.0) % 360.0 - 180.0) > 1e-6:
        raise ConfigError("yaw_deg", yaw_deg, f"the staircase is yawed {yaw_st:.3f} deg, i.e. yaw_deg={-yaw_st:.3f}")
    cpsi = float(d[0])
    if cpsi < 0.2:
        raise ConfigError("yaw_deg", yaw_deg, "|yaw_deg| < 78 (the stairs must lie ahead)")
    terrain = Terrain(truth)
    grid = sole_grid_f(exo)
    for s_side, y in (("l", 0.5 * w), ("r", -0.5 * w)):
        z, ids = terrain.query(grid[:, :2] + [0.0, y])
        if np.any(ids != 0) or np.any(np.abs(z) > 1e-9):
            raise ConfigError(
                "distance_m", distance_m, f"both feet must start on the level ground before the stairs (foot_{s_side} is not)"
            )

    # touch-down: footprint centred on the tread along d (toe short of the next riser)
    proj_t = (tread.polygon_w - riser.point_w) @ d
    lo, hi = float(proj_t.min()), float(proj_t.max())
    if nxt is not None:
        hi = min(hi, float((nxt.point_w - riser.point_w) @ d))
    spread = grid[:, :2] @ np.array([d[0], d[1]])  # footprint along d at yaw 0 (foot along +x)
    half = 0.5 * float(spread.max() - spread.min())
    centre_f = 0.5 * float(spread.max() + spread.min())
    target = 0.5 * (lo + hi)
    if 2.0 * half > hi - lo:  # the foot is longer than the tread: toe 1 cm short of the next riser
        target = hi - 0.01 - half
    start_c = float((np.array([0.0, y_sw, 0.0]) - riser.point_w) @ d) + centre_f
    shift = (target - start_c) / cpsi  # ankle travel along +x
    z_tread = float(truth.surface(tread.surface_id).point_w[2])
    A = np.array([0.0, sg * 0.5 * w, sole_h])
    a1, z1 = shift, z_tread + sole_h
    z_td, ids = terrain.query(grid[:, :2] + [a1, y_sw])
    front = grid[:, 0] >= 0.0  # ankle to toe must rest on the tread; a heel may overhang
    above = np.isfinite(z_td) & (z_td > z_tread + 1e-9)
    if np.any(ids[front] != tread.surface_id) or np.any(above):
        going = float((nxt.point_w - riser.point_w) @ d) if nxt is not None else hi - lo
        raise ConfigError("tread_m", round(going, 4), "a tread that holds the foot from the ankle to the toe "
                          "under the nosing above it")  # fmt: skip

    h_stand = leg_length_for_knee(exo, STAND_KNEE_RAD)
    options = end_pelvis_options(exo, a1, z_tread, CLIMB_LEAN_RAD)
    if not options:
        raise ConfigError(
            "distance_m", distance_m, f"a first tread within one step's reach (ankle travel {a1:.3f} m at yaw {yaw_deg} deg is too long)"
        )
    t_lift, t_td = still_s, duration_s - settle_s
    sole_td = np.array([a1, y_sw, z_tread])
    fs = Footstep(side, t_lift, t_td, sole_td, 0.0, int(tread.surface_id))
    last = ""
    # the paper's parabola (no lag); the toes may point down mid-swing when a flat foot would
    # need more ankle dorsiflexion than the device allows
    for dip in np.radians([0.0, 15.0, 30.0]):
        plan = SwingPlan(
            stance=stance, A=A, stance_pitch=(0.0, 0.0), yaw=(0.0, 0.0), pitch=(0.0, CLIMB_LEAN_RAD),
            f=(0.0, 0.0), h=(h_stand, h_stand), a=(0.0, a1), z=(sole_h, z1), swing_pitch=(0.0, 0.0), dip=float(dip),
        )  # fmt: skip
        apex = swing_apex_m(exo, terrain, plan, clearance_m=clearance_m)
        for f1, h1 in options[:12]:  # the preferred end pose whose whole swing the legs can follow
            plan.f, plan.h = (0.0, f1), (h_stand, h1)
            segs = [
                still_segment(exo, plan, 0.0, t_lift, at_end=False),
                plan.segment(t_lift, t_td, apex),
                still_segment(exo, plan, t_td, duration_s, at_end=True),
            ]
            motion = Motion(
                exo, segs, events={"liftoff_s": t_lift, "touchdown_s": t_td}, footsteps=(fs,), stance_side=stance
            )
            try:
                check_feasible(motion)
            except GaitError as e:
                last = str(e)
                continue
            return motion
    raise ConfigError(
        "distance_m", distance_m, f"a first tread the {side} leg can step onto at yaw {yaw_deg} deg ({last})"
    )
