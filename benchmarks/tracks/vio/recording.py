"""Write a vio episode and its trajectory estimates as a rerun recording (``.rrd``).

Open it with ``rerun FILE.rrd``. Entities (world frame, metres, timeline ``sim_time``):

- ``world/surfaces/<kind>/S{id}``: the true surfaces (static; :func:`..office_recording.log_office_world`);
- ``world/camera``: the true optical-frame pose and its pinhole; ``world/camera/rgb`` and
  ``world/camera/depth`` the images (at most every ``image_every_s``; colour JPEG-compressed);
- ``world/truth``: the true camera path (static line);
- ``world/estimates/{pipeline}``: each estimate's scored poses, SE(3)-aligned to the truth as for
  its ATE (static line), and its current position over time (a point), so the estimate is seen
  against the truth as the walk goes.

The estimate carries no tracked features in the contract; none are drawn. rerun is imported
inside the function so the rest of exobench does not pay for it.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

from exobench.core.episode import Episode
from exobench.core.estimates import TrajectoryEstimate
from exobench.core.frames import RgbdFrame

from ..office_recording import log_office_world, log_rgbd_frames, log_trajectory
from .metrics import aligned_or_centred, camera_truth, scored_mask

IMAGE_EVERY_S = 0.2
COLORS = ((230, 90, 40), (40, 160, 230), (120, 200, 60), (200, 60, 200))


def _final(est: Any) -> Any:
    if isinstance(est, list):
        return est[-1][1] if est else None
    return est


def write_vio_recording(episode: Episode, estimates_by_pipeline: dict[str, Any], path: str | os.PathLike, *,
                        image_every_s: float = IMAGE_EVERY_S) -> Path:  # fmt: skip
    """Write ``episode`` (with its frames) and the estimates to ``path``; returns the path."""
    import rerun as rr
    import rerun.blueprint as rrb

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    rec = rr.RecordingStream("exobench", recording_id=f"vio-{episode.scenario.get('world', '')}-{episode.seed}")
    blueprint = rrb.Blueprint(
        rrb.Horizontal(
            rrb.Spatial3DView(origin="/world", name="walk"),
            rrb.Vertical(
                rrb.Spatial2DView(origin="/world/camera", contents=["/world/camera/rgb"], name="colour"),
                rrb.Spatial2DView(origin="/world/camera", contents=["/world/camera/depth"], name="depth"),
            ),
            column_shares=[3, 2],
        ),
        collapse_panels=True,
    )
    rec.save(path, default_blueprint=blueprint)
    rec.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
    log_office_world(rr, rec, episode)
    truth = camera_truth(episode)
    log_trajectory(rr, rec, "world/truth", truth[:, 1:4], (20, 20, 20))
    log_rgbd_frames(rr, rec, [f for f in episode.frames if isinstance(f, RgbdFrame)], truth, image_every_s)
    for k, name in enumerate(sorted(estimates_by_pipeline)):
        est = _final(estimates_by_pipeline[name])
        if not isinstance(est, TrajectoryEstimate) or not len(est.stamps_s):
            continue
        stamps, poses, use = scored_mask(episode, est)
        if use.sum() < 3:
            continue
        p = aligned_or_centred(truth, stamps[use], poses[use])
        rgb = COLORS[k % len(COLORS)]
        log_trajectory(rr, rec, f"world/estimates/{name}", p, rgb)
        for t, xyz in zip(stamps[use][::3], p[::3], strict=True):
            rec.set_time("sim_time", duration=float(t))
            rec.log(f"world/estimates/{name}/now", rr.Points3D([xyz], radii=0.05, colors=[rgb]))
    rec.flush()
    rec.disconnect()
    return path
