"""The office over several days: the furniture layer, change scripts, their validation, change truth, routes."""

from __future__ import annotations

import hashlib
import json

import numpy as np
import pytest

from exobench.core.errors import ChangeScriptError, ConfigError
from exobench.models.furniture_kinds import MAKERS
from exobench.models.office import OfficeParams, build_office
from exobench.models.office_change_truth import change_truth
from exobench.models.office_changes import (
    Change,
    ChangeScript,
    apply_changes,
    changed_ids,
    draw_changes,
    parse_changes,
)
from exobench.models.office_layout import build_layout
from exobench.models.office_routes import WALKER_HALF_WIDTH_M, region_route, standing
from exobench.models.office_truth import solids_from_truth

pytestmark = pytest.mark.long(seconds=11)  # the workers take it first (tests/conftest.py); 11: the file at -n 0 in one run at load 12-15, scaled to that run's CPU

# digests of offices built by the code before the furniture layer existed (commit e84e66f):
# every geom of the compiled model (name, type, pose, size, material) and the truth (surfaces,
# objects, params less the layer's two new keys)
GOLDEN = {
    "default": (OfficeParams(), "6aa1a6f8b9f05fb1"),
    "small_full": (OfficeParams(seed=7, n_offices=3, corridor_length_m=14.0, furniture_density=1.0), "20b0510603b89acc"),
    "long_sparse": (OfficeParams(seed=11, n_offices=8, corridor_length_m=30.0, furniture_density=0.3), "cc2c14e07423eeaa"),
    "curtain": (OfficeParams(seed=3, facade="curtain"), "c97641bc15cec44a"),
}


def _digest(world) -> str:
    m = world.spec.compile()
    h = hashlib.sha256()
    for i in range(m.ngeom):
        g = m.geom(i)
        h.update(g.name.encode())
        for a in (np.asarray(g.type), g.pos, g.size, g.quat, np.asarray(g.matid)):
            h.update(np.ascontiguousarray(a).tobytes())
    t = world.truth
    for s in t.surfaces:
        h.update(s.kind.encode())
        h.update(np.asarray(s.polygon_w).tobytes())
        h.update(np.asarray(s.normal_w).tobytes())
    h.update(json.dumps([dict(o) for o in t.objects], sort_keys=True).encode())
    params = {k: v for k, v in t.params.items() if k not in ("furniture_seed", "furnish")}
    h.update(json.dumps(params, sort_keys=True, default=str).encode())
    return h.hexdigest()[:16]


@pytest.mark.parametrize("name", list(GOLDEN))
def test_furniture_seed_unset_builds_todays_office_to_the_bit(name):
    params, digest = GOLDEN[name]
    assert params.furniture_seed == -1
    assert _digest(build_office(params)) == digest
    # nor does a script on its day 0: only the truth's params say which script it is
    scripted = build_office(params, ChangeScript((Change(1, "remove", "chair0"),)), 0)
    assert scripted.truth.params["changes"] == "1 remove chair0" and scripted.truth.params["day"] == 0
    assert scripted.truth.params["solids"] == build_office(params).truth.params["solids"]


def test_furniture_seed_refurnishes_the_same_building():
    a, b = build_layout(OfficeParams()), build_layout(OfficeParams(furniture_seed=5))
    assert a.solids[: a.n_static] == b.solids[: b.n_static]
    assert [(p.piece.cls, p.x, p.y) for p in a.furniture] != [(p.piece.cls, p.x, p.y) for p in b.furniture]
    assert [(p.id, p.x) for p in b.furniture] == [(p.id, p.x) for p in build_layout(OfficeParams(furniture_seed=5)).furniture]


def test_lab_is_furnished_with_benches_and_shelves_in_the_same_building():
    office, lab = build_layout(OfficeParams()), build_layout(OfficeParams(furnish="lab"))
    assert office.solids[: office.n_static] == lab.solids[: lab.n_static]
    classes = {p.piece.cls for p in lab.furniture}
    assert {"bench", "shelf", "stool"} <= classes and not classes & {"desk", "chair", "couch"}
    # every piece stands on the floor of its room, clear of the others (boxes of different pieces do not cut)
    for p in lab.furniture:
        solids = p.emit()[0]
        assert min(s.lo[2] for s in solids) == pytest.approx(0.0, abs=1e-12)
    world = build_office(OfficeParams(furnish="lab"))
    assert world.spec.compile().ngeom == len(world.truth.params["solids"])


