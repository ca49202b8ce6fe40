"""Plane set update by IoU with scores (seeds/002 II-F, eq. 23) on constructed plane sets."""

import numpy as np
import pytest

from exobench.core import ConfigError
from exobench.perception.terrain.plane_tracking import (
    DetectedPlane,
    PlaneSet,
    PlaneTrackingConfig,
    iou,
    merge_planes,
    plane_from_points,
    voxel_centers,
    voxel_keys,
)

CELL = 0.1
CFG = PlaneTrackingConfig(cell_m=CELL, iou_min=0.5, scope_min_cells=10)


def patch(x0, x1, y0=0.0, y1=1.0, z=0.05, normal=(0.0, 0.0, 1.0)):
    """A horizontal patch sampled at voxel centres: (x1-x0)/0.1 x (y1-y0)/0.1 voxels."""
    xs = np.arange(x0 + 0.05, x1, CELL)
    ys = np.arange(y0 + 0.05, y1, CELL)
    pts = np.array([(x, y, z) for x in xs for y in ys])
    return DetectedPlane(pts.mean(axis=0), np.array(normal), (x1 - x0) * (y1 - y0), voxel_keys(pts, CELL))


def test_voxel_keys_round_trip_and_iou_by_hand():
    pts = np.array([[0.05, -0.05, 0.05], [-3.25, 7.15, 1.05], [0.06, -0.04, 0.09]])
    keys = voxel_keys(pts, CELL)
    assert keys.size == 2  # the first and third share a voxel
    np.testing.assert_allclose(sorted(map(tuple, voxel_centers(keys, CELL))), [(-3.25, 7.15, 1.05), (0.05, -0.05, 0.05)])
    a, b = patch(0.0, 1.0), patch(0.2, 1.2)
    assert a.cells.size == b.cells.size == 100
    assert iou(a.cells, b.cells) == pytest.approx(80 / 120)
    assert iou(a.cells, patch(3.0, 4.0).cells) == 0.0


def test_matching_plane_merges_and_its_score_increases():
    ps = PlaneSet(CFG)
    rep = ps.update([patch(0.0, 1.0)])
    assert rep.added == [0] and ps.planes[0].score == 1
    rep = ps.update([patch(0.2, 1.2)])  # IoU 2/3 >= 0.5
    assert rep.matched == [0] and rep.added == [] and list(ps.planes) == [0]
    p = ps.planes[0]
    assert p.score == 2
    assert p.cells.size == 120
    assert p.area_m2 == pytest.approx(1.0 + 1.0 * (1 - 80 / 100))  # B's uncovered part only
    np.testing.assert_allclose(p.center_m, [0.6, 0.5, 0.05], atol=1e-9)  # mean of the union's voxels
    np.testing.assert_allclose(p.normal, [0, 0, 1])
    ps.update([patch(0.1, 1.1)])
    assert ps.planes[0].score == 3


def test_new_plane_is_added_and_unmatched_planes_decrement_then_vanish():
    ps = PlaneSet(CFG)
    ps.update([patch(0.0, 1.0)])
    rep = ps.update([patch(0.0, 1.0)])
    assert ps.planes[0].score == 2 and rep.matched == [0]
    rep = ps.update([patch(3.0, 4.0)])  # no pair: added with score 1; plane 0 decremented
    assert rep.added == [1] and rep.decremented == [0] and rep.deleted == []
    assert (ps.planes[0].score, ps.planes[1].score) == (1, 1)
    rep = ps.update([])  # both in scope (observed_cells None), both unmatched: 1 -> 0, deleted
    assert rep.decremented == [0, 1] and rep.deleted == [0, 1] and ps.planes == {}
    assert ps.update([patch(0.0, 1.0)]).added == [2]  # ids are never reused


