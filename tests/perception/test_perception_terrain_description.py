"""Terrain description and next-step mode (seeds/002 II-F) on constructed plane sets."""

import numpy as np
import pytest

from exobench.core import ConfigError
from exobench.perception.terrain import TerrainConfig, describe_terrain, plane_class, predict_mode, slope_deg
from exobench.perception.terrain.plane_tracking import (
    DetectedPlane,
    PlaneSet,
    PlaneTrackingConfig,
    voxel_keys,
)

CELL = 0.05
CFG = TerrainConfig()


def patch(x0, x1, z0, slope_deg_=0.0, y0=-0.5, y1=0.5, center_z=None):
    """A plane over [x0, x1] x [y0, y1] at height z0 at x0, rising along +x by ``slope_deg_``."""
    t = np.tan(np.radians(slope_deg_))
    xs = np.arange(x0 + 0.25 * CELL, x1, 0.5 * CELL)
    ys = np.arange(y0 + 0.25 * CELL, y1, 0.5 * CELL)
    X, Y = np.meshgrid(xs, ys, indexing="ij")
    pts = np.column_stack([X.ravel(), Y.ravel(), z0 + t * (X.ravel() - x0)])
    n = np.array([-np.sin(np.radians(slope_deg_)), 0.0, np.cos(np.radians(slope_deg_))])
    cx, cy = 0.5 * (x0 + x1), 0.5 * (y0 + y1)
    c = np.array([cx, cy, z0 + t * (cx - x0) if center_z is None else center_z])
    area = (x1 - x0) * (y1 - y0) / np.cos(np.radians(slope_deg_))
    return DetectedPlane(c, n, float(area), voxel_keys(pts, CELL))


def plane_set(*planes):
    ps = PlaneSet(PlaneTrackingConfig(cell_m=CELL))
    for p in planes:
        ps.add(p)
    return ps


RISER, TREAD = 0.17, 0.30


def staircase():
    """Ground x in [0, 2] at z 0, four treads 0.3 m deep rising 0.17 m each, a top landing."""
    planes = [patch(0.0, 2.0, 0.0)]
    for k in range(1, 5):
        planes.append(patch(2.0 + TREAD * (k - 1), 2.0 + TREAD * k, RISER * k))
    planes.append(patch(3.2, 5.0, RISER * 5))
    return plane_set(*planes)


def tread_x(k):
    return 2.0 + TREAD * (k - 0.5)


def test_slope_and_plane_class():
    assert slope_deg([0, 0, 1]) == 0.0
    assert slope_deg([0, 0, -1]) == 0.0
    assert slope_deg([np.sin(np.radians(15)), 0, np.cos(np.radians(15))]) == pytest.approx(15.0)
    assert slope_deg([1, 0, 0]) == pytest.approx(90.0)
    assert plane_class([0, 0, 1], CFG) == "horizontal"
    assert plane_class([np.sin(np.radians(15)), 0, np.cos(np.radians(15))], CFG) == "ramp"
    assert plane_class([1, 0, 0], CFG) == "steep"


def test_staircase_description_and_modes_up_and_down():
    desc = describe_terrain(staircase(), CFG)
    stairs = [t for t in desc.terrains.values() if t.kind == "stairs"]
    assert len(stairs) == 1
    # the treads (ids 1-4) are linked; the ground's and the landing's centres are too far away
    assert stairs[0].plane_ids == (1, 2, 3, 4)
    assert desc.terrain_kind(0) == "level" and desc.terrain_kind(5) == "level"

    up = [(1.6, tread_x(1), "SA"), (tread_x(1), tread_x(2), "SA"), (tread_x(3), tread_x(4), "SA"),
          (tread_x(4), 3.6, "SA"), (3.6, 4.2, "LG"), (0.5, 1.1, "LG"), (tread_x(1), tread_x(3), "SA")]
    for cur, nxt, mode in up:
        d = desc.mode_of_step([cur, 0.1], [nxt, -0.1])
        assert (d.mode, d.reason) == (mode, "ok"), (cur, nxt, d)
        d = desc.mode_of_step([nxt, -0.1], [cur, 0.1])  # walking back down
        assert d.mode == {"SA": "SD", "LG": "LG"}[mode], (nxt, cur, d)
    d = desc.mode_of_step([tread_x(1), 0.0], [tread_x(2), 0.0])
    assert d.dz_m == pytest.approx(RISER)
    assert d.next_terrain == "stairs" and d.current_terrain == "stairs"


