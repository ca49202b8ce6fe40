"""The stairs track's rerun recording: an episode and its staircase estimates (``.rrd``).

Open it with ``rerun FILE.rrd``. Entities (world frame, metres, timeline ``sim_time``):

- ``world/surfaces/S{id}``: the true surfaces as meshes (static);
- ``world/exo/{link}``: link poses over time, plus ``world/exo/skeleton`` line strips;
- ``world/tof/{sensor}/ray`` and ``/hits``: each ToF ray from the true sensor pose to its
  measured point, and the measured points so far coloured by the true surface;
- ``world/estimates/{pipeline}/S{i}``: each estimated plane as a finite quad at its centroid,
  logged when it first appears (translucent until reliable) and whenever it changes;
- ``metrics/...``: ranges and the number of reliable planes per pipeline (time series).

The recording carries an explicit blueprint: a 3D view beside time series. rerun is imported
inside the function so the rest of exobench does not pay for it.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from exobench.core.episode import Episode
from exobench.core.estimates import StaircaseEstimate
from exobench.core.frames import ToFReading
from exobench.core.transforms import transform_points

BODY_STEP_S = 0.02  # body poses are logged at 50 Hz at most
QUAD_HALF_M = 0.12
SKELETON = (("pelvis", "thigh_l", "shank_l", "foot_l"), ("pelvis", "thigh_r", "shank_r", "foot_r"), ("pelvis", "head"))
KIND_COLORS = {
    "ground": (150, 150, 150), "tread": (90, 140, 230), "landing": (90, 140, 230),
    "riser": (90, 200, 120), "ramp": (220, 180, 90),
}


def _fan(n: int) -> np.ndarray:
    return np.array([[0, i, i + 1] for i in range(1, n - 1)], dtype=np.uint32)


def _quad(normal: np.ndarray, center: np.ndarray, half: float) -> np.ndarray:
    n = normal / np.linalg.norm(normal)
    a = np.cross(n, [0.0, 0.0, 1.0] if abs(n[2]) < 0.9 else [1.0, 0.0, 0.0])
    a /= np.linalg.norm(a)
    b = np.cross(n, a)
    return np.array([center + half * (sa * a + sb * b) for sa, sb in ((-1, -1), (1, -1), (1, 1), (-1, 1))])


def _surface_color(index: int, reliable: bool) -> tuple[int, int, int, int]:
    rgb = KIND_COLORS["tread"] if index % 2 == 0 else KIND_COLORS["riser"]
    return (*rgb, 200 if reliable else 80)


def _as_series(est: Any) -> list[tuple[float | None, Any]]:
    if isinstance(est, StaircaseEstimate):
        return [(None, est)]
    return [(float(t), e) for t, e in est]


def _log_estimates(rr: Any, rec: Any, episode: Episode, name: str, series: Sequence[tuple[float | None, Any]], t_end: float) -> None:
    T = np.asarray(episode.truth.T_world_estimator, dtype=float)
    last: dict[int, tuple] = {}
    for stamp, est in series:
        if not isinstance(est, StaircaseEstimate):
            continue
        n_reliable = 0
        for p in est.planes:
            if not (np.all(np.isfinite(p.normal)) and np.all(np.isfinite(p.centroid)) and np.linalg.norm(p.normal) > 0):
                continue
            n_reliable += bool(p.reliable)
            key = (tuple(np.round(p.normal, 6)), tuple(np.round(p.centroid, 6)), bool(p.reliable))
            if last.get(p.index) == key:
                continue
            last[p.index] = key
            t = stamp if stamp is not None else (p.reliable_stamp_s if p.reliable_stamp_s is not None else t_end)
            rec.set_time("sim_time", duration=float(t))
            quad = _quad(T[:3, :3] @ p.normal, transform_points(T, p.centroid), QUAD_HALF_M)
            rec.log(
                f"world/estimates/{name}/S{p.index}",
                rr.Mesh3D(vertex_positions=quad, triangle_indices=_fan(4), albedo_factor=_surface_color(p.index, p.reliable)),
            )
        if stamp is not None:
            rec.set_time("sim_time", duration=float(stamp))
            rec.log(f"metrics/{name}/reliable_planes", rr.Scalars(float(n_reliable)))


def _log_world(rr: Any, rec: Any, episode: Episode) -> None:
    for s in episode.truth.scene.surfaces:
        poly = np.asarray(s.polygon_w, dtype=float)
        if len(poly) < 3:
            continue
        color = (*KIND_COLORS.get(s.kind, (180, 180, 180)), 255)
        rec.log(
            f"world/surfaces/S{s.surface_id}",
            rr.Mesh3D(vertex_positions=poly, triangle_indices=_fan(len(poly)), albedo_factor=color),
            static=True,
        )
    rec.log("world/touchdown", rr.Points3D([episode.truth.stairs.touchdown_w], radii=0.012, colors=[(230, 40, 40)]), static=True)


def _log_body(rr: Any, rec: Any, episode: Episode) -> None:
    tracks = {k: np.asarray(v, dtype=float).reshape(-1, 8) for k, v in episode.truth.body_tracks.items()}
    if not tracks:
        return
    times = np.unique(np.concatenate([v[:, 0] for v in tracks.values()]))
    keep, last = [], -np.inf
    for t in times:
        if t - last >= BODY_STEP_S:
            keep.append(t)
            last = t
    for name in tracks:
        rec.log(f"world/exo/{name}/box", rr.Boxes3D(half_sizes=[[0.03, 0.03, 0.03]], colors=[(240, 200, 60)]), static=True)
    for t in keep:
        rec.set_time("sim_time", duration=float(t))
        pos = {}
        for name, tr in tracks.items():
            row = tr[np.searchsorted(tr[:, 0], t, side="right") - 1] if t >= tr[0, 0] else tr[0]
            pos[name] = row[1:4]
            q = row[4:8]
            rec.log(f"world/exo/{name}", rr.Transform3D(translation=row[1:4], quaternion=rr.Quaternion(xyzw=[q[1], q[2], q[3], q[0]])))
        strips = [[pos[n] for n in chain if n in pos] for chain in SKELETON]
        rec.log("world/exo/skeleton", rr.LineStrips3D([s for s in strips if len(s) > 1], colors=[(240, 200, 60)]))


def _log_tof(rr: Any, rec: Any, episode: Episode) -> None:
    tof_frames = [f for f in episode.frames if isinstance(f, ToFReading)]
    hits: dict[str, list] = {}
    colors: dict[str, list] = {}
    for frame, truth in zip(tof_frames, episode.truth.stairs.tof, strict=False):
        rec.set_time("sim_time", duration=float(frame.stamp_s))
        rec.log(f"metrics/tof/{frame.sensor_id}/range_m", rr.Scalars(float(frame.range_m) if frame.valid else np.nan))
        T = np.asarray(truth.T_world_sensor, dtype=float)
        if not frame.valid:
            continue
        origin, beam = T[:3, 3], T[:3, 2]
        hit = origin + frame.range_m * beam
        kind = next((s.kind for s in episode.truth.scene.surfaces if s.surface_id == truth.surface_id), "")
        hits.setdefault(frame.sensor_id, []).append(hit)
        colors.setdefault(frame.sensor_id, []).append(KIND_COLORS.get(kind, (230, 40, 40)))
        rec.log(f"world/tof/{frame.sensor_id}/ray", rr.LineStrips3D([[origin, hit]], colors=[(255, 80, 80)]))
        rec.log(f"world/tof/{frame.sensor_id}/hits", rr.Points3D(hits[frame.sensor_id], colors=colors[frame.sensor_id], radii=0.004))


def write_recording(episode: Episode, estimates_by_pipeline: dict[str, Any], path: str | os.PathLike) -> Path:
    """Write ``episode`` and the estimates to the ``.rrd`` file ``path``; returns the path.

    ``estimates_by_pipeline`` maps a pipeline name to its final :class:`StaircaseEstimate`
    (each plane is then shown from the time it became reliable) or to a time series
    ``[(stamp_s, estimate), ...]`` of its online estimates.
    """
    import rerun as rr
    import rerun.blueprint as rrb

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    rec = rr.RecordingStream("exobench", recording_id=f"{episode.scenario.get('riser_m', '')}-{episode.seed}")
    blueprint = rrb.Blueprint(
        rrb.Horizontal(
            rrb.Spatial3DView(origin="/world", name="staircase"),
            rrb.Vertical(
                rrb.TimeSeriesView(origin="/metrics/tof", name="ToF range (m)"),
                rrb.TimeSeriesView(origin="/metrics", contents=["+ /metrics/**", "- /metrics/tof/**"], name="reliable planes"),
            ),
            column_shares=[3, 2],
        ),
        collapse_panels=True,
    )
    rec.save(path, default_blueprint=blueprint)
    rec.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
    _log_world(rr, rec, episode)
    _log_body(rr, rec, episode)
    _log_tof(rr, rec, episode)
    t_end = float(episode.frames[-1].stamp_s) if episode.frames else 0.0
    for name, est in sorted(estimates_by_pipeline.items()):
        _log_estimates(rr, rec, episode, name, _as_series(est), t_end)
    rec.flush()
    rec.disconnect()
    return path
