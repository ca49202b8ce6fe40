"""World builders: the ground truth is exactly what MuJoCo's ray caster sees, ids follow the contract."""

from __future__ import annotations

import json
import math

import mujoco
import numpy as np
import pytest

from exobench.core.errors import ConfigError, UnknownNameError
from exobench.core.transforms import invert_T, transform_points
from exobench.core.truth import SURFACE_KINDS, SceneTruth, height_at
from exobench.models.exo_spec import ExoSpec
from exobench.models.worlds import (
    BUILDERS,
    PARAMS,
    RAY_GEOMGROUP_WORLD,
    CourseParams,
    RampParams,
    StaircaseParams,
    build_course,
    build_level,
    build_ramp,
    build_staircase,
    build_world,
    compose,
)

WORLD_ONLY = np.array(RAY_GEOMGROUP_WORLD, dtype=np.uint8)

WORLDS = {
    "stairs_yaw_nosing": lambda: build_staircase(StaircaseParams(riser_m=0.17, tread_m=0.27, n_steps=5, nosing_m=0.03,
                                                                 yaw_deg=23.0, position_m=(0.4, -0.7))),
    "stairs_down_walls": lambda: build_staircase(StaircaseParams(direction="down", nosing_m=0.02, yaw_deg=-40.0,
                                                                 walls=True, position_m=(-1.0, 2.0))),
    "ramp_yaw": lambda: build_ramp(RampParams(slope_deg=12.0, length_m=2.5, yaw_deg=-15.0, position_m=(1.0, 0.5))),
    "ramp_down": lambda: build_ramp(RampParams(direction="down", slope_deg=20.0, length_m=2.0)),
    "course": lambda: build_course(CourseParams(yaw_deg=10.0)),
    "course_walls": lambda: build_course(CourseParams(walls=True)),
}


def _first_hit(truth: SceneTruth, o: np.ndarray, d: np.ndarray) -> tuple[float, int]:
    """Nearest front-facing truth polygon along the ray, computed from the truth alone."""
    best, best_id = math.inf, -1
    for s in truth.surfaces:
        dn = float(d @ s.normal_w)
        if dn >= -1e-12:
            continue
        t = float((s.point_w - o) @ s.normal_w) / dn
        if 0.0 < t < best and s.contains(o + t * d, tol_m=1e-9):
            best, best_id = t, s.surface_id
    return best, best_id


def _mj_ray(model: mujoco.MjModel, data: mujoco.MjData, o: np.ndarray, d: np.ndarray) -> tuple[float, str]:
    gid = np.array([-1], dtype=np.int32)
    dist = mujoco.mj_ray(model, data, o, d, WORLD_ONLY, 1, -1, gid)
    return dist, (model.geom(gid[0]).name if gid[0] >= 0 else "")


def _inside_a_box(model: mujoco.MjModel, data: mujoco.MjData, p: np.ndarray) -> bool:
    for g in range(model.ngeom):
        if model.geom_group[g] != 0 or model.geom_type[g] != mujoco.mjtGeom.mjGEOM_BOX:
            continue
        local = data.geom_xmat[g].reshape(3, 3).T @ (p - data.geom_xpos[g])
        if np.all(np.abs(local) < model.geom_size[g] + 1e-6):
            return True
    return False


def _sample_in_polygon(poly: np.ndarray, rng: np.random.Generator, n: int) -> np.ndarray:
    """Random points strictly inside a convex polygon (fan triangles, shrunk towards the centroid)."""
    c = poly.mean(axis=0)
    out = []
    for _ in range(n):
        k = rng.integers(len(poly))
        a, b = poly[k], poly[(k + 1) % len(poly)]
        u, v = rng.uniform(size=2)
        if u + v > 1:
            u, v = 1 - u, 1 - v
        p = c + u * (a - c) + v * (b - c)
        out.append(c + 0.97 * (p - c))
    return np.array(out)


