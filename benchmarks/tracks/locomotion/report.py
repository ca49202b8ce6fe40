"""Report sections of the locomotion track: Table III and Table II beside ours, confusion
matrices, anticipation, and the mode timelines of the figure cases.

Everything is computed from the run's records (``metrics`` of :mod:`.metrics`) and the
figure arrays the runner saved (:func:`timeline_data`), so a report can be rewritten from any
finished or partial run folder. Accuracies are pooled as in the paper: mean ± std over episodes.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from exobench.core.episode import Episode
from exobench.core.estimates import LOCOMOTION_MODES, LocomotionEstimate

from ...plots import pyplot
from .metrics import MODE_INDEX, TRANSITION_TYPES, sorted_predictions
from .paper import (
    HEIGHT_GROUPS,
    MOUNTS,
    PATTERNS,
    TERRAIN_GROUPS,
    table_ii_value,
    table_iii_text,
)

DASH = "–"


def _values(records: Sequence[dict[str, Any]], key: str) -> np.ndarray:
    vals = [r["metrics"].get(key) for r in records]
    return np.array([v for v in vals if isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)], dtype=float)


def pct_cell(records: Sequence[dict[str, Any]], key: str = "accuracy") -> str:
    """``mean ± std`` in % over the records (one value: just it), or a dash."""
    v = _values(records, key) * 100.0
    if v.size == 0:
        return DASH
    return f"{v[0]:.2f}" if v.size == 1 else f"{v.mean():.2f} ± {v.std(ddof=1):.2f}"


def generality_records(records: Sequence[dict[str, Any]]) -> list[dict[str, Any]]:
    """Records of the generality grid: a terrain group, head or chest mount, normal conditions."""
    return [r for r in records if r.get("group") in TERRAIN_GROUPS and r["scenario"].get("mount") in MOUNTS]


def _height_group(h: float) -> str:
    return min(HEIGHT_GROUPS, key=lambda g: abs(g[1] - float(h)))[0]


def table_iii_lines(records: Sequence[dict[str, Any]], pipelines: Sequence[str]) -> list[str]:
    """Accuracy per terrain, terrain kind, pattern and mount, beside Table III."""
    gen = generality_records(records)
    if not gen:
        return []
    rows: list[tuple[str, str, Callable[[dict[str, Any]], bool]]] = []
    for label in TERRAIN_GROUPS:
        rows.append((label, label, lambda r, g=label: r["group"] == g))
    for kind in ("stairs", "ramp"):
        rows.append((f"all {kind}", kind, lambda r, k=kind: r["scenario"].get("terrain") == k))
    for p in PATTERNS:
        rows.append((p, p, lambda r, p=p: r["scenario"].get("pattern") == p))
    for m in MOUNTS:
        rows.append((m, m, lambda r, m=m: r["scenario"].get("mount") == m))
    rows.append(("all conditions", "all", lambda r: True))
    lines = [
        "## Accuracy per condition (Table III layout)",
        "",
        "Mean ± std over the episodes of the generality grid, %; the paper's figure beside ours.",
        "",
        "| condition | episodes | " + " | ".join(pipelines) + " | paper |",
        "|---|---|" + "---|" * len(pipelines) + "---|",
    ]
    for name, group, pick in rows:
        mine = [r for r in gen if pick(r)]
        if not mine:
            continue
        cells = [pct_cell([r for r in mine if r["pipeline"] == p]) for p in pipelines]
        n = len({r["episode"] for r in mine})
        lines.append(f"| {name} | {n} | " + " | ".join(cells) + f" | {table_iii_text(group)} |")
    return [*lines, ""]


def table_ii_lines(records: Sequence[dict[str, Any]], pipeline: str, *, min_cells: int = 13) -> list[str]:
    """The 180 combinations as Table II: ``ours / paper`` (%) per cell, ours the mean over seeds."""
    gen = [r for r in generality_records(records) if r["pipeline"] == pipeline]
    cells: dict[tuple[str, str, str, str], list[dict[str, Any]]] = {}
    for r in gen:
        s = r["scenario"]
        key = (_height_group(s["user_height_m"]), s["pattern"], r["group"], s["mount"])
        cells.setdefault(key, []).append(r)
    if len(cells) < min_cells:
        return []
    head = " | ".join(f"{t} {m}" for t in TERRAIN_GROUPS for m in MOUNTS)
    lines = [
        f"## Every condition combination (Table II layout), {pipeline}",
        "",
        "Accuracy %, ours (mean over seeds) / paper (mean of 3 trials of 3 subjects).",
        "",
        f"| group | pattern | {head} |",
        "|---|---|" + "---|" * (len(TERRAIN_GROUPS) * len(MOUNTS)),
    ]
    for g, _ in HEIGHT_GROUPS:
        for p in PATTERNS:
            row = []
            for t in TERRAIN_GROUPS:
                for m in MOUNTS:
                    v = _values(cells.get((g, p, t, m), []), "accuracy")
                    ours = f"{v.mean() * 100:.1f}" if v.size else DASH
                    row.append(f"{ours} / {table_ii_value(g, p, t, m):.1f}")
            lines.append(f"| {g} | {p} | " + " | ".join(row) + " |")
    return [*lines, ""]


def pooled_confusion(records: Sequence[dict[str, Any]], pipeline: str) -> np.ndarray:
    """Sum of the 5x5 confusion matrices of a pipeline's records."""
    cm = np.zeros((len(LOCOMOTION_MODES), len(LOCOMOTION_MODES)), dtype=int)
    for r in records:
        c = r["metrics"].get("confusion") if r["pipeline"] == pipeline else None
        if c is not None and np.shape(c) == cm.shape:
            cm += np.asarray(c, dtype=int)
    return cm