def test_ramp_modes_by_walking_direction():
    th = 15.8
    rise = 2.0 * np.tan(np.radians(th))
    ps = plane_set(patch(0.0, 2.0, 0.0), patch(2.0, 4.0, 0.0, th), patch(4.0, 6.0, rise))
    desc = describe_terrain(ps, CFG)
    assert [t.kind for t in desc.terrains.values()] == ["level", "ramp", "level"]
    assert desc.mode_of_step([1.2, 0], [1.8, 0]).mode == "LG"
    assert desc.mode_of_step([1.7, 0], [2.3, 0]).mode == "RA"
    assert desc.mode_of_step([2.5, 0], [3.1, 0]).mode == "RA"
    assert desc.mode_of_step([3.7, 0], [4.3, 0]).mode == "LG"  # off the ramp onto the landing
    assert desc.mode_of_step([4.3, 0], [3.7, 0]).mode == "RD"
    assert desc.mode_of_step([3.1, 0], [2.5, 0]).mode == "RD"
    assert desc.mode_of_step([2.3, 0], [1.7, 0]).mode == "LG"
    # across the ramp (no height change along the step): not a descent
    assert desc.mode_of_step([3.0, -0.3], [3.0, 0.3]).mode == "RA"
    # a ramp rising along -x, walked along -x, is ascended
    ps2 = plane_set(DetectedPlane(np.array([3.0, 0, 0.3]), np.array([np.sin(np.radians(th)), 0, np.cos(np.radians(th))]),
                                  2.0, patch(2.0, 4.0, 0.0, th).cells))
    assert predict_mode(ps2, [2.5, 0], [3.0, 0], CFG).mode == "RA"


def test_rise_threshold_boundary():
    h = CFG.stair_rise_min_m
    for dz, mode in ((h + 1e-6, "SA"), (h - 1e-6, "LG"), (-h - 1e-6, "SD"), (-h + 1e-6, "LG")):
        ps = plane_set(patch(0.0, 1.0, 0.0, center_z=0.0), patch(1.0, 2.0, dz, center_z=dz))
        assert predict_mode(ps, [1.5, 0.0], [0.5, 0.0], CFG).mode == mode, dz


def test_slope_threshold_boundary():
    lim = CFG.level_max_slope_deg
    for th, kind in ((lim - 0.01, "level"), (lim + 0.01, "ramp")):
        desc = describe_terrain(plane_set(patch(0.0, 2.0, 0.0, th)), CFG)
        assert [t.kind for t in desc.terrains.values()] == [kind]
    ramp_lim = CFG.ramp_max_slope_deg
    assert describe_terrain(plane_set(patch(0.0, 2.0, 0.0, ramp_lim - 0.01)), CFG).terrains[0].kind == "ramp"
    assert describe_terrain(plane_set(patch(0.0, 2.0, 0.0, ramp_lim + 0.01)), CFG).terrains == {}