@pytest.fixture(scope="module", params=list(WORLDS))
def scene(request):
    world = WORLDS[request.param]()
    sc = compose(world, ExoSpec())
    data = mujoco.MjData(sc.model)
    mujoco.mj_forward(sc.model, data)
    return world, sc, data


def test_surfaces_are_well_formed(scene) -> None:
    world, sc, _ = scene
    truth = world.truth
    assert [s.surface_id for s in truth.surfaces] == list(range(len(truth.surfaces)))
    for s in truth.surfaces:
        assert s.kind in SURFACE_KINDS
        assert abs(np.linalg.norm(s.normal_w) - 1.0) < 1e-12
        np.testing.assert_allclose(s.signed_distance(s.polygon_w), 0.0, atol=1e-12)
        # vertices counter-clockwise seen from outside: the polygon's area vector follows the normal
        area = sum(np.cross(s.polygon_w[i], s.polygon_w[(i + 1) % len(s.polygon_w)]) for i in range(len(s.polygon_w)))
        assert area @ s.normal_w > 0
        assert s.contains(s.point_w)
    world_geoms = {sc.model.geom(g).name for g in range(sc.model.ngeom) if sc.model.geom_group[g] == 0}
    assert set(truth.geom_surfaces) == world_geoms
    if not truth.params["walls"]:  # between walls some supports are entirely out of sight
        assert all(truth.geom_surfaces[g] for g in world_geoms)
    for sid_list in truth.geom_surfaces.values():
        for sid in sid_list:
            assert truth.surface(sid).surface_id == sid


def _check_near_rays(world, model, data, rng: np.random.Generator, per_surface: int) -> int:
    """Rays from 1 cm outside each surface, along its normal, hit it at 1 cm and are labelled with it."""
    n_checked = 0
    for s in world.truth.surfaces:
        hits_this = 0
        for p in _sample_in_polygon(s.polygon_w, rng, per_surface):
            o = p + 0.01 * s.normal_w
            if _inside_a_box(model, data, o):  # a hidden part of the face (behind a step, under a wall)
                continue
            dist, geom = _mj_ray(model, data, o, -s.normal_w)
            assert dist == pytest.approx(0.01, abs=1e-9), (s.surface_id, s.kind, geom)
            assert world.truth.surface_of_hit(geom, o - dist * s.normal_w) == s.surface_id
            hits_this += 1
        assert hits_this > 0, f"surface {s.surface_id} ({s.kind}) is never visible"
        n_checked += hits_this
    return n_checked


def _check_view_rays(world, model, data, rng: np.random.Generator, per_surface: int) -> tuple[int, set[int]]:
    """Rays from viewpoints around the route to points of every surface: MuJoCo's first hit is the
    nearest truth polygon along the ray (computed from the truth alone), at the same distance."""
    truth = world.truth
    T = np.array(truth.params["T_world_local"])
    prof = truth.params["profile"]
    x_end = prof[-1]["x0"]
    top = truth.params["top_z_m"]
    width = truth.params["width_m"]
    # odd fractions keep the viewpoints out of the planes of risers
    views_local = [(-1.0, 0.0, prof[0].get("z", 0.0) + 1.5), (0.537 * x_end, 0.0, top + 1.6), (x_end + 1.0, 0.2, top + 1.2),
                   (0.461 * x_end, width + 1.5, 0.8), (0.313 * x_end, -width - 1.5, 1.2)]
    views = transform_points(T, np.array(views_local))
    seen: set[int] = set()
    n = 0
    for s in truth.surfaces:
        for p in _sample_in_polygon(s.polygon_w, rng, per_surface):
            for o in views:
                # skip grazing rays (ambiguous at edges) and viewpoints inside a solid
                if (p - o) @ s.normal_w > -0.05 * np.linalg.norm(p - o) or _inside_a_box(model, data, o):
                    continue
                d = (p - o) / np.linalg.norm(p - o)
                t_truth, sid = _first_hit(truth, o, d)
                dist, geom = _mj_ray(model, data, o, d)
                if sid < 0:
                    assert dist < 0
                    continue
                assert dist == pytest.approx(t_truth, abs=1e-9)
                assert truth.surface_of_hit(geom, o + dist * d) == sid
                seen.add(sid)
                n += 1
    return n, seen