def plot_confusion(records: Sequence[dict[str, Any]], pipelines: Sequence[str], path: Path) -> Path:
    """Row-normalised confusion matrices (%, counts in brackets), one panel per pipeline (as Fig. 4(a))."""
    plt = pyplot()
    n = max(1, len(pipelines))
    fig, axes = plt.subplots(1, n, figsize=(4.4 * n, 4.0), squeeze=False)
    for ax, p in zip(axes[0], pipelines, strict=False):
        cm = pooled_confusion(records, p)
        rows = cm.sum(axis=1, keepdims=True)
        pct = np.divide(cm * 100.0, rows, out=np.zeros(cm.shape), where=rows > 0)
        ax.imshow(pct, cmap="Blues", vmin=0, vmax=100)
        for i in range(cm.shape[0]):
            for j in range(cm.shape[1]):
                if rows[i, 0] == 0:
                    continue
                color = "white" if pct[i, j] > 60 else "black"
                ax.text(j, i, f"{pct[i, j]:.1f}\n({cm[i, j]})", ha="center", va="center", fontsize=7, color=color)
        ax.set_xticks(range(len(LOCOMOTION_MODES)), LOCOMOTION_MODES)
        ax.set_yticks(range(len(LOCOMOTION_MODES)), LOCOMOTION_MODES)
        ax.set_xlabel("decided mode")
        ax.set_ylabel("true mode")
        ax.set_title(p)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def anticipations(records: Sequence[dict[str, Any]], pipeline: str) -> dict[str, list[float]]:
    """Anticipation (s) of every correctly decided transition, by transition type ``A->B``."""
    out: dict[str, list[float]] = {f"{a}->{b}": [] for a, b in TRANSITION_TYPES}
    for r in records:
        if r["pipeline"] != pipeline:
            continue
        for t in r["metrics"].get("transitions") or []:
            v = t.get("anticipation_s")
            if isinstance(v, (int, float)) and math.isfinite(v):
                out.setdefault(f"{t['from']}->{t['to']}", []).append(float(v))
    return {k: v for k, v in out.items() if v}


