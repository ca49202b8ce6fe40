"""World builders: staircases, ramps, courses and level floors as ``mujoco.MjSpec`` + exact ground truth.

Each builder validates its parameters (:mod:`exobench.models.world_params`), lays out a profile
along a local x axis (:mod:`exobench.models.terrain`), places it in the world by ``yaw_deg`` and
``position_m``, and returns a :class:`BuiltWorld`: the spec (world geoms in group 0, materials,
lights, skybox) and a :class:`~exobench.core.truth.SceneTruth` listing every exposed planar face
as a :class:`~exobench.core.truth.PlanarSurface`. :func:`compose` adds the exoskeleton and
compiles.

Local frame of every route: x forward along the walking direction, y to the left, z up, the
floor at z = 0; ``T_world_local`` = translation ``(position_m, 0)`` @ rotation ``yaw_deg``
about z. Surface ids: the walking surfaces in walking order (0 the surface the walker starts on,
then risers/ramps and treads/landings alternately), then nosing faces, lateral faces, end faces,
floor strips nobody walks on, walls. ``truth.params`` also holds ``T_world_local`` (4x4 list),
``profile`` (the route in local coordinates) and ``start_w`` (a standing point on surface 0).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from exobench.core.errors import ConfigError, UnknownNameError
from exobench.core.transforms import make_T, matrix_to_quat_wxyz, rot_y, rot_z
from exobench.core.truth import PlanarSurface, SceneTruth

from .exo_spec import ExoSpec
from .terrain import Flat, Item, Riser, Slope, Terrain, build_profile
from .world_look import MATERIALS, add_lights, add_materials, set_visual
from .world_params import (
    PARAM_CLASSES,
    PARAMS,
    CourseParams,
    LevelParams,
    ParamSpec,
    RampParams,
    StaircaseParams,
)

if TYPE_CHECKING:
    import mujoco

WORLD_GEOM_GROUP = 0
# geomgroup argument of mujoco.mj_ray / mj_multiRay that sees the world and not the exoskeleton
RAY_GEOMGROUP_WORLD = (1, 0, 0, 0, 0, 0)
APPROACH_M = 3.0  # floor before an 'up' staircase or ramp, and after a 'down' one
START_BACK_M = 1.0  # suggested start: this far before the first transition, on surface 0


@dataclass
class BuiltWorld:
    """A world ready to receive the exoskeleton: its spec, its ground truth, its placement."""

    spec: mujoco.MjSpec
    truth: SceneTruth
    T_world_local: np.ndarray = field(default_factory=lambda: np.eye(4))


@dataclass
class CompiledScene:
    """A compiled world with the exoskeleton in it (see :func:`compose`)."""

    model: mujoco.MjModel
    truth: SceneTruth
    exo: ExoSpec
    spec: mujoco.MjSpec | None = None


def _T_world_local(yaw_deg: float, position_m: tuple[float, float]) -> np.ndarray:
    return make_T(rot_z(math.radians(yaw_deg)), np.array([position_m[0], position_m[1], 0.0]))


def _profile_dicts(terrain: Terrain) -> list[dict[str, Any]]:
    out = []
    for i, (it, (z0, z1)) in enumerate(zip(terrain.items, terrain.heights)):
        if isinstance(it, Flat):
            out.append({"kind": "flat", "surface_id": i, "x0": it.x0, "x1": it.x1, "z": it.z, "surface_kind": it.kind})
        elif isinstance(it, Riser):
            out.append({"kind": "riser", "surface_id": i, "x": it.x, "z0": z0, "z1": z1, "nosing_m": it.nosing_m})
        else:
            out.append({"kind": "slope", "surface_id": i, "x0": it.x0, "x1": it.x1, "z0": z0, "z1": z1})
    return out


def _world_from_terrain(terrain: Terrain, T: np.ndarray, kind: str, params: dict[str, Any]) -> BuiltWorld:
    """Emit geoms, look and truth of a terrain placed at ``T`` (= T_world_local)."""
    import mujoco

    R, t = T[:3, :3], T[:3, 3]
    spec = mujoco.MjSpec()
    spec.modelname = f"exobench_{kind}"
    add_materials(spec)
    set_visual(spec)
    wb = spec.worldbody
    fx0, fx1 = terrain.floor_x
    wb.add_geom(name="floor", type=mujoco.mjtGeom.mjGEOM_PLANE, pos=list(R @ np.array([0.5 * (fx0 + fx1), 0.0, 0.0]) + t),
                quat=list(matrix_to_quat_wxyz(R)), size=[0.5 * (fx1 - fx0), terrain.floor_half_y, 0.05],
                material=MATERIALS["floor"], group=WORLD_GEOM_GROUP)
    for b in terrain.boxes:
        Rb = R @ rot_y(b.pitch_rad)
        wb.add_geom(name=b.name, type=mujoco.mjtGeom.mjGEOM_BOX, pos=list(R @ b.centre + t),
                    quat=list(matrix_to_quat_wxyz(Rb)), size=list(b.half), material=MATERIALS[b.material],
                    group=WORLD_GEOM_GROUP)
    p0 = R @ np.array([terrain.items[0].x1, 0.0, 0.0]) + t
    p1 = R @ np.array([terrain.items[-1].x0, 0.0, 0.0]) + t
    add_lights(spec, p0, p1, terrain.top_z)

    surfaces = []
    geom_surfaces: dict[str, list[int]] = {"floor": []}
    for b in terrain.boxes:
        geom_surfaces[b.name] = []
    for sid, f in enumerate(terrain.faces):
        poly_w = f.polygon @ R.T + t
        surfaces.append(PlanarSurface(surface_id=sid, kind=f.kind, normal_w=R @ f.normal, point_w=poly_w.mean(axis=0),
                                      polygon_w=poly_w, geom_names=f.geoms))
        for g in f.geoms:
            geom_surfaces[g].append(sid)
    first = terrain.items[0]
    start_local = np.array([max(first.x0, first.x1 - START_BACK_M), 0.0, first.z])
    params = dict(params)
    params.update({
        "T_world_local": T.tolist(),
        "profile": _profile_dicts(terrain),
        "start_w": (R @ start_local + t).tolist(),
        "top_z_m": terrain.top_z,
    })
    truth = SceneTruth(surfaces=tuple(surfaces), geom_surfaces={k: tuple(v) for k, v in geom_surfaces.items()},
                       params=params, kind=kind)
    return BuiltWorld(spec=spec, truth=truth, T_world_local=T)


def _stairs_items(x: float, z: float, direction: str, n: int, riser: float, tread: float, nosing: float,
                  field_prefix: str) -> tuple[list[Item], float, float]:
    """Risers and treads of a flight starting at (x, z); returns items, end x, end z."""
    items: list[Item] = []
    sign = 1.0 if direction == "up" else -1.0
    for k in range(1, n + 1):
        zk = z + sign * k * riser
        if abs(zk) < 1e-9:
            zk = 0.0
        if zk < 0.0:
            raise ConfigError(f"{field_prefix}.n_steps", n, f"a flight that stays above the floor (it would reach z = {zk:.3f} m)")
        items.append(Riser(x, nosing))
        items.append(Flat(x, x + tread, zk, "ground" if zk == 0.0 else "tread", f"{field_prefix}.tread_m"))
        x += tread
    return items, x, items[-1].z


def build_staircase(params: StaircaseParams | None = None) -> BuiltWorld:
    """A straight flight of ``n_steps`` risers.

    ``up``: the walker starts on the floor (surface 0, local x < 0) and climbs; riser k is at
    local x = (k-1)*tread_m, tread k at height k*riser_m; the n-th tread is the top landing,
    ``landing_m`` deep. ``down``: the walker starts on the top landing (surface 0, local
    -landing_m < x < 0, at height n*riser_m) and descends; riser k is again at x = (k-1)*tread_m,
    below the edge it hangs from, tread k at height (n-k)*riser_m; the n-th tread is the floor.
    In both cases the local origin is below the first riser walked past, on the floor.
    """
    p = params or StaircaseParams()
    H = p.n_steps * p.riser_m
    if p.direction == "up":
        items: list[Item] = [Flat(-APPROACH_M, 0.0, 0.0, "ground")]
        steps, x, z = _stairs_items(0.0, 0.0, "up", p.n_steps, p.riser_m, p.tread_m, p.nosing_m, "stairs")
        steps[-1] = Flat(steps[-1].x0, steps[-1].x0 + p.landing_m, z, "landing", "stairs.landing_m")
        items += steps
    else:
        items = [Flat(-p.landing_m, 0.0, H, "landing", "stairs.landing_m")]
        steps, x, z = _stairs_items(0.0, H, "down", p.n_steps, p.riser_m, p.tread_m, p.nosing_m, "stairs")
        steps[-1] = Flat(steps[-1].x0, steps[-1].x0 + APPROACH_M, 0.0, "ground")
        items += steps
    terrain = build_profile(items, p.width_m, walls=p.walls)
    return _world_from_terrain(terrain, _T_world_local(p.yaw_deg, p.position_m), "staircase", p.as_dict())


def build_ramp(params: RampParams | None = None) -> BuiltWorld:
    """A straight ramp from local x = 0 to x = length_m.

    ``up``: start on the floor (surface 0, x < 0), ramp 1 rises to the landing (surface 2,
    ``landing_m`` deep). ``down``: start on the top landing (surface 0, -landing_m < x < 0, at
    height ``rise_m``), ramp 1 descends to the floor (surface 2). Raises ConfigError on
    ``landing_m`` if the landing is too short to hold the ramp's supporting box.
    """
    p = params or RampParams()
    h, L = p.rise_m, p.length_m
    if p.direction == "up":
        items: list[Item] = [Flat(-APPROACH_M, 0.0, 0.0, "ground"), Slope(0.0, L, 0.0, h),
                             Flat(L, L + p.landing_m, h, "landing", "ramp.landing_m")]
    else:
        items = [Flat(-p.landing_m, 0.0, h, "landing", "ramp.landing_m"), Slope(0.0, L, h, 0.0),
                 Flat(L, L + APPROACH_M, 0.0, "ground")]
    terrain = build_profile(items, p.width_m, walls=p.walls)
    return _world_from_terrain(terrain, _T_world_local(p.yaw_deg, p.position_m), "ramp", p.as_dict())


def _append_flat(items: list[Item], flat: Flat) -> None:
    """Append a flat, merging it with a flat just before it (a tread running into a level)."""
    if items and isinstance(items[-1], Flat):
        prev = items.pop()
        kind = flat.kind if flat.kind != "tread" else prev.kind
        flat = Flat(prev.x0, flat.x1, prev.z, kind, flat.field)
    items.append(flat)


def build_course(params: CourseParams | None = None) -> BuiltWorld:
    """Segments one after the other along local +x from x = 0, heights accumulating.

    The walker starts on the floor (surface 0, ``approach_m`` long, x < 0); ``exit_m`` of level
    walking follows the last segment. A tread that runs into a level segment is one surface
    (a landing, or the floor at z = 0). Ramps need a level segment on both sides.
    """
    p = params or CourseParams()
    items: list[Item] = [Flat(-p.approach_m, 0.0, 0.0, "ground", "course.approach_m")]
    x, z = 0.0, 0.0
    for i, (kind, s) in enumerate(p.segments):
        f = f"course.segments[{i}]"
        if kind != "level" and not isinstance(items[-1], Flat):
            raise ConfigError(f, kind, "a level segment between a ramp and the next stairs or ramp")
        if kind == "level":
            _append_flat(items, Flat(x, x + s["length_m"], z, "ground" if z == 0.0 else "landing", f"{f}.length_m"))
            x += s["length_m"]
        elif kind == "stairs":
            steps, x, z = _stairs_items(x, z, s["direction"], s["n_steps"], s["riser_m"], s["tread_m"], s["nosing_m"], f)
            items += steps
        else:
            rise = s["length_m"] * math.tan(math.radians(s["slope_deg"]))
            z1 = z + (rise if s["direction"] == "up" else -rise)
            if abs(z1) < 1e-9:
                z1 = 0.0
            if z1 < 0.0:
                raise ConfigError(f"{f}.length_m", s["length_m"], f"a ramp that stays above the floor (it would reach z = {z1:.3f} m)")
            items.append(Slope(x, x + s["length_m"], z, z1))
            x, z = x + s["length_m"], z1
        if 0.0 < z < 0.005:
            raise ConfigError(f, kind, "heights that return exactly to the floor or stay >= 5 mm above it")
    _append_flat(items, Flat(x, x + p.exit_m, z, "ground" if z == 0.0 else "landing", "course.exit_m"))
    terrain = build_profile(items, p.width_m, walls=p.walls)
    return _world_from_terrain(terrain, _T_world_local(p.yaw_deg, p.position_m), "course", p.as_dict())


def build_level(params: LevelParams | None = None) -> BuiltWorld:
    """A level square floor of ``size_m`` centred on the origin; surface 0 is all of it."""
    p = params or LevelParams()
    half = 0.5 * p.size_m
    items: list[Item] = [Flat(-half, half, 0.0, "ground")]
    terrain = build_profile(items, p.size_m, floor_x=(-half, half), floor_half_y=half)
    world = _world_from_terrain(terrain, np.eye(4), "level", p.as_dict())
    world.truth.params["start_w"] = [0.0, 0.0, 0.0]
    return world


BUILDERS: dict[str, tuple[type, Callable[[Any], BuiltWorld]]] = {
    "staircase": (StaircaseParams, build_staircase),
    "ramp": (RampParams, build_ramp),
    "course": (CourseParams, build_course),
    "level": (LevelParams, build_level),
}


def build_world(kind: str, values: dict[str, Any] | None = None) -> BuiltWorld:
    """Build a world by builder name from plain parameter values (unknown names are refused)."""
    if kind not in BUILDERS:
        raise UnknownNameError("world", kind, BUILDERS)
    cls, fn = BUILDERS[kind]
    return fn(cls.from_dict(values or {}))


def compose(world: BuiltWorld, exo: ExoSpec) -> CompiledScene:
    """A copy of the world's spec with the exoskeleton standing at ``truth.params['start_w']``, compiled.

    The built world is not modified, so it can be composed with several users.
    """
    from .exo import add_exo

    spec = world.spec.copy()
    add_exo(spec, exo)
    start = world.truth.params.get("start_w")
    if start is not None:
        pelvis = spec.body("pelvis")
        R = np.asarray(world.T_world_local)[:3, :3]
        pelvis.pos = [start[0], start[1], start[2] + exo.leg_m]
        pelvis.quat = list(matrix_to_quat_wxyz(R))
    model = spec.compile()
    return CompiledScene(model=model, truth=world.truth, exo=exo, spec=spec)


def params_table(kind: str) -> dict[str, ParamSpec]:
    """The parameter table of a builder, for listing and for ``--set`` validation."""
    if kind not in PARAMS:
        raise UnknownNameError("world", kind, PARAMS)
    return PARAMS[kind]


__all__ = [
    "BUILDERS",
    "BuiltWorld",
    "CompiledScene",
    "CourseParams",
    "LevelParams",
    "PARAMS",
    "PARAM_CLASSES",
    "RAY_GEOMGROUP_WORLD",
    "ParamSpec",
    "RampParams",
    "StaircaseParams",
    "WORLD_GEOM_GROUP",
    "build_course",
    "build_level",
    "build_ramp",
    "build_staircase",
    "build_world",
    "compose",
    "params_table",
]
