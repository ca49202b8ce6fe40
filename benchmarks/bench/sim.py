"""`exobench bench sim`, per track: where an episode's time goes, and its peak memory.

For each track the first case of its paper suite is run as the runner runs it (simulated,
streamed when the track streams, through every pipeline of the track, scored), cut to a bench
length (``max_distance_m`` of office walks, ``duration_cap_s`` of locomotion courses) so that
the whole bench takes minutes. Each runs in a fresh process, so that its peak resident memory
(``ru_maxrss`` of that process) is the episode's own, under :mod:`cProfile`: the time spent in
each function's own code is summed into stages by where the function lives (see
:func:`stage_of`). The profile counts CPU time (:func:`cpu_profile`), so the stages are this
process's CPU-seconds, not moved by other jobs on a shared machine (``cpu_s`` is the episode's
whole CPU time, ``wall_s`` its wall time). Profiling slows Python code more than MuJoCo's: read
the stages as shares. The pipelines' wall times are the runner's own (``wall_s`` of each record).

:func:`bench_episode_alone` runs one paper case whole instead (``exobench bench sim --track T
--case NAME``), unprofiled, for its peak memory: the longest episodes of each track are the
ones to check (lidar-filter ``ring-windows-lowe``, loop-closure ``reflective-loop``, odometry
``ring``).
"""

from __future__ import annotations

import cProfile
import functools
import json
import os
import pstats
import resource
import subprocess
import sys
import time
from collections.abc import Sequence
from typing import Any

BENCH_DISTANCE_M = 4.0
BENCH_DURATION_S = 8.0
STAGES = ("motion", "state", "casting", "optics", "rendering", "noise", "truth", "pipelines", "scoring", "other")

# (stage, substrings of a function's file, substrings of a built-in's name): first match wins
_RULES: tuple[tuple[str, tuple[str, ...], tuple[str, ...]], ...] = (
    ("casting", ("sensors/lidar/cast", "sensors/lidar/ray_scene", "sensors/tof/"), ("mj_multiRay", "mj_ray", "RaycastingScene", "cast_rays")),
    ("optics", ("sensors/lidar/optics", "sensors/lidar/pane_shape"), ()),
    ("rendering", ("sensors/rgbd/render",), ("mjr_", "MjrContext", "MjvScene", "mjv_")),  # not gl_platform: its probe is setup
    ("truth", ("sensors/lidar/labels", "sensors/rgbd/segmentation", "core/truth", "sim/pose"), ()),
    ("noise", ("sensors/common", "sensors/lidar/model", "sensors/lidar/faults", "sensors/rgbd/model", "sensors/imu/",
               "sensors/encoders/", "sensors/contact/", "sensors/odometry/"), ("Generator", "random")),  # fmt: skip
    ("motion", ("envs/motion/", "models/"), ()),
    ("state", ("sim/recorder", "sensors/__init__", "sensors/dynamics"), ("mj_kinematics", "mj_forward", "mj_rne", "mj_camlight", "mj_")),
    ("pipelines", ("perception/", "mapping/"), ()),
    ("scoring", ("benchmarks/tracks/", "benchmarks/trajectory"), ()),
)


def _builtin(filename: str) -> bool:
    return filename in ("~", "") or filename.startswith("<")


def stage_of(filename: str, name: str) -> str | None:
    """The stage of a profiled function: an exobench function's by its file ("other" when no
    rule names it), a built-in's by its name; None for the rest (a built-in no rule names, a
    library's function), whose time belongs to the stages of their callers."""
    f = filename.replace("\\", "/")
    if _builtin(f):
        return next((stage for stage, _, names in _RULES if any(n in name for n in names)), None)
    rel = next((f[len(root):] for root in _package_roots() if f.startswith(root)), None)
    if rel is None or rel.startswith(".") or "site-packages/" in rel:  # a venv inside the checkout is not exobench
        return None
    return next((stage for stage, files, _ in _RULES if any(p in rel for p in files)), "other")


@functools.cache
def _package_roots() -> tuple[str, ...]:
    """The folder of the package ``exobench`` with a trailing slash, as imported and resolved:
    a checkout need not be named ``exobench`` (an editable install of /work/main is not)."""
    import exobench

    here = os.path.dirname(os.path.abspath(exobench.__file__)).replace("\\", "/")
    return tuple(dict.fromkeys((here + "/", os.path.realpath(here).replace("\\", "/") + "/")))


def stages_of(profile: cProfile.Profile) -> dict[str, float]:
    """Seconds of own time per stage (:data:`STAGES`) of a finished profile. A function without
    a stage of its own (a numpy, Open3D or MuJoCo call) counts in its callers' stages, shared by
    the time it spent under each caller, up to the nearest caller that has one."""
    stats = pstats.Stats(profile).stats  # type: ignore[attr-defined]
    shares: dict[Any, dict[str, float]] = {}
    visiting: set[Any] = set()

    def share(key: Any) -> dict[str, float]:
        if key not in shares:
            own = stage_of(key[0], key[2])
            out: dict[str, float] = {}
            total = 0.0
            if own is None:
                visiting.add(key)  # a recursive call adds nothing to its own share
                for c, site in stats[key][4].items():
                    if c in visiting or c not in stats or site[3] <= 0:
                        continue
                    total += site[3]
                    for stage, x in share(c).items():
                        out[stage] = out.get(stage, 0.0) + x * site[3]
                visiting.discard(key)
            shares[key] = {k: v / total for k, v in out.items()} if total > 0 else {own or "other": 1.0}
        return shares[key]

    result = dict.fromkeys(STAGES, 0.0)
    for key, (_, _, tottime, _, _) in stats.items():
        for stage, x in share(key).items():
            result[stage] += tottime * x
    return result


