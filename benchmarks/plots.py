"""Figures of the report, saved as PNG (matplotlib with the Agg backend, imported on use).

- :func:`plot_side_view`: one panel per pipeline, like Fig. 4 of the staircase paper: points
  coloured by the surface they were assigned to (treads blue, risers green, discarded red),
  the true profile (light blue, solid), the estimated planes (magenta, dashed), the foot path
  (black, dotted) and a red asterisk where S2 became reliable.
- :func:`plot_distributions`: per pipeline, the spread of riser and tread error, touch-down
  error and alpha of S2 over all episodes.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np


def _pyplot() -> Any:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def plot_side_view(data: dict[str, np.ndarray], path: str | os.PathLike, title: str = "") -> Path:
    """Draw the arrays of ``stairs_figure.side_view_data`` into ``path``."""
    plt = _pyplot()
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
    plt = _pyplot()
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