def test_stair_link_thresholds_at_their_boundaries():
    """Two small horizontal planes form stairs iff d_ij <= d_max and h_min <= h_ij <= h_max."""
    c = CFG

    def pair(dx, h):
        a = patch(0.0, 0.3, 0.0, center_z=0.0)
        b = DetectedPlane(a.center_m + np.array([dx, 0.0, h]), a.normal, a.area_m2, patch(0.0 + dx, 0.3 + dx, h).cells)
        return [t.kind for t in describe_terrain(plane_set(a, b), c).terrains.values()]

    h = 0.15
    dx_max = np.sqrt(c.stair_center_max_m**2 - h**2)
    assert pair(dx_max - 1e-6, h) == ["stairs"]
    assert pair(dx_max + 1e-6, h) == ["level", "level"]
    assert pair(0.3, c.stair_rise_max_m - 1e-6) == ["stairs"]
    assert pair(0.3, c.stair_rise_max_m + 1e-6) == ["level", "level"]
    assert pair(0.3, c.stair_rise_min_m + 1e-6) == ["stairs"]
    assert pair(0.3, c.stair_rise_min_m - 1e-6) == ["level", "level"]


def test_area_and_score_filters():
    tiny = patch(0.0, 0.1, 0.0, y0=0.0, y1=0.1)  # 0.01 m^2 < level_min_area_m2
    assert describe_terrain(plane_set(tiny), CFG).terrains == {}
    ps = plane_set(patch(0.0, 2.0, 0.0))
    assert describe_terrain(ps, TerrainConfig(min_score=2)).terrains == {}
    ps.planes[0].score = 2
    assert list(describe_terrain(ps, TerrainConfig(min_score=2)).terrains) == [0]


def test_unknown_terrain_extrapolation_and_reach():
    th = 12.0
    ps = plane_set(patch(0.0, 2.0, 0.0, th))
    d = predict_mode(ps, [2.5, 0.0], [1.8, 0.0], CFG)  # off the mapped ramp: it continues
    assert (d.mode, d.reason, d.next_plane_id) == ("RA", "extrapolated", None)
    assert predict_mode(ps, [-0.5, 0.0], [0.2, 0.0], CFG).mode == "RD"
    d = predict_mode(plane_set(patch(0.0, 2.0, 0.0)), [2.6, 0.0], [1.8, 0.0], CFG)
    assert (d.mode, d.reason) == ("LG", "extrapolated")
    d = predict_mode(plane_set(patch(0.0, 2.0, 0.0)), [10.0, 0.0], [9.5, 0.0], CFG)
    assert (d.mode, d.reason) == ("", "no_terrain")
    d = predict_mode(plane_set(patch(0.0, 2.0, 0.3)), [1.0, 0.0], [-3.0, 0.0], CFG)
    assert (d.mode, d.reason, d.next_plane_id) == ("LG", "current_unknown", 0)
    # a table top 0.75 m above the floor, over the footprint, is out of reach
    ps = plane_set(patch(0.0, 3.0, 0.0), patch(1.5, 2.5, 0.75))
    d = predict_mode(ps, [2.0, 0.0], [1.4, 0.0], CFG)
    assert (d.mode, d.next_plane_id) == ("LG", 0)


def test_nearest_supporting_plane_at_a_nosing():
    desc = describe_terrain(staircase(), CFG)
    # 1 cm before and after the first riser's line x = 2.0
    assert desc.plane_under([1.99, 0.0]) == 0
    assert desc.plane_under([2.01, 0.0]) == 1


def test_config_errors():
    with pytest.raises(ConfigError):
        TerrainConfig(level_max_slope_deg=-1.0)
    with pytest.raises(ConfigError):
        TerrainConfig(ramp_max_slope_deg=3.0)
    with pytest.raises(ConfigError):
        TerrainConfig(stair_rise_max_m=0.05)
    with pytest.raises(ConfigError):
        TerrainConfig(min_score=0)
    with pytest.raises(ConfigError):
        TerrainConfig(stair_center_max_m=float("nan"))


