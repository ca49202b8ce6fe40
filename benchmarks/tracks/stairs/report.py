"""The stairs track's report: error distributions and side views like Fig. 4 of the staircase paper.

- :func:`side_view_data`: arrays of the side view of one episode (the runner saves them for the
  figure cases). The view plane is vertical and runs up the staircase: ``s`` is the horizontal
  distance along the staircase's ascending direction (from the first riser's plane), ``z`` the
  world height. Keeping the arrays apart lets the report be regenerated from the run folder.
- :func:`plot_side_view`: one panel per pipeline: points coloured by the surface they were
  assigned to (treads blue, risers green, discarded red), the true profile (light blue, solid),
  the estimated planes (magenta, dashed), the foot path (black, dotted) and a red asterisk where
  S2 became reliable.
- :func:`plot_distributions`: per pipeline, the spread of riser and tread error, touch-down
  error and alpha of S2 over all episodes.
- :func:`report_sections`: the markdown of both.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np

from exobench.core.episode import Episode
from exobench.core.estimates import StaircaseEstimate
from exobench.core.transforms import transform_points

from ...plots import pyplot

S_RANGE_M = (-0.8, 1.0)  # side-view extent along the staircase around the first riser
WALKABLE_OR_RISER = ("ground", "tread", "riser", "landing")


def _view_axes(episode: Episode) -> tuple[np.ndarray, np.ndarray]:
    """Origin and ascending horizontal unit direction of the side view."""
    scene = episode.truth.scene
    risers = [s for s in scene.surfaces if s.kind == "riser"]
    if not risers:
        return np.zeros(3), np.array([1.0, 0.0, 0.0])
    first = min(risers, key=lambda s: s.surface_id)
    u = -np.array([first.normal_w[0], first.normal_w[1], 0.0])  # risers face the walker
    return np.asarray(first.point_w, dtype=float), u / np.linalg.norm(u)


def _sz(points_w: np.ndarray, o: np.ndarray, u: np.ndarray) -> np.ndarray:
    p = np.asarray(points_w, dtype=float).reshape(-1, 3)
    return np.column_stack([(p - o) @ u, p[:, 2]])


def _clip_s(seg: np.ndarray) -> np.ndarray | None:
    """Clip a segment ((s0, z0), (s1, z1)) to S_RANGE_M; None when nothing is left."""
    (s0, z0), (s1, z1) = seg
    lo, hi = S_RANGE_M
    if abs(s1 - s0) < 1e-12:
        return seg if lo <= s0 <= hi else None
    t = sorted(((lo - s0) / (s1 - s0), (hi - s0) / (s1 - s0)))
    t0, t1 = max(0.0, t[0]), min(1.0, t[1])
    if t0 >= t1:
        return None
    a, b = np.array([s0, z0]), np.array([s1, z1])
    return np.array([a + t0 * (b - a), a + t1 * (b - a)])


def _extreme_pair(pts: np.ndarray) -> np.ndarray:
    d = np.linalg.norm(pts[:, None, :] - pts[None, :, :], axis=2)
    i, j = np.unravel_index(int(np.argmax(d)), d.shape)
    return np.array([pts[i], pts[j]])


def true_profile(episode: Episode, o: np.ndarray, u: np.ndarray) -> np.ndarray:
    """Segments (K, 2, 2) of the true staircase profile in (s, z)."""
    segs = []
    for s in episode.truth.scene.surfaces:
        if s.kind not in WALKABLE_OR_RISER or len(s.polygon_w) < 2:
            continue
        seg = _clip_s(_extreme_pair(_sz(s.polygon_w, o, u)))
        if seg is not None:
            segs.append(seg)
    return np.array(segs).reshape(-1, 2, 2)


def estimated_profile(
    episode: Episode, est: StaircaseEstimate, o: np.ndarray, u: np.ndarray, points_sz: np.ndarray, labels: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Segments (M, 2, 2) of the estimated planes cut by the view plane through their centroids."""
    T = np.asarray(episode.truth.T_world_estimator, dtype=float)
    segs, idx = [], []
    for p in est.planes:
        if not (np.all(np.isfinite(p.normal)) and np.all(np.isfinite(p.centroid))):
            continue
        n_w = T[:3, :3] @ np.asarray(p.normal, dtype=float)
        c_sz = _sz(transform_points(T, p.centroid), o, u)[0]
        n2 = np.array([n_w @ u, n_w[2]])
        if np.linalg.norm(n2) < 0.3:  # plane nearly parallel to the view plane: no clean cut
            continue
        d2 = np.array([-n2[1], n2[0]]) / np.linalg.norm(n2)
        mine = points_sz[labels == p.index]
        proj = (mine - c_sz) @ d2 if len(mine) else np.array([-0.1, 0.1])
        lo, hi = min(float(proj.min()), -0.02), max(float(proj.max()), 0.02)
        segs.append(np.array([c_sz + lo * d2, c_sz + hi * d2]))
        idx.append(p.index)
    return np.array(segs).reshape(-1, 2, 2), np.array(idx, dtype=int)