def test_scripts_are_drawn_deterministically_from_their_seed():
    layout = build_layout(OfficeParams())
    a, b = draw_changes(layout, 4, 3), draw_changes(layout, 4, 3)
    assert a == b and len(a.changes) >= 3
    assert draw_changes(layout, 5, 3) != a
    assert draw_changes(layout, 4, 2) == a.upto(2)  # a longer script starts with the shorter one
    assert parse_changes(a.compact()) == a and parse_changes(a.to_json()) == a
    kinds = {c.kind for c in draw_changes(layout, 1, 6).changes}
    assert {"move", "add", "obstacle"} <= kinds


def _geoms(model) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    return {model.geom(i).name: (model.geom(i).pos.copy(), model.geom(i).size.copy()) for i in range(model.ngeom)}


def _first_valid(layout, candidates: list[Change]) -> Change:
    for c in candidates:
        try:
            apply_changes(layout, ChangeScript((c,)), 1)
        except ChangeScriptError:
            continue
        return c
    raise AssertionError("no candidate move is valid")


def test_applying_a_script_moves_exactly_the_named_objects():
    p = OfficeParams()
    layout = build_layout(p)
    cab = next(f for f in layout.furniture if f.piece.cls == "cabinet")
    shifts = [(dx, dy) for dx in (0.6, -0.6, 1.0, -1.0, 0.3, -0.3) for dy in (0.0, 0.3, -0.3)]
    move = _first_valid(layout, [Change(1, "move", cab.id, x=cab.x + dx, y=cab.y + dy, turn=cab.k) for dx, dy in shifts])
    gone = next(f for f in layout.furniture if f.piece.cls == "plant")
    script = ChangeScript((move, Change(1, "remove", gone.id)))
    before = _geoms(build_office(p, script, 0).spec.compile())
    after = _geoms(build_office(p, script, 1).spec.compile())
    assert set(before) - set(after) == {n for n in before if n.startswith(gone.id + "_")}
    assert set(after) <= set(before)
    d = np.array([move.x - cab.x, move.y - cab.y, 0.0])
    for name, (pos, size) in after.items():
        if name.startswith(cab.id + "_"):
            np.testing.assert_allclose(pos, before[name][0] + d, atol=1e-12)
        else:
            assert np.array_equal(pos, before[name][0]) and np.array_equal(size, before[name][1]), name
    assert changed_ids(layout.furniture, apply_changes(layout, script, 1)[1]) == {cab.id: "moved", gone.id: "removed"}


def _on_box_boundary(p: np.ndarray, lo: np.ndarray, hi: np.ndarray, tol: float = 1e-9) -> np.ndarray:
    inside = np.all((p >= lo - tol) & (p <= hi + tol), axis=1)
    on_face = np.any((np.abs(p - lo) <= tol) | (np.abs(p - hi) <= tol), axis=1)
    return inside & on_face


def _strictly_inside(p: np.ndarray, lo: np.ndarray, hi: np.ndarray, tol: float = 1e-9) -> np.ndarray:
    return np.all((p > lo + tol) & (p < hi - tol), axis=1)