def test_stray_edge_voxels_do_not_claim_the_neighbouring_plane():
    """A ramp's support holding voxels of the landing beyond its top edge (cells straddling the
    edge merged in): a footprint 0.15 m onto the landing is on the landing, not on the ramp."""
    th = 15.8
    rise = 2.0 * np.tan(np.radians(th))
    ramp = patch(0.0, 2.0, 0.0, th)
    stray = patch(2.0, 2.25, rise).cells  # landing voxels wrongly in the ramp's support
    ramp = DetectedPlane(ramp.center_m, ramp.normal, ramp.area_m2, np.union1d(ramp.cells, stray))
    landing = patch(2.0, 3.5, rise)
    desc = describe_terrain(plane_set(ramp, landing), CFG)
    assert desc.plane_under([2.15, 0.0]) == 1
    assert desc.mode_of_step([1.85, 0.0], [2.15, 0.0]).mode == "LG"
    assert desc.plane_under([1.85, 0.0]) == 0


def test_remembered_current_height():
    """The current footprint out of the mapped area: a height known from before decides the step."""
    ps = plane_set(patch(1.0, 2.0, 0.34))
    d = predict_mode(ps, [1.5, 0.0], [0.7, 0.0], CFG, current_height_m=0.17)
    assert (d.mode, d.reason, d.current_plane_id) == ("SA", "current_remembered", None)
    assert d.dz_m == pytest.approx(0.17)
    assert predict_mode(ps, [1.5, 0.0], [0.7, 0.0], CFG, current_height_m=0.51).mode == "SD"
    assert predict_mode(ps, [1.5, 0.0], [0.7, 0.0], CFG, current_height_m=0.30).mode == "LG"
    # neither footprint over a mapped plane, but the current level known by height: it continues
    # (level walking), unless the foot stood on a ramp (its direction is unknown without the plane)
    far = plane_set(patch(5.0, 6.0, 0.0))
    d = predict_mode(far, [1.5, 0.0], [0.7, 0.0], CFG, current_height_m=0.0)
    assert (d.mode, d.reason, d.current_plane_id, d.next_plane_id) == ("LG", "extrapolated", None, None)
    assert (predict_mode(far, [1.5, 0.0], [0.7, 0.0], CFG).reason) == "no_terrain"
    d = describe_terrain(far, CFG).mode_of_step([0.7, 0.0], [1.5, 0.0], 0.0, "ramp")
    assert (d.mode, d.reason) == ("", "no_terrain")
    # a plane under the current footprint wins over the remembered height
    ps = plane_set(patch(1.0, 2.0, 0.34), patch(0.0, 1.0, 0.17))
    d = predict_mode(ps, [1.5, 0.0], [0.7, 0.0], CFG, current_height_m=0.34)
    assert (d.mode, d.reason, d.current_plane_id) == ("SA", "ok", 1)


def test_drop_ahead_of_an_unseen_descending_flight():
    """From a landing (z 0.45) whose treads below are not mapped, with the floor (z 0) seen
    1 m beyond its edge: a footprint past the edge is SD ("drop_ahead"); short of a mapped
    lower plane within drop_lookahead_m, or with the ground ahead at the same level, LG."""
    landing, floor = patch(0.0, 2.0, 0.45), patch(3.0, 5.0, 0.0)
    d = predict_mode(plane_set(landing, floor), [2.3, 0.0], [1.8, 0.0], CFG)
    assert (d.mode, d.reason, d.next_plane_id) == ("SD", "drop_ahead", None)
    assert d.dz_m == pytest.approx(-0.45)
    d = predict_mode(plane_set(landing, floor), [2.3, 0.0], [1.8, 0.0], TerrainConfig(drop_lookahead_m=0.5))
    assert (d.mode, d.reason) == ("LG", "extrapolated")
    d = predict_mode(plane_set(landing, patch(3.0, 5.0, 0.45)), [2.3, 0.0], [1.8, 0.0], CFG)
    assert (d.mode, d.reason) == ("LG", "extrapolated")
    # walking away from the floor: nothing lower ahead
    d = predict_mode(plane_set(patch(1.0, 2.0, 0.45), floor), [0.7, 0.0], [1.2, 0.0], CFG)
    assert (d.mode, d.reason) == ("LG", "extrapolated")


