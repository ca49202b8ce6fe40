"""The stairwell around a stair or ramp course (``enclosure="stairwell"``): end walls and a ceiling.

The paper's generality, disturbance and unconventional-view trials were indoors (seeds/002,
Sec. III-B, IV-C): a head camera pitched up at the top of a flight or over a side wall sees the
stairwell's end wall or its ceiling, textured and within the D455's range, never sky. The course
of :func:`~.course_world.build_locomotion_world` has side walls only (``walls``); this module
closes it:

- the side walls are continued :data:`END_M` beyond each end of the course's level floor (the
  walk starts and stops 0.4 m inside those ends, so the walker faces a wall 1.4 m ahead when it
  stops, as at the end of a corridor, rather than 0.4 m);
- an end wall across each end, as thick and as tall as the side walls
  (:data:`~exobench.models.terrain.WALL_THICKNESS_M`, up to the ceiling);
- a flat ceiling slab over all of it whose underside is where the side walls end, the highest
  walking surface (the landing) plus :data:`~exobench.models.terrain.WALL_CLEARANCE_M` = 2.4 m:
  2.4 m of headroom over the landing and the top of each flight, 2.8-3.4 m over the floor below
  (the paper's risers and ramps). Codes ask at least 2032 mm (80 in) of headroom over stairs
  (IBC 1011.3) and a ceiling of 2286 mm (7 ft 6 in) over a means of egress (IBC 1003.2); a
  storey is 2.5-3 m;
- the two ceiling spots of the course (:func:`exobench.models.world_look.add_lights`, 3.2 m over
  the top, so above the ceiling and shadowed by it) hang 0.1 m under the ceiling, as the office's
  do; the directional light casts no shadow and still lights the inside (a window).

The walls and the ceiling are plaster boxes of the course's wall material, so the courses' look
(``surfaces="textured"``) hangs posters on the end walls and their side-wall continuations as on
the side walls; the ceiling is plaster. Their inner faces are added to the scene truth (kinds
``wall`` and ``ceiling``, ids after the course's) so that depth and LiDAR hits on them are
labelled; no walkable surface is added or changed, and the walk is planned on the open course,
so the footprints, the steps and their modes are the open course's bit for bit.
"""

from __future__ import annotations

import numpy as np

from exobench.core.transforms import matrix_to_quat_wxyz
from exobench.core.truth import PlanarSurface, SceneTruth
from exobench.models.terrain import WALL_CLEARANCE_M, WALL_THICKNESS_M
from exobench.models.world_look import MATERIALS
from exobench.models.worlds import WORLD_GEOM_GROUP, BuiltWorld

END_M = 1.0  # the side walls run on this far beyond each end of the course's floor, to the end walls [A]
SPOT_BELOW_CEILING_M = 0.1  # the ceiling spots hang this far under it (as the office's)
SPOTS = ("world_spot0", "world_spot1")
PREFIX = "stairwell_"


def _rect(axis: int, value: float, lo: tuple[float, float], hi: tuple[float, float], normal: np.ndarray) -> np.ndarray:
    """Corners (4, 3) of an axis-aligned rectangle at coordinate ``axis`` = ``value``, spanning
    ``lo``..``hi`` in the two other axes (in order), counter-clockwise seen from ``normal``."""
    others = [a for a in range(3) if a != axis]
    pts = []
    for u, v in ((lo[0], lo[1]), (hi[0], lo[1]), (hi[0], hi[1]), (lo[0], hi[1])):
        p = np.zeros(3)
        p[axis], p[others[0]], p[others[1]] = value, u, v
        pts.append(p)
    poly = np.array(pts)
    if float(np.cross(poly[1] - poly[0], poly[2] - poly[1]) @ normal) < 0.0:
        poly = poly[::-1].copy()
    return poly


