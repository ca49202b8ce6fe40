"""Terrain queries (envs/terrain.py) give what the per-surface rule gives: for each walkable
surface in turn, the points in its box and inside its polygon (:func:`inside_polygon`) take its
height where it is higher. The queries test all boxes at once and every edge of a polygon at once;
the answers must stay the same to the bit (the planners' footholds, and so every episode, depend on
them)."""

import numpy as np
import pytest

from exobench.core.errors import ConfigError
from exobench.envs import terrain as terrain_module
from exobench.envs.sim.scenarios.course import LocomotionScenario
from exobench.envs.sim.scenarios.course_world import build_locomotion_world
from exobench.envs.terrain import Terrain, inside_polygon


def _rule(truth, xy, tol_m=1e-6):
    """The rule surface by surface, with :func:`inside_polygon` (the loop the queries replaced)."""
    best_z, best_id = np.full(len(xy), -np.inf), np.full(len(xy), -1)
    for s in truth.surfaces:
        if s.kind not in terrain_module.WALKABLE or abs(s.normal_w[2]) < 1e-6:
            continue
        pad = 10.0 * tol_m
        x0, x1 = s.polygon_w[:, 0].min() - pad, s.polygon_w[:, 0].max() + pad
        y0, y1 = s.polygon_w[:, 1].min() - pad, s.polygon_w[:, 1].max() + pad
        rows = np.flatnonzero((xy[:, 0] >= x0) & (xy[:, 0] <= x1) & (xy[:, 1] >= y0) & (xy[:, 1] <= y1))
        n, p = s.normal_w, s.point_w
        q = xy[rows]
        z = p[2] - (n[0] * (q[:, 0] - p[0]) + n[1] * (q[:, 1] - p[1])) / n[2]
        better = inside_polygon(s.polygon_w, n, np.column_stack([q, z]), tol_m) & (z > best_z[rows])
        best_z[rows[better]], best_id[rows[better]] = z[better], s.surface_id
    best_z[best_id < 0] = np.nan
    return best_z, best_id


def _truth(terrain):
    """A locomotion course's world truth (stairs, ramps, or both lanes side by side)."""
    return build_locomotion_world(LocomotionScenario.from_dict({"terrain": terrain}))[0].truth


@pytest.mark.parametrize("terrain", ["stairs", "ramp", "parallel"])
def test_queries_give_the_per_surface_rule_to_the_bit(terrain, monkeypatch):
    truth = _truth(terrain)
    rng = np.random.default_rng(3)
    corners = np.concatenate([s.polygon_w[:, :2] for s in truth.surfaces])  # on edges and vertices, where the band decides
    lo, hi = corners.min(axis=0) - 0.5, corners.max(axis=0) + 0.5
    xy = np.concatenate([corners, corners + rng.normal(0, 1e-6, corners.shape), rng.uniform(lo, hi, (3000, 2)),
                         [[np.nan, 0.0], [0.0, np.inf]]])  # fmt: skip
    monkeypatch.setattr(terrain_module, "_ROWS", 1000)  # several blocks of points, and one of them short
    z, sid = Terrain(truth).query(xy)
    want_z, want_id = _rule(truth, xy)
    assert (sid >= 0).sum() > 1000 and (sid < 0).sum() > 100
    assert sid.tobytes() == want_id.tobytes() and z.tobytes() == want_z.tobytes()


def test_a_negative_band_is_refused():
    with pytest.raises(ConfigError, match="Terrain.tol_m=-1e-06 is invalid; allowed: 0.0 <= tol_m"):
        Terrain(_truth("stairs"), tol_m=-1e-6)


def _one_foothold(pl, sole_xy, yaw, overhang):
    """:meth:`Footholds.foothold` as it was, one sole point and two terrain queries at a time."""
    z, sid = pl.terrain.query(sole_xy[None, :])
    if sid[0] < 0:
        return None
    n = pl.normals[int(sid[0])]
    x, y = np.array([np.cos(yaw), np.sin(yaw), 0.0]), np.array([-np.sin(yaw), np.cos(yaw), 0.0])
    if abs(float(n @ y)) > np.sin(np.radians(3.0)):
        return None
    pitch = float(np.arctan2(-(n @ x), n[2]))
    zf = np.array([-np.sin(pitch) * x[0], -np.sin(pitch) * x[1], np.cos(pitch)])
    xf = np.array([np.cos(pitch) * x[0], np.cos(pitch) * x[1], np.sin(pitch)])
    sole = np.array([sole_xy[0], sole_xy[1], z[0]])
    pts = sole + np.outer(pl.grid[:, 0], xf) + np.outer(pl.grid[:, 1], y)
    tz, tid = pl.terrain.query(pts[:, :2])
    if np.any(np.isfinite(tz) & (tz > pts[:, 2] + 1e-6)):
        return None
    whole = not np.any(tid[pl.front] != sid[0])
    if whole == overhang or (overhang and np.any(tid[pl.to_ball] != sid[0])):
        return None
    return sole + pl.exo.sole_height_m * zf, pitch, int(sid[0]), float(z[0])


@pytest.mark.parametrize("terrain", ["stairs", "ramp", "parallel"])
def test_footholds_in_one_batch_are_those_found_one_at_a_time(terrain):
    """The planner scans its placements along the heading in one batch (``Footholds.place_all``):
    each is the foothold found alone, to the bit, with and without overhanging toes, on every
    course, on treads, edges, slopes and off the map."""
    from exobench.envs.motion.footholds import Footholds
    from exobench.models.exo_spec import ExoSpec

    truth = _truth(terrain)
    pl = Footholds(ExoSpec(), truth)
    corners = np.concatenate([s.polygon_w[:, :2] for s in truth.surfaces])
    lo, hi = corners.min(axis=0) - 0.3, corners.max(axis=0) + 0.3
    A = np.array([*(0.5 * (lo + hi)), 0.0])
    found = 0
    for yaw in (0.0, 0.4, np.pi):
        for overhang in (False, True):
            a = np.round(np.arange(-0.5 * (hi - lo).max(), 0.5 * (hi - lo).max(), 0.031), 6)
            for sg in (1.0, -1.0):
                got = pl.place_all(A, sg, yaw, a, overhang)
                x, y = np.array([np.cos(yaw), np.sin(yaw)]), np.array([-np.sin(yaw), np.cos(yaw)])
                for ai, g in zip(a, got):
                    want = _one_foothold(pl, A[:2] + float(ai) * x - sg * pl.w * y, yaw, overhang)
                    assert (g is None) == (want is None), (yaw, overhang, ai)
                    if g is not None:
                        found += 1
                        assert g[0].ankle.tobytes() == want[0].tobytes() and (g[0].pitch, g[0].surface, g[1]) == want[1:]
    assert found > 100
