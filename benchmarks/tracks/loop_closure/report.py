"""The loop-closure track's report: precision-recall curves and the loop matches of the figure cases.

- :func:`figure_arrays`: what the runner saves per figure case: the true path, and per pipeline
  the keyframe positions, matches and detections at its best-F1 threshold (correct or not);
- :func:`plot_pr_curves`, :func:`plot_matches`: the figures; :func:`report_sections` their markdown.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from exobench.core.episode import Episode
from exobench.core.estimates import PlaceRecognitionEstimate

from ...plots import pyplot
from .metrics import EXCLUDE_RECENT_S, REVISIT_M, best_f1, keyframe_poses, pr_curve


def figure_arrays(episode: Episode, estimates: Mapping[str, Any], *, revisit_m: float = REVISIT_M,
                  exclude_recent_s: float = EXCLUDE_RECENT_S) -> dict[str, Any]:
    """Arrays of the trajectory figure: true path, and per pipeline the keyframe positions, matches
    and the detections at its best-F1 threshold (correct or not), under the scoring settings."""
    tr = np.asarray(episode.truth.trajectory_w, dtype=float).reshape(-1, 8)
    out: dict[str, Any] = {"trajectory_xyz": tr[:, 1:4], "pipelines": np.array(sorted(estimates), dtype=str)}
    for name, est in sorted(estimates.items()):
        est = final_estimate(est)
        if not isinstance(est, PlaceRecognitionEstimate):
            continue
        pos, _, _ = keyframe_poses(tr, est.stamps_s)
        curve = pr_curve(pos, est.stamps_s, est.match_index, est.distance,
                         revisit_m=float(revisit_m), exclude_recent_s=float(exclude_recent_s))
        _, tau = best_f1(curve)
        m = np.asarray(est.match_index, dtype=np.int64)
        d = np.asarray(est.distance, dtype=float)
        t = np.asarray(est.stamps_s, dtype=float)
        eligible = (m >= 0) & ((t - t[np.where(m >= 0, m, 0)]) >= float(exclude_recent_s))
        detected = eligible & np.isfinite(d) & (d <= tau if math.isfinite(tau) else np.zeros(len(d), dtype=bool))
        out[f"{name}__keyframes_xyz"] = pos
        out[f"{name}__match"] = m
        out[f"{name}__detected"] = detected
        out[f"{name}__correct"] = curve.correct
        out[f"{name}__tau"] = np.array(tau)
    return out


def final_estimate(est: Any) -> Any:
    """The final estimate of a time series ``[(stamp, estimate), ...]`` or the estimate itself."""
    if isinstance(est, (list, tuple)) and est and isinstance(est[-1], (list, tuple)):
        return est[-1][1]
    return est


def plot_pr_curves(records: list[dict[str, Any]], pipelines: list[str], path: Path, title: str) -> Path:
    """PR curves (recall x, precision y) of each pipeline's records of one episode."""
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(5.2, 4.2))
    for p in pipelines:
        for r in records:
            m = r["metrics"]
            if r["pipeline"] != p or not m.get("pr_recall"):
                continue
            rec = np.concatenate([[0.0], np.asarray(m["pr_recall"], dtype=float)])
            prec = np.concatenate([[1.0], np.asarray(m["pr_precision"], dtype=float)])
            mr = m.get("max_recall_at_full_precision")
            label = f"{p} (R@P=1 {100 * mr:.1f} %)" if isinstance(mr, (int, float)) else p
            ax.plot(rec, prec, drawstyle="steps-post", label=label)
    ax.set_xlim(0, 1.02)
    ax.set_ylim(0, 1.02)
    ax.set_xlabel("recall")
    ax.set_ylabel("precision")
    ax.set_title(title, fontsize=9)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, loc="lower left")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def plot_matches(data: Mapping[str, Any], path: Path, title: str) -> Path:
    """One panel per pipeline: the true path, and the detections at best F1 (green correct, red false)."""
    plt = pyplot()
    names = [str(n) for n in np.atleast_1d(data["pipelines"])]
    fig, axes = plt.subplots(1, max(1, len(names)), figsize=(4.0 * max(1, len(names)), 3.6), squeeze=False)
    tr = np.asarray(data["trajectory_xyz"], dtype=float)
    for ax, name in zip(axes[0], names or [""], strict=True):
        if len(tr):
            ax.plot(tr[:, 0], tr[:, 1], color="0.6", lw=1)
        key = f"{name}__keyframes_xyz"
        if key in data:
            pos = np.asarray(data[key], dtype=float)
            m = np.asarray(data[f"{name}__match"], dtype=int)
            det = np.asarray(data[f"{name}__detected"], dtype=bool)
            ok = np.asarray(data[f"{name}__correct"], dtype=bool)
            for k in np.flatnonzero(det):
                a, b = pos[k], pos[m[k]]
                ax.plot([a[0], b[0]], [a[1], b[1]], color="tab:green" if ok[k] else "tab:red", lw=1.2 if ok[k] else 1.5)
            ax.plot(pos[:, 0], pos[:, 1], ".", color="0.3", ms=2)
            good = np.flatnonzero(det & ok)  # a retraced path makes true segments very short: mark the queries
            ax.plot(pos[good, 0], pos[good, 1], "o", mfc="none", color="tab:green", ms=4, mew=0.8)
            ax.set_title(f"{name}: {int(np.sum(det & ok))} true / {int(np.sum(det & ~ok))} false", fontsize=9)
        ax.set_aspect("equal")
        ax.set_xlabel("x (m)")
    axes[0][0].set_ylabel("y (m)")
    fig.suptitle(title, fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def report_sections(records: list[dict[str, Any]], pipelines: list[str], out: Path) -> list[str]:
    """PR curves per episode (up to 12) and the figure cases' trajectories with their matches."""
    lines = ["## Precision-recall curves", ""]
    episodes: list[str] = []
    for r in records:
        if r["episode"] not in episodes:
            episodes.append(r["episode"])
    for ep in episodes[:12]:
        png = out / f"pr_{ep.replace('/', '__')}.png"
        plot_pr_curves([r for r in records if r["episode"] == ep], pipelines, png, ep)
        lines += [f"### {ep}", "", f"![PR {ep}]({png.name})", ""]
    figures = sorted((out / "figures").glob("*.npz")) if (out / "figures").exists() else []
    if figures:
        lines += ["## Loop matches at the best-F1 threshold (green true, red false)", ""]
        for f in figures:
            key = f.stem.replace("__", "/")
            with np.load(f) as data:
                png = plot_matches(dict(data), f.with_suffix(".png"), key)
            lines += [f"### {key}", "", f"![{key}](figures/{png.name})", ""]
    return lines