def plot_anticipation(records: Sequence[dict[str, Any]], pipelines: Sequence[str], path: Path) -> Path:
    """Box plots (with the points) of the anticipation per transition type, one panel per pipeline."""
    plt = pyplot()
    n = max(1, len(pipelines))
    fig, axes = plt.subplots(1, n, figsize=(4.6 * n, 3.4), squeeze=False, sharey=True)
    for ax, p in zip(axes[0], pipelines, strict=False):
        data = anticipations(records, p)
        names = list(data)
        if names:
            ax.boxplot([data[k] for k in names], showfliers=False)
            for i, k in enumerate(names, start=1):
                d = data[k]
                ax.scatter(np.full(len(d), i) + np.linspace(-0.12, 0.12, len(d)), d, s=6, alpha=0.6)
            ax.set_xticks(range(1, len(names) + 1), names, rotation=30)
        ax.set_title(p)
        ax.grid(alpha=0.3)
    axes[0][0].set_ylabel("anticipation before liftoff (s)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def anticipation_lines(records: Sequence[dict[str, Any]], pipelines: Sequence[str]) -> list[str]:
    lines = ["| transition | " + " | ".join(pipelines) + " |", "|---|" + "---|" * len(pipelines)]
    data = {p: anticipations(records, p) for p in pipelines}
    keys = [f"{a}->{b}" for a, b in TRANSITION_TYPES]
    keys += sorted({k for d in data.values() for k in d} - set(keys))
    for k in keys:
        cells = []
        for p in pipelines:
            v = np.array(data[p].get(k, []))
            cells.append(DASH if v.size == 0 else f"{v.mean():.3f} ± {v.std():.3f} (n={v.size}, min {v.min():.3f})")
        if any(c != DASH for c in cells):
            lines.append(f"| {k} | " + " | ".join(cells) + " |")
    return lines


def timeline_data(episode: Episode, estimates: dict[str, Any]) -> dict[str, np.ndarray]:
    """Arrays of the mode timeline of one episode: the true steps and each pipeline's predictions."""
    steps = sorted(episode.truth.steps, key=lambda s: s.index)
    out: dict[str, np.ndarray] = {
        "step_liftoff_s": np.array([s.liftoff_s for s in steps], dtype=float),
        "step_strike_s": np.array([s.heel_strike_s for s in steps], dtype=float),
        "step_mode": np.array([MODE_INDEX.get(s.mode, -1) for s in steps], dtype=int),
        "pipelines": np.array(sorted(estimates), dtype=str),
    }
    for name, est in sorted(estimates.items()):
        if not isinstance(est, LocomotionEstimate):
            continue
        preds = sorted_predictions(est.predictions)
        out[f"{name}__stamp_s"] = np.array([p.stamp_s for p in preds], dtype=float)
        out[f"{name}__mode"] = np.array([MODE_INDEX.get(p.mode, -1) for p in preds], dtype=int)
        out[f"{name}__ok"] = np.array([p.status == "ok" for p in preds], dtype=bool)
    return out


def plot_timeline(data: dict[str, np.ndarray], path: Path, title: str = "") -> Path:
    """True mode of each step (from its liftoff) and the predicted mode over time, per pipeline."""
    plt = pyplot()
    names = [str(n) for n in np.atleast_1d(data["pipelines"])]
    fig, axes = plt.subplots(max(1, len(names)), 1, figsize=(9, 1.9 * max(1, len(names)) + 0.6), squeeze=False, sharex=True)
    lift, strike, mode = data["step_liftoff_s"], data["step_strike_s"], data["step_mode"]
    for ax, name in zip(axes[:, 0], names or [""], strict=False):
        if len(lift):
            t_end = float(strike[-1]) if len(strike) else float(lift[-1])
            ax.step(np.append(lift, t_end), np.append(mode, mode[-1]), where="post", color="#7fc8f8", lw=3, label="true (from liftoff)")
            ax.vlines(lift, -0.5, len(LOCOMOTION_MODES) - 0.5, colors="0.85", lw=0.6)
        t = data.get(f"{name}__stamp_s", np.zeros(0))
        m = data.get(f"{name}__mode", np.zeros(0, dtype=int))
        ok = data.get(f"{name}__ok", np.ones(len(t), dtype=bool))
        if len(t):
            ax.scatter(t[ok], m[ok], s=4, color="k", label="predicted", zorder=3)
            ax.scatter(t[~ok], m[~ok], s=6, color="red", label="predicted (fault status)", zorder=3)
        ax.set_yticks(range(-1, len(LOCOMOTION_MODES)), ["none", *LOCOMOTION_MODES])
        ax.set_ylim(-1.5, len(LOCOMOTION_MODES) - 0.5)
        ax.set_title(name, fontsize=9)
        ax.grid(alpha=0.3, axis="y")
    axes[0][0].legend(fontsize=7, loc="upper right")
    axes[-1][0].set_xlabel("time (s)")
    if title:
        fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def report_sections(records: list[dict[str, Any]], pipelines: list[str], out: Path) -> list[str]:
    """Markdown lines after the summary; PNG figures written into ``out``."""
    lines = table_iii_lines(records, pipelines)
    for p in pipelines:
        lines += table_ii_lines(records, p)
    plot_confusion(records, pipelines, out / "confusion.png")
    lines += ["## Confusion matrices (as Fig. 4(a))", "",
              "Rows: true mode of each step; columns: the mode in effect at its liftoff; % of the row (count). "
              "All episodes of the run.", "", "![confusion matrices](confusion.png)", ""]  # fmt: skip
    lines += ["| pipeline | " + " | ".join(LOCOMOTION_MODES) + " | all |", "|---|" + "---|" * (len(LOCOMOTION_MODES) + 1)]
    for p in pipelines:
        cm = pooled_confusion(records, p)
        tot = cm.sum(axis=1)
        cells = [f"{cm[i, i] / tot[i] * 100:.2f} ({tot[i]})" if tot[i] else DASH for i in range(len(LOCOMOTION_MODES))]
        lines.append(f"| {p} | " + " | ".join(cells) + f" | {pct_cell([r for r in records if r['pipeline'] == p])} |")
    lines += ["", "Per-mode cells: correct / steps of the mode, pooled over the run (count); all: mean ± std of the episodes' accuracy.", ""]
    plot_anticipation(records, pipelines, out / "anticipation.png")
    lines += ["## Anticipation of transition steps", "",
              "Time from the first prediction after which the output stayed the step's true mode until its "
              "liftoff, to the liftoff (s), per correctly decided transition; mean ± std (n, shortest).", "",
              *anticipation_lines(records, pipelines), "", "![anticipation](anticipation.png)", ""]  # fmt: skip
    figures = sorted((out / "figures").glob("*.npz")) if (out / "figures").exists() else []
    if figures:
        lines += ["## Mode timelines", ""]
        for f in figures:
            key = f.stem.replace("__", "/")
            with np.load(f) as data:
                png = plot_timeline(dict(data), f.with_suffix(".png"), title=key)
            lines += [f"### {key}", "", f"![{key}](figures/{png.name})", ""]
    return lines
