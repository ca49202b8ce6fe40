"""The vio track's report: Tables IV and V laid out as the paper's, and top views over the floor plan.

- Table IV: one row per sequence group (the paper suite's EuRoC-like sequences, the quick suite's
  walks, ...), the mean ATE of each pipeline over its episodes beside the paper's figure for the
  EuRoC sequence it stands for (D-VIO, VINS-Mono, VINS-RGBD, VINS-Fusion), and the median time per
  frame;
- Table V: the loop drift x/y/z and TE of each pipeline over the closed loops, beside the paper's;
- per figure case a top view: the floor plan (the true vertical surfaces, walls and glass, seen
  from above, and the stairs' and ramps' edges), the true camera path and every estimate aligned
  as for its ATE; TUM (``t x y z qx qy qz qw``) and KITTI files of the truth and every estimate
  in ``trajectories/``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from exobench.core.episode import Episode
from exobench.core.estimates import TrajectoryEstimate

from ... import trajectory as tj
from .metrics import aligned_or_centred, camera_truth, scored_mask
from .paper import EUROC, TABLE_IV, TABLE_IV_OTHERS, TABLE_V, TIME_MS, TIME_MS_OTHERS

VERTICAL_NZ = 0.3  # a surface whose normal's |z| is below this is drawn as a line of the plan


def floor_plan(episode: Episode) -> np.ndarray:
    """Segments (K, 2, 2) of the plan: each vertical surface's extent seen from above."""
    segs = []
    for s in episode.truth.scene.surfaces:
        poly = np.asarray(s.polygon_w, dtype=float).reshape(-1, 3)
        if len(poly) < 2 or s.kind == "ceiling" or abs(float(np.asarray(s.normal_w)[2])) >= VERTICAL_NZ:
            continue
        xy = poly[:, :2]
        d = xy - xy.mean(axis=0)
        axis = np.linalg.svd(d, full_matrices=False)[2][0]
        u = d @ axis
        segs.append([xy[int(np.argmin(u))], xy[int(np.argmax(u))]])
    return np.asarray(segs, dtype=float).reshape(-1, 2, 2)


def vio_figure_data(episode: Episode, estimates: Mapping[str, Any]) -> dict[str, Any]:
    """Arrays of a figure case: the camera truth, the floor plan, each estimate and its scored mask."""
    data: dict[str, Any] = {"truth": camera_truth(episode), "plan": floor_plan(episode)}
    for name, est in estimates.items():
        if isinstance(est, TrajectoryEstimate) and len(est.stamps_s):
            try:
                stamps, poses, use = scored_mask(episode, est)
            except Exception:  # a malformed estimate has no figure
                continue
            data[f"est_stamps__{name}"] = stamps
            data[f"est_poses__{name}"] = poses
            data[f"est_scored__{name}"] = use
    return data


def _mean(records: list[dict[str, Any]], key: str) -> float:
    vals = [r["metrics"].get(key) for r in records]
    vals = [float(v) for v in vals if isinstance(v, (int, float)) and math.isfinite(v)]
    return float(np.mean(vals)) if vals else math.nan


def _cell(v: float, digits: int = 3) -> str:
    return "-" if not math.isfinite(v) else f"{v:.{digits}f}"


def _paper_cells(group: str) -> list[str]:
    if group not in EUROC:
        return ["" for _ in range(4)]
    i = EUROC.index(group)
    return [f"{v[i]:.2f}" for v in (*TABLE_IV.values(), *TABLE_IV_OTHERS.values())]


def table_iv(records: list[dict[str, Any]], pipelines: list[str]) -> list[str]:
    groups = list(dict.fromkeys(r["group"] for r in records))
    head = ["sequence", *[f"{p} ATE (m)" for p in pipelines], *[f"{p} lost (%)" for p in pipelines],
            "paper D-VIO", "paper VINS-Mono", "paper VINS-RGBD", "paper VINS-Fusion"]  # fmt: skip
    lines = ["## Table IV: ATE per sequence (paper: EuRoC MAV)", "",
             "| " + " | ".join(head) + " |", "|" + "---|" * len(head)]  # fmt: skip
    for g in groups:
        mine = [r for r in records if r["group"] == g]
        ate = [_cell(_mean([r for r in mine if r["pipeline"] == p], "ate_m")) for p in pipelines]
        lost = [_cell(100 * _mean([r for r in mine if r["pipeline"] == p], "lost_frac"), 1) for p in pipelines]
        lines.append("| " + " | ".join([g, *ate, *lost, *_paper_cells(g)]) + " |")
    means = [_cell(_mean([r for r in records if r["pipeline"] == p], "ate_m")) for p in pipelines]
    paper_means = [f"{np.mean(v):.3f}" for v in (*TABLE_IV.values(), *TABLE_IV_OTHERS.values())]
    lines.append("| " + " | ".join(["mean", *means, *["" for _ in pipelines], *paper_means]) + " |")
    times = [_cell(_mean([r for r in records if r["pipeline"] == p], "time_per_frame_ms"), 1) for p in pipelines]
    paper_t = [f"{v:.0f}" for v in (*TIME_MS.values(), *TIME_MS_OTHERS.values())]
    lines += ["| " + " | ".join(["time per frame (ms)", *times, *["" for _ in pipelines], *paper_t]) + " |", ""]
    return lines


