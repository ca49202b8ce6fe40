"""The lidar-filter track's report section: the filters through KISS-ICP in Table 5.4's layout
(the trajectories' top views and files come from :func:`..lidar_trajectory.trajectory_sections`)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from .paper import TABLE_5_4, TABLE_KEYS


def _finite(values: list[Any]) -> np.ndarray:
    """The finite numbers among stored metric values (None, the stored NaN, and non-numbers dropped)."""
    v = np.array([x for x in values if isinstance(x, (int, float)) and not isinstance(x, bool)], dtype=float)
    return v[np.isfinite(v)]


def _rmse(values: list[Any]) -> float:
    v = _finite(values)
    return float(np.sqrt(np.mean(v**2))) if v.size else math.nan


def _mean(values: list[Any]) -> float:
    v = _finite(values)
    return float(np.mean(v)) if v.size else math.nan


def _median(values: list[Any]) -> float:
    v = _finite(values)
    return float(np.median(v)) if v.size else math.nan


def _downsampling(records: list[dict[str, Any]]) -> str:
    """Which KISS-ICP downsampling the records' odometry used (the scenario's ``odometry_downsample``)."""
    modes = sorted({str(r.get("scenario", {}).get("odometry_downsample", "")) for r in records})
    text = {"single": "one downsampling removed, as the thesis ran it", "double": "both downsamplings (kiss-icp as released)",
            "": "both downsamplings if the run predates the parameter"}  # fmt: skip
    return "KISS-ICP registered with " + " / ".join(text.get(m, m) for m in modes) + " (`odometry_downsample`)."


def filter_table(records: list[dict[str, Any]], pipelines: list[str]) -> list[str]:
    """Table 5.4 layout: per filter the RMSE over episodes of KISS-ICP's loop TE, OE, TVE (x y z),
    with the thesis' KISS-ICP row beside it, then the direct point scores (means)."""
    lines = ["## Filters through KISS-ICP odometry (Table 5.4 layout)", "",
             "RMSE over the episodes that returned to their start (the thesis: over its runs). Paper: KISS-ICP on a "
             "Unitree B1 with a VLP-16 (only the naive ground-aware filter was run there). "
             + _downsampling(records), "",
             "| filter | TE (m) | OE (rad) | TVE x y z (m) | spurious removed (%) | ground kept (%) | time/scan (ms) "
             "| paper TE / OE / TVE |", "|---|---|---|---|---|---|---|---|"]  # fmt: skip

    def f(x: float, d: int) -> str:
        return "–" if x is None or (isinstance(x, float) and math.isnan(x)) else f"{x:.{d}f}"

    for p in pipelines:
        rs = [r["metrics"] for r in records if r["pipeline"] == p and not r["metrics"].get("failed")]
        te, oe, tx, ty, tz = (_rmse([m.get(k) for m in rs]) for k in TABLE_KEYS)
        sp = _mean([m.get("spurious_removed_frac") for m in rs]) * 100
        gk = _mean([m.get("ground_kept_frac") for m in rs]) * 100
        tm = _median([m.get("time_per_scan_ms") for m in rs])
        ref = TABLE_5_4.get(p)
        paper = f"{ref[0]:g} / {ref[1]:g} / {ref[2]:g} {ref[3]:g} {ref[4]:g}" if ref else "–"
        lines.append(f"| {p} | {f(te, 3)} | {f(oe, 4)} | {f(tx, 3)} {f(ty, 3)} {f(tz, 3)} | {f(sp, 1)} | {f(gk, 1)} | "
                     f"{f(tm, 2)} | {paper} |")  # fmt: skip
    return lines + [""]
