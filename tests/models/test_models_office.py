"""Procedural office: validated parameters, determinism, and a truth that is exactly what MuJoCo's rays see."""

from __future__ import annotations

import json
import math

import mujoco
import numpy as np
import pytest

from exobench.core.errors import ConfigError, UnknownNameError
from exobench.core.truth import height_at
from exobench.models.exo_spec import ExoSpec
from exobench.models.materials import MATERIALS as LIDAR_MATERIALS
from exobench.models.office import (
    OBJECT_CLASSES,
    OFFICE_PARAMS,
    SURFACE_KINDS,
    OfficeParams,
    build_office,
    office_route,
    sample_surface,
    sample_surface_points,
    surface_material,
)
from exobench.models.worlds import RAY_GEOMGROUP_WORLD, build_level, compose

pytestmark = pytest.mark.long(seconds=5)  # the workers take it first (tests/conftest.py); 5: the file at -n 0 in one run at load 12-15, scaled to that run's CPU

WORLD_ONLY = np.array(RAY_GEOMGROUP_WORLD, dtype=np.uint8)

CONFIGS = {
    "default": OfficeParams(),
    "all_glass_small": OfficeParams(seed=7, n_offices=3, corridor_length_m=14.0, corridor_width_m=1.12, room_depth_m=3.0,
                                    meeting_room_m=4.0, ceiling_m=3.0, door_width_m=1.2, glass_fraction=1.0,
                                    glass_thickness_m=0.008, polished_fraction=1.0, furniture_density=1.0),
    "plaster_bare": OfficeParams(seed=11, n_offices=8, corridor_length_m=30.0, corridor_width_m=2.5, ceiling_m=2.4,
                                 door_width_m=0.81, glass_fraction=0.0, polished_fraction=0.0, furniture_density=0.3,
                                 windows=False),
}


@pytest.fixture(scope="module", params=list(CONFIGS))
def scene(request):
    world = build_office(CONFIGS[request.param])
    sc = compose(world, ExoSpec())
    data = mujoco.MjData(sc.model)
    mujoco.mj_forward(sc.model, data)
    return world, sc.model, data


def _ray(model: mujoco.MjModel, data: mujoco.MjData, o, d) -> tuple[float, str]:
    gid = np.array([-1], dtype=np.int32)
    dist = mujoco.mj_ray(model, data, np.asarray(o, float), np.asarray(d, float), WORLD_ONLY, 1, -1, gid)
    return dist, (model.geom(gid[0]).name if gid[0] >= 0 else "")


def _inside_a_world_geom(model: mujoco.MjModel, data: mujoco.MjData, p: np.ndarray, tol: float = 1e-9) -> bool:
    """From the compiled model alone: whether p lies in (or on) a world box, cylinder or sphere."""
    key = id(model)
    if key not in _GEOMS:
        g = np.flatnonzero(model.geom_group == 0)
        _GEOMS.clear()
        _GEOMS[key] = (model.geom_type[g], data.geom_xpos[g].copy(), data.geom_xmat[g].reshape(-1, 3, 3).copy(),
                       model.geom_size[g].copy())
    types, pos, mat, size = _GEOMS[key]
    local = np.einsum("gji,gj->gi", mat, np.asarray(p, float) - pos)
    box = (types == int(mujoco.mjtGeom.mjGEOM_BOX)) & np.all(np.abs(local) <= size + tol, axis=1)
    cyl = ((types == int(mujoco.mjtGeom.mjGEOM_CYLINDER)) & (np.hypot(local[:, 0], local[:, 1]) <= size[:, 0] + tol)
           & (np.abs(local[:, 2]) <= size[:, 1] + tol))
    sph = (types == int(mujoco.mjtGeom.mjGEOM_SPHERE)) & (np.linalg.norm(local, axis=1) <= size[:, 0] + tol)
    return bool(np.any(box | cyl | sph))


_GEOMS: dict[int, tuple] = {}


def _in_rect(poly: np.ndarray, rng: np.random.Generator, n: int) -> np.ndarray:
    """Random points strictly inside an axis-aligned rectangle polygon."""
    lo, hi = poly.min(axis=0), poly.max(axis=0)
    u = rng.uniform(0.02, 0.98, size=(n, 3))
    return lo + u * (hi - lo)