def test_change_truth_of_a_moved_and_a_removed_cabinet():
    p = OfficeParams()
    layout = build_layout(p)
    cabs = [f for f in layout.furniture if f.piece.cls == "cabinet"]
    cab, gone = cabs[0], cabs[1]
    shifts = [(dx, dy) for dx in (0.6, -0.6, 1.0, -1.0) for dy in (0.0, 0.4, -0.4)]
    move = _first_valid(layout, [Change(1, "move", cab.id, x=cab.x + dx, y=cab.y + dy, turn=cab.k) for dx, dy in shifts])
    truth = change_truth(p, ChangeScript((move, Change(1, "remove", gone.id))), 1)
    day = truth.days[0]
    assert {(o.object_id, o.kind) for o in day.objects} == {(cab.id, "moved"), (gone.id, "removed")}
    old = cab.emit()[0][0]
    new = next(f for f in apply_changes(layout, ChangeScript((move,)), 1)[1] if f.id == cab.id).emit()[0][0]
    rem = gone.emit()[0][0]
    a, dis = day.appeared, day.disappeared
    # appeared: on the new cabinet's faces, or on the floor freed under the old one and the removed one
    on_new = _on_box_boundary(a, new.lo, new.hi)
    on_floor = (np.abs(a[:, 2]) < 1e-12) & (_on_box_boundary(a, old.lo, old.hi) | _on_box_boundary(a, rem.lo, rem.hi))
    assert np.all(on_new | on_floor)
    assert not np.any(_strictly_inside(a, old.lo, old.hi)) and not np.any(a[:, 2] < -1e-12)
    # the new top is all there, on a 1 cm grid
    top = on_new & (np.abs(a[:, 2] - new.hi[2]) < 1e-12)
    w, d = (new.hi - new.lo)[:2]
    assert abs(top.sum() - (w / 0.01) * (d / 0.01)) <= 2 * (w + d) / 0.01 + 4
    assert np.all(day.appeared_normals[top] == [0.0, 0.0, 1.0])
    # disappeared: on the old and the removed cabinets' faces, or the floor now under the new one
    on_old = _on_box_boundary(dis, old.lo, old.hi) | _on_box_boundary(dis, rem.lo, rem.hi)
    under_new = (np.abs(dis[:, 2]) < 1e-12) & _on_box_boundary(dis, new.lo, new.hi)
    assert np.all(on_old | under_new) and under_new.any()
    assert not np.any(_strictly_inside(dis, new.lo, new.hi))
    # voxels: what the removed cabinet occupied, up to the layer it shares with its wall and neighbours
    v = 0.05
    lo_i, hi_i = np.floor(rem.lo / v + 1e-9).astype(int), np.ceil(rem.hi / v - 1e-9).astype(int)
    box = {(i, j, k) for i in range(lo_i[0], hi_i[0]) for j in range(lo_i[1], hi_i[1]) for k in range(lo_i[2], hi_i[2])}
    vs = truth.voxels[0]
    removed = {tuple(x) for x in vs.ijk(day.voxels_removed)}
    assert len(box) > 100
    in_rem = {x for x in removed if all(lo_i[k] <= x[k] < hi_i[k] for k in range(3))}
    old_i, old_h = np.floor(old.lo / v + 1e-9).astype(int), np.ceil(old.hi / v - 1e-9).astype(int)
    assert removed - in_rem == {x for x in removed if all(old_i[k] <= x[k] < old_h[k] for k in range(3))}
    for x in box - in_rem:  # kept only on the outer layer of the box
        assert any(x[k] in (lo_i[k], hi_i[k] - 1) for k in range(3)), x
    assert len(box - in_rem) < 0.5 * len(box)
    # voxel sets of consecutive days differ by exactly the added and removed ones
    rebuilt = np.union1d(np.setdiff1d(truth.voxels[0].index, day.voxels_removed), day.voxels_added)
    assert np.array_equal(rebuilt, truth.voxels[1].index)


def _trolley(variant: int):
    return MAKERS["trolley"](np.random.default_rng(variant))


