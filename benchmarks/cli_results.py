"""`exobench report`, `compare` and `leaderboard`: what is made of finished run folders
(registered on the group in :mod:`.cli`).

Only click is imported at module level, as in :mod:`.cli`: the CLI starts fast.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import click


@click.command()
@click.argument("run_dir", type=click.Path(file_okay=False))
def report(run_dir: str) -> None:
    """Rewrite report.md (and plots) of a run folder and print its summary (of a run of every
    track: of each track's folder)."""
    from exobench.core.errors import ConfigError

    from .out_paths import check_out_dir
    from .results import RUN_ALL_FILE, RUN_CONFIG_FILE, read_run_all

    folder = Path(run_dir)
    check_out_dir("RUN_DIR", run_dir, existing=True)  # it is written into: refused before anything
    if (folder / RUN_CONFIG_FILE).exists():
        _report_folder(folder)
    elif (folder / RUN_ALL_FILE).exists():
        for name in read_run_all(folder)["tracks"]:
            if (folder / name / RUN_CONFIG_FILE).exists():
                check_out_dir("RUN_DIR", str(folder / name), existing=True)
                click.echo(f"\n== track {name}")
                _report_folder(folder / name)
    else:
        raise ConfigError("RUN_DIR", run_dir, f"a run folder with {RUN_CONFIG_FILE} (or {RUN_ALL_FILE} of a run of every track)")


def _report_folder(folder: Path) -> None:
    from .report import summary_text, write_report
    from .results import RESULTS_FILE, read_records, read_run_config, sort_records
    from .tracks import get_track

    config = read_run_config(folder)
    names = [p["name"] for p in config["pipelines"]]
    records = sort_records(read_records(folder / RESULTS_FILE), names)
    click.echo(summary_text(records, get_track(config["track"]), names, config["episodes"]))
    click.echo(f"report: {write_report(folder)}")


@click.command()
@click.argument("run_a", type=click.Path(file_okay=False))
@click.argument("run_b", type=click.Path(file_okay=False))
@click.option("--threshold", type=float, default=0.05, show_default=True,
              help="A change is flagged when its whole 95 % interval is beyond this fraction of A's mean (0: any significant change).")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object per comparison.")
def compare(run_a: str, run_b: str, threshold: float, as_json: bool) -> None:
    """Compare run B against run A (same tracks and suites): per track, group, pipeline and
    headline metric, B - A with its 95 % confidence interval (paired t over the episodes both
    have; Welch's t where none pair). Exit status 1 when a headline metric is worse beyond
    --threshold, so a CI can gate on it."""
    import dataclasses

    from .cli_common import EXIT_FAILED
    from .compare import compare_folders, format_comparisons
    from .results import json_safe

    changes, comps, digits = compare_folders(run_a, run_b, threshold)
    if as_json:
        for c in comps:
            click.echo(json.dumps(json_safe(dataclasses.asdict(c))))
    else:
        click.echo("\n".join([*changes, format_comparisons(comps, digits)]))
    worse = [c for c in comps if c.verdict == "worse"]
    if worse:
        first = "; ".join(f"{c.track} {c.group} {c.pipeline} {c.metric}" for c in worse[:3])
        more = f" (and {len(worse) - 3} more)" if len(worse) > 3 else ""
        click.echo(f"exobench: {len(worse)} headline comparisons worse beyond the threshold {threshold:g}: {first}{more}", err=True)
        sys.exit(EXIT_FAILED)


@click.command()
@click.argument("runs", nargs=-1, required=True, type=click.Path(file_okay=False))
@click.option("--out", default="leaderboard", show_default=True, type=click.Path(), help="Folder of leaderboard.md and its figures.")
def leaderboard(runs: tuple[str, ...], out: str) -> None:
    """Rank the pipelines of RUNS... per track on its headline metrics, beside the published
    figures: OUT/leaderboard.md (printed too) and a figure per track, with the versions and
    configs that produced each entry."""
    from .leaderboard import write_leaderboard
    from .out_paths import check_out_dir

    check_out_dir("--out", out)
    path = write_leaderboard(runs, out)
    click.echo(path.read_text())
    click.echo(f"leaderboard: {path}")