# --- parameters ------------------------------------------------------------------------------

@pytest.mark.parametrize("field,value", [("corridor_width_m", 1.0), ("door_width_m", 0.8), ("n_offices", 0),
                                         ("n_offices", 2.5), ("glass_fraction", 1.5), ("glass_thickness_m", 0.02),
                                         ("ceiling_m", 3.5), ("windows", "maybe"), ("seed", -1),
                                         ("room_depth_m", float("nan"))])
def test_out_of_range_params_name_the_field(field: str, value: object) -> None:
    with pytest.raises(ConfigError) as err:
        OfficeParams(**{field: value})
    assert err.value.field == f"office.{field}"
    assert field in str(err.value)


@pytest.mark.parametrize("values,field,mentions", [
    ({"room_depth_m": 1.5, "door_width_m": 1.2}, "office.door_width_m", "room_depth_m"),  # door wider than the room
    ({"n_offices": 10, "corridor_length_m": 20.0}, "office.corridor_length_m", "10 offices"),
    ({"meeting_room_m": 17.0, "corridor_length_m": 20.0}, "office.meeting_room_m", "corridor_length_m"),
    ({"meeting_room_m": 1.5, "door_width_m": 1.2}, "office.meeting_room_m", "doors"),
])
def test_impossible_offices_are_refused_naming_the_field(values: dict, field: str, mentions: str) -> None:
    with pytest.raises(ConfigError) as err:
        OfficeParams(**values)
    assert err.value.field == field
    assert mentions in str(err.value)


def test_param_table_matches_the_dataclass_and_bounds_are_enforced() -> None:
    default = OfficeParams()
    assert set(OFFICE_PARAMS) == set(vars(default))
    for name, spec in OFFICE_PARAMS.items():
        assert getattr(default, name) == spec.default
        if spec.low is None:
            continue
        for bad in (spec.low - 1e-3, spec.high + 1e-3):
            with pytest.raises(ConfigError) as err:
                OfficeParams(**{name: bad})
            assert err.value.field == f"office.{name}"
    with pytest.raises(UnknownNameError):
        OfficeParams.from_dict({"n_rooms": 3})
    assert OfficeParams.from_dict({"n_offices": 4}).n_offices == 4


# --- determinism -----------------------------------------------------------------------------

def _truth_signature(world) -> str:
    t = world.truth
    return json.dumps({"params": t.params, "objects": list(t.objects), "materials": t.geom_materials,
                       "geom_surfaces": {k: list(v) for k, v in t.geom_surfaces.items()},
                       "surfaces": [[s.surface_id, s.kind, s.normal_w.tolist(), s.polygon_w.tolist(), list(s.geom_names)]
                                    for s in t.surfaces]}, sort_keys=True)


def test_same_seed_same_office_and_different_seed_different_layout() -> None:
    a, b = build_office(OfficeParams(seed=5)), build_office(OfficeParams(seed=5))
    assert a.spec.to_xml() == b.spec.to_xml()
    assert _truth_signature(a) == _truth_signature(b)
    c = build_office(OfficeParams(seed=6))
    assert c.spec.to_xml() != a.spec.to_xml()
    poses_a = {o["name"]: o["T_world_object"] for o in a.truth.objects}
    poses_c = {o["name"]: o["T_world_object"] for o in c.truth.objects}
    assert poses_a != poses_c
    walls_a = sorted(s["centre"][0] for s in a.truth.params["solids"] if s["name"].startswith("wall_side"))
    walls_c = sorted(s["centre"][0] for s in c.truth.params["solids"] if s["name"].startswith("wall_side"))
    assert walls_a != walls_c  # office widths follow the seed


# --- model and materials ---------------------------------------------------------------------

def test_compiles_without_warnings_and_the_walker_stands_on_the_floor(scene) -> None:
    world, model, data = scene
    assert data.warning.number.sum() == 0
    sole = data.site("sole_l").xpos
    assert sole[2] == pytest.approx(0.0, abs=1e-9)
    assert height_at(world.truth, sole[0], sole[1]) == 0.0
    dist, geom = _ray(model, data, sole + [0.0, 0.0, 0.5], [0.0, 0.0, -1.0])
    assert geom.startswith("floor_") and dist == pytest.approx(0.5, abs=1e-9)
    start = world.truth.params["start_w"]
    assert tuple(start[:2]) == office_route(world.truth, "loop")[0]
    json.dumps(world.truth.params)
    again = mujoco.MjSpec.from_string(world.spec.to_xml()).compile()
    assert again.ngeom == world.spec.compile().ngeom


