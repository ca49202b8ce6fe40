"""The terrain description's config, its result types and the geometry of one plane (slope, class,
height under a point).

The paper gives no values for its thresholds; the defaults are [A] choices: level ground up to
6 deg (building codes allow 1:12 = 4.8 deg for ramps' landings), ramps up to 25 deg (the paper's
steepest is 17.8 deg), risers 0.10-0.30 m (its stairs are 0.15-0.25 m), adjacent tread centres
within 0.8 m (a tread 0.25-0.35 m deep plus the rise, with room for partly seen treads).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from exobench.core import check_int, check_range

from .plane_tracking import TrackedPlane

__all__ = [
    "PLANE_CLASSES",
    "TERRAIN_TYPES",
    "ModeDecision",
    "Terrain",
    "TerrainConfig",
    "plane_class",
    "plane_height_at",
    "plane_heights_at",
    "slope_deg",
]

TERRAIN_TYPES = ("level", "ramp", "stairs")
# "overhead": a plane no steeper than a ramp seen from below (a ceiling, a soffit): never walked on
PLANE_CLASSES = ("horizontal", "ramp", "steep", "overhead")


@dataclass(frozen=True)
class TerrainConfig:
    """Thresholds of the terrain description and of the mode decision (module docstring)."""

    level_max_slope_deg: float = 6.0
    ramp_max_slope_deg: float = 25.0
    level_min_area_m2: float = 0.05
    ramp_min_area_m2: float = 0.05
    stair_min_area_m2: float = 0.02
    stair_center_max_m: float = 0.8
    stair_rise_min_m: float = 0.10
    stair_rise_max_m: float = 0.30
    max_step_rise_m: float = 0.6
    support_margin_m: float = 0.06
    support_radius_m: float = 0.10
    support_fit_tol_m: float = 0.01
    min_score: int = 1
    drop_lookahead_m: float = 1.5
    crease_min_angle_deg: float = 5.0
    crease_min_score: int = 3

    def __post_init__(self) -> None:
        check_range("terrain.level_max_slope_deg", self.level_max_slope_deg, 0.0, 45.0)
        check_range("terrain.ramp_max_slope_deg", self.ramp_max_slope_deg, self.level_max_slope_deg, 89.0)
        for name in ("level_min_area_m2", "ramp_min_area_m2", "stair_min_area_m2"):
            check_range(f"terrain.{name}", getattr(self, name), 0.0)
        check_range("terrain.stair_center_max_m", self.stair_center_max_m, 0.0, low_open=True)
        check_range("terrain.stair_rise_min_m", self.stair_rise_min_m, 0.0, low_open=True)
        check_range("terrain.stair_rise_max_m", self.stair_rise_max_m, self.stair_rise_min_m)
        check_range("terrain.max_step_rise_m", self.max_step_rise_m, self.stair_rise_min_m)
        check_range("terrain.support_margin_m", self.support_margin_m, 0.0)
        check_range("terrain.support_radius_m", self.support_radius_m, 0.0)
        check_range("terrain.support_fit_tol_m", self.support_fit_tol_m, 0.0)
        check_range("terrain.drop_lookahead_m", self.drop_lookahead_m, 0.0)
        check_range("terrain.crease_min_angle_deg", self.crease_min_angle_deg, 0.0, 90.0)
        object.__setattr__(self, "crease_min_score", check_int("terrain.crease_min_score", self.crease_min_score, 1))
        object.__setattr__(self, "min_score", check_int("terrain.min_score", self.min_score, 1))


@dataclass(frozen=True)
class Terrain:
    """T = <tau, s, Gamma>: type, terrain id, plane ids (stairs: ordered by height, lowest first)."""

    kind: str
    terrain_id: int
    plane_ids: tuple[int, ...]


@dataclass(frozen=True)
class ModeDecision:
    """The mode of the next step and how it was found.

    ``reason``: ``"ok"``, ``"extrapolated"`` (no plane under the predicted footprint),
    ``"drop_ahead"`` (none, lower ground beyond it: SD),
    ``"current_unknown"`` (no plane under the current one), ``"current_remembered"`` (none,
    but its height was given) or ``"no_terrain"`` (neither).
    ``dz_m``: height of the terrain under the predicted footprint minus under the current one
    (NaN when either is unknown).
    """

    mode: str
    reason: str
    next_plane_id: int | None
    current_plane_id: int | None
    next_terrain: str | None
    current_terrain: str | None
    dz_m: float


def slope_deg(normal: np.ndarray) -> float:
    """Slope theta of a plane from its normal (either orientation), deg, in [0, 90]."""
    n = np.asarray(normal, dtype=float)
    nz = abs(float(n[2])) / max(float(np.linalg.norm(n)), 1e-12)
    return float(np.degrees(np.arccos(min(1.0, nz))))


def plane_class(normal: np.ndarray, config: TerrainConfig) -> str:
    """``"horizontal"``, ``"ramp"`` or ``"steep"`` by slope; ``"overhead"`` for a plane no steeper
    than a ramp whose normal, oriented towards the camera that saw it (as plane extraction and
    tracking keep it), points down: the camera was below it, so it is the underside of something
    (a stairwell's ceiling), never walked on. A walkable surface is always seen from above."""
    th = slope_deg(normal)
    if th <= config.ramp_max_slope_deg and float(np.asarray(normal, dtype=float)[2]) < 0.0:
        return "overhead"
    if th <= config.level_max_slope_deg:
        return "horizontal"
    if th <= config.ramp_max_slope_deg:
        return "ramp"
    return "steep"


def plane_height_at(plane: TrackedPlane, xy: np.ndarray) -> float:
    """Height z of the (non-vertical) plane at (x, y)."""
    return float(plane_heights_at(plane, np.asarray(xy, dtype=float)[:2])[0])


def plane_heights_at(plane: TrackedPlane, xy: np.ndarray) -> np.ndarray:
    """Heights z of the (non-vertical) plane at the points (K, 2) (or one (2,))."""
    q = np.asarray(xy, dtype=float).reshape(-1, 2)
    n, c = plane.normal, plane.center_m
    return c[2] - (n[0] * (q[:, 0] - c[0]) + n[1] * (q[:, 1] - c[1])) / n[2]