def test_ramp_ahead_of_an_unseen_ramp_start():
    """From a landing (z 0.8, x < 4.3) a 17.8 deg ramp runs down from its edge, but only its
    lower part (x 5.5-6.8) is mapped (a head camera sees a ramp down only beyond the crest): a
    footprint on the unmapped upper part is RD ("ramp_ahead"), as the ramp plane's extension
    passes under it less than a ramp's slope below the landing; with only lower level ground
    mapped ahead it stays SD ("drop_ahead"), and a ramp plane far below the landing (its
    extension under the footprint beyond any ramp's slope) does not make it RD."""
    slope = 17.8
    t = np.tan(np.radians(slope))
    landing = patch(0.0, 4.3, 0.8)
    lower_ramp = patch(5.5, 6.8, 0.8 - (5.5 - 4.3) * t, -slope)
    d = predict_mode(plane_set(landing, lower_ramp), [4.9, 0.0], [4.2, 0.0], CFG)
    assert (d.mode, d.reason, d.next_plane_id) == ("RD", "ramp_ahead", None)
    assert d.dz_m == pytest.approx(-(4.9 - 4.3) * t, abs=0.01)
    d = predict_mode(plane_set(landing, patch(5.5, 6.8, 0.0)), [4.9, 0.0], [4.2, 0.0], CFG)
    assert (d.mode, d.reason) == ("SD", "drop_ahead")
    deep = patch(5.5, 6.8, 0.8 - (5.5 - 4.3) * t - 0.5, -slope)  # the same slope 0.5 m lower
    d = predict_mode(plane_set(landing, deep), [4.9, 0.0], [4.2, 0.0], CFG)
    assert (d.mode, d.reason) == ("SD", "drop_ahead")


def test_tread_above_a_foot_against_a_riser():
    """Level ground (z 0) up to a riser at x 2.0, the first tread (z 0.17) beyond: a level step
    whose toes (0.15 m ahead) would be inside the riser goes just past it onto the tread; one
    whose toes stop short stays; a step already on the stairs, or toward a step down, is left."""
    ps = staircase()
    desc = describe_terrain(ps, CFG)
    fwd = np.array([1.0, 0.0])
    onto = desc.tread_above([1.9, 0.0], fwd, 0.0, 0.15)
    assert onto is not None and 2.0 < onto[0] < 2.1
    assert predict_mode(ps, onto, [1.5, 0.0], CFG).mode == "SA"
    assert desc.tread_above([1.7, 0.0], fwd, 0.0, 0.15) is None  # toes 0.15 m short of the riser
    assert desc.tread_above([tread_x(1), 0.0], fwd, 0.0, 0.15) is None  # on the first tread already
    assert desc.tread_above([tread_x(2) + 0.1, 0.0], fwd, 0.0, 0.15) is None  # on the stairs (the swing foot two treads lower)
    assert desc.tread_above([tread_x(1), 0.0], -fwd, 0.17, 0.15) is None  # toward the step down


def test_remembered_class_of_a_ramp_footprint():
    """A foot that was on a ramp (its class known from before) lands on level ground: LG, even
    0.2 m lower (RD ended), as the track's truth labels leaving a ramp."""
    ps = plane_set(patch(1.0, 2.0, 0.0))
    assert predict_mode(ps, [1.5, 0.0], [0.7, 0.0], CFG, current_height_m=0.2).mode == "SD"
    desc = describe_terrain(ps, CFG)
    assert desc.mode_of_step([0.7, 0.0], [1.5, 0.0], 0.2, "ramp").mode == "LG"


def _crest(score=3):
    """A 11.8 deg ramp from x 0 up to its crest at x 2.5, a landing beyond; each plane's support
    reaches 0.25 m (ramp) and 0.1 m (landing) past the crest, as cells straddling a shallow crease
    are merged into either plane."""
    th = 11.8
    top = 2.5 * np.tan(np.radians(th))
    ps = plane_set(patch(0.0, 2.75, 0.0, th), patch(2.4, 4.5, top))
    for p in ps.planes.values():
        p.score = score
    return ps, top