def test_every_world_geom_has_a_lidar_material_and_a_look(scene) -> None:
    world, model, _ = scene
    truth = world.truth
    world_geoms = {model.geom(g).name for g in range(model.ngeom) if model.geom_group[g] == 0}
    assert set(truth.geom_materials) == world_geoms
    assert set(truth.geom_surfaces) == world_geoms
    assert set(truth.geom_materials.values()) <= set(LIDAR_MATERIALS)
    for g in range(model.ngeom):
        if model.geom_group[g] != 0:
            continue
        name = model.geom(g).name
        assert model.geom_matid[g] >= 0, name
        transparent = model.mat_rgba[model.geom_matid[g]][3] < 0.5
        assert transparent == (truth.geom_materials[name] == "glass"), name
        if truth.geom_materials[name] == "glass":  # every pane and glass leaf is 8-12 mm thick
            assert 0.008 - 1e-12 <= 2 * model.geom_size[g].min() <= 0.012 + 1e-12, name
    floors = {r["name"]: r["floor"] for r in truth.params["regions"]}
    for name, mat in floors.items():
        assert truth.geom_materials[f"floor_{name}"] == mat
    for srf in truth.surfaces:  # glass surfaces are exactly those of glass material
        assert (surface_material(truth, srf.surface_id) == "glass") == (srf.kind == "glass")
    share = sum(m == "polished_floor" for m in floors.values()) / len(floors)
    assert share == pytest.approx(truth.params["polished_fraction"], abs=0.5 / len(floors))


def test_every_surface_is_hit_where_the_truth_says_and_labelled(scene) -> None:
    """Rays from 1 cm outside random points of every surface, against its normal, hit it at 1 cm."""
    world, model, data = scene
    truth = world.truth
    rng = np.random.default_rng(1)
    assert {s.kind for s in truth.surfaces} <= set(SURFACE_KINDS)
    for s in truth.surfaces:
        np.testing.assert_allclose(s.signed_distance(s.polygon_w), 0.0, atol=1e-12)
        area = sum(np.cross(s.polygon_w[i], s.polygon_w[(i + 1) % 4]) for i in range(4))
        assert area @ s.normal_w > 0  # counter-clockwise seen from outside
        hits = 0
        for p in _in_rect(s.polygon_w, rng, 4 if s.kind in ("ground", "ceiling") else 2):
            o = p + 0.01 * s.normal_w
            if _inside_a_world_geom(model, data, o):  # floor strips under walls and furniture
                continue
            dist, geom = _ray(model, data, o, -s.normal_w)
            assert dist == pytest.approx(0.01, abs=1e-9), (s.surface_id, s.kind, geom)
            assert truth.surface_of_hit(geom, o - dist * s.normal_w) == s.surface_id
            hits += 1
        assert hits > 0 or s.kind in ("ground", "ceiling"), (s.surface_id, s.kind, s.geom_names)


def _first_planar_hit(normals, points, lo, hi, o, d) -> tuple[float, int]:
    """Nearest front-facing truth rectangle along the ray, from the truth polygons alone."""
    dn = normals @ d
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.einsum("ij,ij->i", points - o, normals) / dn
    ok = (dn < -1e-12) & (t > 0)
    q = o + t[:, None] * d
    ok &= np.all((q >= lo - 1e-9) & (q <= hi + 1e-9), axis=1)
    if not ok.any():
        return math.inf, -1
    i = int(np.argmin(np.where(ok, t, np.inf)))
    return float(t[i]), i


