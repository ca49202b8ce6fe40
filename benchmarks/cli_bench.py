"""`exobench bench`: timings of the RTLS update, the simulator, the LiDAR, the locomotion track,
the executors and the multisession merge (registered on the group in :mod:`.cli`).

Only click is imported at module level, as in :mod:`.cli`: the CLI starts fast.
"""

from __future__ import annotations

import json
import sys
from typing import Any

import click


@click.command()
@click.argument("what", type=click.Choice(["rtls", "sim", "lidar", "locomotion", "executor", "multisession"]))
@click.option("--json", "as_json", is_flag=True, help="Print the result as JSON.")
@click.option("--seed", type=int, default=0, show_default=True)
@click.option("--session", type=click.Path(file_okay=False), default=None, help="rtls: a recorded case-A session instead of simulating one.")
@click.option("--track", "tracks", multiple=True, help="sim: a track whose paper episode to break down (repeatable; default: every track); executor: the track whose suite to time (default stairs: its paper suite).")
@click.option("--case", "case", default=None, help="sim: run this paper case of the one --track whole, unprofiled: wall time and peak memory.")
def bench(what: str, as_json: bool, seed: int, session: str | None, tracks: tuple[str, ...], case: str | None) -> None:
    """Time the RTLS update against a batch refit (rtls), the simulator (sim: the stairs real-time
    factor, and per track a paper episode cut short: time per stage and pipeline, peak memory),
    the LiDAR (lidar) or the locomotion track at 640x480 (locomotion: latency per prediction,
    TSDF and rendering fps) or the executors (executor: episodes per second of the stairs paper
    suite on the pool at 1 and 2 workers and on a local Ray at 2, Ray's overhead per episode) or
    the multisession merge (multisession: peak memory merging two and ten sessions, and the ratio)."""
    from exobench.core.errors import ConfigError

    from .bench import bench_lidar, bench_rtls, bench_sim, case_a_episode
    from .cli_common import EXIT_FAILED
    from .results import json_safe
    from .tracks import get_track

    if session and what != "rtls":
        raise ConfigError("--session", session, "bench rtls only")
    if case is not None and (what != "sim" or len(tracks) != 1):
        raise ConfigError("--case", case, "bench sim with exactly one --track")
    if tracks and what not in ("sim", "executor") or (what == "executor" and len(tracks) > 1):
        raise ConfigError("--track", ",".join(tracks), "bench sim (any number) or bench executor (one)")
    for name in tracks:
        get_track(name)  # an unknown name is refused before anything runs
    if case is not None:
        from .runner import load_case

        load_case(get_track(tracks[0]), "paper", case)
    if what == "rtls":
        if session:
            from exobench.envs.session import read_meta, read_session

            recorded = read_meta(session).get("track")
            if recorded not in (None, "stairs"):
                raise ConfigError("--session", session, f"a session of track 'stairs' (this one is of {recorded!r})")
            episode = read_session(session)
        else:
            episode = case_a_episode(seed)
        result = bench_rtls(episode)
    elif what == "lidar":
        result = bench_lidar(seed=seed)
    elif what == "locomotion":
        from .bench import bench_locomotion

        result = bench_locomotion(seed=seed)
    elif what == "multisession":
        from .bench.multisession import bench_multisession

        result = bench_multisession(seed=seed)
    elif what == "executor":
        from .bench.executor import SUITES, bench_executor
        from .ray_executor import executor_from_options
        from .runner import plan_run

        name = tracks[0] if tracks else "stairs"
        executor_from_options("ray", None, 2, None, None)  # refused at once when Ray is not installed
        result = bench_executor(plan_run(name, SUITES.get(name, "quick"), None, [seed]))
    elif case is not None:
        from .bench.sim import bench_episode_alone

        result = {"episode": bench_episode_alone(tracks[0], case, seed)}
        if "error" in result["episode"]:
            result["error"] = result["episode"]["error"]
    else:
        from .bench.sim import bench_sim_tracks

        result = {**bench_sim(seed=seed), "episodes": bench_sim_tracks(tracks or None, seed)}
    if result.get("error"):  # nothing to time: never a table of zeros with exit 0
        if session:
            raise ConfigError("--session", session, f"a stairs session the RTLS pipeline finds surfaces in ({result['error']})")
        click.echo(f"exobench: bench {what}: {result['error']}", err=True)
        sys.exit(EXIT_FAILED)
    if as_json:
        click.echo(json.dumps(json_safe(result), indent=2))
        return
    if what in ("lidar", "locomotion", "sim", "executor", "multisession"):  # one figure per line: exobench.static.ms_per_sweep ...
        result = _flat(result)
    w = max(28, *(len(k) + 1 for k in result))
    for key, value in json_safe(result).items():
        click.echo(f"{key:<{w}} {value:.4g}" if isinstance(value, float) else f"{key:<{w}} {value}")


def _flat(d: dict[str, Any], prefix: str = "") -> dict[str, Any]:
    """Nested dicts as one level of dotted keys."""
    out: dict[str, Any] = {}
    for k, v in d.items():
        out.update(_flat(v, f"{prefix}{k}.") if isinstance(v, dict) else {f"{prefix}{k}": v})
    return out
