"""The multisession track's report and rerun recording.

- :func:`figure_arrays`: per figure case and pipeline, the merged map seen from above (every
  :data:`TOP_VIEW_EVERY`-th point, its session), the removed and added points (world frame),
  the keyframe positions and inter-session edges;
- :func:`report_sections`: Tables I-III of the paper's layout (per case and pipeline), then the
  top views as Fig. 3 (map coloured by session, removed red, added blue);
- :func:`write_recording`: the sessions' keyframe paths (estimated, coloured by session, and
  true), the pose graph's inter-session edges, the merged map and the changes.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from exobench.core.episode import Episode
from exobench.core.estimates import MultiSessionEstimate

from ...plots import pyplot

TOP_VIEW_EVERY = 10
TABLES = (
    ("Table I: trajectory", (("ate_m", "ATE (m)"), ("ate_aligned_m", "ATE aligned (m)"), ("rpe_1m_m", "RPE 1 m (m)"))),
    ("Table II: change detection", (("change_precision", "P"), ("change_recall", "R"), ("change_f1", "F1"),
                                    ("change_chamfer_m", "Chamfer (m)"), ("change_precision_whole_map", "P whole map"),
                                    ("change_recall_whole_map", "R whole map"))),
    ("Table III: merged-map error", (("map_error_mean_m", "mean (m)"), ("map_error_median_m", "median (m)"),
                                     ("map_error_max_m", "max (m)"), ("map_error_p90_m", "p90 (m)"),
                                     ("map_error_mean_m_no_change_detection", "mean, no change detection (m)"),
                                     ("map_error_mean_m_single_session", "mean, last session alone (m)"))),
)  # fmt: skip


def _final(est: Any) -> Any:
    if isinstance(est, (list, tuple)) and est and isinstance(est[-1], (list, tuple)):
        return est[-1][1]
    return est


def _world(T: np.ndarray, p: Any) -> np.ndarray:
    p = np.asarray(p, dtype=float).reshape(-1, 3)
    return p @ T[:3, :3].T + T[:3, 3]


def figure_arrays(episode: Episode, estimates: Mapping[str, Any]) -> dict[str, Any]:
    """Arrays of the top view (module docstring), world frame."""
    T = np.asarray(episode.truth.T_world_estimator, dtype=float)
    out: dict[str, Any] = {"pipelines": np.array(sorted(estimates), dtype=str)}
    out["true_paths_xyz"] = np.concatenate([s["camera_w"][:, 1:4] for s in episode.truth.extra["sessions"]])
    for name, est in sorted(estimates.items()):
        est = _final(est)
        if not isinstance(est, MultiSessionEstimate) or not est.sessions:
            continue
        pts = _world(T, est.merged_map_points)[::TOP_VIEW_EVERY]
        out[f"{name}__map_xyz"] = pts
        kf = [(_world(T, Tm[:, :3, 3]), s) for Tm, s, m in zip(est.T_map_cam, est.sessions, est.map_of_session) if m == 0]
        out[f"{name}__keyframes_xyz"] = np.concatenate([p for p, _ in kf]) if kf else np.zeros((0, 3))
        out[f"{name}__keyframe_session"] = np.concatenate([np.full(len(p), s) for p, s in kf]) if kf else np.zeros(0, int)
        out[f"{name}__removed_xyz"] = _world(T, np.concatenate([np.zeros((0, 3)), *est.removed_points]))
        out[f"{name}__added_xyz"] = _world(T, np.concatenate([np.zeros((0, 3)), *est.added_points]))
    return out


def plot_top_view(data: Mapping[str, Any], path: Path, title: str) -> Path:
    """Fig. 3: per pipeline the merged map from above (grey), keyframes by session, removed red, added blue."""
    plt = pyplot()
    names = [str(n) for n in np.atleast_1d(data["pipelines"]) if f"{n}__map_xyz" in data]
    fig, axes = plt.subplots(1, max(1, len(names)), figsize=(5.0 * max(1, len(names)), 4.2), squeeze=False)
    for ax, name in zip(axes[0], names or [""], strict=True):
        if name:
            m = np.asarray(data[f"{name}__map_xyz"])
            ax.scatter(m[:, 0], m[:, 1], s=0.2, c="0.7", rasterized=True)
            kf, ses = np.asarray(data[f"{name}__keyframes_xyz"]), np.asarray(data[f"{name}__keyframe_session"])
            for s in np.unique(ses):
                ax.plot(kf[ses == s, 0], kf[ses == s, 1], ".-", ms=3, lw=0.8, label=f"session {int(s)}")
            for key, colour, label in (("removed", "tab:red", "removed"), ("added", "tab:blue", "added")):
                p = np.asarray(data[f"{name}__{key}_xyz"])
                ax.scatter(p[:, 0], p[:, 1], s=1.0, c=colour, label=f"{label} ({len(p)})", rasterized=True)
            ax.legend(fontsize=7, markerscale=4)
            ax.set_title(name, fontsize=9)
        ax.set_aspect("equal")
        ax.set_xlabel("x (m)")
    axes[0][0].set_ylabel("y (m)")
    fig.suptitle(title, fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def _cell(v: Any) -> str:
    return f"{v:.3f}" if isinstance(v, (int, float)) and math.isfinite(v) else "-"


def report_sections(records: list[dict[str, Any]], pipelines: list[str], out: Path) -> list[str]:
    """Tables I-III (one row per episode and pipeline), sessions kept apart, then Fig. 3 per figure case."""
    lines: list[str] = []
    for title, cols in TABLES:
        lines += [f"## {title}", "", "| episode | pipeline | " + " | ".join(c[1] for c in cols) + " |",
                  "|---|---|" + "---|" * len(cols)]  # fmt: skip
        for r in records:
            if r["pipeline"] in pipelines:
                m = r["metrics"]
                lines.append(f"| {r['episode']} | {r['pipeline']} | " + " | ".join(_cell(m.get(c[0])) for c in cols) + " |")
        lines.append("")
    apart = [(r["episode"], r["pipeline"], r["metrics"].get("separate_sessions")) for r in records
             if r["metrics"].get("separate_sessions")]  # fmt: skip
    if apart:
        lines += ["Sessions kept as maps of their own (overlapping no other, or joined to the main map by no two "
                  "inter-session edges that agree); the ATE and the map figures are over the main map's sessions:", ""]
        lines += [f"- {e} / {p}: sessions {', '.join(str(s) for s in ss)}" for e, p, ss in apart] + [""]
    figures = sorted((out / "figures").glob("*.npz")) if (out / "figures").exists() else []
    if figures:
        lines += ["## Merged maps from above (Fig. 3: keyframes by session, removed red, added blue)", ""]
        for f in figures:
            key = f.stem.replace("__", "/")
            with np.load(f) as data:
                png = plot_top_view(dict(data), f.with_suffix(".png"), key)
            lines += [f"### {key}", "", f"![{key}](figures/{png.name})", ""]
    return lines


def write_recording(episode: Episode, estimates_by_pipeline: dict[str, Any], path: Path) -> Path:
    """Rerun: true paths, per pipeline the keyframe paths by session, inter-session edges, the
    merged map and the removed (red) and added (blue) points."""
    import rerun as rr
    import rerun.blueprint as rrb

    from ..office_recording import log_office_world, log_trajectory

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    rec = rr.RecordingStream("exobench", recording_id=f"multisession-{episode.seed}")
    rec.save(path, default_blueprint=rrb.Blueprint(rrb.Spatial3DView(origin="/world", name="office"), collapse_panels=True))
    rec.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
    log_office_world(rr, rec, episode)
    T = np.asarray(episode.truth.T_world_estimator, dtype=float)
    for s in episode.truth.extra["sessions"]:
        log_trajectory(rr, rec, f"world/true/session{s['session']}", s["camera_w"][:, 1:4], (240, 200, 60))
    palette = [(31, 119, 180), (44, 160, 44), (148, 103, 189), (140, 86, 75), (227, 119, 194), (127, 127, 127)]
    for name, est in sorted(estimates_by_pipeline.items()):
        est = _final(est)
        if not isinstance(est, MultiSessionEstimate) or not est.sessions:
            continue
        ent = f"world/{name}"
        pos = {}
        for k, (s, Tm, m) in enumerate(zip(est.sessions, est.T_map_cam, est.map_of_session)):
            p = _world(T, np.asarray(Tm)[:, :3, 3])
            pos[s] = p
            if m == 0:
                log_trajectory(rr, rec, f"{ent}/session{s}", p, palette[k % len(palette)])
        segs = [[pos[a][i], pos[b][j]] for a, i, b, j in est.inter_edges if a in pos and b in pos]
        if segs:
            rec.log(f"{ent}/inter_session_edges", rr.LineStrips3D(segs, colors=[(255, 140, 0)], radii=0.01), static=True)
        rec.log(f"{ent}/map", rr.Points3D(_world(T, est.merged_map_points)[::TOP_VIEW_EVERY], colors=[(170, 170, 170)],
                                          radii=0.01), static=True)  # fmt: skip
        for key, pts, colour in (("removed", est.removed_points, (220, 30, 30)), ("added", est.added_points, (30, 60, 220))):
            p = _world(T, np.concatenate([np.zeros((0, 3)), *pts]))
            rec.log(f"{ent}/{key}", rr.Points3D(p, colors=[colour], radii=0.015), static=True)
    return path
