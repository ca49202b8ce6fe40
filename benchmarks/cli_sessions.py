"""`exobench record` and `exobench replay`: write a simulated episode as a session folder, and
score pipelines on one (registered on the group in :mod:`.cli`).

Only click is imported at module level, as in :mod:`.cli`: the CLI starts fast.
"""

from __future__ import annotations

import json

import click


@click.command()
@click.argument("session_dir", type=click.Path(file_okay=False))
@click.option("--track", default=None, help="Track to score on (default: the track the session was recorded for; stairs for old sessions).")
@click.option("--pipeline", "pipelines", multiple=True, help="Pipeline (repeatable); default: all of the track.")
@click.option("--set", "assignments", multiple=True, metavar="KEY=VALUE",
              help="Pipeline parameter (NAME.KEY=VALUE) or a scoring setting of the track (e.g. revisit_m).")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON record per pipeline.")
def replay(session_dir: str, track: str | None, pipelines: tuple[str, ...], assignments: tuple[str, ...], as_json: bool) -> None:
    """Score pipelines on a recorded session (SESSION_DIR written by `exobench record`), after
    checking it against its meta.json (track, file hashes, frame and truth counts)."""
    from exobench.envs.session import check_track, content_checked, read_meta, read_session

    from .cli_common import exit_on_harness_errors
    from .overrides import parse_assignments
    from .report import summary_text
    from .results import json_safe
    from .runner import plan_run, run_pipelines, setup_pipelines

    meta = read_meta(session_dir)
    check_track(session_dir, meta, track)
    track = track or meta.get("track") or "stairs"
    overrides = parse_assignments(assignments)
    plan = plan_run(track, None, pipelines or None, [0], overrides)
    scoring_keys = plan.track.scoring_keys
    recorded = [k for k in plan.scenario_overrides if k not in scoring_keys]
    if recorded:
        from exobench.core.errors import ConfigError

        allowed = "pipeline parameters (NAME.KEY=VALUE)" + (f" and scoring settings ({', '.join(sorted(scoring_keys))})" if scoring_keys else "")
        raise ConfigError("--set", ",".join(recorded), allowed)
    episode = read_session(session_dir, track=plan.track.name)  # a refused session: its one error line only
    for name, why in plan.skipped.items():
        click.echo(f"exobench: skipping pipeline {name}: {why}", err=True)
    setup_pipelines(plan.pipelines)
    if not content_checked(meta):
        click.echo(f"exobench: note: session version {meta['version']} has no file hashes; its files are not verified, only its frames against their truth", err=True)
    scorer_errors: dict[str, str] = {}
    # sessions recorded before scoring settings left the episode carry them in their scenario
    scoring = {**{k: v for k, v in episode.scenario.items() if k in scoring_keys},
               **{k: v for k, v in plan.scenario_overrides.items() if k in scoring_keys}}  # fmt: skip
    _, metrics, walls, _ = run_pipelines(plan.track, episode, plan.pipelines, scoring=scoring, scorer_errors=scorer_errors)
    records = [
        {"episode": "session", "group": "session", "pipeline": p.name, "config": p.config_dict(), "metrics": metrics[p.name], "wall_s": walls[p.name]}
        for p in plan.pipelines
    ]
    if as_json:
        for r in records:
            click.echo(json.dumps(json_safe({**r, "session": str(session_dir), "scenario": episode.scenario, "seed": episode.seed})))
    else:
        click.echo(summary_text(json_safe(records), plan.track, [p.name for p in plan.pipelines]))
    exit_on_harness_errors([f"session {name}: {reason}" for name, reason in scorer_errors.items()])


@click.command()
@click.argument("out_dir", type=click.Path())
@click.option("--track", default="stairs", show_default=True)
@click.option("--suite", default=None,
              help="Take --case from this suite of the track, drawn as `exobench run` draws it: --seed is then the run seed (default: the paper suite, --seed the episode seed).")
@click.option("--case", "case_name", default=None, help="Start from a named case of the paper suite (A, B, C, ...), or of --suite.")
@click.option("--set", "assignments", multiple=True, metavar="KEY=VALUE", help="Scenario parameter.")
@click.option("--seed", type=int, default=0, show_default=True,
              help="Episode seed; with --suite, the run seed (the episode seed is derived from it and the case's name).")
def record(out_dir: str, track: str, suite: str | None, case_name: str | None, assignments: tuple[str, ...], seed: int) -> None:
    """Simulate one episode and write it as a session folder OUT_DIR.

    With --suite, the episode is the one `exobench run SUITE --track TRACK --case CASE --seed SEED`
    scores (the same scenario, drawn from the run seed in a drawn suite, and the same episode
    seed), so a replay of the session gives the run's figures."""

    from exobench.core.errors import ConfigError, UnknownNameError
    from exobench.envs.session import write_session

    from .out_paths import check_out_dir, reserve_dir
    from .overrides import check_scenario_overrides, parse_assignments
    from .runner import episode_seed, load_case
    from .tracks import get_track

    trk = get_track(track)
    if seed < 0:
        raise ConfigError("--seed", seed, "--seed >= 0")
    sim_seed = seed
    if suite is not None:
        if suite not in trk.suites:
            raise UnknownNameError(f"suite of track {trk.name!r}", suite, trk.suites)
        if case_name is None:
            raise ConfigError("--case", None, f"a case of suite {suite!r} (a session holds one episode)")
        base = load_case(trk, suite, case_name, seed).scenario
        sim_seed = episode_seed(seed, case_name)
    else:
        base = load_case(trk, "paper", case_name).scenario if case_name else {}
    given = check_scenario_overrides(trk, parse_assignments(assignments))
    scoring = sorted(k for k in given if k in trk.scoring_keys)
    if scoring:  # not part of the episode: they would be silently lost
        raise ConfigError("--set", ",".join(scoring), "simulation parameters; scoring settings are given to `exobench replay`")
    scenario = trk.validate_scenario({**base, **given})
    check_out_dir("OUT_DIR", out_dir, existing=False)
    with reserve_dir(out_dir, "record"):  # a second `record` into it is refused before simulating
        episode = trk.simulate(scenario, sim_seed)
        path = write_session(episode, out_dir, track=trk.name)
    drawn = f"seed {sim_seed} (run seed {seed}, {suite} {case_name})" if suite is not None else f"seed {seed}"
    click.echo(f"session: {path} ({len(episode.frames)} frames, {drawn}, track {trk.name})")