def test_rays_near_every_surface_hit_it_at_the_plane_distance(scene) -> None:
    world, sc, data = scene
    n = _check_near_rays(world, sc.model, data, np.random.default_rng(1), 12)
    assert n > 10 * len(world.truth.surfaces)


def test_rays_from_viewpoints_agree_with_the_truth_polygons(scene) -> None:
    world, sc, data = scene
    n, seen = _check_view_rays(world, sc.model, data, np.random.default_rng(2), 6)
    assert n > 50
    # every walking surface of the route is seen from somewhere (risers going down face away)
    prof = world.truth.params["profile"]
    assert all(item["surface_id"] in seen for item in prof if item["kind"] != "riser" or item["z0"] < item["z1"])


def _random_world(rng: np.random.Generator):
    kind = rng.choice(["staircase", "ramp", "course"])
    common = {"yaw_deg": float(rng.uniform(-90, 90)), "position_m": tuple(rng.uniform(-3, 3, 2)),
              "walls": bool(rng.integers(2)), "width_m": float(rng.uniform(0.5, 3.0))}
    nosing = float(rng.choice([0.0, rng.uniform(0.005, 0.05)]))
    direction = str(rng.choice(["up", "down"]))
    if kind == "staircase":
        return build_staircase(StaircaseParams(riser_m=float(rng.uniform(0.02, 0.3)), tread_m=float(rng.uniform(0.15, 0.6)),
                                               n_steps=int(rng.integers(1, 7)), nosing_m=nosing, direction=direction,
                                               landing_m=float(rng.uniform(0.3, 2.0)), **common))
    if kind == "ramp":
        slope, length = float(rng.uniform(0.5, 25.0)), float(rng.uniform(0.5, 4.0))
        return build_ramp(RampParams(slope_deg=slope, length_m=length, direction=direction, landing_m=2.0, **common))
    r = float(rng.uniform(0.05, 0.25))
    segments = [("level", {"length_m": 1.0}),
                ("stairs", {"direction": "up", "n_steps": 3, "riser_m": r, "tread_m": 0.3, "nosing_m": nosing}),
                ("ramp", {"direction": "down", "slope_deg": float(rng.uniform(1.0, 5.0)), "length_m": 1.0}),
                ("level", {"length_m": 0.8}),
                ("ramp", {"direction": "up", "slope_deg": float(rng.uniform(1.0, 5.0)), "length_m": 1.0}),
                ("level", {"length_m": 1.0}),
                ("stairs", {"direction": "down", "n_steps": 1, "riser_m": r, "tread_m": 0.3, "nosing_m": nosing})]
    common["position_m"] = (0.0, 0.0)
    return build_course(CourseParams(segments=segments, **common))


@pytest.mark.parametrize("seed", range(6))
def test_random_routes_match_ray_casts(seed: int) -> None:
    world = _random_world(np.random.default_rng(seed))
    sc = compose(world, ExoSpec())
    data = mujoco.MjData(sc.model)
    mujoco.mj_forward(sc.model, data)
    rng = np.random.default_rng(100 + seed)
    assert _check_near_rays(world, sc.model, data, rng, 4) > 0
    assert _check_view_rays(world, sc.model, data, rng, 3)[0] > 0


def _local(truth: SceneTruth, p: np.ndarray) -> np.ndarray:
    return transform_points(invert_T(np.array(truth.params["T_world_local"])), p)