def test_invalid_scripts_are_refused_naming_day_and_object():
    p = OfficeParams()
    layout = build_layout(p)
    desk = next(f for f in layout.furniture if f.piece.cls == "desk" and f.room.startswith("office"))
    chair = next(f for f in layout.furniture if f.piece.cls == "chair" and f.room == desk.room)
    cab = next(f for f in layout.furniture if f.piece.cls == "cabinet" and f.room.startswith("office"))
    y_wall = layout.regions[5]["clear"][3] + 0.1  # inside the north exterior wall
    cases = [
        (Change(2, "move", cab.id, x=cab.x, y=y_wall, turn=cab.k), "wall_ext_n"),
        (Change(1, "move", chair.id, x=desk.x, y=desk.y, turn=chair.k), f"cut {desk.id}"),
        (Change(3, "remove", "chair999"), "no such object"),
        (Change(1, "move", "desk_missing", x=1.0, y=1.0), "no such object"),
        (Change(1, "add", cab.id, "cabinet", 1, 1.0, 1.0, 0), "taken"),
    ]
    # a spot in a room where a couch may go holds a stack of boxes too, but obstacles go in corridors
    spots = [(x, y) for r in layout.regions if r["kind"] == "office" for x in np.linspace(r["clear"][0] + 1.1, r["clear"][1] - 1.1, 5)
             for y in np.linspace(r["clear"][2] + 0.6, r["clear"][3] - 0.6, 7)]
    spot = _first_valid(layout, [Change(1, "add", "sofa", "couch", 0, x, y, 0) for x, y in spots])
    cases.append((Change(1, "obstacle", "cart", "boxes", 2, spot.x, spot.y, 0), "corridor, not in office"))
    for change, words in cases:
        with pytest.raises(ChangeScriptError) as e:
            build_office(p, ChangeScript((change,)), 0)  # refused whatever day is asked
        assert e.value.day == change.day and e.value.object_id == change.object_id, str(e.value)
        assert words in str(e.value) and f"day {change.day}" in str(e.value)
        assert isinstance(e.value, ConfigError)
    # two trolleys in the south corridor: the first leaves room, the second closes it
    t = _trolley(1)
    w, d = t.size[0], t.size[1]
    first = Change(1, "obstacle", "cart_a", "trolley", 1, 12.0, 0.02 + w / 2, 1)
    apply_changes(layout, ChangeScript((first,)), 1)
    second = Change(2, "obstacle", "cart_b", "trolley", 1, 12.0 + d + 0.2, 1.78 - w / 2, 1)
    with pytest.raises(ChangeScriptError) as e:
        apply_changes(layout, ChangeScript((first, second)), 1)
    assert (e.value.day, e.value.object_id) == (2, "cart_b") and "close corridor_s" in str(e.value)
    with pytest.raises(ConfigError):
        parse_changes("1 move chair0 1.0")
    with pytest.raises(ConfigError):
        parse_changes('[{"day": 0, "kind": "remove", "object_id": "chair0"}]')


def _dense(route: list[tuple[float, float]], step: float = 0.01) -> np.ndarray:
    out = [np.asarray(route[0])]
    for a, b in zip(route[:-1], route[1:]):
        a, b = np.asarray(a), np.asarray(b)
        n = max(1, int(np.ceil(np.linalg.norm(b - a) / step)))
        out.append(a + np.linspace(0, 1, n + 1)[1:, None] * (b - a))
    return np.concatenate([o.reshape(-1, 2) for o in out])