def stairwell_boxes(truth: SceneTruth, width_m: float) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """name -> (centre, half sizes) in the course's local frame of the stairwell's boxes: the side
    walls' continuations, the end walls and the ceiling (module docstring)."""
    prof = truth.params["profile"]
    xs = float(prof[0]["x0"])
    xe = float(prof[-1]["x1"])
    top = float(truth.params["top_z_m"])
    W, T = 0.5 * width_m, WALL_THICKNESS_M
    zc = top + WALL_CLEARANCE_M  # the ceiling's underside: the side walls' top
    x0, x1 = xs - END_M, xe + END_M  # the end walls' inner faces
    out: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    for side, sgn in (("l", 1.0), ("r", -1.0)):
        yc = sgn * (W + 0.5 * T)
        out[f"{PREFIX}wall_{side}_start"] = (np.array([0.5 * (x0 + xs), yc, 0.5 * zc]), np.array([0.5 * END_M, 0.5 * T, 0.5 * zc]))
        out[f"{PREFIX}wall_{side}_end"] = (np.array([0.5 * (xe + x1), yc, 0.5 * zc]), np.array([0.5 * END_M, 0.5 * T, 0.5 * zc]))
    for end, xc in (("start", x0 - 0.5 * T), ("end", x1 + 0.5 * T)):
        out[f"{PREFIX}end_{end}"] = (np.array([xc, 0.0, 0.5 * zc]), np.array([0.5 * T, W + T, 0.5 * zc]))
    out[f"{PREFIX}ceiling"] = (np.array([0.5 * (x0 + x1), 0.0, zc + 0.5 * T]), np.array([0.5 * (x1 - x0) + T, W + T, 0.5 * T]))
    return out


def _inner_faces(boxes: dict[str, tuple[np.ndarray, np.ndarray]], width_m: float) -> list[tuple[str, str, np.ndarray, np.ndarray]]:
    """(geom, kind, normal, polygon) in the local frame of the faces seen from inside."""
    W = 0.5 * width_m
    out = []
    for name, (c, h) in boxes.items():
        lo, hi = c - h, c + h
        if name.endswith("ceiling"):
            n = np.array([0.0, 0.0, -1.0])
            out.append((name, "ceiling", n, _rect(2, lo[2], (lo[0], max(lo[1], -W)), (hi[0], min(hi[1], W)), n)))
        elif "_end_" in name:
            inward = 1.0 if name.endswith("start") else -1.0
            n = np.array([inward, 0.0, 0.0])
            x = hi[0] if inward > 0 else lo[0]
            out.append((name, "wall", n, _rect(0, x, (-W, lo[2]), (W, hi[2]), n)))
        else:
            inward = -1.0 if c[1] > 0 else 1.0
            n = np.array([0.0, inward, 0.0])
            y = lo[1] if inward < 0 else hi[1]
            out.append((name, "wall", n, _rect(1, y, (lo[0], lo[2]), (hi[0], hi[2]), n)))
    return out


def enclose_stairwell(world: BuiltWorld, width_m: float) -> BuiltWorld:
    """``world`` (a stair or ramp course with side walls, :func:`~.course_world.build_locomotion_world`)
    inside its stairwell (module docstring): a new spec and truth; ``world`` is not changed."""
    import mujoco

    spec = world.spec.copy()
    T = np.asarray(world.T_world_local, dtype=float)
    R, t = T[:3, :3], T[:3, 3]
    boxes = stairwell_boxes(world.truth, width_m)
    q = list(matrix_to_quat_wxyz(R))
    for name, (c, h) in boxes.items():
        spec.worldbody.add_geom(name=name, type=mujoco.mjtGeom.mjGEOM_BOX, pos=list(R @ c + t), quat=q, size=list(h),
                                material=MATERIALS["wall"], group=WORLD_GEOM_GROUP)
    zc = float(boxes[f"{PREFIX}ceiling"][0][2] - boxes[f"{PREFIX}ceiling"][1][2]) + float(t[2])
    for light in spec.worldbody.find_all(mujoco.mjtObj.mjOBJ_LIGHT):
        if light.name in SPOTS:
            light.pos = [float(light.pos[0]), float(light.pos[1]), zc - SPOT_BELOW_CEILING_M]
    tr = world.truth
    surfaces = list(tr.surfaces)
    geom_surfaces = {k: list(v) for k, v in tr.geom_surfaces.items()}
    sid = 1 + max(s.surface_id for s in surfaces)
    for name, kind, n, poly in _inner_faces(boxes, width_m):
        poly_w = poly @ R.T + t
        surfaces.append(PlanarSurface(surface_id=sid, kind=kind, normal_w=R @ n, point_w=poly_w.mean(axis=0),
                                      polygon_w=poly_w, geom_names=(name,)))
        geom_surfaces.setdefault(name, []).append(sid)
        sid += 1
    params = {**tr.params, "enclosure": "stairwell", "ceiling_z_m": zc}
    truth = SceneTruth(surfaces=tuple(surfaces), geom_surfaces={k: tuple(v) for k, v in geom_surfaces.items()},
                       params=params, kind=tr.kind, geom_materials=dict(tr.geom_materials), objects=tr.objects)
    return BuiltWorld(spec=spec, truth=truth, T_world_local=world.T_world_local)