def side_view_data(episode: Episode, estimates: dict[str, Any]) -> dict[str, np.ndarray]:
    """Arrays for the report's side view (see module docstring); one block per pipeline."""
    o, u = _view_axes(episode)
    track = np.asarray(episode.truth.stairs.foot_track_w, dtype=float).reshape(-1, 4)
    T = np.asarray(episode.truth.T_world_estimator, dtype=float)
    out: dict[str, np.ndarray] = {
        "true_segments": true_profile(episode, o, u),
        "foot_sz": _sz(track[:, 1:4], o, u),
        "pipelines": np.array(sorted(estimates), dtype=str),
    }
    for name, est in sorted(estimates.items()):
        if not isinstance(est, StaircaseEstimate):
            continue
        used = [a for a in est.assignments if a.surface_index != -2 and np.all(np.isfinite(a.point))]
        pts_w = transform_points(T, np.array([a.point for a in used]).reshape(-1, 3))
        pts_sz = _sz(pts_w, o, u)
        labels = np.array([a.surface_index for a in used], dtype=int)
        segs, idx = estimated_profile(episode, est, o, u, pts_sz, labels)
        rel = np.full(2, np.nan)
        s2 = est.plane(2)
        if s2 is not None and s2.reliable_stamp_s is not None and len(track):
            t = float(s2.reliable_stamp_s)
            rel = _sz(np.array([np.interp(t, track[:, 0], track[:, k]) for k in (1, 2, 3)]), o, u)[0]
        out[f"{name}__points_sz"] = pts_sz
        out[f"{name}__labels"] = labels
        out[f"{name}__plane_segments"] = segs
        out[f"{name}__plane_index"] = idx
        out[f"{name}__s2_reliable_sz"] = rel
    return out


def plot_side_view(data: dict[str, np.ndarray], path: str | os.PathLike, title: str = "") -> Path:
    """Draw the arrays of :func:`side_view_data` into ``path``."""
    plt = pyplot()
    names = [str(n) for n in np.atleast_1d(data["pipelines"])]
    fig, axes = plt.subplots(1, max(1, len(names)), figsize=(4.2 * max(1, len(names)), 3.6), squeeze=False, sharey=True)
    for ax, name in zip(axes[0], names or [""], strict=True):
        for seg in data["true_segments"]:
            ax.plot(seg[:, 0], seg[:, 1], color="#7fc8f8", lw=2.5, zorder=1)
        foot = data["foot_sz"]
        if len(foot):
            ax.plot(foot[:, 0], foot[:, 1], "k:", lw=1.2, zorder=2)
        pts = data.get(f"{name}__points_sz", np.zeros((0, 2)))
        lab = data.get(f"{name}__labels", np.zeros(0, dtype=int))
        if len(pts):
            colors = np.where(lab < 0, "red", np.where(lab % 2 == 0, "tab:blue", "tab:green"))
            ax.scatter(pts[:, 0], pts[:, 1], s=5, c=colors, zorder=3)
        for seg in data.get(f"{name}__plane_segments", np.zeros((0, 2, 2))):
            ax.plot(seg[:, 0], seg[:, 1], color="magenta", ls="--", lw=1.5, zorder=4)
        rel = data.get(f"{name}__s2_reliable_sz", np.full(2, np.nan))
        if np.all(np.isfinite(rel)):
            ax.plot(rel[0], rel[1], "r*", ms=12, zorder=5)
        ax.set_title(name)
        ax.set_xlabel("along the stairs s (m)")
        ax.set_aspect("equal", adjustable="datalim")
        ax.grid(alpha=0.3)
    axes[0][0].set_ylabel("height z (m)")
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


DISTRIBUTIONS = (
    ("riser_error_pct", "riser error (%)", 1.0, False),
    ("tread_error_pct", "tread error (%)", 1.0, False),
    ("touchdown_error_m", "|e| touch-down (mm)", 1000.0, True),
    ("alpha_deg_S2", "alpha S2 (deg)", 1.0, False),
)


def plot_distributions(records: list[dict[str, Any]], pipelines: list[str], path: str | os.PathLike) -> Path:
    """Box plots (with the points) of the main errors per pipeline, over every episode."""
    plt = pyplot()
    fig, axes = plt.subplots(1, len(DISTRIBUTIONS), figsize=(3.6 * len(DISTRIBUTIONS), 3.4))
    for ax, (key, label, scale, absolute) in zip(axes, DISTRIBUTIONS, strict=True):
        data = []
        for p in pipelines:
            vals = [r["metrics"].get(key) for r in records if r["pipeline"] == p]
            arr = np.array([v for v in vals if v is not None], dtype=float) * scale
            data.append(np.abs(arr) if absolute else arr)
        ax.boxplot([d if len(d) else [np.nan] for d in data], showfliers=False)
        ax.set_xticks(range(1, len(pipelines) + 1), pipelines, rotation=20)
        for i, d in enumerate(data, start=1):
            ax.scatter(np.full(len(d), i) + np.linspace(-0.12, 0.12, len(d)), d, s=6, alpha=0.6)
        ax.set_title(label)
        ax.grid(alpha=0.3)
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def report_sections(records: list[dict[str, Any]], pipelines: list[str], out: Path) -> list[str]:
    """Error distributions and the side views of the figure cases (as Fig. 4 of the paper)."""
    plot_distributions(records, pipelines, out / "errors.png")
    lines = ["## Error distributions", "", "![error distributions](errors.png)", ""]
    figures = sorted((out / "figures").glob("*.npz")) if (out / "figures").exists() else []
    if figures:
        lines += ["## Side views (as Fig. 4 of the paper)", ""]
        for f in figures:
            key = f.stem.replace("__", "/")
            with np.load(f) as data:
                png = plot_side_view(dict(data), f.with_suffix(".png"), title=key)
            lines += [f"### {key}", "", f"![{key}](figures/{png.name})", ""]
    return lines
