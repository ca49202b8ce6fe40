"""The `exobench` command: a thin shell over the runner, report, bench and session functions.

This module holds the group, `run` (with its helpers) and `list`/`orbvoc`; `bench` is in
:mod:`.cli_bench`, `record`/`replay` in :mod:`.cli_sessions`, `report`/`compare`/`leaderboard`
in :mod:`.cli_results`.

Only click is imported at module level so that `exobench --help` answers at once; each
command imports what it needs. Every :class:`exobench.core.errors.ExobenchError` becomes one
line on stderr, ``exobench: error: <message>``, and exit status 2; everything is validated
before an output folder is created, so a refused call leaves nothing behind. A run or replay
whose simulation or scorer raised (a failure of the benchmark, not of a pipeline) ends with
exit status 1 and the first reasons on stderr, after its table and report are written.
"""

from __future__ import annotations

import contextlib
import json
import os
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import click

from .cli_bench import bench
from .cli_common import EXIT_INTERRUPTED, EXIT_USAGE, exit_on_harness_errors
from .cli_results import compare, leaderboard, report
from .cli_sessions import record, replay

EXIT_BROKEN_PIPE = 141  # 128 + SIGPIPE, what a shell reports for a writer whose reader left


class _Group(click.Group):
    """Turns exobench's typed errors into a one-line message and exit status 2."""

    def invoke(self, ctx: click.Context) -> Any:
        try:
            return super().invoke(ctx)
        except Exception as e:
            from exobench.core.errors import ExobenchError

            if isinstance(e, ExobenchError):
                click.echo(f"exobench: error: {e}", err=True)
                ctx.exit(EXIT_USAGE)
            if isinstance(e, BrokenPipeError):  # the reader left (`exobench list | head`): quiet, as Unix tools are
                with contextlib.suppress(OSError, ValueError):  # no second error at exit's flush
                    os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
                ctx.exit(EXIT_BROKEN_PIPE)
            if isinstance(e, OSError):  # the file system said no (disk full, read-only, ...)
                name = e.filename2 or e.filename
                click.echo(f"exobench: error: {name}: {e.strerror}" if name and e.strerror else f"exobench: error: {e}", err=True)
                ctx.exit(EXIT_USAGE)
            raise


