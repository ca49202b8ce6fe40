"""The lidar-filter track's report section: the filters through KISS-ICP in Table 5.4's layout
(the trajectories' top views and files come from :func:`..lidar_trajectory.trajectory_sections`)."""

from __future__ import annotations

import math
from collections.abc import Sequence
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


OFF_M = 0.1
"""A loop "ends off" when its TE exceeds this (m): glazed loops end either within a few cm or
decimetres off (docs/tracks/lidar-filter.md), so RMSEs over a few runs mostly count the latter."""


def _filter_rows(records: list[dict[str, Any]], pipelines: list[str]) -> list[str]:
    def f(x: float, d: int) -> str:
        return "–" if x is None or (isinstance(x, float) and math.isnan(x)) else f"{x:.{d}f}"

    lines = [f"| filter | loops | ends > {OFF_M:g} m off | TE (m) | OE (rad) | TVE x y z (m) | spurious removed (%) | ground kept (%) | time/scan (ms) "
             "| paper TE / OE / TVE |", "|---|---|---|---|---|---|---|---|---|---|"]  # fmt: skip
    for p in pipelines:
        rs = [r["metrics"] for r in records if r["pipeline"] == p and not r["metrics"].get("failed")]
        te, oe, tx, ty, tz = (_rmse([m.get(k) for m in rs]) for k in TABLE_KEYS)
        loop_te = _finite([m.get("odom_te_m") for m in rs])
        n_loops, n_off = int(loop_te.size), int(np.sum(loop_te > OFF_M))
        sp = _mean([m.get("spurious_removed_frac") for m in rs]) * 100
        gk = _mean([m.get("ground_kept_frac") for m in rs]) * 100
        tm = _median([m.get("time_per_scan_ms") for m in rs])
        ref = TABLE_5_4.get(p)
        paper = f"{ref[0]:g} / {ref[1]:g} / {ref[2]:g} {ref[3]:g} {ref[4]:g}" if ref else "–"
        lines.append(f"| {p} | {n_loops} | {n_off if n_loops else '–'} | {f(te, 3)} | {f(oe, 4)} | {f(tx, 3)} {f(ty, 3)} {f(tz, 3)} | {f(sp, 1)} | {f(gk, 1)} | "
                     f"{f(tm, 2)} | {paper} |")  # fmt: skip
    return lines


GROUND_AWARE = {"filter-naive-ground": "naive ground-aware", "filter-floor-ground": "floor-plane ground-aware",
                "filter-normal-ground": "normal ground-aware"}  # fmt: skip


def table_5_4_ordering(records: list[dict[str, Any]], ground: str = "filter-naive-ground") -> dict[str, float]:
    """Table 5.4's two comparisons over the records' loops (RMSE over episodes) for the ground-aware
    filter ``ground`` (the thesis ran the naive one): ``te_ratio``, the unfiltered TE over the
    ground-aware filter's (thesis 22.529 / 1.112 = 20x), and the TVE z of the intensity-only filter
    (``z_threshold``) and of the ground-aware one (``z_ground``; thesis 2.297 and 0.187);
    ``te_median_ratio``, the same ratio of medians, which one outlying episode does not sway (loop
    errors can be bimodal, docs/tracks/lidar-filter.md). NaN where a filter has no loop."""

    def values(pipe: str, key: str) -> list[Any]:
        return [r["metrics"].get(key) for r in records if r["pipeline"] == pipe and not r["metrics"].get("failed")]

    def ratio(a: float, b: float) -> float:
        return a / b if b > 0 else math.nan

    te_none, te_ground = values("filter-none", "odom_te_m"), values(ground, "odom_te_m")
    return {"te_ratio": ratio(_rmse(te_none), _rmse(te_ground)),
            "te_median_ratio": ratio(_median(te_none), _median(te_ground)),
            "z_threshold": _rmse(values("filter-threshold", "odom_tve_z_m")),
            "z_ground": _rmse(values(ground, "odom_tve_z_m"))}  # fmt: skip


def filter_table(
    records: list[dict[str, Any]], pipelines: list[str], loop_sets: Sequence[tuple[str, Sequence[str]]] = ()
) -> list[str]:
    """Table 5.4 layout: per filter the RMSE over episodes of KISS-ICP's loop TE, OE, TVE (x y z),
    with the thesis' KISS-ICP row beside it, then the direct point scores (means). ``loop_sets``
    (title, case names): one table per set of cases (the thesis' RMSE is over runs of one
    building), with Table 5.4's two comparisons under it; the other cases' records in a last table."""
    lines = ["## Filters through KISS-ICP odometry (Table 5.4 layout)", "",
             "RMSE over the episodes that returned to their start (the thesis: over its runs). Paper: KISS-ICP on a "
             "Unitree B1 with a VLP-16 (only the naive ground-aware filter was run there). "
             + _downsampling(records), ""]  # fmt: skip
    none, thr, naive = (TABLE_5_4[p] for p in ("filter-none", "filter-threshold", "filter-naive-ground"))
    placed: set[str] = set()
    for title, names in loop_sets:
        rs = [r for r in records if r.get("case") in names]
        placed.update(names)
        if not rs:
            continue
        lines += [f"### {title}: {', '.join(f'`{n}`' for n in names)}", ""] + _filter_rows(rs, pipelines) + [""]
        for ground, label in GROUND_AWARE.items():
            o = table_5_4_ordering(rs, ground) if ground in pipelines else {}
            if all(math.isnan(v) for v in o.values()):
                continue
            g = {k: "–" if math.isnan(v) else f"{v:.{1 if 'ratio' in k else 3}f}" for k, v in o.items()}
            lines += [f"Unfiltered TE / {label} TE: {g['te_ratio']}x (thesis, naive: {none[0] / naive[0]:.1f}x; medians "
                      f"{g['te_median_ratio']}x); TVE z, intensity-only {g['z_threshold']} m against {label} "
                      f"{g['z_ground']} m (thesis {thr[4]:.3f} against {naive[4]:.3f}).", ""]  # fmt: skip
    rest = [r for r in records if r.get("case") not in placed]
    if rest:
        heading = ["### Other cases", ""] if len(rest) < len(records) else []  # no heading when no set is in the run
        lines += heading + _filter_rows(rest, pipelines) + [""]
    return lines
