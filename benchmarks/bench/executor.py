"""`exobench bench executor`: episodes per second of one suite on the local pool at 1 and 2
workers (:func:`~exobench.benchmarks.pool.run_pool`, spawned processes even for one, so that
the two differ in workers only) and on Ray with 2 concurrent episodes, in one run; Ray's
overhead per episode against the pool at 2 workers; and whether the three gave the same
records (timings aside).

Each executor's wall time runs from its first job submitted (the pool's processes are started
inside it, as in a run) to its last record handed over; starting or joining Ray, done once
before, is reported apart (``ray_start_s``). The default is the stairs track's paper suite
(63 episodes of well under a second each, every pipeline of the track): short episodes, where
a per-episode overhead shows most.
"""

from __future__ import annotations

import time
from typing import Any

SUITES = {"stairs": "paper"}  # the suite timed per track; any other track: its quick suite


def _timed(run: Any, jobs: list[Any]) -> tuple[float, dict[str, Any]]:
    """(wall seconds, records by episode) of ``run(jobs, work, finish, on_lost)``."""
    from ..runner import _failed_job, _run_job

    got: dict[str, Any] = {}

    def finish(key: str, records: list[dict[str, Any]], figure: Any) -> None:
        got[key] = records

    t0 = time.perf_counter()
    run(jobs, _run_job, finish, _failed_job)
    return time.perf_counter() - t0, got


def _untimed(plan: Any, by_episode: dict[str, Any]) -> list[tuple]:
    from ..runner import untimed_metrics

    return sorted(
        (r["episode"], r["pipeline"], repr(untimed_metrics(plan.track, r["metrics"])))
        for records in by_episode.values()
        for r in records
    )


def bench_executor(plan: Any, *, ray_jobs: int = 2, ray_executor: Any = None) -> dict[str, Any]:
    """Time ``plan``'s episodes on the pool at 1 and 2 workers and on Ray (``ray_executor``, or
    a local Ray of ``ray_jobs`` CPUs started here and shut down after); see the module doc."""
    from ..pool import run_pool
    from ..ray_executor import RayExecutor
    from ..results import versions
    from ..runner import _Job

    vers = versions()
    jobs = [_Job(plan.track, e, tuple(plan.pipelines), vers) for e in plan.episodes]
    n = len(jobs)
    walls: dict[str, float] = {}
    records: dict[str, list[tuple]] = {}
    for workers in (1, 2):
        name = f"pool_{workers}"
        walls[name], got = _timed(lambda j, w, f, lost, k=workers: run_pool(j, k, w, f, lost), jobs)
        records[name] = _untimed(plan, got)
    ex = ray_executor or RayExecutor(jobs=ray_jobs, num_cpus=ray_jobs)
    t0 = time.perf_counter()
    ex.connect()
    ray_start = time.perf_counter() - t0
    try:
        walls[f"ray_{ray_jobs}"], got = _timed(ex.run, jobs)
    finally:
        if ray_executor is None:
            ex.close()
    records[f"ray_{ray_jobs}"] = _untimed(plan, got)
    per_episode = {k: w / n for k, w in walls.items()}
    overhead = per_episode[f"ray_{ray_jobs}"] - per_episode["pool_2"]
    first = records["pool_1"]
    return {
        "track": plan.track.name,
        "suite": plan.suite,
        "episodes": n,
        "pipelines": [p.name for p in plan.pipelines],
        "episodes_per_s": {k: n / w for k, w in walls.items()},
        "wall_s": walls,
        "ray_start_s": ray_start,
        "pool_2_over_pool_1_speedup": walls["pool_1"] / walls["pool_2"],
        "ray_overhead_s_per_episode": overhead,
        "ray_overhead_pct_of_pool_2": 100.0 * overhead / per_episode["pool_2"],
        "records_identical": all(r == first for r in records.values()) and len(first) == n * len(plan.pipelines),
    }