def test_rays_from_the_route_agree_with_the_truth_polygons(scene) -> None:
    world, model, data = scene
    truth = world.truth
    surfaces = truth.surfaces
    normals = np.array([s.normal_w for s in surfaces])
    points = np.array([s.point_w for s in surfaces])
    lo = np.array([s.polygon_w.min(axis=0) for s in surfaces])
    hi = np.array([s.polygon_w.max(axis=0) for s in surfaces])
    curved = {s["name"] for s in truth.params["solids"] if s["shape"] in ("cylinder", "sphere")}
    rng = np.random.default_rng(2)
    route = office_route(truth, "loop")
    n_checked, kinds = 0, set()
    for x, y in route[::2]:
        for z in (0.45, 1.37):
            o = np.array([x + 0.013, y - 0.007, z])
            for _ in range(60):
                d = rng.normal(size=3)
                d /= np.linalg.norm(d)
                dist, geom = _ray(model, data, o, d)
                t, i = _first_planar_hit(normals, points, lo, hi, o, d)
                if geom in curved:
                    assert dist <= t + 1e-9
                    continue
                assert dist == pytest.approx(t, abs=1e-9)
                assert truth.surface_of_hit(geom, o + dist * d) == surfaces[i].surface_id
                kinds.add(surfaces[i].kind)
                n_checked += 1
    assert n_checked > 500
    assert {"ground", "ceiling", "wall"} <= kinds


# --- objects ---------------------------------------------------------------------------------

def _geom_aabb(model: mujoco.MjModel, data: mujoco.MjData, g: int) -> tuple[np.ndarray, np.ndarray]:
    R = data.geom_xmat[g].reshape(3, 3)
    c = data.geom_xpos[g] + R @ model.geom_aabb[g][:3]
    h = np.abs(R) @ model.geom_aabb[g][3:]
    return c - h, c + h


def test_objects_are_boxed_by_their_pose_and_size(scene) -> None:
    world, model, data = scene
    objects = world.truth.objects
    names = [o["name"] for o in objects]
    assert len(set(names)) == len(names)
    classes = {o["class"] for o in objects}
    assert classes <= set(OBJECT_CLASSES)
    assert {"desk", "chair", "door"} <= classes
    for o in objects:
        T = np.array(o["T_world_object"])
        R = T[:3, :3]
        np.testing.assert_allclose(R.T @ R, np.eye(3), atol=1e-12)
        assert np.linalg.det(R) == pytest.approx(1.0)
        lo_all, hi_all = np.full(3, np.inf), np.full(3, -np.inf)
        for g in o["geom_names"]:
            lo, hi = _geom_aabb(model, data, model.geom(g).id)
            corners = np.array([[a, b, c] for a in (lo[0], hi[0]) for b in (lo[1], hi[1]) for c in (lo[2], hi[2])])
            local = (corners - T[:3, 3]) @ R
            lo_all, hi_all = np.minimum(lo_all, local.min(axis=0)), np.maximum(hi_all, local.max(axis=0))
        size = np.array(o["size_m"])
        # the object frame: origin at the bottom centre, its box exactly the union of its geoms
        np.testing.assert_allclose(lo_all, [-size[0] / 2, -size[1] / 2, 0.0], atol=1e-9, err_msg=o["name"])
        np.testing.assert_allclose(hi_all, [size[0] / 2, size[1] / 2, size[2]], atol=1e-9, err_msg=o["name"])


def test_furniture_sizes_follow_the_sensors_table(scene) -> None:
    world, model, data = scene
    p = world.truth.params
    for o in world.truth.objects:
        w, d, h = o["size_m"]
        if o["class"] == "desk":
            assert 0.73 <= h <= 0.76 and 1.2 <= w <= 1.8 and 0.6 <= d <= 0.9
        elif o["class"] == "chair":
            seat = [g for g in o["geom_names"] if g.endswith("_seat")][0]
            assert 0.40 - 1e-9 <= _geom_aabb(model, data, model.geom(seat).id)[1][2] <= 0.45 + 1e-9
        elif o["class"] == "couch":
            assert 1.8 <= w <= 2.2 and 0.8 <= d <= 1.0
        elif o["class"] == "glass_partition":
            assert 2.4 <= h <= 3.0 and h == p["ceiling_m"]


