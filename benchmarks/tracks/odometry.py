"""The odometry track: LiDAR trajectory estimation on office walks (seeds/003 Sec. 4.2.1, 5.2.1).

A walker with a trunk LiDAR walks an office route (:mod:`exobench.envs.office_sim`); each
pipeline returns a :class:`TrajectoryEstimate` of the LiDAR, scored by
:mod:`odometry_metrics` against the true LiDAR pose (ATE/RPE as evo, drift per metre, loop
TE/OE/TVE when the route ends where it started, time per scan).

Suites (cases deterministic; the run seed drives the sensor noise):

- ``quick``: 4 m of the south corridor (the office LiDAR simulation runs about 1.6x real time).
- ``paper``: the whole corridor (featureless, where LiDAR odometry slides) and the ring route
  (once round the corridor ring, past the glass, back to the start: loop TE/OE/TVE), VLP-16 as
  in the thesis.
- ``full``: the paper cases with VLP-32 and Ouster-64 patterns, without range noise, and for
  users of 1.60 / 1.90 m, plus the whole office loop route (every office, two laps).

Memory: the paper cases keep only the LiDAR truth's labels (``lidar_truth="labels"``: kind,
surface and range per point, ~21 bytes instead of ~170), so the ring walk (~170 s, ~1,700
sweeps) fits in about 3 GB; the full office ``loop`` route (~380 s, two laps) is in ``full``.

Published figures (VBR outdoor sequences and a real indoor loop, not this office) are printed
beside ours: Table 5.3 (ATE/RPE per VBR sequence), Sec. 5.2.1 (185 ms per LEO-SLAM loop) and
Table 5.4 (KISS-ICP loop TE/OE without filter).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from exobench.core.episode import Episode
from exobench.core.errors import UnknownNameError
from exobench.core.estimates import TrajectoryEstimate

from .base import Case, ParamInfo, Reference, SummaryRow
from .odometry_metrics import failure_metrics, score_trajectory, true_track
from .office_common import office_params, simulate_office_episode, validate_office_scenario

QUICK_M = 4.0
LABELS = {"lidar_truth": "labels"}
PAPER_CASES = {
    "corridor": {"route": "corridor", "max_distance_m": 60.0, **LABELS},
    "ring": {"route": "ring", "max_distance_m": 500.0, **LABELS},
}
LONG_CASES = {"loop": {"route": "loop", "max_distance_m": 500.0, **LABELS}}
FULL_VARIANTS = {
    "vlp32": {"lidar": "vlp32"},
    "ouster64": {"lidar": "ouster64"},
    "noise-off": {"lidar_noise_m": 0.0, "imu_noise_scale": 0.0, "encoder_noise_rad": 0.0},
    "h1.60": {"user_height_m": 1.60},
    "h1.90": {"user_height_m": 1.90},
}
VBR = ("Colosseum", "Diag", "Pincio", "Spagna")
TABLE_5_3 = {  # pipeline -> metric -> values per VBR sequence (m)
    "leo-slam": {"ate_m": (0.40748, 0.63319, 1.019423, 0.775329), "rpe_m": (0.33596, 0.30345, 0.328775, 1.027941)},
    "kiss-icp": {"ate_m": (1.51690, 1.39727, 0.78472, 1.04755), "rpe_m": (0.45299, 1.7908, 0.48580, 0.39860)},
}

SUMMARY_ROWS = [
    SummaryRow("ate_m", "ATE RMSE (m)", digits=3),
    SummaryRow("rpe_m", "RPE RMSE, consecutive (m)", digits=4),
    SummaryRow("rpe_1m_m", "RPE RMSE, 1 m (m)", digits=3, terminal=False),
    SummaryRow("drift_per_m", "drift (% of path)", scale=100, digits=2),
    SummaryRow("te_m", "loop TE (m)", digits=3),
    SummaryRow("oe_rad", "loop OE (rad)", digits=4),
    SummaryRow("tve_x_m", "loop TVE x (m)", digits=3, absolute=True, terminal=False),
    SummaryRow("tve_y_m", "loop TVE y (m)", digits=3, absolute=True, terminal=False),
    SummaryRow("tve_z_m", "loop TVE z (m)", digits=3, absolute=True, terminal=False),
    SummaryRow("time_per_scan_ms", "time per scan (ms)", digits=1),
    SummaryRow("failures", "poses not ok", digits=0),
    SummaryRow("path_m", "true path (m)", digits=1, terminal=False),
    SummaryRow("loop_edges", "loop edges", digits=0, terminal=False),
]


def published_references() -> list[Reference]:
    refs = []
    for pipe, metrics in TABLE_5_3.items():
        for metric, values in metrics.items():
            text = ", ".join(f"{name} {v:.3f}" for name, v in zip(VBR, values, strict=True))
            refs.append(Reference(metric, text, "Tab. 5.3, VBR", (), (pipe,), value=float(np.mean(values))))
    refs.append(Reference("time_per_scan_ms", "185 per loop", "Sec. 5.2.1", (), ("leo-slam",), value=185.0))
    refs += [
        Reference("te_m", "22.529 (no filter)", "Tab. 5.4, B1 + VLP-16 indoor", (), ("kiss-icp",), value=22.529),
        Reference("oe_rad", "0.270 (no filter)", "Tab. 5.4", (), ("kiss-icp",), value=0.270),
    ]
    return refs


class OdometryTrack:
    """Track protocol implementation for LiDAR odometry (see module docstring)."""

    name: ClassVar[str] = "odometry"
    suites: ClassVar[tuple[str, ...]] = ("quick", "paper", "full")
    default_suite: ClassVar[str] = "quick"
    report_intro = (
        "Published figures come from VBR outdoor sequences (Tab. 5.3) and a real indoor loop with a quadruped "
        "(Tab. 5.4) of seeds/003; ours from the simulated office walk."
    )

    def params(self) -> list[ParamInfo]:
        return office_params()

    def validate_scenario(self, values: Mapping[str, Any]) -> dict[str, Any]:
        return validate_office_scenario(values)

    def cases(self, suite: str) -> list[Case]:
        if suite == "quick":
            return [Case("corridor-4m", "corridor", {"route": "corridor", "max_distance_m": QUICK_M}, figure=True)]
        paper = [Case(name, name, dict(sc), figure=True) for name, sc in PAPER_CASES.items()]
        if suite == "paper":
            return paper
        if suite == "full":
            extra = [
                Case(f"{v}/{c.name}", f"{c.group} {v}", {**c.scenario, **sv}, figure=False)
                for v, sv in FULL_VARIANTS.items()
                for c in paper
            ]
            long = [Case(name, name, dict(sc), figure=True) for name, sc in LONG_CASES.items()]
            return paper + extra + long
        raise UnknownNameError("suite", suite, self.suites)

    def simulate(self, scenario: dict[str, Any], seed: int) -> Episode:
        return simulate_office_episode(scenario, seed)

    def score(self, episode: Episode, estimate: Any) -> dict[str, Any]:
        if not isinstance(estimate, TrajectoryEstimate):
            return failure_metrics(episode, f"finalize() returned {type(estimate).__name__}, not TrajectoryEstimate")
        return score_trajectory(episode, estimate)

    def failed_metrics(self, episode: Episode | None, reason: str) -> dict[str, Any]:
        return failure_metrics(episode, reason)

    def references(self) -> list[Reference]:
        return published_references()

    def summary_rows(self) -> list[SummaryRow]:
        return list(SUMMARY_ROWS)

    def figure_data(self, episode: Episode, estimates: dict[str, Any]) -> dict[str, Any]:
        return trajectory_figure_data(episode, estimates)

    def report_sections(self, records: list[dict[str, Any]], pipelines: list[str], out: Path) -> list[str]:
        return trajectory_sections(out)

    def write_recording(self, episode: Episode, estimates_by_pipeline: dict[str, Any], path: Path) -> Path:
        return write_lidar_recording(episode, estimates_by_pipeline, path)


# ------------------------------------------------------------------ figures, files, recording


def trajectory_figure_data(episode: Episode, estimates: Mapping[str, Any]) -> dict[str, Any]:
    """Arrays of the top-view figure and the trajectory files: truth and each estimate."""
    track = true_track(episode)
    data: dict[str, Any] = {"truth": track}
    for name, est in estimates.items():
        if isinstance(est, TrajectoryEstimate) and len(est.stamps_s):
            data[f"est_stamps__{name}"] = np.asarray(est.stamps_s, dtype=float)
            data[f"est_poses__{name}"] = np.asarray(est.T_world_sensor, dtype=float).reshape(-1, 4, 4)
    return data


def alignment(truth: np.ndarray, stamps: np.ndarray, poses: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(R, t) of the SE(3) Umeyama fit of the estimated positions onto the true ones (as the ATE);
    identity when fewer than 3 poses fall inside the truth."""
    from .. import trajectory as tj
    from .odometry_metrics import interpolate_poses

    inside, Q = interpolate_poses(truth, stamps)
    P = poses[inside]
    ok = np.all(np.isfinite(P.reshape(len(P), -1)), axis=1)
    if ok.sum() < 3:
        return np.eye(3), np.zeros(3)
    R, t, _ = tj.umeyama_alignment(P[ok, :3, 3], Q[ok, :3, 3])
    return R, t


