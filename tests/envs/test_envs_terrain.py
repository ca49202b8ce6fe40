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
