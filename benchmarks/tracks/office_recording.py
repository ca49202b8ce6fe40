"""Rerun views of office walks, shared by the LiDAR tracks (rerun is imported by the caller
and passed in as ``rr``, or inside :func:`write_lidar_recording`).

- :func:`log_office_world`: true surfaces as static meshes coloured by kind;
- :func:`log_scans`: every ``every``-th scan in the world, coloured by intensity and by true
  return kind, optional keep masks per pipeline;
- :func:`log_trajectory`: a line strip of positions; :func:`kind_colors`, :func:`intensity_colors`;
- :func:`log_rgbd_frames`: a camera's true pose, pinhole, colour and depth images over time
  (the vio and locomotion recordings);
- :func:`write_lidar_recording`: the recording of the odometry and lidar-filter tracks (scans,
  kept points, true and estimated trajectories, maps and loop edges).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from exobench.core.episode import Episode
from exobench.core.estimates import FilterEstimate, TrajectoryEstimate

from .lidar_trajectory import alignment, true_track
from .office_walks import (
    GENUINE,
    GHOST,
    GLASS,
    NAN_POINT,
    lidar_pairs,
    point_classes,
    points_world,
    sweep_start_poses,
)

KIND_RGB = {GENUINE: (170, 170, 170), GLASS: (60, 160, 255), GHOST: (255, 60, 200), NAN_POINT: (255, 220, 0)}
SURFACE_RGB = {
    "ground": (130, 130, 130), "ceiling": (200, 200, 220), "wall": (210, 200, 180), "glass": (90, 170, 255),
    "door": (160, 110, 70), "frame": (90, 90, 90), "furniture": (120, 170, 110),
}  # fmt: skip


def kind_colors(cls: np.ndarray) -> np.ndarray:
    """RGB (N, 3) u8 of point classes (genuine grey, glass blue, ghost magenta, NaN yellow)."""
    lut = np.array([KIND_RGB[GENUINE], KIND_RGB[GLASS], KIND_RGB[GHOST], KIND_RGB[NAN_POINT]], dtype=np.uint8)
    return lut[np.clip(np.asarray(cls, dtype=int), 0, 3)]


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


def log_rgbd_frames(rr: Any, rec: Any, frames: Sequence[Any], traj: np.ndarray, image_every_s: float,
                    entity: str = "world/camera") -> None:
    """Every RGB-D frame at least ``image_every_s`` after the last one logged: the true pose
    (the row of ``traj``, rows ``[t, x, y, z, qw, qx, qy, qz]``, at or after its stamp; none when
    ``traj`` is empty), its pinhole, the colour image (JPEG) and the depth (millimetres)."""
    traj = np.asarray(traj, dtype=float).reshape(-1, 8)
    last = -np.inf
    for f in frames:
        t = float(f.stamp_s)
        if t - last < image_every_s:
            continue
        last = t
        rec.set_time("sim_time", duration=t)
        if len(traj):
            row = traj[min(int(np.searchsorted(traj[:, 0], t - 1e-9)), len(traj) - 1)]
            q = row[4:8]
            rec.log(entity, rr.Transform3D(translation=row[1:4], quaternion=rr.Quaternion(xyzw=[q[1], q[2], q[3], q[0]])))
        h, w = np.asarray(f.depth_m).shape[:2]
        rec.log(entity, rr.Pinhole(image_from_camera=np.asarray(f.K, dtype=float), resolution=[w, h], image_plane_distance=0.3))
        if f.rgb is not None:
            rec.log(f"{entity}/rgb", rr.Image(np.asarray(f.rgb, dtype=np.uint8)).compress(jpeg_quality=80))
        depth_mm = np.clip(np.nan_to_num(np.asarray(f.depth_m, dtype=float)) * 1000.0, 0, 65535).astype(np.uint16)
        rec.log(f"{entity}/depth", rr.DepthImage(depth_mm, meter=1000.0))


def _final(est: Any) -> Any:
    if isinstance(est, list):
        return est[-1][1] if est else None
    return est


def write_lidar_recording(episode: Episode, estimates_by_pipeline: Mapping[str, Any], path: Path, *,
                          masks: Mapping[str, Any] | None = None, every: int = 5, stride: int = 3) -> Path:
    """Rerun recording: office surfaces, scans (by intensity, by true kind), kept points of each
    filter (``masks`` and every :class:`FilterEstimate`), the true and estimated trajectories, the
    corrected maps of estimates that carry ``map_points`` and their loop edges (estimates moved
    onto the truth by the SE(3) fit the ATE uses)."""
    import rerun as rr
    import rerun.blueprint as rrb

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    rec = rr.RecordingStream("exobench", recording_id=f"{episode.scenario.get('route', '')}-{episode.seed}")
    blueprint = rrb.Blueprint(rrb.Spatial3DView(origin="/world", name="office"), collapse_panels=True)
    rec.save(path, default_blueprint=blueprint)
    rec.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
    log_office_world(rr, rec, episode)
    finals = {name: _final(e) for name, e in estimates_by_pipeline.items()}
    kept = dict(masks or {})
    kept.update({n: e.keep for n, e in finals.items() if isinstance(e, FilterEstimate)})
    log_scans(rr, rec, episode, every=every, masks=kept, stride=stride)
    truth = true_track(episode)
    log_trajectory(rr, rec, "world/trajectories/truth", truth[:, 1:4], (20, 20, 20))
    palette = [(230, 60, 60), (60, 120, 230), (60, 180, 90), (230, 160, 40)]
    for i, (name, est) in enumerate(sorted(finals.items())):
        if not isinstance(est, TrajectoryEstimate) or not len(est.stamps_s):
            continue
        poses = np.asarray(est.T_world_sensor, dtype=float).reshape(-1, 4, 4)
        R, t = alignment(truth, np.asarray(est.stamps_s, dtype=float), poses)
        p = poses[:, :3, 3] @ R.T + t
        rgb = palette[i % len(palette)]
        log_trajectory(rr, rec, f"world/trajectories/{name}", p, rgb)
        if est.map_points is not None and len(est.map_points):
            m = np.asarray(est.map_points, dtype=float).reshape(-1, 3) @ R.T + t
            rec.log(f"world/maps/{name}", rr.Points3D(m, colors=[rgb], radii=0.02), static=True)
        if est.loop_edges:
            segs = [[p[i0], p[j0]] for i0, j0 in est.loop_edges if max(i0, j0) < len(p)]
            rec.log(f"world/loop_edges/{name}", rr.LineStrips3D(segs, colors=[(255, 0, 255)], radii=0.03), static=True)
    rec.flush()
    rec.disconnect()
    return path
