"""Terrain description from the tracked plane set and the locomotion mode of the next step
(seeds/002, II-F "Finally, we reconstruct representations of terrain information ...").

The paper builds T = {<tau, s, Gamma>} (type, terrain id, planes) from the existing plane set of
eq. 23: "Ramps and level grounds are extracted directly based on slope theta and area a, while
stairs are constructed iteratively from at least two planes with two preset thresholds, the
distance of centres d_ij = |c_i - c_j| and the vertical distance h_ij = |z_i - z_j|". Terrains are
hash tables (plane id -> terrain id, terrain id -> terrain) so a predicted footprint is projected
on the ground by a look-up. Here, in a gravity-aligned frame (z up):

- slope theta = arccos |n_z| of a plane's unit normal; a plane with theta <= ``level_max_slope_deg``
  is *horizontal*, one with ``level_max_slope_deg`` < theta <= ``ramp_max_slope_deg`` a *ramp*
  plane, steeper ones (risers, walls) are not walkable;
- stairs: the horizontal planes (area >= ``stair_min_area_m2``) are linked pairwise when
  d_ij <= ``stair_center_max_m`` and ``stair_rise_min_m`` <= h_ij <= ``stair_rise_max_m``
  (h_ij from the plane centres); every connected group of at least two planes (grown iteratively
  from a pair, as in the paper) is one stairs terrain;
- level ground: every other horizontal plane with area >= ``level_min_area_m2``;
- ramp: every ramp plane with area >= ``ramp_min_area_m2``;
- a terrain's id s is the smallest plane id in Gamma, so it stays while its planes are tracked.

Footprint projection: a walkable plane (of any terrain) *supports* (x, y) when some voxel of its
support (the ``cells`` of :mod:`plane_tracking`) that lies on the plane (see
:meth:`TerrainDescription.support_xy`) has its centre within ``support_margin_m`` of (x, y)
horizontally; of the supporting planes the one with the most such voxels within
``support_radius_m`` (then the highest) is the terrain under the point: near an edge, a few
voxels of one plane reach over the other one's area (cells straddling the edge), and the plane
that covers the neighbourhood wins. Two supporting planes that meet at a crease (normals more
than ``crease_min_angle_deg`` apart, both with a score of at least ``crease_min_score``: a ramp's
start or end) are told apart by their line of intersection instead, each plane owning the side
where most of its support lies [A]: at a shallow crease cells straddling it fit either plane,
so the supports overlap by up to 0.25 m, while the two plane equations place the crease within a
few centimetres. :meth:`TerrainDescription.crease_ahead`
moves a foot whose toes would be across such a crease onto the plane ahead (a flat foot does not
rest across a crease). With a known current plane, planes more than ``max_step_rise_m`` above or below the current
footprint are skipped (a table top, a floor seen down a stairwell).

Mode of the next step, "the terrain under the predicted footprint relative to the current one"
(:func:`predict_mode`), with T the plane under the predicted footprint and C the one under the
current footprint:

- T a ramp plane: RA when T rises from the current to the predicted footprint (along the walking
  direction), else RD;
- T horizontal, C horizontal: dz = z_T - z_C; SA if dz >= ``stair_rise_min_m``, SD if
  dz <= -``stair_rise_min_m``, else LG. A step between two horizontal planes that far apart is a
  stair step even when the lower one (a large floor, its centre far away) is not linked to the
  stairs by d_ij;
- T horizontal, C a ramp: LG (leaving the ramp); no plane under the current footprint: its
  height ``current_height_m`` if the caller knows it (e.g. measured before the foot left the
  view; reason ``"current_remembered"``), else LG, reason ``"current_unknown"``;
- no plane under the predicted footprint, but the first walkable plane beyond it along the
  walking direction (within ``drop_lookahead_m``) lies ``stair_rise_min_m`` or more below the
  current terrain: SD, reason ``"drop_ahead"`` [A]. A head or chest camera above a descending
  flight sees the floor beyond it, but the treads below its own level are hidden by the nosings
  (or out of the view of a camera looking ahead), so the footprint beyond the edge of the
  current level has no plane under it. If that first plane is a ramp whose extension passes
  under the predicted footprint below the current terrain by no more than
  ``ramp_max_slope_deg`` over the step (``cur`` -> ``nxt``): RD, reason ``"ramp_ahead"`` [A]. A
  head camera on a landing sees a ramp down only beyond the crest;
- otherwise no plane under the predicted footprint: the current terrain is assumed to continue
  (C a ramp: RA/RD along it; C horizontal, or no plane under it but its height given and not
  measured on a ramp: LG), reason ``"extrapolated"``; neither known: mode ``""``, reason
  ``"no_terrain"``.

The config, result types and per-plane geometry are in :mod:`.terrain_types`. Pure numpy.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .plane_tracking import PlaneSet, TrackedPlane, voxel_centers
from .terrain_types import (
    ModeDecision,
    Terrain,
    TerrainConfig,
    plane_class,
    plane_height_at,
    plane_heights_at,
)


@dataclass
class TerrainDescription:
    """The terrains of one plane set and the look-ups of the footprint projection.

    ``terrains``: terrain id -> :class:`Terrain`; ``terrain_of_plane``: plane id -> terrain id
    (walkable planes of some terrain only); ``planes``: plane id -> plane; ``plane_classes``:
    plane id -> class of every plane considered (score >= min_score).
    """

    config: TerrainConfig
    cell_m: float
    planes: dict[int, TrackedPlane]
    plane_classes: dict[int, str]
    terrains: dict[int, Terrain]
    terrain_of_plane: dict[int, int]
    _support_xy: dict[int, np.ndarray] = field(default_factory=dict, repr=False)
    _crease: dict[tuple[int, int], tuple[float, float]] = field(default_factory=dict, repr=False)

    def terrain_kind(self, plane_id: int | None) -> str | None:
        """Type of the terrain a plane belongs to (None if none)."""
        if plane_id is None or plane_id not in self.terrain_of_plane:
            return None
        return self.terrains[self.terrain_of_plane[plane_id]].kind

    def support_xy(self, plane_id: int) -> np.ndarray:
        """Horizontal positions (K, 2) of the voxel centres of a plane's support that lie on the
        plane: within 0.5 cell (|n_x| + |n_y| + |n_z|) + ``support_fit_tol_m`` of it (a voxel
        crossed by the plane has its centre that close; voxels of points of a neighbouring
        surface merged in at an edge lie farther)."""
        if plane_id not in self._support_xy:
            p = self.planes[plane_id]
            v = voxel_centers(p.cells, self.cell_m)
            n = np.asarray(p.normal, dtype=float)
            tol = 0.5 * self.cell_m * float(np.abs(n).sum()) + self.config.support_fit_tol_m
            on = np.abs((v - p.center_m) @ n) <= tol
            self._support_xy[plane_id] = v[on, :2]
        return self._support_xy[plane_id]

    def plane_under(self, xy: np.ndarray, ref_height_m: float | None = None) -> int | None:
        """Id of the walkable plane under (x, y), or None. The candidates are the planes with a
        support voxel within ``support_margin_m`` of (x, y) (and, given ``ref_height_m``, within
        ``max_step_rise_m`` of it). Two candidates that meet at a crease (normals more than
        ``crease_min_angle_deg`` apart) are told apart by the side of their line of
        intersection (x, y) lies on (:meth:`_crease_side`); otherwise, and when the sides do
        not decide, the one with the most support voxels within ``support_radius_m`` wins (then
        the highest at (x, y), then the lowest id)."""
        p = np.asarray(xy, dtype=float)[:2]
        c = self.config
        cands: list[tuple[tuple[int, float, int], int]] = []
        for pid in sorted(self.terrain_of_plane):
            sup = self.support_xy(pid)
            if sup.size == 0:
                continue
            d2 = (sup[:, 0] - p[0]) ** 2 + (sup[:, 1] - p[1]) ** 2
            if float(d2.min()) > c.support_margin_m ** 2:
                continue
            z = plane_height_at(self.planes[pid], p)
            if ref_height_m is not None and abs(z - ref_height_m) > c.max_step_rise_m:
                continue
            cands.append(((-int(np.count_nonzero(d2 <= c.support_radius_m ** 2)), -z, pid), pid))
        if not cands:
            return None
        cands.sort()
        if len(cands) > 1:
            # the candidate that is the surface at (x, y) against every other one: by the
            # crease side where they meet at one, else by the order above
            for i, (_, a) in enumerate(cands):
                if all((side := self._crease_side(a, b, p)) == a or (side is None and i < j)
                       for j, (_, b) in enumerate(cands) if j != i):
                    return a
        return cands[0][1]

    def _crease_side(self, a: int, b: int, p: np.ndarray) -> int | None:
        """Which of planes ``a``, ``b`` is the surface at (x, y) ``p`` when they meet at a crease:
        s(q) = z_a(q) - z_b(q) changes sign on their line of intersection, and each plane's
        support lies mostly on its own side (the median of s over its support voxels). The
        support of either plane reaches past the crease by up to a few cells (cells straddling
        it, merged into the plane they nearly fit at a shallow angle: at 11.8 deg, 0.25 m past
        the crest of a ramp the ramp plane is still within the support tolerance of the landing),
        while the planes' own equations place the crease within centimetres. None if the
        normals are within ``crease_min_angle_deg`` (parallel treads: no crease), either plane's
        score is below ``crease_min_score`` (a plane fitted once across a stair's nosings is no
        ramp to trust a crease with), or the supports do not lie on opposite sides."""
        pa, pb = self.planes[a], self.planes[b]
        if min(pa.score, pb.score) < self.config.crease_min_score:
            return None
        na, nb = np.asarray(pa.normal, dtype=float), np.asarray(pb.normal, dtype=float)
        cos = abs(float(na @ nb)) / max(float(np.linalg.norm(na) * np.linalg.norm(nb)), 1e-12)
        if cos >= np.cos(np.radians(self.config.crease_min_angle_deg)):
            return None
        key = (a, b)
        if key not in self._crease:
            sa, sb = self.support_xy(a), self.support_xy(b)
            self._crease[key] = (float(np.median(self._height_diff(a, b, sa))),
                                 float(np.median(self._height_diff(a, b, sb))))
        med_a, med_b = self._crease[key]
        if not (med_a * med_b < 0.0):
            return None
        s = float(self._height_diff(a, b, p[None, :])[0])
        return a if s * med_a > 0.0 else b

    def _height_diff(self, a: int, b: int, xy: np.ndarray) -> np.ndarray:
        """z_a - z_b at the points (K, 2)."""
        return plane_heights_at(self.planes[a], xy) - plane_heights_at(self.planes[b], xy)

    def tread_above(self, xy: np.ndarray, fwd_xy: np.ndarray, level_m: float, toe_m: float) -> np.ndarray | None:
        """Where a foot put down at ``xy`` (on the level ``level_m``, walking along ``fwd_xy``)
        goes when its toes, ``toe_m`` ahead, would be inside a riser: the point just past the
        riser on the horizontal plane above (``stair_rise_min_m`` or more higher), else None.
        A foot is not put down against a step up: the first step of a flight goes onto the
        tread (the walker lengthens it to centre the foot on the first tread)."""
        p = np.asarray(xy, dtype=float)[:2]
        d = np.asarray(fwd_xy, dtype=float)[:2]
        norm = float(np.hypot(d[0], d[1]))
        pid0 = self.plane_under(p)
        if norm < 1e-9 or pid0 is None or self.plane_classes[pid0] != "horizontal":
            return None
        d = d / norm
        z0 = plane_height_at(self.planes[pid0], p)
        if abs(z0 - level_m) > 0.5 * self.config.stair_rise_min_m:
            return None  # not a level step (on stairs already)
        for s in np.arange(0.02, toe_m + 1e-9, 0.02):
            q = p + s * d
            pid = self.plane_under(q)
            if pid is None or pid == pid0:
                continue
            up = plane_height_at(self.planes[pid], q) - z0
            if self.plane_classes[pid] == "horizontal" and up >= self.config.stair_rise_min_m:
                return q + 0.02 * d
            return None
        return None

    def crease_ahead(self, xy: np.ndarray, fwd_xy: np.ndarray, toe_m: float) -> np.ndarray | None:
        """Where a foot put down at ``xy`` (walking along ``fwd_xy``) goes when its toes,
        ``toe_m`` ahead, would be on another walkable plane that meets the one under ``xy`` at a
        crease (a ramp's start or end): the point just past the crease, else None. A flat foot
        does not rest across a crease (its heel or toes would be in the other plane): the step
        ends with the whole foot on the surface ahead."""
        p = np.asarray(xy, dtype=float)[:2]
        d = np.asarray(fwd_xy, dtype=float)[:2]
        norm = float(np.hypot(d[0], d[1]))
        pid0 = self.plane_under(p)
        if norm < 1e-9 or pid0 is None or toe_m <= 0.0:
            return None
        d = d / norm
        for s in np.arange(0.02, toe_m + 1e-9, 0.02):
            q = p + s * d
            pid = self.plane_under(q)
            if pid is None or pid == pid0:
                continue
            return q + 0.02 * d if self._crease_side(pid0, pid, q) is not None else None
        return None

    def mode_of_step(self, current_xy: np.ndarray, next_xy: np.ndarray,
                     current_height_m: float | None = None, current_class: str | None = None) -> ModeDecision:
        """Locomotion mode of the step from the current footprint to the predicted one.

        ``current_height_m``: terrain height under the current footprint known otherwise (e.g.
        measured before the foot left the view), used only when no plane lies under it; the
        reason is then ``"current_remembered"``; ``current_class`` the class of the plane it was
        measured on, if known (a foot that was on a ramp leaves it: LG)."""
        cur = np.asarray(current_xy, dtype=float)[:2]
        nxt = np.asarray(next_xy, dtype=float)[:2]
        c_id = self.plane_under(cur)
        if c_id is not None:
            z_c: float | None = plane_height_at(self.planes[c_id], cur)
        elif current_height_m is not None and np.isfinite(current_height_m):
            z_c = float(current_height_m)
        else:
            z_c = None
        n_id = self.plane_under(nxt, z_c)
        c_cls = current_class if c_id is None else self.plane_classes[c_id]
        c_kind, n_kind = self.terrain_kind(c_id), self.terrain_kind(n_id)
        if n_id is None:
            ahead = self._lower_ahead(cur, nxt, z_c)
            if ahead is not None:
                pid, drop = ahead
                z_ext = plane_height_at(self.planes[pid], nxt)
                reach = float(np.hypot(*(nxt - cur))) * np.tan(np.radians(self.config.ramp_max_slope_deg))
                if self.plane_classes[pid] == "ramp" and z_c is not None and \
                        z_c - reach <= z_ext <= z_c + self.config.support_fit_tol_m:
                    # the hidden start of a ramp down from here (beyond the crest, out of a head
                    # camera's view): its plane, seen farther on, passes under the footprint
                    # below the current level by no more than a ramp's slope allows
                    return ModeDecision("RD", "ramp_ahead", None, c_id, None, c_kind, z_ext - z_c)
                return ModeDecision("SD", "drop_ahead", None, c_id, None, c_kind, drop)
            if c_id is None:
                if z_c is not None and c_cls != "ramp":  # the level the foot stands on, known by height
                    return ModeDecision("LG", "extrapolated", None, None, None, None, float("nan"))
                return ModeDecision("", "no_terrain", None, None, None, None, float("nan"))
            mode = self._ramp_mode(c_id, cur, nxt) if c_cls == "ramp" else "LG"
            return ModeDecision(mode, "extrapolated", None, c_id, None, c_kind, float("nan"))
        z_n = plane_height_at(self.planes[n_id], nxt)
        dz = float("nan") if z_c is None else z_n - z_c
        reason = "ok" if c_id is not None else ("current_remembered" if z_c is not None else "current_unknown")
        if self.plane_classes[n_id] == "ramp":
            return ModeDecision(self._ramp_mode(n_id, cur, nxt), reason, n_id, c_id, n_kind, c_kind, dz)
        mode = "LG"
        if c_cls in ("horizontal", None) and z_c is not None:
            if dz >= self.config.stair_rise_min_m:
                mode = "SA"
            elif dz <= -self.config.stair_rise_min_m:
                mode = "SD"
        return ModeDecision(mode, reason, n_id, c_id, n_kind, c_kind, dz)

    def _lower_ahead(self, cur: np.ndarray, nxt: np.ndarray, z_c: float | None) -> tuple[int, float] | None:
        """(plane id, height change) of the first walkable plane found beyond ``nxt`` along the
        walking direction (``cur`` -> ``nxt``, up to ``drop_lookahead_m``, steps of
        ``support_margin_m``) if it lies ``stair_rise_min_m`` or more below ``z_c``; else None.
        Used when no plane lies under ``nxt``: a camera above a descending flight sees the floor
        beyond it but hardly the treads below its own (nosings hide them), so the footprint
        beyond the edge of the current level with lower ground ahead is a step down
        ("drop_ahead"); a head camera on a landing sees a ramp down only beyond the crest, so
        a ramp plane found ahead whose extension passes under the footprint, below the current
        level by no more than a ramp's slope over the step, makes it RD ("ramp_ahead")."""
        c = self.config
        if z_c is None or c.drop_lookahead_m <= 0.0:
            return None
        d = nxt - cur
        norm = float(np.hypot(d[0], d[1]))
        if norm < 1e-9:
            return None
        d = d / norm
        step = max(c.support_margin_m, 1e-3)
        for s in np.arange(step, c.drop_lookahead_m + 0.5 * step, step):
            q = nxt + s * d
            pid = self.plane_under(q)  # the floor below a whole flight may lie beyond max_step_rise_m
            if pid is None:
                continue
            dz = plane_height_at(self.planes[pid], q) - z_c
            return (pid, dz) if dz <= -c.stair_rise_min_m else None
        return None

    def _ramp_mode(self, plane_id: int, cur: np.ndarray, nxt: np.ndarray) -> str:
        """RA when the ramp plane rises from ``cur`` to ``nxt``, else RD."""
        plane = self.planes[plane_id]
        return "RA" if plane_height_at(plane, nxt) - plane_height_at(plane, cur) >= 0.0 else "RD"


def describe_terrain(plane_set: PlaneSet, config: TerrainConfig | None = None) -> TerrainDescription:
    """The terrain description T of the current plane set (module docstring)."""
    c = config or TerrainConfig()
    planes = {pid: p for pid, p in sorted(plane_set.planes.items()) if p.score >= c.min_score}
    classes = {pid: plane_class(p.normal, c) for pid, p in planes.items()}
    horiz = [pid for pid in planes if classes[pid] == "horizontal"]

    # stairs: link horizontal planes pairwise by d_ij and h_ij, grow groups (union-find)
    cand = [pid for pid in horiz if planes[pid].area_m2 >= c.stair_min_area_m2]
    parent = {pid: pid for pid in cand}

    def find(i: int) -> int:
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    for a_i, a in enumerate(cand):
        for b in cand[a_i + 1:]:
            ca, cb = planes[a].center_m, planes[b].center_m
            d = float(np.linalg.norm(ca - cb))
            h = abs(float(ca[2] - cb[2]))
            if d <= c.stair_center_max_m and c.stair_rise_min_m <= h <= c.stair_rise_max_m:
                ra, rb = find(a), find(b)
                if ra != rb:
                    parent[max(ra, rb)] = min(ra, rb)
    groups: dict[int, list[int]] = {}
    for pid in cand:
        groups.setdefault(find(pid), []).append(pid)

    terrains: dict[int, Terrain] = {}
    of_plane: dict[int, int] = {}
    for members in groups.values():
        if len(members) < 2:
            continue
        tid = min(members)
        ordered = tuple(sorted(members, key=lambda i: (float(planes[i].center_m[2]), i)))
        terrains[tid] = Terrain("stairs", tid, ordered)
        for pid in members:
            of_plane[pid] = tid
    for pid, p in planes.items():
        if pid in of_plane:
            continue
        if classes[pid] == "horizontal" and p.area_m2 >= c.level_min_area_m2:
            terrains[pid] = Terrain("level", pid, (pid,))
            of_plane[pid] = pid
        elif classes[pid] == "ramp" and p.area_m2 >= c.ramp_min_area_m2:
            terrains[pid] = Terrain("ramp", pid, (pid,))
            of_plane[pid] = pid
    terrains = dict(sorted(terrains.items()))
    return TerrainDescription(c, plane_set.config.cell_m, planes, classes, terrains, of_plane)


def predict_mode(plane_set: PlaneSet, next_xy: np.ndarray, current_xy: np.ndarray,
                 config: TerrainConfig | None = None, current_height_m: float | None = None) -> ModeDecision:
    """Mode of the next step: the terrain under the predicted footprint ``next_xy`` relative to
    the one under the current footprint ``current_xy`` (module docstring)."""
    return describe_terrain(plane_set, config).mode_of_step(current_xy, next_xy, current_height_m)
