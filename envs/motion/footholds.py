"""Footholds of the walker: where a foot can stand, which one the next step takes, and how the
last steps before a transition are regulated.

A placement is a *foothold* when the sole from the ankle to the toe rests on one walkable
surface (the heel may overhang a lower one, as on stairs) with the foot pitched along it and no
roll; only when no such foothold can be reached, the toes beyond the ball of the foot
(``BALL_FRACTION``) may overhang a lower one too (treads shorter than the foot, on the way
down). On level ground and ramps the nominal step is kept when it is a foothold at about the
same level; otherwise (a riser or a slope change ahead) the foot goes to the next surface
ahead, centred on it if it is a tread, at the nominal length clamped into it otherwise.
``step-over`` puts each foot on the next tread; ``step-to`` brings the trailing foot beside the
leading one before the next tread (:func:`choose_footholds`). Before a transition the step
length may be regulated over the last steps (:func:`approach_step`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from exobench.core import SceneTruth
from exobench.models.exo_spec import ExoSpec

from ..terrain import Terrain
from .kinematics import sole_grid_f
from .route import Route

BALL_FRACTION = 0.73  # ball of the foot (metatarsal heads) from the heel, fraction of the foot length [A]
# Approach regulation (Route.approach_steps, see approach_step) [A]
APPROACH_RANGE = (0.75, 1.25)  # regulated step lengths, fractions of the nominal step
APPROACH_DOWN_MAX = 1.1  # ... at most this onto a ramp going down
ONTO_MARGIN_M = 0.10  # the first foot on a ramp, landing or floor lands this far beyond its first foothold if it can
EDGE_BAND_M = 0.05  # before a flight (up or down) the last foot on the level lands with its toes this close to the edge
TREAD_RUN_M = 0.25  # a run of footholds shorter than this is a tread: the foot is centred on it


@dataclass
class Foot:
    """A foot at rest: its ankle (world), toes-up sole pitch and the surface it stands on."""

    ankle: np.ndarray  # world (3,)
    pitch: float
    surface: int


class Footholds:
    """Where a foot can stand in the world of ``truth``: the foothold rule (module docstring)."""

    def __init__(self, exo: ExoSpec, truth: SceneTruth) -> None:
        self.exo, self.truth = exo, truth
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

    def foothold(self, sole_xy: np.ndarray, yaw: float, overhang: bool = False) -> tuple[Foot, float] | None:
        """The foot placed with its sole point at ``sole_xy`` and heading ``yaw``, or None.

        ``overhang``: only placements whose toes overhang a lower surface (or nothing) beyond the
        ball of the foot, the rest of the sole from the ankle on the surface.
        """
        return self.footholds(np.asarray(sole_xy, dtype=float)[None, :2], yaw, overhang)[0]

    def footholds(self, soles_xy: np.ndarray, yaw: float, overhang: bool = False) -> list[tuple[Foot, float] | None]:
        """:meth:`foothold` of each sole point (M, 2), with two terrain queries in all instead of two
        per point: the planner scans a hundred placements along the heading at each step, and the
        queries' fixed cost was most of its time. Each point's answer is the one it has alone
        (the terrain answers every point by itself)."""
        soles_xy = np.asarray(soles_xy, dtype=float)
        z, sid = self.terrain.query(soles_xy)
        x = np.array([np.cos(yaw), np.sin(yaw), 0.0])
        y = np.array([-np.sin(yaw), np.cos(yaw), 0.0])
        out: list[tuple[Foot, float] | None] = [None] * len(soles_xy)
        placed = []  # (row, sole point, the foot's up axis, pitch, the sole grid's points)
        for i in np.flatnonzero(sid >= 0):
            n = self.normals[int(sid[i])]
            if abs(float(n @ y)) > np.sin(np.radians(3.0)):
                continue  # the foot cannot roll
            pitch = float(np.arctan2(-(n @ x), n[2]))
            zf = np.array([-np.sin(pitch) * x[0], -np.sin(pitch) * x[1], np.cos(pitch)])
            xf = np.array([np.cos(pitch) * x[0], np.cos(pitch) * x[1], np.sin(pitch)])
            sole = np.array([soles_xy[i, 0], soles_xy[i, 1], z[i]])
            pts = sole + np.outer(self.grid[:, 0], xf) + np.outer(self.grid[:, 1], y)
            placed.append((int(i), sole, zf, pitch, pts))
        if not placed:
            return out
        tz_all, tid_all = self.terrain.query(np.concatenate([p[4][:, :2] for p in placed]))
        g = len(self.grid)
        for k, (i, sole, zf, pitch, pts) in enumerate(placed):
            tz, tid = tz_all[k * g:(k + 1) * g], tid_all[k * g:(k + 1) * g]
            if np.any(np.isfinite(tz) & (tz > pts[:, 2] + 1e-6)):
                continue
            whole = not np.any(tid[self.front] != sid[i])
            if whole == overhang or (overhang and np.any(tid[self.to_ball] != sid[i])):
                continue
            ankle = sole + self.exo.sole_height_m * zf
            out[i] = (Foot(ankle, pitch, int(sid[i])), float(z[i]))
        return out

    def place(self, A: np.ndarray, sg: float, yaw: float, a: float, overhang: bool = False) -> tuple[Foot, float] | None:
        """:meth:`foothold` of the swing foot ``a`` ahead of the stance ankle ``A`` along the
        heading ``yaw``, one hip width beside it (``sg`` +1 for a left stance)."""
        return self.place_all(A, sg, yaw, np.array([a], dtype=float), overhang)[0]

    def place_all(self, A: np.ndarray, sg: float, yaw: float, a: np.ndarray, overhang: bool = False) -> list[tuple[Foot, float] | None]:
        """:meth:`place` at each of the distances ``a`` (M,), in one :meth:`footholds` call."""
        x = np.array([np.cos(yaw), np.sin(yaw)])
        y = np.array([-np.sin(yaw), np.cos(yaw)])
        return self.footholds(A[:2] + np.asarray(a, dtype=float)[:, None] * x - sg * self.w * y, yaw, overhang)


def choose_footholds(
    pl: Footholds, route: Route, A: np.ndarray, sg: float, yaw: float, a_nom: float,
    feet: dict[str, Foot], stance: str, swing: str, final: bool, overhang: bool = False,
) -> list[tuple[Foot, float]]:  # fmt: skip
    """Footholds for the swing foot with their distance ``a`` ahead of the stance ankle, best first
    (with ``overhang``: only those with the toes over a lower surface, see :meth:`Footholds.foothold`)."""
    S_A = feet[stance].surface
    z_A = float(A[2])
    trailing_low = abs(float(feet[swing].ankle[2]) - z_A) > 0.05
    if not final and not (route.stairs == "step-to" and trailing_low):
        got = pl.place(A, sg, yaw, a_nom, overhang)  # the nominal step, when it lands at about the same level
        if got is not None and abs(got[0].ankle[2] - z_A) <= 0.03 + abs(a_nom) * np.tan(np.radians(25.0)):
            return [(got[0], a_nom)]
    grid = np.round(np.arange(-0.15, max(0.8, 2.0 * route.step_length_m) + 1e-9, 0.01), 6)
    cands: list[tuple[float, Foot]] = []
    for a, got in zip(grid, pl.place_all(A, sg, yaw, grid, overhang)):
        if got is not None and abs(got[0].ankle[2] - z_A) <= 0.35:
            cands.append((float(a), got[0]))

    def nearest(target: float, pool: list[tuple[float, Foot]]) -> list[tuple[Foot, float]]:
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
    out: list[tuple[Foot, float]] = []
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


def approach_step(
    pl: Footholds, route: Route, A: np.ndarray, sg: float, yaw: float, a_nom: float,
    feet: dict[str, Foot], stance: str, swing: str, under_way: tuple[int, int] | None = None,
) -> tuple[float, tuple[int, int] | None]:  # fmt: skip
    """The step length regulated towards the next transition ahead, or ``a_nom``,
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
    got = pl.place_all(A, sg, yaw, grid)
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
