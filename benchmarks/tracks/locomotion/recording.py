"""Write a locomotion episode and its mode predictions as a rerun recording (``.rrd``).

Open it with ``rerun FILE.rrd``. Entities (world frame, metres, timeline ``sim_time``):

- ``world/surfaces/S{id}``: the true surfaces as meshes coloured by kind (static);
- ``world/true_footprints``: the true footprint of every step, coloured and labelled by its
  mode (static);
- ``world/camera``: the true camera optical-frame pose and its pinhole; ``world/camera/rgb`` and
  ``world/camera/depth`` the images (at most every ``image_every_s``; colour JPEG-compressed);
- ``world/pedestrians``: the people crossing the view, when the episode has them;
- ``world/tsdf``: the TSDF surface rebuilt here from the episode's depth frames at the
  odometry poses (default :class:`~exobench.mapping.tsdf.TsdfConfig`, what the ``terrain-recon``
  pipeline integrates), every ``tsdf_every_s``; the estimate itself carries no map;
- ``world/estimates/{pipeline}/footprint``: the footprint of each prediction (odometry frame
  mapped to the world with ``truth.T_world_estimator``; for a pipeline on its own odometry, with
  the true camera pose times the inverse of the pose the prediction carries, as the track scores
  it), coloured by its mode;
- ``world/estimates/{pipeline}/planes/P{id}``: the final plane set of the estimate, a quad per
  plane at its centroid (own odometry: mapped as its last footprint), coloured by plane id,
  labelled with kind and score;
- ``modes/true`` and ``modes/{pipeline}``: true mode (of the step, from its liftoff) and predicted
  mode over time as scalars: 0 LG, 1 SA, 2 SD, 3 RA, 4 RD (NaN: none).

The blueprint shows the 3D view beside the colour and depth images and the mode plot. rerun is
imported inside the functions so the rest of exobench does not pay for it.
"""

from __future__ import annotations

import colorsys
import os
from pathlib import Path
from typing import Any

import numpy as np

from exobench.core.episode import Episode
from exobench.core.estimates import LocomotionEstimate, ModePrediction
from exobench.core.frames import OdometrySample, RgbdFrame

from ..office_recording import log_rgbd_frames
from .metrics import MODE_INDEX, own_pose_alignment

IMAGE_EVERY_S = 0.2
TSDF_EVERY_S = 1.0
PLANE_HALF_M = 0.2
MODE_COLORS = {"LG": (150, 150, 150), "SA": (90, 140, 230), "SD": (40, 60, 160), "RA": (230, 170, 60), "RD": (170, 90, 20)}
KIND_COLORS = {
    "ground": (150, 150, 150), "tread": (90, 140, 230), "landing": (90, 140, 230), "riser": (90, 200, 120),
    "ramp": (220, 180, 90), "wall": (200, 200, 190), "side": (200, 200, 190),
}  # fmt: skip


def _fan(n: int) -> np.ndarray:
    return np.array([[0, i, i + 1] for i in range(1, n - 1)], dtype=np.uint32)


def _quad(normal: np.ndarray, center: np.ndarray, half: float) -> np.ndarray:
    n = normal / np.linalg.norm(normal)
    a = np.cross(n, [0.0, 0.0, 1.0] if abs(n[2]) < 0.9 else [1.0, 0.0, 0.0])
    a /= np.linalg.norm(a)
    b = np.cross(n, a)
    return np.array([center + half * (sa * a + sb * b) for sa, sb in ((-1, -1), (1, -1), (1, 1), (-1, 1))])


def id_color(i: int) -> tuple[int, int, int]:
    """A distinct colour per plane id (golden-ratio hue steps)."""
    r, g, b = colorsys.hsv_to_rgb((i * 0.618033988749895) % 1.0, 0.75, 0.95)
    return int(r * 255), int(g * 255), int(b * 255)


def _transform(T: np.ndarray, p: np.ndarray) -> np.ndarray:
    return np.asarray(p, dtype=float) @ T[:3, :3].T + T[:3, 3]


def _series(est: Any) -> tuple[list[ModePrediction], LocomotionEstimate | None]:
    """The predictions and the final estimate from a final estimate or a ``[(stamp, x), ...]`` series."""
    if isinstance(est, LocomotionEstimate):
        return list(est.predictions), est
    preds: list[ModePrediction] = []
    final = None
    for _, x in est:
        if isinstance(x, LocomotionEstimate):
            final = x
        elif isinstance(x, ModePrediction):
            preds.append(x)
    if final is not None:
        preds = list(final.predictions)
    return sorted(preds, key=lambda p: float(p.stamp_s) if np.isfinite(p.stamp_s) else np.inf), final


def _rgbd_frames(episode: Episode) -> list[RgbdFrame]:
    return [f for f in episode.frames if isinstance(f, RgbdFrame)]


