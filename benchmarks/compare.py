"""Did a change make a pipeline better or worse? Two runs of one track and suite, compared.

For every group (and all groups together, ``(all)``), pipeline and headline metric
(:func:`.tracks.spec.headline_rows`: the metrics a track marks, with the way that is better),
:func:`compare_runs` gives the difference B - A of the means, in the unit the summary table
shows (``SummaryRow.shown``: scaled, |x| for an absolute row), with a 95 % confidence interval:

- paired where both runs have the pair: the same episode (same case and seed) and pipeline
  when both runs used the same seeds, else the same case at the same position in each run's
  seed list (a rerun with other seeds: each case against itself). The interval is the paired
  t interval, ``mean(d) ± t(0.975, n-1) sd(d) / sqrt(n)``, over the pairs with both values
  finite (a failed record has none);
- unpaired when no pair exists (a drawn suite whose cases differ per seed): Welch's t interval
  of the difference of the two means.

A t interval, not a bootstrap: runs are often a handful of episodes per group, where a
bootstrap's percentile interval is too narrow (one pair gives a zero-width interval) and the
t interval is honest (no interval with fewer than two pairs: never flagged).

A comparison is **worse** when its interval lies wholly on the worse side of zero, beyond the
threshold: ``threshold`` times |mean A| (so 0.05 asks for a change of more than 5 % of A's
value); **better** the other way round. The interval that decides is Bonferroni-corrected over
the track's comparisons (level ``1 - 0.05 / m`` for ``m`` of them, the shown one stays 95 %):
a track has tens of them (groups x pipelines x metrics), and at 95 % each, two runs of the
same code would flag one by chance; so corrected, the chance that any is flagged when nothing
changed is at most 5 %. Timings and versions are not compared. Runs of different tracks or
suites are refused (:class:`ConfigError`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from exobench.core.errors import ConfigError

from .results import RESULTS_FILE, RUN_ALL_FILE, RUN_CONFIG_FILE, read_records, read_run_all, read_run_config
from .tracks.spec import SummaryRow, headline_rows

ALL_GROUPS = "(all)"
LEVEL = 0.95


@dataclass(frozen=True)
class Comparison:
    """One (track, group, pipeline, metric): means of A and B, B - A with its 95 % interval
    (NaN when there are fewer than two values to judge by), the number of pairs (0: unpaired,
    then ``n_a`` and ``n_b`` values), and the verdict: "worse", "better" or ""."""

    track: str
    group: str
    pipeline: str
    metric: str
    label: str
    better: str
    mean_a: float
    mean_b: float
    diff: float
    low: float
    high: float
    n_pairs: int
    n_a: int
    n_b: int
    verdict: str


@dataclass(frozen=True)
class RunData:
    folder: Path
    config: dict[str, Any]
    records: list[dict[str, Any]]


def load_runs(folder: str | Path) -> dict[str, RunData]:
    """The run folders of ``folder`` by track: itself (a run of one track, ``run_config.json``)
    or each track's folder of a run of every track (``run_all.json``)."""
    path = Path(folder)
    if (path / RUN_CONFIG_FILE).exists():
        config = read_run_config(path)
        return {config["track"]: RunData(path, config, read_records(path / RESULTS_FILE))}
    if (path / RUN_ALL_FILE).exists():
        out = {}
        for name in read_run_all(path)["tracks"]:
            if (path / name / RUN_CONFIG_FILE).exists():
                config = read_run_config(path / name)
                out[name] = RunData(path / name, config, read_records(path / name / RESULTS_FILE))
        return out
    raise ConfigError("RUN", str(folder), f"a run folder with {RUN_CONFIG_FILE} (or {RUN_ALL_FILE} of a run of every track)")


def check_comparable(a: Mapping[str, RunData], b: Mapping[str, RunData], name_a: str, name_b: str) -> None:
    """ConfigError (one line) unless both hold the same tracks, each of the same suite."""
    if set(a) != set(b):
        raise ConfigError("RUN_B", name_b, f"a run of the tracks of {name_a} ({', '.join(sorted(a))}); it has {', '.join(sorted(b)) or 'none'}")
    for track in sorted(a):
        sa, sb = a[track].config["suite"], b[track].config["suite"]
        if sa != sb:
            raise ConfigError("RUN_B", name_b, f"a run of track {track!r} suite {sa!r} as {name_a}; it ran suite {sb!r}")


