"""Summaries of a run: mean ± std per group and pipeline, beside the published figures.

:func:`summary_rows` computes the table from records; :func:`format_text` renders it for the
terminal, :func:`format_markdown` for ``report.md``; :func:`write_report` writes ``report.md``
with its PNG figures into the run folder (it can be rerun on any finished or partial run).
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from exobench.core.errors import FolderError

from .out_paths import LOCK_FILE
from .results import RESULTS_FILE, RUN_CONFIG_FILE, read_records, read_run_config, sort_records
from .tracks.spec import Reference, SummaryRow

REPORT_FILE = "report.md"
TMP_FILE = f".{REPORT_FILE}.tmp"
KEEP = {RESULTS_FILE, RUN_CONFIG_FILE, LOCK_FILE}  # never removed by a failed report
DASH = "–"


def _fmt(x: float, digits: int) -> str:
    return f"{x:.{digits}f}"


def cell(values: Sequence[Any], row: SummaryRow) -> str:
    """``mean ± std`` of the non-missing values in the row's unit, or a dash."""
    arr = np.array([v for v in values if v is not None and not (isinstance(v, float) and math.isnan(v))], dtype=float)
    if arr.size == 0:
        return DASH
    arr = arr * row.scale
    if row.absolute:
        arr = np.abs(arr)
    if arr.size == 1:
        return _fmt(arr[0], row.digits)
    return f"{_fmt(arr.mean(), row.digits)} ± {_fmt(arr.std(ddof=1), row.digits)}"


def reference_text(
    refs: Sequence[Reference], metric: str, group: str, pipelines: Sequence[str], *, absolute: bool = False
) -> str:
    """The published figures for a metric and group, each with its source (and pipeline).

    With ``absolute`` a signed figure is shown as its magnitude (for rows such as |e|).
    """
    texts = []
    for r in refs:
        if r.metric != metric or (r.groups and group not in r.groups):
            continue
        if r.pipelines and not set(r.pipelines) & set(pipelines):
            continue
        who = f", {'/'.join(r.pipelines)}" if r.pipelines else ""
        text = r.text.lstrip("-") if absolute and r.bound is None else r.text
        texts.append(f"{text} ({r.source}{who})")
    return "; ".join(texts)


def group_order(records: Sequence[dict[str, Any]], episode_order: Sequence[str] = ()) -> list[str]:
    """Groups in the order their first episode appears in the run."""
    index = {k: i for i, k in enumerate(episode_order)}
    ordered = sorted(records, key=lambda r: (index.get(r["episode"], len(index)), r["episode"]))
    seen: list[str] = []
    for r in ordered:
        if r["group"] not in seen:
            seen.append(r["group"])
    return seen


def summary_rows(
    records: Sequence[dict[str, Any]],
    track: Any,
    pipelines: Sequence[str],
    *,
    terminal: bool = True,
    episode_order: Sequence[str] = (),
) -> list[list[str]]:
    """Table rows ``[group, metric, <one cell per pipeline>, paper]``, header first."""
    refs = track.references()
    rows = [["group", "metric", *pipelines, "paper"]]
    for group in group_order(records, episode_order):
        mine = [r for r in records if r["group"] == group]
        by_pipe = {p: [r for r in mine if r["pipeline"] == p] for p in pipelines}
        failed = [f"{sum(bool(r['metrics'].get('failed')) for r in rs)}/{len(rs)}" for rs in by_pipe.values()]
        rows.append([group, "failed / episodes", *failed, ""])
        for row in track.summary_rows():
            if terminal and not row.terminal:
                continue
            cells = [cell([r["metrics"].get(row.metric) for r in by_pipe[p]], row) for p in pipelines]
            if all(c == DASH for c in cells):
                continue
            rows.append(["", row.label, *cells, reference_text(refs, row.metric, group, pipelines, absolute=row.absolute)])
    return rows


def format_text(rows: list[list[str]]) -> str:
    """Aligned plain-text table."""
    widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
    lines = []
    for k, r in enumerate(rows):
        lines.append("  ".join(c.ljust(w) for c, w in zip(r, widths, strict=True)).rstrip())
        if k == 0:
            lines.append("  ".join("-" * w for w in widths))
    return "\n".join(lines)