def _log_world(rr: Any, rec: Any, episode: Episode) -> None:
    for s in episode.truth.scene.surfaces:
        poly = np.asarray(s.polygon_w, dtype=float)
        if len(poly) < 3:
            continue
        color = (*KIND_COLORS.get(s.kind, (180, 180, 180)), 255)
        rec.log(f"world/surfaces/S{s.surface_id}", rr.Mesh3D(vertex_positions=poly, triangle_indices=_fan(len(poly)),
                                                              albedo_factor=color), static=True)  # fmt: skip
    steps = sorted(episode.truth.steps, key=lambda s: s.index)
    if steps:
        pts = np.array([np.asarray(s.footprint_w, dtype=float) for s in steps])
        rec.log("world/true_footprints", rr.Points3D(pts, radii=0.025, colors=[MODE_COLORS.get(s.mode, (230, 40, 40)) for s in steps],
                                                      labels=[f"{s.index} {s.mode}" for s in steps]), static=True)  # fmt: skip
        for s in steps:  # the true mode, from each step's liftoff
            rec.set_time("sim_time", duration=float(s.liftoff_s))
            rec.log("modes/true", rr.Scalars(float(MODE_INDEX.get(s.mode, np.nan))))


def _log_camera(rr: Any, rec: Any, episode: Episode, image_every_s: float) -> None:
    traj = np.asarray(episode.truth.trajectory_w, dtype=float).reshape(-1, 8)
    log_rgbd_frames(rr, rec, _rgbd_frames(episode), traj, image_every_s)
    peds = episode.truth.extra.get("pedestrian_tracks") if isinstance(episode.truth.extra, dict) else None
    if peds is None or np.size(peds) == 0:
        return
    tracks = np.asarray(peds, dtype=float)  # (P, N, 5) rows [t, x, y, yaw, ground z]
    heights = np.asarray(episode.truth.extra.get("pedestrian_height_m", np.full(len(tracks), 1.75)), dtype=float)
    last = -np.inf
    for k in range(tracks.shape[1]):
        t = float(tracks[0, k, 0])
        if t - last < image_every_s:
            continue
        last = t
        rec.set_time("sim_time", duration=t)
        z0 = tracks[:, k, 4] if tracks.shape[2] > 4 else np.zeros(len(tracks))
        centers = np.column_stack([tracks[:, k, 1], tracks[:, k, 2], z0 + heights / 2])
        half = np.column_stack([np.full(len(tracks), 0.2), np.full(len(tracks), 0.2), heights / 2])
        rec.log("world/pedestrians", rr.Boxes3D(centers=centers, half_sizes=half, colors=[(230, 80, 80)]))


def _odometry_poses(episode: Episode, camera_id: str) -> list[tuple[float, np.ndarray]]:
    suffix = camera_id[len("rgbd_"):] if camera_id.startswith("rgbd_") else camera_id
    return [(float(f.stamp_s), np.asarray(f.T_odom_body, dtype=float)) for f in episode.frames
            if isinstance(f, OdometrySample) and f.sensor_id == f"odom_{suffix}"]  # fmt: skip


def _log_tsdf(rr: Any, rec: Any, episode: Episode, every_s: float) -> None:
    """Rebuild the TSDF from the depth frames at the odometry poses and log its surface."""
    from exobench.mapping.tsdf import Tsdf, TsdfConfig

    frames = _rgbd_frames(episode)
    if not frames:
        return
    odom = _odometry_poses(episode, frames[0].sensor_id)
    if not odom:
        return
    stamps = np.array([t for t, _ in odom])
    T_world_odom = np.asarray(episode.truth.T_world_estimator, dtype=float)
    tsdf = Tsdf(TsdfConfig())
    last = -np.inf
    for f in frames:
        if f.sensor_id != frames[0].sensor_id:
            continue
        i = int(np.argmin(np.abs(stamps - float(f.stamp_s))))
        if abs(stamps[i] - float(f.stamp_s)) > 0.1:
            continue
        tsdf.integrate(np.asarray(f.depth_m, dtype=np.float32), np.asarray(f.K, dtype=float), odom[i][1])
        if float(f.stamp_s) - last >= every_s or f is frames[-1]:
            last = float(f.stamp_s)
            try:
                pts = np.asarray(tsdf.surface_points(), dtype=float).reshape(-1, 3)
            except RuntimeError:  # Open3D refuses to extract from an empty map
                continue
            rec.set_time("sim_time", duration=last)
            rec.log("world/tsdf", rr.Points3D(_transform(T_world_odom, pts), radii=0.008, colors=[(120, 200, 200)]))


