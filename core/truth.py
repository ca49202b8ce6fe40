"""Ground-truth types. The harness keeps these; they never reach a pipeline."""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import IntEnum
from typing import Any

import numpy as np

SURFACE_KINDS = ("ground", "tread", "riser", "ramp", "landing", "wall", "side", "ceiling")


@dataclass(frozen=True, eq=False)
class PlanarSurface:
    """One planar surface of a built world, in world coordinates.

    Attributes:
        surface_id: unique id within the scene. For a staircase built alone the ids follow the
            staircase paper: 0 the ground before it, 1 the first riser, 2 the first tread,
            3 the second riser, ... (odd risers, even treads).
        kind: one of :data:`SURFACE_KINDS`.
        normal_w: unit normal pointing out of the solid (up for treads, towards the
            approaching walker for risers), shape (3,).
        point_w: a point on the plane, shape (3,).
        polygon_w: vertices of the surface's boundary in order, shape (K, 3).
        geom_names: MuJoCo geoms whose faces make up this surface.
    """

    surface_id: int
    kind: str
    normal_w: np.ndarray
    point_w: np.ndarray
    polygon_w: np.ndarray
    geom_names: tuple[str, ...] = ()

    def signed_distance(self, points_w: np.ndarray) -> np.ndarray:
        """Signed distance of points (N, 3) or (3,) to the infinite plane, m."""
        return (np.asarray(points_w, dtype=float) - self.point_w) @ self.normal_w

    def contains(self, point_w: np.ndarray, tol_m: float = 1e-6) -> bool:
        """Whether a point lies on the plane and inside the polygon (within ``tol_m``)."""
        p = np.asarray(point_w, dtype=float)
        if abs(float(self.signed_distance(p))) > tol_m:
            return False
        # project on the plane and test the point against each polygon edge (convex polygons)
        n = self.normal_w
        poly = self.polygon_w
        sign = 0.0
        for i in range(len(poly)):
            a, b = poly[i], poly[(i + 1) % len(poly)]
            c = float(np.dot(np.cross(b - a, p - a), n))
            if abs(c) <= tol_m * np.linalg.norm(b - a):
                continue
            if sign == 0.0:
                sign = np.sign(c)
            elif np.sign(c) != sign:
                return False
        return True


@dataclass(frozen=True, eq=False)
class SceneTruth:
    """Static ground truth of a built world.

    Attributes:
        surfaces: every planar surface.
        geom_surfaces: for each named geom, the ids of the surfaces it contributes to.
        params: the builder's validated parameters (riser_m, tread_m, yaw_deg, ...).
        kind: ``"staircase"``, ``"ramp"``, ``"course"``, ``"level"`` or ``"office"``.
        geom_materials: material name of each world geom (see ``exobench.models.materials``);
            geoms not listed are of the default diffuse material.
        objects: objects of interest (furniture, people, ...), each a dict with at least
            ``name``, ``class``, ``T_world_object`` (4x4 list) and ``geom_names``.
    """

    surfaces: tuple[PlanarSurface, ...]
    geom_surfaces: dict[str, tuple[int, ...]]
    params: dict[str, Any] = field(default_factory=dict)
    kind: str = "level"
    geom_materials: dict[str, str] = field(default_factory=dict)
    objects: tuple[dict[str, Any], ...] = ()

    def surface(self, surface_id: int) -> PlanarSurface:
        for s in self.surfaces:
            if s.surface_id == surface_id:
                return s
        raise KeyError(surface_id)

    def surface_of_hit(self, geom_name: str, point_w: np.ndarray, tol_m: float = 1e-4) -> int:
        """Surface id of a ray hit on ``geom_name`` at ``point_w``; -1 if on no listed surface.

        A box contributes several faces; the face whose plane passes through the point (and
        whose polygon contains it) is the one hit.
        """
        best, best_d = -1, tol_m
        for sid in self.geom_surfaces.get(geom_name, ()):
            s = self.surface(sid)
            d = abs(float(s.signed_distance(point_w)))
            if d <= best_d and s.contains(point_w, tol_m=max(tol_m, 1e-6)):
                best, best_d = sid, d
        return best


