"""The loop-closure track's rerun recording: scans, true surfaces and trajectory, and each
pipeline's detections at its best-F1 threshold (rerun is imported inside the function)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from exobench.core.episode import Episode
from exobench.core.estimates import PlaceRecognitionEstimate

from ..office_recording import log_office_world, log_scans, log_trajectory
from .report import figure_arrays, final_estimate


def write_recording(episode: Episode, estimates_by_pipeline: dict[str, Any], path: Path, *,
                    revisit_m: float, exclude_recent_s: float) -> Path:
    """Scans (every 5th, by intensity and by true return kind), true surfaces and trajectory,
    and each pipeline's detections at its best-F1 threshold (under the scoring settings) as
    segments between the true keyframe positions (green true, red false), shown from the query's time."""
    import rerun as rr
    import rerun.blueprint as rrb

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    rec = rr.RecordingStream("exobench", recording_id=f"loop-closure-{episode.seed}")
    blueprint = rrb.Blueprint(rrb.Spatial3DView(origin="/world", name="office"), collapse_panels=True)
    rec.save(path, default_blueprint=blueprint)
    rec.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
    log_office_world(rr, rec, episode)
    tr = np.asarray(episode.truth.trajectory_w, dtype=float).reshape(-1, 8)
    log_trajectory(rr, rec, "world/trajectory/true", tr[:, 1:4], (240, 200, 60))
    log_scans(rr, rec, episode, every=5)
    finals = {n: final_estimate(e) for n, e in estimates_by_pipeline.items()}
    data = figure_arrays(episode, finals, revisit_m=revisit_m, exclude_recent_s=exclude_recent_s)
    for name, est in sorted(finals.items()):
        if not isinstance(est, PlaceRecognitionEstimate) or f"{name}__keyframes_xyz" not in data:
            continue
        pos = data[f"{name}__keyframes_xyz"]
        ent = name.replace("+", "p")  # "sc++" -> "scpp": no escapes in entity paths
        m, det, ok = data[f"{name}__match"], data[f"{name}__detected"], data[f"{name}__correct"]
        segs_ok: list = []
        segs_bad: list = []
        for k in np.flatnonzero(det):
            (segs_ok if ok[k] else segs_bad).append([pos[k], pos[m[k]]])
            rec.set_time("sim_time", duration=float(est.stamps_s[k]))
            if segs_ok:
                rec.log(f"world/loops/{ent}/true", rr.LineStrips3D(segs_ok, colors=[(40, 200, 60)], radii=0.03))
            if segs_bad:
                rec.log(f"world/loops/{ent}/false", rr.LineStrips3D(segs_bad, colors=[(230, 40, 40)], radii=0.03))
        log_trajectory(rr, rec, f"world/keyframes/{ent}", pos, (120, 120, 255))
    rec.flush()
    rec.disconnect()
    return path