def _log_estimate(rr: Any, rec: Any, episode: Episode, name: str, est: Any) -> None:

    preds, final = _series(est)
    T = T_fixed = np.asarray(episode.truth.T_world_estimator, dtype=float)
    own = own_pose_alignment(episode, final) if final is not None and final.odometry != "given" else None
    for p in preds:
        if not np.isfinite(p.stamp_s):
            continue
        if own is not None:
            T = own(float(p.stamp_s)) if p.T_odom_camera is not None else T
            if not np.all(np.isfinite(T)):
                T = T_fixed
        rec.set_time("sim_time", duration=float(p.stamp_s))
        rec.log(f"modes/{name}", rr.Scalars(float(MODE_INDEX.get(p.mode, np.nan))))
        f = np.asarray(p.footprint_odom, dtype=float).reshape(-1)
        if f.size == 3 and np.all(np.isfinite(f[:2])):
            fw = _transform(T, np.array([f[0], f[1], f[2] if np.isfinite(f[2]) else 0.0]))
            rec.log(f"world/estimates/{name}/footprint", rr.Points3D([fw], radii=0.03, colors=[MODE_COLORS.get(p.mode, (230, 40, 40))],
                                                                      labels=[p.mode or "?"]))  # fmt: skip
    if final is None:
        return
    t_end = float(episode.frames[-1].stamp_s) if episode.frames else 0.0
    rec.set_time("sim_time", duration=t_end)
    for plane in final.planes:
        n, c = np.asarray(plane.get("normal", np.full(3, np.nan)), dtype=float), np.asarray(plane.get("centroid", np.full(3, np.nan)), dtype=float)
        if n.shape != (3,) or c.shape != (3,) or not (np.all(np.isfinite(n)) and np.all(np.isfinite(c))) or np.linalg.norm(n) == 0:
            continue
        pid = int(plane.get("id", 0))
        quad = _quad(T[:3, :3] @ n, _transform(T, c), PLANE_HALF_M)
        rec.log(f"world/estimates/{name}/planes/P{pid}", rr.Mesh3D(vertex_positions=quad, triangle_indices=_fan(4), albedo_factor=(*id_color(pid), 180)))
        rec.log(f"world/estimates/{name}/planes/P{pid}/label", rr.Points3D([_transform(T, c)], radii=0.01, colors=[id_color(pid)],
                                                                           labels=[f"P{pid} {plane.get('kind', '')} score {plane.get('score', '')}"]))  # fmt: skip


def write_recording(
    episode: Episode,
    estimates_by_pipeline: dict[str, Any],
    path: str | os.PathLike,
    *,
    image_every_s: float = IMAGE_EVERY_S,
    tsdf_every_s: float | None = TSDF_EVERY_S,
) -> Path:
    """Write ``episode`` and the estimates to the ``.rrd`` file ``path``; returns the path.

    ``estimates_by_pipeline`` maps a pipeline name to its final :class:`LocomotionEstimate` or
    to a time series ``[(stamp_s, ModePrediction or LocomotionEstimate), ...]`` (the runner's
    online outputs followed by the final estimate). ``tsdf_every_s=None`` skips the TSDF.
    """
    import rerun as rr
    import rerun.blueprint as rrb

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    rec = rr.RecordingStream("exobench", recording_id=f"locomotion-{episode.scenario.get('terrain', '')}-{episode.seed}")
    names = sorted(estimates_by_pipeline)
    blueprint = rrb.Blueprint(
        rrb.Horizontal(
            rrb.Spatial3DView(origin="/world", name="course"),
            rrb.Vertical(
                rrb.Horizontal(
                    rrb.Spatial2DView(origin="/world/camera", contents=["/world/camera/rgb"], name="colour"),
                    rrb.Spatial2DView(origin="/world/camera", contents=["/world/camera/depth"], name="depth"),
                ),
                rrb.TimeSeriesView(origin="/modes", name="mode (0 LG, 1 SA, 2 SD, 3 RA, 4 RD)"),
            ),
            column_shares=[3, 2],
        ),
        collapse_panels=True,
    )
    rec.save(path, default_blueprint=blueprint)
    rec.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
    rec.log("modes/true", rr.SeriesLines(colors=[(127, 200, 248)], widths=[3.0], names=["true"]), static=True)
    for k, name in enumerate(names):
        rec.log(f"modes/{name}", rr.SeriesPoints(colors=[id_color(k + 3)], names=[name], markers=["circle"], marker_sizes=[2.0]), static=True)
    _log_world(rr, rec, episode)
    _log_camera(rr, rec, episode, image_every_s)
    if tsdf_every_s is not None:
        _log_tsdf(rr, rec, episode, tsdf_every_s)
    for name in names:
        _log_estimate(rr, rec, episode, name, estimates_by_pipeline[name])
    rec.flush()
    rec.disconnect()
    return path