def table_v(records: list[dict[str, Any]], pipelines: list[str]) -> list[str]:
    loops = [r for r in records if isinstance(r["metrics"].get("te_m"), (int, float)) and math.isfinite(r["metrics"]["te_m"])]
    lines = ["## Table V: loop drift over the closed loops", "",
             "| odometry | loops | drift x (m) | drift y (m) | drift z (m) | TE (m) |", "|---|---|---|---|---|---|"]  # fmt: skip
    for p in pipelines:
        mine = [r for r in loops if r["pipeline"] == p]
        cells = [_cell(_mean(mine, k)) for k in ("tve_x_m", "tve_y_m", "tve_z_m", "te_m")]
        lines.append(f"| {p} | {len({r['episode'] for r in mine})} | " + " | ".join(cells) + " |")
    for name, (x, y, z) in TABLE_V.items():
        label = "D-VIO" if name == "dvio" else name
        lines.append(f"| paper {label} | 1 | {x:.3f} | {y:.3f} | {z:.3f} | {math.sqrt(x * x + y * y + z * z):.3f} |")
    lines += ["| paper VINS-Mono | 1 | > 10 | > 10 | > 10 | |", "",
              "Drift: the last pose's error after putting the first poses on each other, in the estimate's "
              "gravity-aligned axes as D-VIO's frame G (VINS-Mono's: z up, x the first camera's right, y its "
              "forward; the paper names the frame G, not its yaw).", ""]  # fmt: skip
    return lines


def _top_view(plt: Any, key: str, data: dict[str, np.ndarray], folder: Path, traj_dir: Path) -> str:
    truth = data["truth"]
    ref = tj.Trajectory(truth[:, 0], truth[:, 1:4], truth[:, 4:8])
    tj.write_tum(ref, traj_dir / f"{key}__truth.tum")
    tj.write_kitti(ref, traj_dir / f"{key}__truth.kitti")
    fig, ax = plt.subplots(figsize=(7, 5))
    for seg in data.get("plan", np.zeros((0, 2, 2))):
        ax.plot(seg[:, 0], seg[:, 1], "-", color="0.7", lw=0.8)
    ax.plot(truth[:, 1], truth[:, 2], "k-", lw=2, label="truth")
    for name in sorted(k.split("__", 1)[1] for k in data if k.startswith("est_poses__")):
        stamps, poses = data[f"est_stamps__{name}"], data[f"est_poses__{name}"]
        use = data.get(f"est_scored__{name}", np.ones(len(stamps), dtype=bool)).astype(bool)
        if use.sum() < 3:
            continue
        est = tj.Trajectory.from_poses(stamps[use], poses[use])
        tj.write_tum(est, traj_dir / f"{key}__{name}.tum")
        tj.write_kitti(est, traj_dir / f"{key}__{name}.kitti")
        p = aligned_or_centred(truth, stamps[use], poses[use])
        ax.plot(p[:, 0], p[:, 1], "-", lw=1.2, label=name)
    span = np.ptp(truth[:, 1:3], axis=0) if len(truth) else np.ones(2)
    lo, hi = truth[:, 1:3].min(axis=0) - 0.5 * span - 1.0, truth[:, 1:3].max(axis=0) + 0.5 * span + 1.0
    ax.set_xlim(lo[0], hi[0])
    ax.set_ylim(lo[1], hi[1])
    ax.set_aspect("equal", adjustable="box")  # "datalim" would override the limits set above, with a warning
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.legend(fontsize=8)
    ax.set_title(key.replace("__", "/"))
    png = folder / f"{key}_top.png"
    fig.savefig(png, dpi=110, bbox_inches="tight")
    plt.close(fig)
    return png.name


def vio_sections(records: list[dict[str, Any]], pipelines: list[str], out: Path) -> list[str]:
    """Tables IV and V, then the top views (module docstring)."""
    lines = [*table_iv(records, pipelines), *table_v(records, pipelines)] if records else []
    folder = out / "figures"
    files = []
    for f in sorted(folder.glob("*.npz")) if folder.exists() else []:
        with np.load(f) as z:
            if "truth" in z.files and "plan" in z.files:
                files.append(f)
    if not files:
        return lines
    from ...plots import pyplot

    traj_dir = out / "trajectories"
    traj_dir.mkdir(exist_ok=True)
    lines += ["## Trajectories over the floor plan (top view, estimates SE(3)-aligned to the truth)", "",
              "TUM and KITTI files of every estimate (its scored poses) and of the truth are in `trajectories/`.", ""]  # fmt: skip
    plt = pyplot()
    for f in files:
        with np.load(f) as z:
            data = dict(z)
        name = _top_view(plt, f.stem, data, folder, traj_dir)
        lines += [f"### {f.stem.replace('__', '/')}", "", f"![{f.stem}](figures/{name})", ""]
    return lines