def test_planes_out_of_scope_keep_their_score():
    ps = PlaneSet(CFG)
    far = ps.add(patch(0.0, 1.0), score=1)
    near = patch(5.0, 6.0)
    seen = near.cells  # this frame observes only the region of the new detection
    rep = ps.update([near], observed_cells=seen)
    assert rep.added == [1] and rep.decremented == [] and ps.planes[far].score == 1
    # a plane with fewer than scope_min_cells voxels in view is out of scope as well
    few = voxel_keys(np.array([[0.05 + 0.1 * i, 0.05, 0.05] for i in range(9)]), CELL)
    rep = ps.update([], observed_cells=np.union1d(few, seen))
    assert rep.decremented == [1] and rep.deleted == [1] and ps.planes[far].score == 1


def test_iou_uses_the_observed_part_of_a_large_plane():
    big, part = patch(0.0, 3.0), patch(2.0, 3.0)
    assert iou(big.cells, part.cells) == pytest.approx(1 / 3)  # the whole plane would not match
    ps = PlaneSet(CFG)
    ps.add(big)
    rep = ps.update([part], observed_cells=part.cells)
    assert rep.matched == [0] and rep.added == []
    assert ps.planes[0].score == 2 and ps.planes[0].area_m2 == pytest.approx(3.0)
    ps2 = PlaneSet(CFG)
    ps2.add(big)
    rep = ps2.update([part])  # without the view, the whole plane is compared: no match
    assert rep.added == [1] and rep.decremented == [0]


def test_a_detection_bridging_two_planes_merges_them():
    ps = PlaneSet(CFG)
    a = ps.add(patch(0.0, 1.0), score=3)
    b = ps.add(patch(1.0, 2.0), score=1)
    rep = ps.update([patch(0.0, 2.0)])  # IoU 100/200 = 0.5 with each
    assert rep.merged == {a: [b]} and rep.matched == [a] and list(ps.planes) == [a]
    p = ps.planes[a]
    assert p.score == 4  # highest score of the group + 1
    assert p.cells.size == 200 and p.area_m2 == pytest.approx(2.0)
    np.testing.assert_allclose(p.center_m, [1.0, 0.5, 0.05], atol=1e-9)


def test_score_rises_once_per_frame():
    ps = PlaneSet(CFG)
    ps.add(patch(0.0, 1.0))
    rep = ps.update([patch(0.0, 0.5), patch(0.5, 1.0)])  # two halves, IoU 0.5 each
    assert rep.matched == [0] and ps.planes[0].score == 2 and len(ps.planes) == 1
    capped = PlaneSet(PlaneTrackingConfig(cell_m=CELL, max_score=2))
    capped.add(patch(0.0, 1.0), score=2)
    capped.update([patch(0.0, 1.0)])
    assert capped.planes[0].score == 2


def test_merge_geometry_by_hand():
    cells = patch(0.0, 1.0).cells
    t = np.radians(10.0)
    p = DetectedPlane(np.array([0.5, 0.5, 0.0]), np.array([0.0, 0.0, 1.0]), 1.0, cells)
    q = DetectedPlane(np.array([0.5, 0.5, 0.04]), -np.array([np.sin(t), 0.0, np.cos(t)]), 3.0, cells)
    center, n, area, merged = merge_planes(p, q, CELL)
    n_hand = np.array([3 * np.sin(t), 0.0, 1 + 3 * np.cos(t)])
    n_hand /= np.linalg.norm(n_hand)
    np.testing.assert_allclose(n, n_hand)  # q's normal flipped to agree with p's
    offset = (1.0 * n_hand @ p.center_m + 3.0 * n_hand @ q.center_m) / 4.0
    assert n @ center == pytest.approx(offset)
    m = np.array([0.5, 0.5, 0.05])  # mean of the voxel centres
    np.testing.assert_allclose(center - (n @ center) * n, m - (n @ m) * n, atol=1e-12)  # in-plane part of m
    assert area == pytest.approx(1.0) and merged.size == 100  # q entirely inside p