def t_interval_paired(d: Sequence[float], level: float = LEVEL) -> tuple[float, float, float]:
    """(mean, low, high) of the paired t interval of differences ``d`` (NaN bounds for n < 2)."""
    from scipy import stats

    d = np.asarray(d, dtype=float)
    n = d.size
    if n == 0:
        return math.nan, math.nan, math.nan
    mean = float(d.mean())
    if n < 2:
        return mean, math.nan, math.nan
    half = float(stats.t.ppf(0.5 + level / 2, n - 1) * d.std(ddof=1) / math.sqrt(n))
    return mean, mean - half, mean + half


def t_interval_welch(a: Sequence[float], b: Sequence[float], level: float = LEVEL) -> tuple[float, float, float]:
    """(mean(b) - mean(a), low, high) of Welch's t interval (NaN bounds with fewer than two of either)."""
    from scipy import stats

    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    if a.size == 0 or b.size == 0:
        return math.nan, math.nan, math.nan
    diff = float(b.mean() - a.mean())
    if a.size < 2 or b.size < 2:
        return diff, math.nan, math.nan
    va, vb = a.var(ddof=1) / a.size, b.var(ddof=1) / b.size
    se = math.sqrt(va + vb)
    if se == 0:
        return diff, diff, diff
    dof = (va + vb) ** 2 / (va**2 / (a.size - 1) + vb**2 / (b.size - 1))
    half = float(stats.t.ppf(0.5 + level / 2, dof) * se)
    return diff, diff - half, diff + half


def verdict(better: str, low: float, high: float, mean_a: float, threshold: float) -> str:
    """"worse" / "better" when the whole interval is past ``threshold * |mean_a|`` on that side."""
    if not (math.isfinite(low) and math.isfinite(high)):
        return ""
    margin = threshold * abs(mean_a) if math.isfinite(mean_a) else 0.0
    up, down = low > margin, high < -margin  # B clearly above / below A
    if not (up or down):
        return ""
    return "better" if (up and better == "higher") or (down and better == "lower") else "worse"


def _value(record: Mapping[str, Any], row: SummaryRow) -> float:
    v = record["metrics"].get(row.metric)
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        return math.nan
    return float(row.shown(v))


def _pair_keys(run: RunData, same_seeds: bool) -> dict[tuple[str, str], tuple[Any, ...]]:
    """(episode, pipeline) -> what it is paired on in the other run (see the module doc)."""
    rank = {s: i for i, s in enumerate(run.config["seeds"])}
    out = {}
    for r in run.records:
        key = (r["episode"],) if same_seeds else (r.get("case", r["episode"]), rank.get(r.get("run_seed"), -1))
        out[(r["episode"], r["pipeline"])] = key
    return out


def compare_track(track: Any, a: RunData, b: RunData, threshold: float = 0.05) -> list[Comparison]:
    """Every comparison of one track's two runs (see the module doc), groups in A's order."""
    rows = headline_rows(track)
    if not rows:
        raise ConfigError("track", track.name, "a track that marks its headline metrics (SummaryRow.better)")
    same_seeds = a.config["seeds"] == b.config["seeds"]
    keys_a, keys_b = _pair_keys(a, same_seeds), _pair_keys(b, same_seeds)
    pipes = [p["name"] for p in a.config["pipelines"] if p["name"] in {q["name"] for q in b.config["pipelines"]}]
    groups = list(dict.fromkeys(r["group"] for r in a.records)) + [ALL_GROUPS]
    samples: list[tuple[str, str, SummaryRow, np.ndarray, np.ndarray, np.ndarray | None]] = []
    for group in groups:
        for pipe in pipes:
            sel_a = [r for r in a.records if r["pipeline"] == pipe and (group == ALL_GROUPS or r["group"] == group)]
            sel_b = [r for r in b.records if r["pipeline"] == pipe and (group == ALL_GROUPS or r["group"] == group)]
            by_key_b = {keys_b[(r["episode"], pipe)]: r for r in sel_b}
            pairs = [(r, by_key_b[keys_a[(r["episode"], pipe)]]) for r in sel_a if keys_a[(r["episode"], pipe)] in by_key_b]
            for row in rows:
                va = np.array([_value(r, row) for r in sel_a])
                vb = np.array([_value(r, row) for r in sel_b])
                va, vb = va[np.isfinite(va)], vb[np.isfinite(vb)]
                d = np.array([_value(y, row) - _value(x, row) for x, y in pairs])
                d = d[np.isfinite(d)]
                samples.append((group, pipe, row, va, vb, d if pairs else None))

    def interval(va: np.ndarray, vb: np.ndarray, d: np.ndarray | None, level: float) -> tuple[float, float, float]:
        return t_interval_paired(d, level) if d is not None else t_interval_welch(va, vb, level)

    m = sum(math.isfinite(interval(va, vb, d, LEVEL)[1]) for _, _, _, va, vb, d in samples)
    gate_level = 1 - (1 - LEVEL) / max(m, 1)
    out = []
    for group, pipe, row, va, vb, d in samples:
        diff, low, high = interval(va, vb, d, LEVEL)
        _, gate_low, gate_high = interval(va, vb, d, gate_level)
        mean_a = float(va.mean()) if va.size else math.nan
        mean_b = float(vb.mean()) if vb.size else math.nan
        out.append(Comparison(track.name, group, pipe, row.metric, row.label, row.better, mean_a, mean_b, diff, low, high,
                              int(d.size) if d is not None else 0, int(va.size), int(vb.size),
                              verdict(row.better, gate_low, gate_high, mean_a, threshold)))  # fmt: skip
    return out