@dataclass(frozen=True, eq=False)
class ToFTruth:
    """Ground truth of one emitted ToF frame (same ``stamp_s`` and ``sensor_id``).

    Attributes:
        true_range_m: exact distance along the beam at the measurement time, NaN if no hit.
        hit_w: exact hit point in the world, shape (3,) (NaN if none).
        surface_id: id of the surface hit, -1 if none or not a listed surface.
        T_world_sensor: true pose of the sensor at the measurement time.
    """

    stamp_s: float
    sensor_id: str
    true_range_m: float
    hit_w: np.ndarray
    surface_id: int
    T_world_sensor: np.ndarray


@dataclass(frozen=True, eq=False)
class StairTruth:
    """Truth of the staircase paper's climbing step: what the stairs track scores against.

    Attributes:
        tof: one entry per emitted ToF frame, in the same order as the ToF frames.
        stance_side: ``"l"`` or ``"r"``, the supporting foot during the climbing step.
        touchdown_w: the climbing foot's sole point below the ankle at touch-down, world, (3,).
        foot_track_w: the climbing foot's sole point over time, (N, 4) rows ``[t, x, y, z]``.
    """

    tof: tuple[ToFTruth, ...]
    stance_side: str
    touchdown_w: np.ndarray
    foot_track_w: np.ndarray


def height_at(truth: SceneTruth, x: float, y: float, kinds: tuple[str, ...] = ("ground", "tread", "ramp", "landing")) -> float:
    """Terrain height under (x, y): the highest walkable surface whose polygon covers the point.

    Returns NaN where no walkable surface lies below the point.
    """
    best = float("nan")
    for s in truth.surfaces:
        n = s.normal_w
        if s.kind not in kinds or abs(n[2]) < 1e-6:
            continue
        z = s.point_w[2] - (n[0] * (x - s.point_w[0]) + n[1] * (y - s.point_w[1])) / n[2]
        if s.contains(np.array([x, y, z]), tol_m=1e-6) and not (z <= best):
            best = float(z)
    return best


@dataclass(frozen=True, eq=False)
class StepTruth:
    """One step of a walk: where and when a foot landed and the locomotion mode of that step.

    Attributes:
        index: step number in the walk, 0-based.
        side: ``"l"`` or ``"r"``, the foot that swings in this step.
        liftoff_s: time the foot leaves the ground (start of the step), s.
        heel_strike_s: time its heel touches down (end of the step), s.
        footprint_w: sole point below the ankle where it lands, world, (3,).
        terrain: kind of the surface it lands on (``"ground"``, ``"tread"``, ``"ramp"``, ...).
        mode: locomotion mode of the step, one of ``LG SA SD RA RD`` (from the terrain under the
            landing footprint relative to the one under the previous footprint).
    """

    index: int
    side: str
    liftoff_s: float
    heel_strike_s: float
    footprint_w: np.ndarray
    terrain: str
    mode: str


class ReturnKind(IntEnum):
    """What produced a LiDAR point (ground truth)."""

    GENUINE = 0  # a real surface on the straight ray
    GLASS = 1  # the weak reflection of a glass pane itself
    GHOST = 2  # a surface seen in a mirror / pane, reported along the original ray
    THROUGH_GLASS = 3  # a real surface behind glass, on the straight ray (counts as genuine)
    NAN = 4  # reported as NaN (a sensor fault, LidarConfig.nan_point_prob); the other fields are the beam's true hit