def cpu_profile() -> cProfile.Profile:
    """A profiler that counts this process's CPU time: under a load of 10-30 on two shared cores
    a wall-clock profile counts the time other processes held the core in whatever function was
    running, several times the episode's own CPU time."""
    return cProfile.Profile(time.process_time)


def bench_case(track_name: str, seed: int = 0, *, distance_m: float = BENCH_DISTANCE_M, duration_s: float = BENCH_DURATION_S) -> dict[str, Any]:
    """In this process: the first paper case of ``track_name`` (cut to the bench length), run
    and scored under the profiler; its stages, pipelines' walls and this process's peak RSS."""
    from ..runner import _Job, _run_job, plan_run
    from ..tracks import get_track

    track = get_track(track_name)
    case = track.cases("paper", seed)[0]
    cut: dict[str, Any] = {}
    if "max_distance_m" in case.scenario or any(p.name == "max_distance_m" for p in track.params()):
        cut["max_distance_m"] = min(float(case.scenario.get("max_distance_m", distance_m)), distance_m)
    if any(p.name == "duration_cap_s" for p in track.params()):
        cut["duration_cap_s"] = duration_s
    plan = plan_run(track, "paper", None, [seed], cut)
    ep = next(e for e in plan.episodes if e.case.name == case.name)
    profile = cpu_profile()
    t0, c0 = time.perf_counter(), time.process_time()
    profile.enable()
    try:
        _, records, _ = _run_job(_Job(track, ep, tuple(plan.pipelines), {}))
    finally:
        profile.disable()
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    return {
        "track": track.name,
        "case": case.name,
        "cut": cut,
        "wall_s": wall,
        "cpu_s": cpu,
        "sim_wall_s": float(records[0]["sim_wall_s"]) if records else 0.0,
        "stages_s": stages_of(profile),
        "pipelines_wall_s": {r["pipeline"]: float(r["wall_s"]) for r in records},
        "failed": {r["pipeline"]: r["metrics"].get("failed_reason", "") for r in records if r["metrics"].get("failed")},
        "peak_rss_gb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024 / 1e9,  # KiB on Linux
    }


def bench_sim_tracks(tracks: Sequence[str] | None = None, seed: int = 0, *, distance_m: float = BENCH_DISTANCE_M,
                     duration_s: float = BENCH_DURATION_S) -> dict[str, Any]:  # fmt: skip
    """:func:`bench_case` of each track (default: every built-in track), each in a fresh process."""
    from ..tracks.registry import BUILTIN_TRACKS

    out: dict[str, Any] = {}
    for name in tracks or tuple(BUILTIN_TRACKS):
        out[name] = _in_fresh_process(
            f"bench_case({name!r}, {int(seed)}, distance_m={float(distance_m)!r}, duration_s={float(duration_s)!r})")
    return out


def bench_episode(track_name: str, case_name: str, seed: int = 0) -> dict[str, Any]:
    """In this process: one case of ``track_name``'s paper suite, whole (not cut, not
    profiled), run and scored as the runner runs it (streamed when the track streams); its wall
    and CPU time, the simulation's share and this process's peak RSS: the figure that says whether the
    longest episodes fit (issue 26: at most 3 GB)."""
    from ..runner import _Job, _run_job, plan_run
    from ..tracks import get_track

    track = get_track(track_name)
    plan = plan_run(track, "paper", None, [seed])
    ep = next((e for e in plan.episodes if e.case.name == case_name), None)
    if ep is None:
        from exobench.core.errors import UnknownNameError

        raise UnknownNameError(f"paper case of track {track.name!r}", case_name, [c.name for c in track.cases("paper", seed)])
    t0, c0 = time.perf_counter(), time.process_time()
    _, records, _ = _run_job(_Job(track, ep, tuple(plan.pipelines), {}))
    return {
        "track": track.name,
        "case": case_name,
        "wall_s": time.perf_counter() - t0,
        "cpu_s": time.process_time() - c0,
        "sim_wall_s": float(records[0]["sim_wall_s"]) if records else 0.0,
        "pipelines_wall_s": {r["pipeline"]: float(r["wall_s"]) for r in records},
        "failed": {r["pipeline"]: r["metrics"].get("failed_reason", "") for r in records if r["metrics"].get("failed")},
        "peak_rss_gb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024 / 1e9,  # KiB on Linux
    }


def bench_episode_alone(track_name: str, case_name: str, seed: int = 0) -> dict[str, Any]:
    """:func:`bench_episode` in a fresh process, so that the peak is the episode's own."""
    return _in_fresh_process(f"bench_episode({track_name!r}, {case_name!r}, {int(seed)})")


def _in_fresh_process(call: str) -> dict[str, Any]:
    """The JSON result of ``call`` (a function of this module) run in a new interpreter, or
    ``{"error": <its last line of stderr>}``."""
    code = f"import json, sys; from exobench.benchmarks.bench import sim; json.dump(sim.{call}, sys.stdout)"
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=dict(os.environ))
    if proc.returncode != 0:
        lines = (proc.stderr or "").strip().splitlines() or [f"exit status {proc.returncode}"]
        return {"error": lines[-1]}
    return json.loads(proc.stdout.strip().splitlines()[-1])