def test_plane_from_points_on_a_tilted_rectangle():
    a = np.radians(30.0)
    u, v = np.meshgrid(np.arange(0.0, 1.0, 0.01), np.arange(0.0, 0.8, 0.01))
    local = np.column_stack([u.ravel(), v.ravel(), np.zeros(u.size)])
    R = np.array([[1, 0, 0], [0, np.cos(a), -np.sin(a)], [0, np.sin(a), np.cos(a)]])
    pts = local @ R.T + [2.0, 1.0, 0.3]
    d = plane_from_points(pts, 0.02)
    np.testing.assert_allclose(d.normal, [0, -np.sin(a), np.cos(a)], atol=1e-9)
    np.testing.assert_allclose(d.center_m, pts.mean(axis=0))
    assert d.area_m2 == pytest.approx(0.8, rel=0.08)
    below = plane_from_points(pts, 0.02, toward_m=np.array([2.5, 1.0, -5.0]))
    np.testing.assert_allclose(below.normal, -d.normal)


@pytest.mark.parametrize(
    "kw, field",
    [({"cell_m": 0.0}, "plane_tracking.cell_m"), ({"iou_min": 0.0}, "plane_tracking.iou_min"),
     ({"iou_min": 1.5}, "plane_tracking.iou_min"), ({"scope_min_cells": 0}, "plane_tracking.scope_min_cells"),
     ({"max_score": 0}, "plane_tracking.max_score")],
)
def test_bad_config_names_the_field(kw, field):
    with pytest.raises(ConfigError) as err:
        PlaneTrackingConfig(**kw)
    assert err.value.field == field


def _tilted(x0, x1, deg, y0=0.0, y1=1.0):
    """A ramp strip rising along x at ``deg`` from (x0, z=0.05), sampled at 2 cm (voxels of 0.1 m)."""
    t = np.radians(deg)
    xs = np.arange(x0 + 0.01, x1, 0.02)
    ys = np.arange(y0 + 0.05, y1, CELL)
    pts = np.array([(x, y, 0.05 + (x - x0) * np.tan(t)) for x in xs for y in ys])
    n = np.array([-np.sin(t), 0.0, np.cos(t)])
    return DetectedPlane(pts.mean(axis=0), n, (x1 - x0) * (y1 - y0) / np.cos(t), voxel_keys(pts, CELL))


def test_a_ramp_sharing_the_crease_voxels_is_not_merged_into_its_landing():
    """Gate: IoU >= 0.5 on the seen part alone would merge a 12 deg ramp strip into the level plane
    whose voxels it shares near the crease; with the normal gate it is a plane of its own, and the
    landing, whose seen voxels the ramp detection claims, is neither matched nor decremented."""
    landing = patch(0.0, 1.0)
    ramp = _tilted(0.0, 0.4, 12.0)  # rises 8.5 cm over 0.4 m: its voxels are the landing's, one row up at most
    seen = ramp.cells
    ungated = PlaneSet(PlaneTrackingConfig(cell_m=CELL, scope_min_cells=10, match_angle_deg=None, match_offset_m=None,
                                           scope_min_fraction=0.0))
    ungated.add(landing, score=5)
    vis = np.intersect1d(landing.cells, seen)
    assert iou(ramp.cells, vis) >= 0.5  # eq. 23 alone matches them
    assert ungated.update([ramp], observed_cells=seen).matched == [0]
    ps = PlaneSet(CFG)
    ps.add(landing, score=5)
    rep = ps.update([ramp], observed_cells=seen)
    assert rep.added == [1] and rep.matched == [] and rep.decremented == [] and ps.planes[0].score == 5
    np.testing.assert_allclose(ps.planes[0].normal, [0, 0, 1])


def test_a_plane_mostly_out_of_view_is_not_in_scope():
    """scope_min_fraction: a 100-voxel plane with 20 voxels seen and no detection keeps its score;
    with 40 seen (>= 30 %) it is decremented."""
    ps = PlaneSet(CFG)
    ps.add(patch(0.0, 1.0), score=3)
    assert ps.update([], observed_cells=patch(0.0, 0.2).cells).decremented == []
    assert ps.update([], observed_cells=patch(0.0, 0.4).cells).decremented == [0] and ps.planes[0].score == 2