def config_changes(a: RunData, b: RunData) -> list[str]:
    """``pipeline.key: A -> B`` for every pipeline parameter that differs, and the scenario overrides."""
    out = []
    conf_b = {p["name"]: p.get("config", {}) for p in b.config["pipelines"]}
    for p in a.config["pipelines"]:
        if p["name"] not in conf_b:
            out.append(f"{p['name']}: only in A")
            continue
        ca, cb = _flat(p.get("config", {})), _flat(conf_b[p["name"]])
        out += [f"{p['name']}.{k}: {ca.get(k)!r} -> {cb.get(k)!r}" for k in sorted(set(ca) | set(cb)) if ca.get(k) != cb.get(k)]
    out += [f"{name}: only in B" for name in conf_b if name not in {p["name"] for p in a.config["pipelines"]}]
    if a.config.get("overrides") != b.config.get("overrides"):
        out.append(f"scenario overrides: {a.config.get('overrides')!r} -> {b.config.get('overrides')!r}")
    if a.config["seeds"] != b.config["seeds"]:
        out.append(f"seeds: {a.config['seeds']} -> {b.config['seeds']} (paired by case)")
    return out


def _flat(d: Mapping[str, Any], prefix: str = "") -> dict[str, Any]:
    out: dict[str, Any] = {}
    for k, v in d.items():
        out.update(_flat(v, f"{prefix}{k}.") if isinstance(v, Mapping) else {f"{prefix}{k}": v})
    return out


def _num(x: float, digits: int) -> str:
    return f"{x:.{digits}f}" if math.isfinite(x) else "–"


def format_comparisons(comps: Sequence[Comparison], digits: dict[tuple[str, str], int] | None = None) -> str:
    """An aligned text table of the comparisons (``digits``: (track, metric) -> decimals)."""
    rows = [["track", "group", "pipeline", "metric", "better", "A", "B", "B - A [95 % CI]", "n", "verdict"]]
    for c in comps:
        k = (digits or {}).get((c.track, c.metric), 3) + 1
        ci = f"{_num(c.diff, k)} [{_num(c.low, k)}, {_num(c.high, k)}]"
        n = str(c.n_pairs) if c.n_pairs else f"{c.n_a}/{c.n_b} unpaired"
        rows.append([c.track, c.group, c.pipeline, c.label, c.better, _num(c.mean_a, k), _num(c.mean_b, k), ci, n,
                     c.verdict.upper() if c.verdict == "worse" else c.verdict])  # fmt: skip
    widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
    lines = ["  ".join(c.ljust(w) for c, w in zip(r, widths, strict=True)).rstrip() for r in rows]
    lines.insert(1, "  ".join("-" * w for w in widths))
    return "\n".join(lines)


def compare_folders(run_a: str, run_b: str, threshold: float = 0.05) -> tuple[list[str], list[Comparison], dict[tuple[str, str], int]]:
    """What `exobench compare` shows: the config changes (``track: change``), every comparison,
    and the decimals of each (track, metric); refusals as ConfigError before anything is read
    twice."""
    from .tracks import get_track

    if not (threshold >= 0 and math.isfinite(threshold)):
        raise ConfigError("--threshold", threshold, "a fraction >= 0 of A's mean (0.05: 5 %)")
    runs_a, runs_b = load_runs(run_a), load_runs(run_b)
    check_comparable(runs_a, runs_b, run_a, run_b)
    changes: list[str] = []
    comps: list[Comparison] = []
    digits: dict[tuple[str, str], int] = {}
    for name in runs_a:
        track = get_track(name)
        digits.update({(name, r.metric): r.digits for r in track.summary_rows()})
        changes += [f"{name}: {c}" for c in config_changes(runs_a[name], runs_b[name])]
        comps += compare_track(track, runs_a[name], runs_b[name], threshold)
    return changes, comps, digits