@pytest.mark.parametrize("direction", ["up", "down"])
def test_staircase_ids_follow_walking_order(direction: str) -> None:
    r, t, n, nose = 0.15, 0.30, 4, 0.025
    world = build_staircase(StaircaseParams(riser_m=r, tread_m=t, n_steps=n, nosing_m=nose, yaw_deg=35.0,
                                            position_m=(2.0, 1.0), direction=direction))
    truth = world.truth
    H = n * r
    s0 = truth.surface(0)
    assert s0.kind == ("ground" if direction == "up" else "landing")
    assert _local(truth, s0.point_w)[2] == pytest.approx(0.0 if direction == "up" else H, abs=1e-12)
    z_axis = np.array([0.0, 0.0, 1.0])
    x_w = np.array([math.cos(math.radians(35.0)), math.sin(math.radians(35.0)), 0.0])
    for k in range(1, n + 1):
        riser, tread = truth.surface(2 * k - 1), truth.surface(2 * k)
        assert riser.kind == "riser"
        # risers face the walker going up, away from the walker going down
        np.testing.assert_allclose(riser.normal_w, -x_w if direction == "up" else x_w, atol=1e-12)
        assert _local(truth, riser.point_w)[0] == pytest.approx((k - 1) * t, abs=1e-12)
        np.testing.assert_allclose(tread.normal_w, z_axis, atol=1e-12)
        z = k * r if direction == "up" else H - k * r
        assert tread.point_w[2] == pytest.approx(z, abs=1e-12)
        last_kind = "landing" if direction == "up" else "ground"
        assert tread.kind == (last_kind if k == n else "tread")
    # position_m is the centre of the bottom edge of the first riser
    bottom = truth.surface(1).polygon_w
    riser_bottom = bottom[np.isclose(bottom[:, 2], bottom[:, 2].min())].mean(axis=0)
    np.testing.assert_allclose(riser_bottom[:2], [2.0, 1.0], atol=1e-12)
    assert riser_bottom[2] == pytest.approx(0.0 if direction == "up" else H - r, abs=1e-12)


def test_height_at_returns_tread_heights_including_under_the_nosing() -> None:
    r, t, n, nose = 0.162, 0.28, 4, 0.03
    world = build_staircase(StaircaseParams(riser_m=r, tread_m=t, n_steps=n, nosing_m=nose, yaw_deg=-23.0,
                                            position_m=(0.5, 0.3)))
    T = np.array(world.truth.params["T_world_local"])
    for x_local, y_local, z in [(-0.5, 0.0, 0.0), (-0.01, 0.4, r), (-0.5 * nose, 0.0, r)] + [
        ((k - 1) * t + 0.5 * t, 0.2, k * r) for k in range(1, n)
    ] + [((k - 1) * t - 0.5 * nose, -0.3, k * r) for k in range(1, n + 1)] + [((n - 1) * t + 0.6, 0.0, n * r)]:
        p = T[:3, :3] @ np.array([x_local, y_local, 0.0]) + T[:3, 3]
        assert height_at(world.truth, p[0], p[1]) == pytest.approx(z, abs=1e-12), (x_local, z)


def test_height_at_on_a_ramp_follows_the_slope() -> None:
    a, L = 10.0, 2.0
    world = build_ramp(RampParams(slope_deg=a, length_m=L, yaw_deg=30.0))
    T = np.array(world.truth.params["T_world_local"])
    for x in (0.1, 0.7, 1.9):
        p = T[:3, :3] @ np.array([x, 0.3, 0.0]) + T[:3, 3]
        assert height_at(world.truth, p[0], p[1]) == pytest.approx(x * math.tan(math.radians(a)), abs=1e-12)


def test_course_heights_accumulate_and_return_to_the_floor() -> None:
    world = build_course()
    prof = world.truth.params["profile"]
    assert [p["surface_id"] for p in prof] == list(range(len(prof)))
    flats = [p for p in prof if p["kind"] == "flat"]
    assert flats[0]["z"] == 0.0 and flats[-1]["z"] == 0.0
    assert max(f["z"] for f in flats) == pytest.approx(0.6, abs=1e-12)  # 4 x 0.15 m
    for a, b in zip(prof, prof[1:]):  # the route is contiguous in x and z
        xa = a.get("x1", a.get("x"))
        xb = b.get("x0", b.get("x"))
        assert xa == pytest.approx(xb, abs=1e-12)
    for p in prof:
        s = world.truth.surface(p["surface_id"])
        assert s.kind == {"flat": p.get("surface_kind"), "riser": "riser", "slope": "ramp"}[p["kind"]]