@dataclass(frozen=True, eq=False)
class LidarTruth:
    """Ground truth of one :class:`~exobench.core.LidarScan`, point by point (same order, same length N).

    Attributes:
        stamp_s, sensor_id: as the scan.
        true_range_m: noise-free distance along the original ray at which the point lies, m
            (for a ghost the total reflected path length).
        hit_w: the surface point that returned the light, world frame, (N, 3) (for a ghost the
            real surface seen in the mirror, not where the point appears).
        geom_id: MuJoCo geom of that surface, (N,).
        surface_id: ``SceneTruth`` surface of that point, -1 if none, (N,).
        material: material name of that surface, (N,) str.
        kind: :class:`ReturnKind` code, (N,).
        via_geom_id: the glass / mirror geom the beam crossed or bounced on, -1 if none, (N,).
        signal: unclipped return strength on the intensity scale, (N,), with the path's energy
            share (``G`` of :mod:`exobench.envs.sensors.lidar.optics`: ghosts keep the specular
            fraction squared of their light, returns through glass the transmission squared).
        origin_w / dir_w: the original ray in the world at its firing pose, (N, 3).
    """

    stamp_s: float
    sensor_id: str
    true_range_m: np.ndarray
    hit_w: np.ndarray
    geom_id: np.ndarray
    surface_id: np.ndarray
    material: np.ndarray
    kind: np.ndarray
    via_geom_id: np.ndarray
    signal: np.ndarray
    origin_w: np.ndarray
    dir_w: np.ndarray

    @property
    def genuine(self) -> np.ndarray:
        """Points on a real surface along the straight ray (directly or through glass)."""
        return (self.kind == ReturnKind.GENUINE) | (self.kind == ReturnKind.THROUGH_GLASS)


@dataclass(frozen=True, eq=False)
class SegmentationTruth:
    """Ground truth of one RGB-D frame, pixel by pixel: what each pixel of the depth image shows.

    Aligned with the :class:`~exobench.core.RgbdFrame` of the same ``stamp_s`` and ``sensor_id``:
    the same (H, W) pixel grid, rendered at the same pose and instant as its depth image.

    Attributes:
        stamp_s, sensor_id: as the frame.
        surface_id: ``SceneTruth`` surface the pixel shows, (H, W) int32; -1 for no surface, a geom
            with no listed surface, or a face of a geom that is not one of its listed surfaces.
        geom_id: MuJoCo geom the pixel shows, (H, W) int32; -1 for the background.
        object_index: index into ``SceneTruth.objects`` of the object whose geom the pixel shows,
            (H, W) int32; -1 for none.
    """

    stamp_s: float
    sensor_id: str
    surface_id: np.ndarray
    geom_id: np.ndarray
    object_index: np.ndarray


def compact_truth(t: LidarTruth) -> LidarTruth:
    """The labels of a scan's truth without its per-point geometry, for long walks.

    Keeps, per point, ``true_range_m`` and ``signal`` (float32), ``geom_id``, ``surface_id`` and
    ``via_geom_id`` (int32) and ``kind`` (int8): about 21 bytes a point instead of ~170. ``hit_w``,
    ``origin_w`` and ``dir_w`` become empty (0, 3) arrays and ``material`` an empty array (a
    surface's material is ``SceneTruth.geom_materials`` of its geoms).
    """
    empty3 = np.zeros((0, 3), dtype=np.float32)
    return LidarTruth(
        stamp_s=t.stamp_s,
        sensor_id=t.sensor_id,
        true_range_m=np.asarray(t.true_range_m, dtype=np.float32),
        hit_w=empty3,
        geom_id=np.asarray(t.geom_id, dtype=np.int32),
        surface_id=np.asarray(t.surface_id, dtype=np.int32),
        material=np.zeros(0, dtype="<U1"),
        kind=np.asarray(t.kind, dtype=np.int8),
        via_geom_id=np.asarray(t.via_geom_id, dtype=np.int32),
        signal=np.asarray(t.signal, dtype=np.float32),
        origin_w=empty3,
        dir_w=empty3.copy(),
    )
