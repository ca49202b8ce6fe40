"""Shared pieces of the LiDAR tracks that walk the office (lidar-filter, odometry, loop-closure).

- Scenario parameters: :func:`office_params` (the :data:`exobench.envs.office_sim.PARAMS` table
  as :class:`ParamInfo` rows, plus a track's own extra rows), :func:`validate_office_scenario`
  (typed values; the track's extra keys validated by the same ``ParamSpec`` rules) and
  :func:`simulate_office_episode` (drops the extra keys, runs ``simulate_office``).
- Ground truth per LiDAR point: :func:`lidar_pairs` (scans with their ``LidarTruth``),
  :func:`point_classes` (genuine / glass / ghost codes and whether the true surface is ground),
  :func:`points_world` (each measured point in the world: the true ray origin and direction of
  its firing, at the measured range, so motion distortion is shown as the sensor saw it).
- Rerun helpers (rerun imported by the caller and passed in as ``rr``): :func:`log_office_world`
  (true surfaces as static meshes coloured by kind), :func:`log_scans` (every ``every``-th scan
  in the world, coloured by intensity and by true return kind, optional keep masks per
  pipeline), :func:`log_trajectory` (a line strip of positions), :func:`kind_colors`.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from exobench.core.episode import Episode
from exobench.core.errors import UnknownNameError
from exobench.core.frames import LidarScan

from .base import ParamInfo

GROUND_KINDS = ("ground", "tread", "landing", "ramp")  # surfaces a walker stands on (SceneTruth kinds)
KIND_NAMES = ("genuine", "glass", "ghost")  # class of a point: ReturnKind GENUINE/THROUGH_GLASS, GLASS, GHOST
GENUINE, GLASS, GHOST = 0, 1, 2
KIND_RGB = {GENUINE: (170, 170, 170), GLASS: (60, 160, 255), GHOST: (255, 60, 200)}
SURFACE_RGB = {
    "ground": (130, 130, 130), "ceiling": (200, 200, 220), "wall": (210, 200, 180), "glass": (90, 170, 255),
    "door": (160, 110, 70), "frame": (90, 90, 90), "furniture": (120, 170, 110),
}  # fmt: skip


def _info(name: str, spec: Any) -> ParamInfo:
    return ParamInfo(name, spec.default, spec.low, spec.high, spec.unit, spec.doc, bool(getattr(spec, "low_open", False)))


def office_params(extra: Mapping[str, Any] | None = None) -> list[ParamInfo]:
    """Rows of the office scenario table, then ``extra`` (name -> ``ParamSpec``) of a track."""
    from exobench.envs.office_sim import PARAMS

    return [_info(k, v) for k, v in {**PARAMS, **dict(extra or {})}.items()]


def validate_office_scenario(values: Mapping[str, Any], extra: Mapping[str, Any] | None = None) -> dict[str, Any]:
    """Typed office scenario values plus the track's ``extra`` keys (defaults filled in).

    Unknown names raise :class:`UnknownNameError`; bad values ``ConfigError``.
    """
    from exobench.envs.office_sim import PARAMS, OfficeScenario
    from exobench.models.world_params import ParamSpec

    extra = dict(extra or {})
    own = {k: v for k, v in values.items() if k in extra}
    rest = {k: v for k, v in values.items() if k not in extra}
    for k in rest:
        if k not in PARAMS:
            raise UnknownNameError("office scenario parameter", k, [*PARAMS, *extra])
    out = OfficeScenario.from_dict(rest).as_dict()
    for name, spec in extra.items():
        out[name] = _check_extra(name, own.get(name, spec.default), spec) if isinstance(spec, ParamSpec) else own.get(name)
    return out


def _check_extra(name: str, raw: Any, spec: Any) -> Any:
    from exobench.core.errors import ConfigError, check_range
    from exobench.core.pipeline import coerce_like

    value = coerce_like(name, raw, spec.default)
    if spec.choices and value not in spec.choices:
        raise ConfigError(name, raw, " or ".join(repr(c) for c in spec.choices))
    if spec.low is not None and spec.high is not None and not isinstance(value, (str, bool)):
        check_range(name, value, spec.low, spec.high, low_open=spec.low_open)
    return value


def simulate_office_episode(scenario: Mapping[str, Any], seed: int, extra: Mapping[str, Any] | None = None) -> Episode:
    """``simulate_office`` on the office part of a validated scenario (``extra`` keys dropped)."""
    from exobench.envs.office_sim import OfficeScenario, simulate_office

    office = {k: v for k, v in scenario.items() if k not in dict(extra or {})}
    return simulate_office(OfficeScenario.from_dict(office), seed)


# ------------------------------------------------------------------------- truth per point


def lidar_pairs(episode: Episode, sensor_id: str | None = None) -> list[tuple[LidarScan, Any]]:
    """(scan, LidarTruth) in time order, matched by sensor and stamp (truth is per scan)."""
    scans = [f for f in episode.frames if isinstance(f, LidarScan) and (sensor_id is None or f.sensor_id == sensor_id)]
    truths = {(t.sensor_id, round(float(t.stamp_s), 9)): t for t in episode.truth.lidar}
    out = []
    for s in scans:
        t = truths.get((s.sensor_id, round(float(s.stamp_s), 9)))
        if t is not None and len(t.kind) == len(s.points_xyz):
            out.append((s, t))
    return out


def point_classes(episode: Episode, truth: Any) -> tuple[np.ndarray, np.ndarray]:
    """(class per point: :data:`GENUINE`/:data:`GLASS`/:data:`GHOST`, on a ground surface per point).

    ``THROUGH_GLASS`` counts as genuine (a real surface on the straight ray). A point is ground
    when it is genuine and its true surface's kind is in :data:`GROUND_KINDS`.
    """
    from exobench.core import ReturnKind

    kind = np.asarray(truth.kind)
    cls = np.full(len(kind), GENUINE, dtype=np.int8)
    cls[kind == ReturnKind.GLASS] = GLASS
    cls[kind == ReturnKind.GHOST] = GHOST
    ground_ids = np.array([s.surface_id for s in episode.truth.scene.surfaces if s.kind in GROUND_KINDS], dtype=int)
    ground = (cls == GENUINE) & np.isin(np.asarray(truth.surface_id, dtype=int), ground_ids)
    return cls, ground


def points_world(scan: LidarScan, truth: Any, T_world_sensor: np.ndarray | None = None) -> np.ndarray:
    """Measured points in the world frame: ``origin_w + |p| dir_w`` of each point's firing, (N, 3).

    A compact truth (``lidar_truth="labels"``) has no rays; then the points are moved by
    ``T_world_sensor`` (the pose at the sweep start; the motion within the sweep is ignored).
    """
    if len(truth.origin_w) != len(scan.points_xyz):
        if T_world_sensor is None:
            raise ValueError("a compact LiDAR truth has no rays: pass the scan's T_world_sensor")
        T = np.asarray(T_world_sensor, dtype=float)
        return np.asarray(scan.points_xyz, dtype=float) @ T[:3, :3].T + T[:3, 3]
    r = np.linalg.norm(np.asarray(scan.points_xyz, dtype=float), axis=1)
    return np.asarray(truth.origin_w, dtype=float) + r[:, None] * np.asarray(truth.dir_w, dtype=float)


def sweep_start_poses(episode: Episode) -> dict[float, np.ndarray]:
    """True ``T_world_sensor`` at each scan start, keyed by the start time rounded to 1 ns."""
    from exobench.core.transforms import make_T, quat_wxyz_to_matrix

    return {
        round(float(r[0]), 9): make_T(quat_wxyz_to_matrix(r[4:8]), r[1:4]) for r in np.asarray(episode.truth.trajectory_w)
    }


# ------------------------------------------------------------------------- rerun helpers


def kind_colors(cls: np.ndarray) -> np.ndarray:
    """RGB (N, 3) u8 of point classes (genuine grey, glass blue, ghost magenta)."""
    lut = np.array([KIND_RGB[GENUINE], KIND_RGB[GLASS], KIND_RGB[GHOST]], dtype=np.uint8)
    return lut[np.clip(np.asarray(cls, dtype=int), 0, 2)]


def intensity_colors(intensity: np.ndarray) -> np.ndarray:
    """RGB (N, 3) u8 of intensity bytes, 0..100 blue to red (above 100: white)."""
    v = np.clip(np.asarray(intensity, dtype=float) / 100.0, 0.0, 1.0)
    rgb = np.stack([255 * v, 255 * (1 - np.abs(2 * v - 1)), 255 * (1 - v)], axis=1)
    rgb[np.asarray(intensity) > 100] = 255
    return rgb.astype(np.uint8)


def _fan(n: int) -> np.ndarray:
    return np.array([[0, i, i + 1] for i in range(1, n - 1)], dtype=np.uint32)


def log_office_world(rr: Any, rec: Any, episode: Episode, root: str = "world/surfaces") -> None:
    """The true planar surfaces (static meshes, coloured by kind; ceilings left out)."""
    for s in episode.truth.scene.surfaces:
        poly = np.asarray(s.polygon_w, dtype=float)
        if len(poly) < 3 or s.kind == "ceiling":
            continue
        alpha = 90 if s.kind == "glass" else 255
        rec.log(
            f"{root}/{s.kind}/S{s.surface_id}",
            rr.Mesh3D(vertex_positions=poly, triangle_indices=_fan(len(poly)), albedo_factor=(*SURFACE_RGB.get(s.kind, (180, 180, 180)), alpha)),
            static=True,
        )


def log_scans(
    rr: Any,
    rec: Any,
    episode: Episode,
    *,
    every: int = 1,
    masks: Mapping[str, Sequence[np.ndarray]] | None = None,
    root: str = "world/lidar",
    radius_m: float = 0.015,
    stride: int = 1,
) -> None:
    """Every ``every``-th scan in the world at its stamp: ``{root}/by_intensity``, ``{root}/by_kind``
    and, per pipeline of ``masks`` (keep masks per scan, in scan order), ``{root}/kept/{name}``;
    every ``stride``-th point of a scan (glass and ghost points always)."""
    pairs = lidar_pairs(episode)
    starts = sweep_start_poses(episode)
    masks = dict(masks or {})
    for i, (scan, truth) in enumerate(pairs):
        if i % max(1, every):
            continue
        rec.set_time("sim_time", duration=float(scan.stamp_s))
        p_w = points_world(scan, truth, starts.get(round(float(scan.sweep_start_s), 9)))
        cls, _ = point_classes(episode, truth)
        sel = (np.arange(len(p_w)) % max(1, stride) == 0) | (cls != GENUINE)
        psi = np.asarray(scan.intensity)
        rec.log(f"{root}/by_intensity", rr.Points3D(p_w[sel], colors=intensity_colors(psi[sel]), radii=radius_m))
        rec.log(f"{root}/by_kind", rr.Points3D(p_w[sel], colors=kind_colors(cls[sel]), radii=radius_m))
        for name, per_scan in masks.items():
            if i < len(per_scan) and len(per_scan[i]) == len(p_w):
                keep = np.asarray(per_scan[i], dtype=bool) & sel
                rec.log(f"{root}/kept/{name}", rr.Points3D(p_w[keep], colors=kind_colors(cls[keep]), radii=radius_m))


def log_trajectory(rr: Any, rec: Any, path: str, positions_xyz: np.ndarray, rgb: tuple[int, int, int]) -> None:
    """A static line strip through ``positions_xyz`` (N, 3)."""
    p = np.asarray(positions_xyz, dtype=float).reshape(-1, 3)
    p = p[np.all(np.isfinite(p), axis=1)]
    if len(p) > 1:
        rec.log(path, rr.LineStrips3D([p], colors=[rgb], radii=0.02), static=True)
