"""Procedural office floor for the LiDAR track: ``mujoco.MjSpec`` + exact ground truth + routes.

``build_office(OfficeParams(...))`` lays out (:mod:`office_layout`) offices along a corridor,
a meeting room and a blank service core between two long corridors joined at both ends,
with plaster or glass partitions, doors, windows, polished or carpeted floors and furniture
(:mod:`office_furniture`), and returns a :class:`~exobench.models.worlds.BuiltWorld` whose
truth (kind ``"office"``) lists:

- ``surfaces``: every floor and ceiling area and the exposed part of every box face
  (:mod:`office_truth`), kinds ``ground``, ``ceiling``, ``wall``, ``glass``, ``frame``
  (mullions, head rails), ``door`` (wooden leaves) and ``furniture``;
- ``geom_surfaces`` and ``geom_materials`` for every world geom (LiDAR materials of
  :mod:`exobench.models.materials`);
- ``objects``: desks, chairs, couches, cabinets, plants, bins, doors, glass partitions and
  windows with class, ``T_world_object`` (origin at the bottom centre, x along the width,
  y from back to front), ``size_m`` (width, depth, height) and ``geom_names``;
- ``params``: the parameters plus ``start_w`` (where :func:`~exobench.models.worlds.compose`
  stands the walker, at the west end of the north corridor, facing +x), ``routes``,
  ``regions`` (floor areas with their floor material), ``solids`` (every primitive, for
  sampling and inside tests), ``featureless_x_m`` (the blank stretch of the south corridor),
  ``corridor_y_m`` and ``T_world_local`` (identity).

:func:`office_route` returns the walking routes, :func:`sample_surface_points` dense points on
all surfaces for map scoring. All geoms are boxes, planes, cylinders and spheres (exact in
double precision); :mod:`office_look` gives them their materials.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from exobench.core.errors import ConfigError, UnknownNameError, check_int
from exobench.core.truth import SceneTruth

from .furniture_kinds import LAB_CLASSES, OBSTACLE_CLASSES
from .materials import MATERIALS as LIDAR_MATERIALS
from .office_changes import MAX_DAY, ChangeScript, apply_changes
from .office_furniture import CLASSES as FURNITURE_CLASSES
from .office_layout import Layout, build_layout
from .office_look import add_office_materials
from .office_params import OFFICE_PARAMS, OfficeParams
from .office_truth import office_surfaces, points_inside_solids, sample_surface, sample_surface_points
from .world_look import add_lights, set_visual
from .worlds import WORLD_GEOM_GROUP, BuiltWorld

if TYPE_CHECKING:
    import mujoco

OBJECT_CLASSES = FURNITURE_CLASSES + ("door", "glass_partition", "window") + LAB_CLASSES + OBSTACLE_CLASSES
SURFACE_KINDS = ("ground", "ceiling", "wall", "glass", "frame", "door", "furniture")
ROUTE_KINDS = ("loop", "ring", "corridor")


def _emit(spec: mujoco.MjSpec, layout: Layout) -> None:
    import mujoco

    types = {"box": mujoco.mjtGeom.mjGEOM_BOX, "plane": mujoco.mjtGeom.mjGEOM_PLANE,
             "cylinder": mujoco.mjtGeom.mjGEOM_CYLINDER, "sphere": mujoco.mjtGeom.mjGEOM_SPHERE}
    wb = spec.worldbody
    for s in layout.solids:
        if s.material not in LIDAR_MATERIALS:
            raise ValueError(f"solid {s.name} has unknown material {s.material}")
        if s.shape == "box":
            size = list(s.half)
        elif s.shape == "plane":
            size = [s.half[0], s.half[1], 0.05]
        elif s.shape == "cylinder":
            size = [s.half[0], s.half[2], 0.0]
        else:
            size = [s.half[0], 0.0, 0.0]
        wb.add_geom(name=s.name, type=types[s.shape], pos=list(s.centre), size=size, material=s.look,
                    quat=[1.0, 0.0, 0.0, 0.0] if s.up else [0.0, 1.0, 0.0, 0.0], group=WORLD_GEOM_GROUP)


def build_office(params: OfficeParams | None = None, changes: ChangeScript | None = None, day: int = 0) -> BuiltWorld:
    """The office of ``params`` (defaults if None): spec with materials and lights, and its truth.

    With a change script, the office of ``day``: the furniture after the changes of days
    1..``day`` (:mod:`office_changes`; the whole script is validated first, and an invalid one
    raises ``ChangeScriptError`` naming the day and the object); the truth's params then hold
    ``day`` and ``changes`` (the script's compact form).
    """
    import mujoco

    p = params or OfficeParams()
    day = check_int("day", day, 0, MAX_DAY)
    layout = build_layout(p)
    if changes is not None:
        layout = layout.with_furniture(apply_changes(layout, changes, day)[day])
    spec = mujoco.MjSpec()
    spec.modelname = "exobench_office"
    add_office_materials(spec)
    set_visual(spec)
    _emit(spec, layout)
    x0, x1, y0, y1 = layout.extent
    ym = 0.5 * (y0 + y1)
    # two shadow-casting ceiling spots 10 cm under the ceiling, and the "window" light
    add_lights(spec, np.array([x0, ym, 0.0]), np.array([x1, ym, 0.0]), p.ceiling_m - 3.3)

    surfaces, geom_surfaces = office_surfaces(layout.solids, p.ceiling_m, layout.extent)
    values = p.as_dict()
    values.update({
        "T_world_local": np.eye(4).tolist(),
        "start_w": layout.start_w,
        "top_z_m": 0.0,
        "routes": layout.routes,
        "regions": layout.regions,
        "solids": [s.as_dict() for s in layout.solids],
        "featureless_x_m": layout.featureless_x_m,
        "corridor_y_m": layout.corridor_y_m,
        "extent_m": list(layout.extent),
    })
    if changes is not None:
        values.update({"day": day, "changes": changes.compact()})
    truth = SceneTruth(surfaces=tuple(surfaces), geom_surfaces=geom_surfaces, params=values, kind="office",
                       geom_materials={s.name: s.material for s in layout.solids}, objects=tuple(layout.objects))
    return BuiltWorld(spec=spec, truth=truth)


def office_route(truth: SceneTruth, kind: str = "loop") -> list[tuple[float, float]]:
    """Waypoints (x, y) on the floor of an office; straight walking between consecutive ones is free.

    ``"loop"``: from the start round the corridor ring, into every office and out again, back
    to the start (a loop closure), then a second lap through the meeting room's two doors and
    back along the featureless corridor to the start. ``"ring"``: once round the corridor ring,
    back to the start (a short loop). ``"corridor"``: the whole south corridor,
    blank-walled along the service core (``params["featureless_x_m"]``), where LiDAR odometry
    slides.
    """
    if truth.kind != "office":
        raise ConfigError("truth.kind", truth.kind, "a truth built by build_office ('office')")
    if kind not in ROUTE_KINDS:
        raise UnknownNameError("office route", kind, ROUTE_KINDS)
    return [(float(x), float(y)) for x, y in truth.params["routes"][kind]]


def surface_material(truth: SceneTruth, surface_id: int) -> str:
    """LiDAR material (:data:`exobench.models.materials.MATERIALS`) of a surface: that of its geom."""
    return truth.geom_materials[truth.surface(surface_id).geom_names[0]]


__all__ = [
    "OBJECT_CLASSES",
    "OFFICE_PARAMS",
    "OfficeParams",
    "ROUTE_KINDS",
    "SURFACE_KINDS",
    "build_office",
    "office_route",
    "points_inside_solids",
    "sample_surface",
    "sample_surface_points",
    "surface_material",
]