def test_level_is_one_ground_surface() -> None:
    world = build_level()
    assert len(world.truth.surfaces) == 1
    assert height_at(world.truth, 3.0, -4.0) == 0.0
    assert math.isnan(height_at(world.truth, 30.0, 0.0))


@pytest.mark.parametrize("field,value", [("riser_m", 0.0), ("riser_m", 0.31), ("tread_m", 0.1), ("riser_m", float("nan")),
                                         ("n_steps", 2.5), ("n_steps", 0), ("nosing_m", 0.06), ("yaw_deg", 91.0),
                                         ("direction", "sideways"), ("position_m", (0.0, float("inf"))), ("walls", "maybe")])
def test_invalid_staircase_params_name_the_field(field: str, value: object) -> None:
    with pytest.raises(ConfigError) as err:
        StaircaseParams(**{field: value})
    assert err.value.field == f"stairs.{field}"
    assert field in str(err.value)


@pytest.mark.parametrize("kind", list(PARAMS))
def test_param_tables_match_the_dataclasses_and_bounds_are_enforced(kind: str) -> None:
    cls, _ = BUILDERS[kind]
    table = PARAMS[kind]
    default = cls()
    assert set(table) == set(vars(default))
    for name, spec in table.items():
        assert getattr(default, name) == spec.default or name == "segments"
        if spec.low is None or isinstance(spec.default, tuple):
            continue
        for bad in (spec.low - 1e-3 if not spec.low_open else spec.low, spec.high + 1e-3):
            with pytest.raises(ConfigError) as err:
                cls(**{name: bad})
            assert err.value.field.endswith(f".{name}")
    with pytest.raises(UnknownNameError):
        cls.from_dict({"no_such_param": 1})


def test_course_and_ramp_structure_errors() -> None:
    with pytest.raises(ConfigError, match="level segment"):
        build_course(CourseParams(segments=(("ramp", {"direction": "up"}), ("ramp", {"direction": "down"}))))
    with pytest.raises(ConfigError) as err:
        build_course(CourseParams(segments=(("stairs", {"direction": "down"}),)))
    assert err.value.field == "course.segments[0].n_steps"
    with pytest.raises(UnknownNameError):
        CourseParams(segments=(("escalator", {}),))
    with pytest.raises(ConfigError) as err:
        CourseParams(segments=(("stairs", {"riser_m": 0.4}),))
    assert err.value.field == "course.segments[0].riser_m"
    with pytest.raises(ConfigError) as err:  # a steep long ramp needs a deeper landing to hold its support
        build_ramp(RampParams(slope_deg=25.0, length_m=10.0, landing_m=0.5))
    assert err.value.field == "ramp.landing_m"
    with pytest.raises(UnknownNameError):
        build_world("office")


def test_worlds_compile_without_warnings_and_export_to_xml() -> None:
    for make in WORLDS.values():
        world = make()
        sc = compose(world, ExoSpec(user_height_m=1.65))
        data = mujoco.MjData(sc.model)
        mujoco.mj_forward(sc.model, data)
        assert data.warning.number.sum() == 0
        # the exoskeleton stands on surface 0 at the suggested start
        sole = data.site("sole_l").xpos
        s0 = world.truth.surface(0)
        assert s0.contains(sole, tol_m=1e-9)
        json.dumps(world.truth.params)  # plain values, so a session can store them
        # nothing needs files: the spec writes out and reads back
        again = mujoco.MjSpec.from_string(world.spec.to_xml()).compile()
        assert again.ngeom == world.spec.compile().ngeom
    # compose leaves the built world untouched
    world = build_staircase()
    n = world.spec.compile().nbody
    compose(world, ExoSpec())
    assert world.spec.compile().nbody == n