def test_every_door_leaves_its_clear_width(scene) -> None:
    """From the face of the open leaf, across the opening, to the opposite jamb: door_width_m (>= 0.81 m)."""
    world, model, data = scene
    dw = world.truth.params["door_width_m"]
    doors = [o for o in world.truth.objects if o["class"] == "door"]
    assert len(doors) == world.truth.params["n_offices"] + 2
    for o in doors:
        T = np.array(o["T_world_object"])
        into = T[:3, 0]  # the leaf points from its wall into the room
        lo, hi = _geom_aabb(model, data, model.geom(o["geom_names"][0]).id)
        wall_face = (lo if into[1] > 0 else hi)[1]
        y = wall_face - 0.02 * into[1]  # inside the wall, in the opening
        for side in (1.0, -1.0):  # the leaf is on one side of the passage: measure from its face
            x = hi[0] if side > 0 else lo[0]
            dist, geom = _ray(model, data, [x, y, 1.0], [side, 0.0, 0.0])
            if dist > 0 and abs(dist - dw) < 1e-9:
                break
        else:
            pytest.fail(f"{o['name']}: no clear width of {dw} m beside the leaf")
        assert dw >= 0.81


# --- routes ----------------------------------------------------------------------------------

def _free_segment(model, data, a, b, heights=(0.3, 1.0), offsets=(0.0, 0.2, -0.2)) -> bool:
    a, b = np.asarray(a, float), np.asarray(b, float)
    L = float(np.linalg.norm(b - a))
    d2 = (b - a) / L
    side = np.array([-d2[1], d2[0]])
    for z in heights:
        for off in offsets:
            o = np.array([*(a + off * side), z])
            dist, _ = _ray(model, data, o, [d2[0], d2[1], 0.0])
            if 0 <= dist < L:
                return False
    return True


def test_routes_stay_on_the_floor_and_walk_through_doors_only(scene) -> None:
    world, model, data = scene
    truth = world.truth
    for kind in ("loop", "corridor"):
        route = office_route(truth, kind)
        for x, y in route:
            assert height_at(truth, x, y) == 0.0
            dist, geom = _ray(model, data, [x, y, 2.0], [0.0, 0.0, -1.0])
            assert geom.startswith("floor_") and dist == pytest.approx(2.0, abs=1e-9)
        for a, b in zip(route, route[1:]):
            assert _free_segment(model, data, a, b), (kind, a, b)
    # glass is an obstacle: straight through a glass partition is not free
    glass = [s for s in truth.params["solids"] if s["material"] == "glass" and s["name"].startswith("wall_")]
    if glass:
        c = glass[0]["centre"]
        assert not _free_segment(model, data, (c[0], c[1] - 0.5), (c[0], c[1] + 0.5), heights=(1.0,), offsets=(0.0,))
    with pytest.raises(UnknownNameError):
        office_route(truth, "spiral")
    with pytest.raises(ConfigError):
        office_route(build_level().truth)


def test_loop_closes_revisits_and_enters_every_room(scene) -> None:
    world, _, _ = scene
    truth = world.truth
    loop = office_route(truth, "loop")
    assert loop[0] == loop[-1] == tuple(truth.params["start_w"][:2])
    assert sum(q == loop[0] for q in loop) >= 3  # closes twice
    inner = loop[1:-1]
    assert len(set(inner)) < len(inner)  # revisits
    for r in truth.params["regions"]:
        if r["kind"] == "corridor":
            continue
        x0, x1, y0, y1 = r["clear"]
        assert any(x0 < x < x1 and y0 < y < y1 for x, y in loop), r["name"]
    # the meeting room is crossed from one corridor to the other
    y_n, y_s = truth.params["corridor_y_m"]["north"], truth.params["corridor_y_m"]["south"]
    assert any(a[0] == b[0] and {a[1], b[1]} == {y_n, y_s} for a, b in zip(loop, loop[1:]))


def test_the_corridor_run_is_long_straight_and_featureless(scene) -> None:
    world, model, data = scene
    truth = world.truth
    (xa, ya), (xb, yb) = office_route(truth, "corridor")
    assert ya == yb
    x0, x1 = truth.params["featureless_x_m"]
    assert xa < x0 < x1 < xb and x1 - x0 > 3.0
    half = 0.5 * truth.params["corridor_width_m"]
    for x in np.linspace(x0 + 0.01, x1 - 0.01, 25):
        for z in (0.3, 1.0, 2.0):
            for side in (1.0, -1.0):
                dist, geom = _ray(model, data, [x, ya, z], [0.0, side, 0.0])
                assert dist == pytest.approx(half, abs=1e-9), (x, z, geom)