def test_crease_side_decides_where_supports_overlap():
    ps, _ = _crest()
    desc = describe_terrain(ps, CFG)
    ramp, landing = 0, 1
    for x, want in ((2.3, ramp), (2.46, ramp), (2.54, landing), (2.6, landing), (2.7, landing), (3.0, landing)):
        assert desc.plane_under([x, 0.0]) == want, x
    # the step onto the landing just past the crest leaves the ramp: LG, not RA
    assert desc.mode_of_step([2.1, 0.0], [2.56, 0.0]).mode == "LG"
    # without the crease rule the ramp, reaching farther and higher there, claims the landing
    off = describe_terrain(ps, TerrainConfig(crease_min_angle_deg=90.0))
    assert off.plane_under([2.6, 0.0]) == ramp
    assert off.mode_of_step([2.1, 0.0], [2.56, 0.0]).mode == "RA"
    # a plane fitted in one update only (score below crease_min_score) is not trusted with a crease
    ps1, _ = _crest(score=1)
    assert describe_terrain(ps1, CFG).plane_under([2.6, 0.0]) == ramp


def test_crease_ahead_puts_the_foot_past_a_ramp_crease():
    ps, _ = _crest()
    desc = describe_terrain(ps, CFG)
    fwd = np.array([1.0, 0.0])
    onto = desc.crease_ahead([2.46, 0.0], fwd, 0.06)  # toes across the crest
    assert onto is not None and 2.5 < onto[0] <= 2.54
    assert desc.plane_under(onto) == 1
    assert desc.crease_ahead([2.3, 0.0], fwd, 0.06) is None  # toes still on the ramp
    assert desc.crease_ahead([2.7, 0.0], fwd, 0.06) is None  # on the landing already
    # treads are parallel planes: a riser is no crease
    stairs = staircase()
    for p in stairs.planes.values():
        p.score = 3
    st = describe_terrain(stairs, CFG)
    assert st.crease_ahead([tread_x(1) + 0.12, 0.0], fwd, 0.06) is None


def test_a_ceiling_seen_from_below_is_no_terrain():
    """A stairwell's ceiling over the course (2.4 m over its landing): extracted as a level plane
    whose normal, oriented towards the camera below it, points down. It is classed overhead and
    never walked on: the floor stays the plane under a footprint (before, the ceiling, as large
    and higher, won the look-up) and the stairs under it keep their modes."""
    from exobench.perception.terrain.plane_tracking import plane_from_points

    camera = np.array([1.0, 0.0, 1.6])
    xs, ys = np.meshgrid(np.arange(-0.5, 5.0, 0.5 * CELL), np.arange(-0.5, 0.5, 0.5 * CELL), indexing="ij")
    pts = np.column_stack([xs.ravel(), ys.ravel(), np.full(xs.size, 0.17 * 5 + 2.4)])
    ceiling = plane_from_points(pts, CELL, toward_m=camera)
    assert ceiling.normal[2] == pytest.approx(-1.0)
    assert plane_class(ceiling.normal, CFG) == "overhead"
    assert plane_class([0.0, 0.0, 1.0], CFG) == "horizontal"
    ps = staircase()
    ps.add(ceiling)
    desc = describe_terrain(ps, CFG)
    ceiling_id = max(desc.planes)
    assert desc.plane_classes[ceiling_id] == "overhead"
    assert ceiling_id not in desc.terrain_of_plane
    assert desc.plane_under(np.array([1.0, 0.0])) == 0
    assert predict_mode(ps, np.array([1.6, 0.0]), np.array([1.0, 0.0]), CFG).mode == "LG"
    assert predict_mode(ps, np.array([tread_x(2), 0.0]), np.array([tread_x(1), 0.0]), CFG).mode == "SA"
    assert predict_mode(ps, np.array([tread_x(1), 0.0]), np.array([tread_x(2), 0.0]), CFG).mode == "SD"