def _distance_to_rect(p: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    return np.linalg.norm(np.maximum(np.maximum(lo - p, p - hi), 0.0), axis=1)


def test_a_route_visits_the_regions_and_goes_round_a_corridor_obstacle():
    p = OfficeParams()
    regions = ["corridor_s", "corridor_e", "office2"]
    t = _trolley(3)
    w, d = t.size[0], t.size[1]
    # across the middle of the south corridor, where the way along it runs, leaving 0.85 m on its south side
    cart = Change(1, "obstacle", "cart", "trolley", 3, 8.0, 0.85 + d / 2, 0)
    script = ChangeScript((cart,))
    day0, day1 = build_office(p, script, 0), build_office(p, script, 1)
    lo, hi = np.array([8.0 - w / 2, 0.85]), np.array([8.0 + w / 2, 0.85 + d])
    before, after = _dense(region_route(day0.truth, regions)), _dense(region_route(day1.truth, regions))
    assert _distance_to_rect(before, lo, hi).min() < WALKER_HALF_WIDTH_M  # the obstacle is in the way
    assert _distance_to_rect(after, lo, hi).min() >= WALKER_HALF_WIDTH_M
    for s in standing(solids_from_truth(day1.truth)):  # and so is everything else standing that day
        assert _distance_to_rect(after, s.lo[:2], s.hi[:2]).min() >= WALKER_HALF_WIDTH_M, s.name
    rects = {r["name"]: r["rect"] for r in day1.truth.params["regions"]}
    for name in regions:
        x0, x1, y0, y1 = rects[name]
        assert np.any((after[:, 0] > x0) & (after[:, 0] < x1) & (after[:, 1] > y0) & (after[:, 1] < y1)), name
    assert after[0].tolist() == day1.truth.params["start_w"][:2]
    with pytest.raises(KeyError):
        region_route(day1.truth, ["kitchen"])


def _day1_solids():
    """The small full office on day 1 of a drawn script: chairs (cylinders), bins, walls meeting walls."""
    from exobench.models.office_change_truth import _day_solids

    params = OfficeParams(seed=7, n_offices=3, corridor_length_m=14.0, furniture_density=1.0)
    layout = build_layout(params)
    script = draw_changes(layout, 5, 1)
    return params, script, _day_solids(layout, apply_changes(layout, script, 1)[1])


def test_surface_samples_are_the_sampled_points_that_exist_to_the_bit():
    """surface_samples (one face run at a time, duplicates looked for only where runs meet) gives
    exactly what sampling everything, dropping repeated rows and testing every point against
    every solid gives: the same points, in the same order, to the bit; in a region holding
    curved solids, and on two boxes with coincident faces (repeated rows)."""
    from exobench.models.office_change_truth import (
        _exists,
        _exposed_samples,
        _runs,
        _samples,
        _slabs,
        surface_samples,
    )
    from exobench.models.office_furniture import Solid
    from exobench.models.office_truth import SolidIndex

    def reference(solids, region):
        p, n, _ = _samples(solids, [region], 0.01)
        return p[_exists(SolidIndex(solids + _slabs(solids)), p, n)]

    def same(a, b):
        return a.shape == b.shape and np.array_equal(a.view(np.uint64), b.view(np.uint64))

    params, script, solids = _day1_solids()
    c = np.asarray(next(s for s in solids if s.shape == "cylinder").centre)
    region = np.array([c - [1.0, 1.0, 1.0], c + [1.0, 1.0, 3.0]])
    want = reference(solids, region)
    assert len(want) > 50_000
    assert same(surface_samples(params, script, 1, 0.01, region), want)
    # no office has coincident faces of one orientation (no row repeats): two overlapping boxes
    # with one top and one bottom do, with a cylinder and a sphere standing on them
    boxes = [Solid("floor", "plane", (1.0, 1.0, 0.0), (2.0, 2.0, 0.0), "", "", "floor"),
             Solid("a", "box", (1.0, 1.0, 0.5), (0.5, 0.5, 0.5), "", "", "furniture"),
             Solid("b", "box", (1.3, 1.1, 0.5), (0.5, 0.3, 0.5), "", "", "furniture"),
             Solid("c", "cylinder", (0.8, 0.8, 1.2), (0.1, 0.1, 0.2), "", "", "furniture"),
             Solid("d", "sphere", (1.5, 1.2, 1.1), (0.1, 0.1, 0.1), "", "", "furniture")]  # fmt: skip
    region = np.array([[-0.5, -0.5, -0.5], [2.5, 2.5, 2.0]])
    raw = sum(len(q) for _, q, _, _ in _runs(boxes, region, 0.01))
    assert raw > len(_samples(boxes, [region], 0.01)[0]) + 1000  # rows repeat
    assert same(_exposed_samples(boxes, region, 0.01), reference(boxes, region))


def test_surface_samples_of_a_region_are_those_of_a_larger_one_inside_it_to_the_bit():
    """Growing the region (the camera's reach, not 3 m) keeps every sample of the smaller one as
    it was: the grid is the world's, not the region's."""
    from exobench.models.office_change_truth import surface_samples

    params, script, solids = _day1_solids()
    small = np.array([[2.0, 4.0, -1.0], [3.5, 6.5, 4.0]])
    big = np.array([[0.5, 2.5, -1.0], [5.0, 8.0, 4.0]])
    a = surface_samples(params, script, 1, 0.01, small)
    b = surface_samples(params, script, 1, 0.01, big)
    inside = np.all((b >= small[0]) & (b <= small[1]), axis=1)
    assert len(b) > 2 * len(a) > 50_000
    assert np.array_equal(b[inside].view(np.uint64), a.view(np.uint64))