@click.group(cls=_Group, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(package_name="exobench", prog_name="exobench")
def cli() -> None:
    """exobench: a MuJoCo benchmark for exoskeleton perception.

    \b
    exobench run                   the quick suite of every track with every pipeline
    exobench run paper --track stairs --jobs 2    the staircase paper's protocol
    exobench list                  suites, tracks, pipelines, scenario parameters
    """
    # before any command imports mujoco: choose the OpenGL platform when MuJoCo is first imported
    import exobench.envs.gl_platform  # noqa: F401


def _default_out(suite: str) -> str:
    import datetime

    return f"runs/{suite}-{datetime.datetime.now().strftime('%Y%m%d-%H%M%S')}"


def _rerun_path(rerun_path: str, track: str | None) -> str:
    """--rerun NAME as given (one track) or as NAME-<track>.rrd (--track all)."""
    if track is None:
        return rerun_path
    p = Path(rerun_path)
    return str(p.with_name(f"{p.stem}-{track}{p.suffix or '.rrd'}"))


def _seeds(seed: int | None, seeds: int | None) -> list[int]:
    from exobench.core.errors import ConfigError

    if seed is not None and seeds is not None:
        raise ConfigError("--seed/--seeds", f"{seed}/{seeds}", "one of --seed N or --seeds N")
    if seeds is not None:
        from .runner import MAX_SEEDS

        if not 1 <= seeds <= MAX_SEEDS:  # before the list is built: click takes any integer
            raise ConfigError("--seeds", seeds, f"1 <= --seeds <= {MAX_SEEDS}")
        return list(range(seeds))
    if seed is not None and seed < 0:
        raise ConfigError("--seed", seed, "--seed >= 0")
    return [0 if seed is None else seed]


@cli.command()
@click.argument("suite", required=False)
@click.option("--track", default="all", show_default=True, help="Track to run, or 'all' (each track in turn).")
@click.option("--pipeline", "pipelines", multiple=True, help="Pipeline (repeatable); default: all of the track.")
@click.option("--case", "case_patterns", multiple=True, metavar="PATTERN",
              help="Only the suite's cases of this name or shell-style glob ('multi-direction/*'; repeatable; one track); default: every case.")
@click.option("--seed", type=int, default=None, help="Run seed (default 0).")
@click.option("--seeds", type=int, default=None, help="Run seeds 0..N-1.")
@click.option("--set", "assignments", multiple=True, metavar="KEY=VALUE", help="Scenario (riser_m=0.17) or pipeline (rtls.th_z_m=0.01) parameter.")
@click.option("--jobs", type=int, default=None, help="Episodes at once: processes of the local pool (default 1: in this process), or Ray tasks (default: the cluster's CPUs).")
@click.option("--executor", type=click.Choice(["local", "ray"]), default="local", show_default=True, help="Where episodes run: this machine (--jobs processes) or Ray (optional extra `ray`).")
@click.option("--address", default=None, help="Ray: the head's host:port (or ray://host:port); default: start a local Ray.")
@click.option("--episode-cpus", type=float, default=None, help="Ray: CPUs each episode reserves (default 1).")
@click.option("--episode-gpus", type=float, default=None, help="Ray: GPU fraction each episode reserves, for tracks that render (default 0).")
@click.option("--out", type=click.Path(), default=None, help="Run folder (default runs/<track>-<suite>-<time>; with --track all, one subfolder per track).")
@click.option("--resume", is_flag=True, help="Continue the run in --out DIR with the settings stored there, skipping finished episodes.")
@click.option("--rerun", "rerun_path", type=click.Path(), default=None, help="Also write the first episode as a rerun .rrd (with --track all, one per track: NAME-<track>.rrd).")
@click.option("--no-report", is_flag=True, help="Skip report.md and its plots.")
def run(
    suite: str | None,
    track: str,
    pipelines: tuple[str, ...],
    case_patterns: tuple[str, ...],
    seed: int | None,
    seeds: int | None,
    assignments: tuple[str, ...],
    jobs: int | None,
    executor: str,
    address: str | None,
    episode_cpus: float | None,
    episode_gpus: float | None,
    out: str | None,
    resume: bool,
    rerun_path: str | None,
    no_report: bool,
) -> None:
    """Run SUITE (default: each track's quick suite) of one track or of all, and print the tables.

    \b
    --resume --out DIR continues the run in DIR with the settings stored there (one track's
    run_config.json, or run_all.json of a run of every track); options given with it must match."""
    from exobench.core.errors import ConfigError, FolderError

    from .out_paths import check_out_dir, check_out_file
    from .overrides import parse_assignments
    from .ray_executor import connected, executor_from_options
    from .results import RUN_CONFIG_FILE
    from .run_folder import check_resume
    from .runner import plan_run
    from .tracks import track_names

    if jobs is not None and jobs < 1:
        raise ConfigError("--jobs", jobs, "--jobs >= 1")
    ray_ex = executor_from_options(executor, address, jobs, episode_cpus, episode_gpus)
    jobs = jobs or 1
    if resume and out is None:
        raise ConfigError("--resume", True, "--resume together with --out DIR of the run to continue")
    run_seeds = _seeds(seed, seeds)
    overrides: dict[str, Any] = parse_assignments(assignments)
    if out is not None:
        check_out_dir("--out", out, existing=True if resume else None)
    stored_tracks = None
    if resume:
        given = click.get_current_context().get_parameter_source
        stored = _stored_settings(str(out))
        if given("track") != click.core.ParameterSource.DEFAULT and track != stored.get("track", track):
            raise ConfigError("--resume track", track, f"the value of the run being resumed: {stored['track']!r}")
        track = stored.get("track", track)
        suite = suite if suite is not None else stored.get("suite")
        pipelines = pipelines or tuple(stored.get("pipelines", ()))
        run_seeds = run_seeds if seed is not None or seeds is not None else stored.get("seeds", run_seeds)
        overrides = overrides if assignments else stored.get("overrides", {})
        case_patterns = case_patterns or tuple(stored.get("cases", ()))
        stored_tracks = stored.get("tracks")
    if track != "all":
        plan = plan_run(track, suite, pipelines or None, run_seeds, overrides, cases=case_patterns)
        out = out or _default_out(f"{plan.track.name}-{plan.suite}")
        check_out_dir("--out", out)
        if rerun_path is not None:
            check_out_file("--rerun", rerun_path)
        with connected(ray_ex, plan):  # its actors start while the run folder is prepared
            errors = _run_plan(plan, out, jobs, resume, rerun_path, no_report, _continue_command(out, jobs, rerun_path, no_report, ray_ex), ray_ex)
        exit_on_harness_errors(errors)
        return
    if case_patterns:  # case names are a suite's own: another track's suite has others
        raise ConfigError("--case", ",".join(case_patterns), "one track (--track NAME), not --track all")
    if pipelines or overrides:
        raise ConfigError("--track", "all", "one track (--track NAME) when --pipeline or --set is given")
    # every plan is validated before anything runs, so a bad suite name writes nothing
    names, unserved = (stored_tracks, []) if stored_tracks else _served_tracks(track_names())
    plans = [plan_run(name, suite, None, run_seeds, {}) for name in names]
    for name in unserved:  # said once the run is known to go ahead
        click.echo(f"exobench: skipping track {name}: no registered pipeline serves it", err=True)
    root = Path(out or _default_out(f"all-{suite or 'quick'}"))
    check_out_dir("--out", str(root))
    for plan in plans if rerun_path is not None else ():
        check_out_file("--rerun", _rerun_path(rerun_path, plan.track.name))
    if resume:  # each track folder already there must be this run's, before any track runs
        for plan in plans:
            folder = root / plan.track.name
            if (folder / RUN_CONFIG_FILE).exists():
                check_resume(folder, plan)
            elif folder.is_dir() and _has_files(folder):
                raise FolderError(f"{folder}: not a run folder (no {RUN_CONFIG_FILE}) in the run being resumed")
    elif root.is_dir() and _has_files(root):
        again = " (or --resume to continue the run in it)" if _stored_settings(str(root), must=False) else ""
        raise ConfigError("--out", str(root), f"a new or empty folder{again}")
    hint = _continue_command(str(root), jobs, rerun_path, no_report, ray_ex)
    with connected(ray_ex, plans[0] if plans else None):
        root.mkdir(parents=True, exist_ok=True)
        errors = _run_all(plans, root, names, suite, run_seeds, jobs, resume, rerun_path, no_report, hint, ray_ex)
    exit_on_harness_errors(errors)


def _served_tracks(names: list[str]) -> tuple[list[str], list[str]]:
    """(the tracks some registered pipeline serves, the others): a track whose pipelines are not
    installed or not yet written has nothing to run, and a run of every track skips it."""
    from .registry import default_registry

    reg = default_registry()
    served = [n for n in names if reg.names(track=n)]
    return served, [n for n in names if n not in served]


def _run_all(plans: list[Any], root: Path, names: list[str], suite: str | None, run_seeds: list[int], jobs: int,
             resume: bool, rerun_path: str | None, no_report: bool, hint: str, ray_ex: Any) -> list[str]:
    """Run every track's plan into its folder of ``root`` (a run of every track), all their
    episodes in one pool (:func:`.run_tracks.execute_tracks`) under one progress bar. Each
    track's table, report and recording are made as soon as its last episode is in, and
    printed in the tracks' order, as a run of one track after the other printed them."""
    from tqdm import tqdm

    from exobench.core.errors import ExobenchError, FolderError

    from .out_paths import exclusive_lock
    from .results import RUN_ALL_FILE, RUN_CONFIG_FILE, run_all_config, write_json_atomic
    from .run_tracks import execute_tracks

    errors: list[str] = []
    bar: dict[str, Any] = {}
    blocks: dict[int, list[tuple[str, bool]]] = {}  # finished tracks' lines (text, to stderr), not yet printed
    shown, finished_tracks = [0], set()
    folders = [root / plan.track.name for plan in plans]

    def close_bar() -> None:
        if "tqdm" in bar and "finished" not in bar:
            bar["tqdm"].close()
            bar["finished"] = True

    def flush() -> None:
        while shown[0] in blocks:
            with tqdm.external_write_mode(file=sys.stdout):  # the bar (on stderr) stays whole
                for text, err in blocks.pop(shown[0]):
                    click.echo(text, err=err)
            shown[0] += 1

    def on_start(counts: list[tuple[int, int]]) -> None:
        for plan, (_, n_skipped) in zip(plans, counts, strict=True):
            for name, why in plan.skipped.items():  # left out of a run of all the track's pipelines
                click.echo(f"exobench: skipping pipeline {name}: {why}", err=True)
            if n_skipped:
                click.echo(f"resuming {plan.track.name}: {n_skipped} finished episodes kept", err=True)
        suites = "/".join(dict.fromkeys(plan.suite for plan in plans))
        bar["tqdm"] = tqdm(total=sum(n for n, _ in counts), unit="episode", file=sys.stderr, desc=f"all/{suites}")
        if not bar["tqdm"].total:
            close_bar()

    def on_episode(i: int, key: str, records: list[dict[str, Any]]) -> None:
        bar["tqdm"].update(1)
        if bar["tqdm"].n >= bar["tqdm"].total:  # before the last track's table
            close_bar()

    def on_done(i: int, outcome: Any) -> None:
        plan, lines = plans[i], []
        lines.append((f"\n== track {plan.track.name} / {plan.suite}", False))
        rrd = _rerun_path(rerun_path, plan.track.name) if rerun_path is not None else None
        finished_tracks.add(i)
        bar["reporting"] = True  # kept if it raises: a report's error says itself how to go on
        try:
            errors.extend(_finish_plan(plan, outcome, str(folders[i]), rrd, no_report, hint, len(finished_tracks) == len(plans),
                                       echo=lambda text, err=False: lines.append((text, err))))
        finally:
            blocks[i] = lines
            flush()
        bar.pop("reporting")

    # tracks not started yet get their folders; finished and interrupted ones are continued
    runs = [(plan, folder, resume and (folder / RUN_CONFIG_FILE).exists()) for plan, folder in zip(plans, folders, strict=True)]
    try:
        with exclusive_lock(root, "run"):
            if not resume:  # what `--resume --out ROOT` reads to continue every track
                write_json_atomic(root / RUN_ALL_FILE, run_all_config(names, suite, run_seeds))
            recordings = [_rerun_path(rerun_path, plan.track.name) if rerun_path is not None else None for plan in plans]
            execute_tracks(runs, jobs=jobs, on_start=on_start, on_episode=on_episode, on_done=on_done, executor=ray_ex,
                           recordings=recordings)  # fmt: skip
    except KeyboardInterrupt:  # while episodes run, or while a report or recording is written
        close_bar()
        click.echo(f"exobench: interrupted; finished episodes are kept in {root} (continue: {hint})", err=True)
        sys.exit(EXIT_INTERRUPTED)
    except ExobenchError as e:
        lost = type(e).__name__ == "ClusterLostError"  # the Ray cluster went away mid-run
        close_bar()
        if not (isinstance(e, FolderError) or lost) or "tqdm" not in bar or "reporting" in bar:
            raise  # refused before anything ran, or a report's error that says what to do
        # a write failed during the run (disk full)
        click.echo(f"exobench: error: {e}; finished episodes are kept in {root} (continue: {hint})", err=True)
        sys.exit(EXIT_USAGE)
    return errors


def _has_files(folder: Path) -> bool:
    from .out_paths import LOCK_FILE

    return any(p.name != LOCK_FILE for p in folder.iterdir())


def _stored_settings(out: str, *, must: bool = True) -> dict[str, Any]:
    """The settings of the run in folder ``out``, as `run` takes them: one track's from its
    run_config.json, a run of every track's from run_all.json ({"track": "all"} alone for such a
    run written before run_all.json existed: its settings are the command line's). Not a run
    folder: ConfigError, or {} when not ``must``."""
    from exobench.core.errors import ConfigError

    from .results import RUN_ALL_FILE, RUN_CONFIG_FILE, read_run_all, read_run_config
    from .tracks import track_names

    folder = Path(out)
    if (folder / RUN_CONFIG_FILE).exists():
        c = read_run_config(folder)
        pipeline_sets = {f"{p}.{k}": v for p, d in c["pipeline_overrides"].items() for k, v in d.items()}
        return {"track": c["track"], "suite": c["suite"], "pipelines": [p["name"] for p in c["pipelines"]],
                "seeds": c["seeds"], "overrides": {**c["overrides"], **pipeline_sets}, "cases": c["cases"]}  # fmt: skip
    if (folder / RUN_ALL_FILE).exists():
        c = read_run_all(folder)
        return {"track": "all", "suite": c["suite"], "seeds": c["seeds"], "tracks": c["tracks"]}
    if any((folder / name / RUN_CONFIG_FILE).exists() for name in track_names()):
        return {"track": "all"}
    if not must:
        return {}
    raise ConfigError("--out", out, f"a run folder to resume: with {RUN_CONFIG_FILE} (one track) or {RUN_ALL_FILE} (every track)")


def _continue_command(out: str, jobs: int, rerun_path: str | None, no_report: bool, ray_ex: Any = None) -> str:
    """The command that continues this run: its settings are read back from the folder (any
    executor can continue it; this one names the run's own)."""
    import shlex

    words = ["exobench", "run", "--resume", "--out", str(out)]
    if ray_ex is not None:
        words += ["--executor", "ray", *(["--address", ray_ex.address] if ray_ex.address else [])]
        words += ["--jobs", str(ray_ex.jobs)] if ray_ex.jobs else []
    else:
        words += ["--jobs", str(jobs)] if jobs != 1 else []
    words += ["--rerun", rerun_path] if rerun_path else []
    words += ["--no-report"] if no_report else []
    return shlex.join(words)


def _run_plan(
    plan: Any, out_dir: str, jobs: int, resume: bool, rerun_path: str | None, no_report: bool, hint: str,
    ray_ex: Any = None, last: bool = True,
) -> list[str]:
    """Execute one validated plan with a progress bar; print its table and where it went.
    ``hint`` is the command that continues the run; ``last``: no track of the run comes after
    this one. Returns the failures of the simulation or the scorer (see
    :func:`runner.harness_errors`)."""
    from tqdm import tqdm

    from exobench.core.errors import ExobenchError, FolderError

    from .runner import execute

    bar: dict[str, Any] = {}
    for name, why in plan.skipped.items():  # left out of a run of all the track's pipelines
        click.echo(f"exobench: skipping pipeline {name}: {why}", err=True)

    def on_start(n_todo: int, n_skipped: int) -> None:
        if n_skipped:
            click.echo(f"resuming: {n_skipped} finished episodes kept", err=True)
        bar["tqdm"] = tqdm(total=n_todo, unit="episode", file=sys.stderr, desc=f"{plan.track.name}/{plan.suite}")

    def on_episode(key: str, records: list[dict[str, Any]]) -> None:
        bar["tqdm"].update(1)

    try:
        outcome = execute(plan, out_dir, jobs=jobs, resume=resume, on_start=on_start, on_episode=on_episode, executor=ray_ex,
                          recording=rerun_path)  # fmt: skip
        bar["tqdm"].close()
        bar["finished"] = True
        return _finish_plan(plan, outcome, out_dir, rerun_path, no_report, hint, last)
    except KeyboardInterrupt:  # while episodes run, or while the report or recording is written
        if "tqdm" in bar and "finished" not in bar:
            bar["tqdm"].close()
        click.echo(f"exobench: interrupted; finished episodes are kept in {out_dir} (continue: {hint})", err=True)
        sys.exit(EXIT_INTERRUPTED)
    except ExobenchError as e:
        lost = type(e).__name__ == "ClusterLostError"  # the Ray cluster went away mid-run
        if not (isinstance(e, FolderError) or lost) or "tqdm" not in bar or "finished" in bar:
            raise  # refused before anything ran, or a report's error that says what to do

        bar["tqdm"].close()  # a write failed during the run (disk full)
        click.echo(f"exobench: error: {e}; finished episodes are kept in {out_dir} (continue: {hint})", err=True)
        sys.exit(EXIT_USAGE)


def _finish_plan(plan: Any, outcome: Any, out_dir: str, rerun_path: str | None, no_report: bool, hint: str, last: bool,
                 echo: Callable[..., None] = click.echo) -> list[str]:
    """Print the table of a finished plan (with ``echo(text, err=False)``), write its report
    and rerun recording."""
    import shlex

    from exobench.core.errors import FolderError

    from .report import summary_text, write_report
    from .runner import harness_errors, rerun_first_episode

    if outcome.figure_errors:
        first = outcome.figure_errors[0]
        echo(f"exobench: warning: {len(outcome.figure_errors)} figures not saved ({first}); their records are kept", err=True)
    names = [p.name for p in plan.pipelines]
    echo(summary_text(outcome.records, plan.track, names, [e.key for e in plan.episodes]))
    if plan.cases:  # a part of the suite: the table is not the suite's
        echo(f"\nonly the cases matching --case {', '.join(plan.cases)}: {len(plan.episodes)} episodes")
    failed = sum(bool(r["metrics"].get("failed")) for r in outcome.records)
    echo(f"\n{len(outcome.records)} records ({failed} failed) in {outcome.out_dir / 'results.jsonl'}")
    if not no_report:
        try:
            echo(f"report: {write_report(outcome.out_dir)}")
        except FolderError as e:  # tracks not finished yet: continuing runs them
            later = f"write it later: exobench report {shlex.quote(out_dir)}" if last else f"continue: {hint}"
            raise FolderError(f"{e}; the records are kept ({later})") from None
    if rerun_path:  # written by the run's own first episode, when it could be (runner.execute)
        if outcome.recording_error:
            raise FolderError(outcome.recording_error)
        echo(f"rerun recording: {outcome.recording or rerun_first_episode(plan, rerun_path)}")
    return harness_errors(outcome.records)


@cli.command("list")
def list_() -> None:
    """List tracks, suites, pipelines and the scenario parameters with ranges and units."""
    from .registry import default_registry
    from .tracks import get_track, track_names

    reg = default_registry()
    for tname in track_names():
        track = get_track(tname)
        click.echo(f"track {tname}")
        click.echo("  suites:")
        for s in track.suites:
            default = " (default)" if s == track.default_suite else ""
            click.echo(f"    {s:<8} {len(track.cases(s))} cases{default}")
        click.echo("  scenario parameters (--set KEY=VALUE): name, default, range, unit, meaning")
        for p in track.params():
            click.echo(f"    {p.name:<20} {p.default!s:<7} {p.range_text():<14} {p.unit:<4} {p.doc}")
    click.echo("pipelines (--pipeline NAME; parameters with --set NAME.KEY=VALUE):")
    for name in reg.names():
        spec = reg.spec(name)
        why = reg.unavailable(name)
        note = f"  UNAVAILABLE: {why}" if why else ""
        click.echo(f"  {name:<14} track {spec.track or '?':<8} {spec.source:<12} {spec.entry_point}{note}")


@cli.command()
@click.option("--json", "as_json", is_flag=True, help="Print the figures as JSON.")
def orbvoc(as_json: bool) -> None:
    """Build the ORB vocabulary of the orb-slam3 pipeline from simulated images (once per user, a
    few minutes; a run with orb-slam3 builds it itself on first use) and print where it is."""
    from exobench.mapping.odometry.orbslam3.vocabulary import DEFAULT_PARAMS, vocabulary_path

    from . import orbvoc as builder

    path = vocabulary_path(DEFAULT_PARAMS)
    if path.is_file():
        info: dict[str, Any] = {"path": str(path), "built": False, "bytes": path.stat().st_size}
    else:
        info = {**builder.build_vocabulary(path, DEFAULT_PARAMS, builder.training_images()), "built": True}
    click.echo(json.dumps(info) if as_json else "\n".join(f"{k}: {v}" for k, v in info.items()))


# commands of their own modules (each imports only click at module level)
for _command in (bench, replay, record, report, compare, leaderboard):
    cli.add_command(_command)


def main(argv: list[str] | None = None) -> None:
    """Console-script entry point."""
    cli.main(args=argv, prog_name="exobench")


if __name__ == "__main__":
    main()
