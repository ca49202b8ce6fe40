"""How a commanded swing of ``exobench/StairClimb-v0`` is planned and judged on the stairs.

:func:`belief_terrain` is what the controller assumes from the command and the feet alone (the
swing is planned over it); :func:`judge_swing` checks the swing on the true staircase. A
touch-down is *safe* when no sole point goes more than ``penetration_tol_m`` into the terrain
("collision"), the swing toe passes every nosing it crosses at least ``min_nosing_clearance_m``
above it ("scuff"), the sole from the ankle to the toe rests on one walkable surface
("no_foothold") and the foot lands at most ``max_drop_m`` above it ("drop").
:func:`placement_error_m` measures how far a landed foot is from the centre of its tread.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from exobench.core import PlanarSurface, SceneTruth

from ..motion import MotionState
from ..terrain import Terrain


@dataclass
class Outcome:
    """How a swing ended: safe or the failure (module docstring), what it touched, the margins."""

    safe: bool
    failure: str
    touched_surface_id: int
    penetration_m: float
    nosing_clearance_m: float
    drop_m: float


def belief_terrain(
    stance_sole_w: np.ndarray, x: np.ndarray, y: np.ndarray, swing_toe_w: np.ndarray, swing_support_z_m: float,
    stance_toe_m: float, target_sole_w: np.ndarray, heel_to_ankle_m: float,
) -> Terrain:  # fmt: skip
    """The terrain the swing planner assumes, from the command and the feet alone.

    Along the heading ``x`` (``y`` to its left) from the stance sole point: the swing foot's
    support up to its toe (``swing_toe_w``); from there to the stance toe (``stance_toe_m``
    ahead) the higher of the swing and stance supports; from there to the target's heel the
    higher of the stance support and the commanded target; then the commanded level. (Between
    two footholds a staircase is no higher than the higher of them.)
    """
    P = stance_sole_w
    s_sw = float((swing_toe_w - P) @ x)
    s_st = stance_toe_m
    s_tg = float((target_sole_w - P) @ x) - heel_to_ankle_m
    z_sw, z_st, z_tg = swing_support_z_m, float(P[2]), float(target_sole_w[2])
    eps, far = 1e-3, 5.0
    bands = [(-far, s_sw, z_sw), (s_tg, far, z_tg)]
    for s0, s1, zb in ((s_sw, s_st, max(z_sw, z_st)), (max(s_sw, s_st), s_tg, max(z_sw, z_st, z_tg))):
        if s1 - eps > s0 + eps:
            bands.append((s0 + eps, s1 - eps, zb))
    surfaces = []
    for i, (s0, s1, zb) in enumerate(bands):
        corners = [P + s * x + l * y for s, l in ((s0, -far), (s1, -far), (s1, far), (s0, far))]
        poly = np.array([[c[0], c[1], zb] for c in corners])
        surfaces.append(PlanarSurface(i, "ground", np.array([0.0, 0.0, 1.0]), poly.mean(axis=0), poly))
    return Terrain(SceneTruth(surfaces=tuple(surfaces), geom_surfaces={}))


def judge_swing(
    st: MotionState, swing: str, terrain: Terrain, surfaces: dict[int, PlanarSurface], grid: np.ndarray,
    toe_f: np.ndarray, sole_height_m: float, *, penetration_tol_m: float, min_nosing_clearance_m: float,
    max_drop_m: float,
) -> Outcome:  # fmt: skip
    """Safety of a swing (``st`` over the swing, the ``swing`` foot moving) on the true terrain:
    sole points ``grid`` and toe tip ``toe_f`` in the foot frame, the staircase's ``surfaces``."""
    pen = 0.0
    for side in ("l", "r"):
        pts = st.sole_points_w(side, grid).reshape(-1, 3)
        pen = max(pen, float(np.max(terrain.penetration(pts), initial=0.0)))
    toe = st.sole_points_w(swing, toe_f[None, :])[:, 0]
    clearance = float("inf")
    for s in surfaces.values():
        if s.kind != "riser":
            continue
        sd = (toe - s.point_w) @ s.normal_w  # > 0 on the walker's side of the riser
        top = float(np.max(s.polygon_w[:, 2]))
        for i in np.flatnonzero((sd[:-1] > 0.0) & (sd[1:] <= 0.0)):
            w = sd[i] / (sd[i] - sd[i + 1])
            clearance = min(clearance, float(toe[i, 2] + w * (toe[i + 1, 2] - toe[i, 2])) - top)
    end = st.sole_points_w(swing, grid)[-1]
    zt, ids = terrain.query(end[:, :2])
    sole_end = st.sole_points_w(swing, np.array([[0.0, 0.0, -sole_height_m]]))[-1, 0]
    touched = int(terrain.query(sole_end[None, :2])[1][0])
    front = grid[:, 0] >= 0.0
    supported = bool(ids[front][0] >= 0 and np.all(ids[front] == ids[front][0]))
    drop = float(np.max(end[front, 2] - zt[front])) if supported else 0.0  # < 0: slightly in (within tol)
    if pen > penetration_tol_m:
        failure = "collision"
    elif clearance < min_nosing_clearance_m:
        failure = "scuff"
    elif not supported:
        failure = "no_foothold"
    elif drop > max_drop_m:
        failure = "drop"
    else:
        failure = ""
    if supported:
        touched = int(ids[front][0])
    return Outcome(failure == "", failure, touched, pen, clearance, drop)


def placement_error_m(
    ends_w: np.ndarray, surface: PlanarSurface | None, T_world_stairs: np.ndarray, tread_m: float, heading_x: np.ndarray
) -> float:
    """Signed distance along the heading ``heading_x`` from the centre line of the tread (or of a
    virtual tread ``tread_m`` deep at the landing's front edge) to the foot centre (the midpoint
    of ``ends_w``: the landed sole point below the ankle and the toe tip), m; + beyond the centre;
    0 off the treads and landing. ``T_world_stairs``: the staircase frame, x up the flight."""
    if surface is None or surface.kind not in ("tread", "landing"):
        return 0.0
    R, o = T_world_stairs[:3, :3], T_world_stairs[:3, 3]
    lx = (surface.polygon_w - o) @ R[:, 0]
    lo, hi = float(lx.min()), float(lx.max())
    if surface.kind == "landing":
        hi = lo + tread_m
    c = float((ends_w.mean(axis=0) - o) @ R[:, 0])
    return (c - 0.5 * (lo + hi)) / float(heading_x @ R[:, 0])
