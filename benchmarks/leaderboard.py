"""Where pipelines stand: `exobench leaderboard RUN...`, per track, beside the published figures.

An entry is a pipeline with the config it ran under, in one run folder (the same pipeline run
twice with other configs is two entries). Per track and headline metric
(:func:`.tracks.spec.headline_rows`), entries are ranked on the mean over every episode they
finished (failed records, which have no value, are counted apart), best first as the row's
``better`` says; ties share a rank. Each entry's overall place is its mean rank over the
track's headline metrics. The published figures (``track.references()``) that apply to the
metric and pipeline are shown beside it, with their groups: they are per group, ours pooled.

:func:`write_leaderboard` writes ``leaderboard.md`` and one figure per track
(``leaderboard-<track>.png``: a bar per entry and metric, the published values as lines), and
names the runs, versions and configs that produced each entry.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from exobench.core.errors import FolderError

from .compare import RunData, load_runs
from .tracks.spec import Reference, SummaryRow, headline_rows

LEADERBOARD_FILE = "leaderboard.md"


@dataclass
class Entry:
    """A pipeline with one config in one run: its values of each headline metric (shown units)."""

    track: str
    pipeline: str
    run: str
    config: dict[str, Any]
    versions: dict[str, Any]
    values: dict[str, list[float]] = field(default_factory=dict)
    failed: int = 0
    records: int = 0
    label: str = ""

    def mean(self, metric: str) -> float:
        v = self.values.get(metric, [])
        return float(np.mean(v)) if v else math.nan


def collect(runs: Sequence[tuple[str, Mapping[str, RunData]]]) -> dict[str, list[Entry]]:
    """Entries per track from ``(name, load_runs(folder))`` of each run given."""
    from .tracks import get_track

    out: dict[str, list[Entry]] = {}
    for name, by_track in runs:
        for tname, run in by_track.items():
            rows = headline_rows(get_track(tname))
            for p in run.config["pipelines"]:
                mine = [r for r in run.records if r["pipeline"] == p["name"]]
                e = Entry(tname, p["name"], name, p.get("config", {}), run.config.get("versions", {}))
                e.records, e.failed = len(mine), sum(bool(r["metrics"].get("failed")) for r in mine)
                for row in rows:
                    vals = [r["metrics"].get(row.metric) for r in mine]
                    e.values[row.metric] = [row.shown(float(v)) for v in vals if _finite(v)]
                out.setdefault(tname, []).append(e)
    for entries in out.values():  # a pipeline in several runs is told apart by its run
        counts: dict[str, int] = {}
        for e in entries:
            counts[e.pipeline] = counts.get(e.pipeline, 0) + 1
        for e in entries:
            e.label = e.pipeline if counts[e.pipeline] == 1 else f"{e.pipeline} ({e.run})"
    return out


def _finite(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def ranking(entries: Sequence[Entry], row: SummaryRow) -> list[tuple[int, Entry]]:
    """(rank, entry), best first on ``row`` (entries with no value last, unranked: rank 0)."""
    scored = [e for e in entries if math.isfinite(e.mean(row.metric))]
    sign = -1.0 if row.better == "higher" else 1.0
    scored.sort(key=lambda e: (sign * e.mean(row.metric), e.label))
    out: list[tuple[int, Entry]] = []
    for i, e in enumerate(scored):
        tied = out and out[-1][1].mean(row.metric) == e.mean(row.metric)
        out.append((out[-1][0] if tied else i + 1, e))
    return out + [(0, e) for e in entries if e not in scored]


def overall(entries: Sequence[Entry], rows: Sequence[SummaryRow]) -> list[tuple[float, Entry]]:
    """(mean rank over the metrics the entry has a value of, entry), best first."""
    ranks: dict[int, list[int]] = {id(e): [] for e in entries}
    for row in rows:
        for rank, e in ranking(entries, row):
            if rank:
                ranks[id(e)].append(rank)
    scored = [(float(np.mean(ranks[id(e)])) if ranks[id(e)] else math.inf, e) for e in entries]
    return sorted(scored, key=lambda x: (x[0], x[1].label))


def published(refs: Sequence[Reference], metric: str, pipeline: str, row: SummaryRow) -> str:
    """The published figures of ``metric`` that apply to ``pipeline`` (or to all), with their groups."""
    texts = []
    for r in refs:
        if r.metric == metric and (not r.pipelines or pipeline in r.pipelines):
            where = f", {'/'.join(r.groups)}" if r.groups else ""
            text = r.text.lstrip("-") if row.absolute and r.bound is None else r.text
            texts.append(f"{text} ({r.source}{where})")
    return "; ".join(texts)


def _cell(e: Entry, row: SummaryRow) -> str:
    v = e.values.get(row.metric, [])
    if not v:
        return "–"
    d = row.digits
    return f"{np.mean(v):.{d}f}" if len(v) == 1 else f"{np.mean(v):.{d}f} ± {np.std(v, ddof=1):.{d}f} (n={len(v)})"


def track_markdown(track: Any, entries: Sequence[Entry], figure: str | None) -> list[str]:
    """The leaderboard section of one track (markdown lines)."""
    rows = headline_rows(track)
    refs = track.references()
    esc = lambda s: str(s).replace("|", "\\|")  # noqa: E731
    lines = [f"## {track.name}", "", "| place | pipeline | mean rank | failed / records |", "|---|---|---|---|"]
    for place, (mean_rank, e) in enumerate(overall(entries, rows), 1):
        shown = f"{mean_rank:.2f}" if math.isfinite(mean_rank) else "–"
        lines.append(f"| {place} | {esc(e.label)} | {shown} | {e.failed}/{e.records} |")
    for row in rows:
        lines += ["", f"### {esc(row.label)} ({row.better} is better)", "", "| rank | pipeline | ours (mean ± std) | published |", "|---|---|---|---|"]
        for rank, e in ranking(entries, row):
            lines.append(f"| {rank or '–'} | {esc(e.label)} | {_cell(e, row)} | {esc(published(refs, row.metric, e.pipeline, row))} |")
    if figure:
        lines += ["", f"![{track.name}]({figure})"]
    return lines + [""]


def plot_track(track: Any, entries: Sequence[Entry], path: Path) -> None:
    """One panel per headline metric: a bar per entry (best at the top), published values as lines."""
    from .plots import pyplot

    plt = pyplot()
    rows = headline_rows(track)
    fig, axes = plt.subplots(1, len(rows), figsize=(3.6 * len(rows), 0.5 * len(entries) + 1.8), squeeze=False)
    for ax, row in zip(axes[0], rows, strict=True):
        ranked = [e for rank, e in ranking(entries, row) if rank]
        means = [e.mean(row.metric) for e in ranked]
        stds = [float(np.std(e.values[row.metric], ddof=1)) if len(e.values[row.metric]) > 1 else 0.0 for e in ranked]
        y = np.arange(len(ranked))[::-1]
        ax.barh(y, means, xerr=stds, color="tab:blue", alpha=0.7)
        ax.set_yticks(y, [e.label for e in ranked], fontsize=8)
        values = sorted({row.shown(r.value) for r in track.references() if r.metric == row.metric and r.value is not None})
        for i, v in enumerate(values):
            ax.axvline(v, color="tab:red", ls="--", lw=1, label="published" if i == 0 else None)
        if values:
            ax.legend(fontsize=7, loc="lower right")
        ax.set_title(f"{row.label}\n({row.better} is better)", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def write_leaderboard(runs: Sequence[str], out_dir: str | os.PathLike) -> Path:
    """Write ``leaderboard.md`` and its figures into ``out_dir`` (created); returns its path.
    A write that fails raises FolderError naming the file."""
    from .tracks import get_track

    out = Path(out_dir)
    loaded = [(str(folder), load_runs(folder)) for folder in runs]
    by_track = collect(loaded)
    lines = ["# exobench leaderboard", "", f"Runs: {', '.join(f'`{name}`' for name, _ in loaded)}. Ours: mean ± std over "
             "every finished episode (all groups); published figures are per group, as their source states them.", ""]  # fmt: skip
    try:
        out.mkdir(parents=True, exist_ok=True)
        for tname, entries in by_track.items():
            figure = f"leaderboard-{tname}.png"
            plot_track(get_track(tname), entries, out / figure)
            lines += track_markdown(get_track(tname), entries, figure)
        lines += ["## Runs, versions and configs", ""]
        for tname, entries in by_track.items():
            for e in entries:
                lines += [f"- {tname} / {e.label}: run `{e.run}`, versions {json.dumps(e.versions)}, config `{json.dumps(e.config)}`"]
        path = out / LEADERBOARD_FILE
        tmp = out / f".{LEADERBOARD_FILE}.tmp"
        tmp.write_text("\n".join(lines) + "\n")
        os.replace(tmp, path)
    except OSError as e:
        raise FolderError(f"{e.filename or out}: cannot be written ({e.strerror or e})") from None
    return path