def aligned_positions(truth: np.ndarray, stamps: np.ndarray, poses: np.ndarray) -> np.ndarray:
    """Estimated positions moved onto the truth by :func:`alignment`, (N, 3)."""
    R, t = alignment(truth, stamps, poses)
    return poses[:, :3, 3] @ R.T + t


def trajectory_sections(out: Path) -> list[str]:
    """Top views (estimate aligned as for the ATE, vs truth) and TUM/KITTI files per case."""
    from .. import trajectory as tj
    from ..plots import _pyplot

    folder = out / "figures"
    files = []
    for f in sorted(folder.glob("*.npz")) if folder.exists() else []:
        with np.load(f) as z:
            if "truth" in z.files and any(k.startswith("est_poses__") for k in z.files):
                files.append(f)
    if not files:
        return []
    traj_dir = out / "trajectories"
    traj_dir.mkdir(exist_ok=True)
    lines = ["## Trajectories (top view, estimates SE(3)-aligned to the truth)", "",
             "TUM (`t x y z qx qy qz qw`) and KITTI (3x4 per line) files of every estimate and of the truth are in "
             "`trajectories/`.", ""]  # fmt: skip
    plt = _pyplot()
    for f in files:
        key = f.stem
        with np.load(f) as z:
            data = dict(z)
        truth = data["truth"]
        ref = tj.Trajectory(truth[:, 0], truth[:, 1:4], truth[:, 4:8])
        tj.write_tum(ref, traj_dir / f"{key}__truth.tum")
        tj.write_kitti(ref, traj_dir / f"{key}__truth.kitti")
        fig, ax = plt.subplots(figsize=(7, 5))
        ax.plot(truth[:, 1], truth[:, 2], "k-", lw=2, label="truth")
        for name in sorted(k.split("__", 1)[1] for k in data if k.startswith("est_poses__")):
            stamps, poses = data[f"est_stamps__{name}"], data[f"est_poses__{name}"]
            est = tj.Trajectory.from_poses(stamps, poses)
            tj.write_tum(est, traj_dir / f"{key}__{name}.tum")
            tj.write_kitti(est, traj_dir / f"{key}__{name}.kitti")
            p = aligned_positions(truth, stamps, poses)
            ax.plot(p[:, 0], p[:, 1], "-", lw=1.2, label=name)
        ax.set_aspect("equal", adjustable="datalim")
        ax.set_xlabel("x (m)")
        ax.set_ylabel("y (m)")
        ax.legend(fontsize=8)
        ax.set_title(key.replace("__", "/"))
        png = folder / f"{key}_top.png"
        fig.savefig(png, dpi=110, bbox_inches="tight")
        plt.close(fig)
        lines += [f"### {key.replace('__', '/')}", "", f"![{key}](figures/{png.name})", ""]
    return lines


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

    from exobench.core.estimates import FilterEstimate

    from .office_common import log_office_world, log_scans, log_trajectory

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


def replace_scenario(episode: Episode, extra: Mapping[str, Any]) -> Episode:
    """The episode with ``extra`` keys added to its scenario record."""
    return dataclasses.replace(episode, scenario={**episode.scenario, **dict(extra)})