# --- surface samples -------------------------------------------------------------------------

def test_surface_samples_lie_on_visible_surfaces(scene) -> None:
    world, model, data = scene
    truth = world.truth
    spacing = 0.25
    pts, normals, ids = sample_surface(truth, spacing)
    np.testing.assert_array_equal(pts, sample_surface_points(truth, spacing))
    assert len(pts) > 5000 and np.all(np.isfinite(pts))
    for i in np.flatnonzero(ids >= 0)[::7]:
        assert truth.surface(int(ids[i])).contains(pts[i], tol_m=1e-9)
    solids = {s["name"]: s for s in truth.params["solids"]}
    curved = [s for s in solids.values() if s["shape"] in ("cylinder", "sphere")]
    for p in pts[ids < 0]:  # on a pot, foliage or bin: zero distance to one of them
        dmin = math.inf
        for s in curved:
            q = p - np.array(s["centre"])
            r, hz = s["half"][0], s["half"][2]
            if s["shape"] == "sphere":
                dmin = min(dmin, abs(np.linalg.norm(q) - r))
            else:
                rho = math.hypot(q[0], q[1])
                dmin = min(dmin, abs(rho - r) if abs(q[2]) <= hz + 1e-9 else math.inf,
                           abs(abs(q[2]) - hz) if rho <= r + 1e-9 else math.inf)
        assert dmin < 1e-9
    # independent of the truth: each sampled point is seen by a ray from 1 cm outside
    rng = np.random.default_rng(3)
    for i in rng.choice(len(pts), 400, replace=False):
        o = pts[i] + 0.01 * normals[i]
        if _inside_a_world_geom(model, data, o):  # 1 cm off a pot, into its foliage
            continue
        dist, geom = _ray(model, data, o, -normals[i])
        assert dist == pytest.approx(0.01, abs=1e-6 if ids[i] < 0 else 1e-9), (ids[i], geom)
    # spacing: neighbours on a large floor are at most spacing_m apart
    floor = [k for k, s in enumerate(truth.surfaces) if s.kind == "ground"][0]
    f = pts[ids == floor]
    assert 0 < np.min(np.linalg.norm(f[1:] - f[:-1], axis=1)) <= spacing
    glass = sample_surface_points(truth, spacing, kinds=("glass",))
    if any(s.kind == "glass" for s in truth.surfaces):
        assert len(glass) > 0 and len(glass) < len(pts)


@pytest.mark.parametrize("facade, bay, pier, sill", [("windows", 1.5, 0.3, 0.9), ("curtain", 1.35, 0.06, 0.05)])
def test_facade_glazing_spans_its_bays_and_heights(facade: str, bay: float, pier: float, sill: float) -> None:
    """Rays from the south corridor at the façade: the glazed share of the 14 m wall at each height is
    the stated bays' (``windows``: 1.2 m windows, sill 0.9 m, head 2.2 m, between 0.3 m piers;
    ``curtain``: glazing from 0.05 m to 0.25 m under the ceiling between 60 mm mullions at 1.35 m)."""
    p = OfficeParams(n_offices=2, corridor_length_m=14.0, meeting_room_m=4.0, facade=facade, facade_glass="float_glass")
    sc = compose(build_office(p), ExoSpec())
    data = mujoco.MjData(sc.model)
    mujoco.mj_forward(sc.model, data)
    n = math.floor((14.0 - pier) / bay)
    glazed_share = (14.0 - (n + 1) * pier) / 14.0
    head = 2.2 if facade == "windows" else p.ceiling_m - 0.25
    xs = np.arange(0.0025, 14.0, 0.005)
    for z in (0.3, 1.5, 2.4):
        hits = [_ray(sc.model, data, [x, 0.5 * p.corridor_width_m, z], [0.0, -1.0, 0.0])[1] for x in xs]
        share = float(np.mean([h.startswith("window") for h in hits]))
        expected = glazed_share if sill < z < head else 0.0
        assert share == pytest.approx(expected, abs=0.005), (z, share)
