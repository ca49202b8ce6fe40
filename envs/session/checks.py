"""The frames of a session against the truth they are scored with, whatever ``meta.json`` claims.

``meta.json`` counts (frames, truths) and hashes are written by the same hand that could edit
the files, so a session whose ``meta.json`` was edited with them (or an old format without
hashes) passes those checks. What the scorers rely on is that each frame has its truth, and
that is checked here from the files alone, for every format version:

- ToF: a truth for each ToF reading, of its sensor and stamp, and a reading for each truth
  (climbing-step episodes, the only ones with ToF truth: the stairs scorer labels each point
  through it; a reading delivered twice shares its truth);
- LiDAR: one truth per scan, in scan order, with the scan's sensor, stamp and point count;
- segmentation: a per-pixel truth for each frame of each camera that keeps one, and for every
  camera frame when the scenario asked for it;
- the true trajectory: one pose per distinct sweep of the trunk LiDAR (office walks, what the
  LiDAR tracks score against) or per odometry sample (course walks, the camera's ticks).

A mismatch is a :class:`SessionError` naming the truth file, the two counts and the first
frame without its truth, so a cut or padded truth is never scored against a part of the frames.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from exobench.core import EpisodeTruth, Frame, LidarScan, OdometrySample, RgbdFrame, SessionError, ToFReading

LIDAR_TRUNK = "lidar_trunk"  # the LiDAR an office walk's trajectory_w follows (envs.sim.scenarios.office)


def _keys(items: Sequence[Any]) -> set[tuple[str, float]]:
    return {(str(x.sensor_id), float(x.stamp_s)) for x in items}


def _same_keys(where: Path, what: str, frames: Sequence[Any], truths: Sequence[Any]) -> None:
    """Each frame has a truth of its sensor and stamp and each truth a frame; a frame delivered
    twice (same sensor and stamp, a delivery fault) shares its truth."""
    got, want = _keys(truths), _keys(frames)
    if got == want:
        return
    missing = sorted(want - got)
    extra = sorted(got - want)
    first = f"first {what} without its truth: {missing[0][0]} at {missing[0][1]!r} s" if missing else (
        f"first truth without its {what}: {extra[0][0]} at {extra[0][1]!r} s")  # fmt: skip
    raise SessionError(f"{where}: {len(truths)} truths for {len(frames)} {what}s ({first}); cut or edited")


def check_truth_matches_frames(root: Path, frames: Sequence[Frame], truth: EpisodeTruth, scenario: dict[str, Any]) -> None:
    """SessionError when a frame the track scores lacks its truth or a truth lacks its frame
    (see the module docstring)."""
    tof = [f for f in frames if isinstance(f, ToFReading)]
    if truth.stairs is not None:
        _same_keys(root / "truth" / "tof.jsonl", "ToF reading", tof, truth.stairs.tof)
    scans = [f for f in frames if isinstance(f, LidarScan)]
    lidar_file = root / "truth" / ("lidar.npz" if (root / "truth" / "lidar.npz").exists() else "lidar")
    if len(scans) != len(truth.lidar):
        raise SessionError(f"{lidar_file}: {len(truth.lidar)} truths for {len(scans)} LiDAR scans; cut or edited")
    for k, (scan, lt) in enumerate(zip(scans, truth.lidar, strict=True)):
        n_pts, n_truth = len(np.asarray(scan.points_xyz).reshape(-1, 3)), len(np.asarray(lt.true_range_m).reshape(-1))
        if (scan.sensor_id, float(scan.stamp_s), n_pts) != (lt.sensor_id, float(lt.stamp_s), n_truth):
            raise SessionError(
                f"{lidar_file}: truth {k} is of {lt.sensor_id} at {float(lt.stamp_s)!r} s with {n_truth} points, "
                f"scan {k} of {scan.sensor_id} at {float(scan.stamp_s)!r} s with {n_pts}; cut or edited"
            )
    rgbd = [f for f in frames if isinstance(f, RgbdFrame)]
    cams = {s.sensor_id for s in truth.segmentation}
    if scenario.get("segmentation_truth") is True:
        cams |= {f.sensor_id for f in rgbd}
    if cams:
        _same_keys(root / "truth" / "segmentation", "RGB-D frame", [f for f in rgbd if f.sensor_id in cams], truth.segmentation)
    _check_trajectory(root, frames, truth, scans)


def _check_trajectory(root: Path, frames: Sequence[Frame], truth: EpisodeTruth, scans: Sequence[LidarScan]) -> None:
    n_poses = len(np.asarray(truth.trajectory_w).reshape(-1, 8))
    kind = truth.scene.kind
    if kind == "office" and any(s.sensor_id == LIDAR_TRUNK for s in scans):
        # a duplicated sweep shares its start with the original; a clock step shifts the starts
        # of later sweeps but keeps them distinct
        want, of = len({float(s.sweep_start_s) for s in scans if s.sensor_id == LIDAR_TRUNK}), f"sweeps of {LIDAR_TRUNK}"
    elif kind == "course" and any(isinstance(f, OdometrySample) for f in frames):
        first = next(f.sensor_id for f in frames if isinstance(f, OdometrySample))
        want, of = sum(1 for f in frames if isinstance(f, OdometrySample) and f.sensor_id == first), f"samples of {first}"
    else:
        return
    if n_poses != want:
        raise SessionError(f"{root / 'truth' / 'episode.json'}: trajectory_w has {n_poses} poses for {want} {of}; cut or edited")