def format_markdown(rows: list[list[str]]) -> str:
    """GitHub-flavoured markdown table."""
    esc = [[c.replace("|", "\\|") for c in r] for r in rows]
    out = ["| " + " | ".join(esc[0]) + " |", "|" + "---|" * len(esc[0])]
    out += ["| " + " | ".join(r) + " |" for r in esc[1:]]
    return "\n".join(out)


def summary_text(records: Sequence[dict[str, Any]], track: Any, pipelines: Sequence[str], episode_order: Sequence[str] = ()) -> str:
    """The table `exobench run` prints at the end."""
    if not records:
        return "no finished episodes"
    return format_text(summary_rows(records, track, pipelines, terminal=True, episode_order=episode_order))


def _failures(records: Sequence[dict[str, Any]], limit: int = 30) -> list[str]:
    lines = []
    for r in records:
        if r["metrics"].get("failed"):
            lines.append(f"- `{r['episode']}` {r['pipeline']}: {r['metrics'].get('failed_reason') or 'failed'}")
    return lines[:limit] + ([f"- ... {len(lines) - limit} more"] if len(lines) > limit else [])


def track_sections(track: Any, records: Sequence[dict[str, Any]], pipelines: Sequence[str], out: Path) -> list[str]:
    """The track's own report sections (markdown lines, figures written into ``out``)."""
    return list(track.report_sections(list(records), list(pipelines), out))


def _files(out: Path) -> dict[Path, tuple[int, int]]:
    return {p: (st.st_mtime_ns, st.st_size) for p in out.rglob("*") if p.is_file() and (st := p.stat())}


def write_report(out_dir: str | os.PathLike) -> Path:
    """Write ``report.md`` and its figures (PNG) into a run folder; returns the report's path.

    A write that fails (disk full, read-only folder) raises FolderError and, as Ctrl-C does,
    leaves no part of the report behind: the files this call created or changed are removed (the run's records,
    configuration and figure data are never among them)."""
    out = Path(out_dir)
    before = _files(out)
    try:
        return _write_report(out)
    except BaseException as e:  # disk full, or Ctrl-C while the figures are drawn
        for p, stamp in _files(out).items():
            if before.get(p) != stamp and p.name not in KEEP and p.suffix != ".npz":
                p.unlink(missing_ok=True)
        if not isinstance(e, OSError):
            raise
        name = e.filename2 or e.filename or out / REPORT_FILE
        name = out / REPORT_FILE if Path(name).name == TMP_FILE else name
        raise FolderError(f"{name}: cannot be written ({e.strerror or e}); the report was not written") from None


def _write_report(out: Path) -> Path:
    from .tracks import get_track

    config = read_run_config(out)
    track = get_track(config["track"])
    pipelines = [p["name"] for p in config["pipelines"]]
    records = sort_records(read_records(out / RESULTS_FILE), pipelines)
    order = config.get("episodes", [])
    lines = [
        f"# exobench run: {config['track']} / {config['suite']}",
        "",
        f"{len({r['episode'] for r in records})} of {len(order)} episodes finished; "
        f"seeds {config['seeds']}; scenario overrides {config.get('overrides') or 'none'}"
        + (f"; only the cases matching --case {', '.join(config['cases'])}." if config.get("cases") else "."),
        track.report_intro,
        "",
        "## Summary (mean ± std over episodes)",
        "",
        format_markdown(summary_rows(records, track, pipelines, terminal=False, episode_order=order)) if records else "no finished episodes",
        "",
    ]
    loose = [p["name"] for p in config["pipelines"] if p.get("deterministic") is False]
    if loose:
        lines += [f"Not bit-reproducible (a second run of the same episodes may give other figures): "
                  f"{', '.join(loose)}.", ""]
    if records:
        lines += track_sections(track, records, pipelines, out)
    fails = _failures(records)
    if fails:
        lines += ["## Failures", "", *fails, ""]
    lines += ["## Configuration", "", "```json", json.dumps({k: config[k] for k in ("pipelines", "versions") if k in config}, indent=2), "```", ""]
    path = out / REPORT_FILE
    tmp = out / TMP_FILE
    tmp.write_text("\n".join(lines))
    os.replace(tmp, path)
    return path
