"""`exobench bench executor`: episodes per second of one suite on the local pool at 1 and 2
workers (:func:`~exobench.benchmarks.pool.run_pool`, spawned processes even for one, so that
the two differ in workers only) and on Ray with 2 concurrent episodes, in one run; Ray's
overhead per episode against the pool at 2 workers; and whether the three gave the same
records (timings aside).

Each executor's wall time runs from its first job submitted to its last record handed over.
The pool's processes are started inside it, as in a run; Ray is started or joined before it
(``ray_start_s``) and its actors started and made to import the episodes' modules before it
too (``ray_workers_start_s``), as `run` starts them while it prepares the run folder. So that
a fixed start-up is neither hidden nor spread over the episodes, each executor's start-up
inside its window (``startup_s``: until its last worker began its first episode, read from the
workers' clocks: the pool's spawning and imports) is taken out of the per-episode figures
(``per_episode_s``, Ray's overhead); ``wall_s``, ``episodes_per_s`` and the pool's speed-up are
whole windows. The default is the stairs track's paper suite (63 episodes of well under a
second each, every pipeline of the track): short episodes, where a per-episode overhead shows
most.
"""

from __future__ import annotations

import os
import time
from typing import Any

SUITES = {"stairs": "paper"}  # the suite timed per track; any other track: its quick suite


def _stamped_job(job: Any) -> tuple:
    """The runner's unit of work (:func:`~..runner._run_job`), with when and in which process it
    began (``time.time()``: one clock for every process of this machine)."""
    from ..runner import _run_job

    began = (os.getpid(), time.time())
    return (*_run_job(job), began)


def _timed(run: Any, jobs: list[Any]) -> tuple[float, float, dict[str, Any]]:
    """(wall seconds, start-up seconds, records by episode) of ``run(jobs, work, finish,
    on_lost)``; the start-up lasts until the last worker began its first episode."""
    from ..runner import _failed_job

    got: dict[str, Any] = {}
    first: dict[int, float] = {}

    def finish(key: str, records: list[dict[str, Any]], figure: Any, began: tuple[int, float] | None = None) -> None:
        got[key] = records
        if began is not None:
            first[began[0]] = min(began[1], first.get(began[0], began[1]))

    t0, w0 = time.perf_counter(), time.time()
    run(jobs, _stamped_job, finish, _failed_job)
    wall = time.perf_counter() - t0
    return wall, min(wall, max(0.0, max(first.values(), default=w0) - w0)), got


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
    import ray

    from ..pool import run_pool
    from ..ray_executor import RayExecutor, plan_modules
    from ..results import versions
    from ..runner import _Job

    vers = versions()
    jobs = [_Job(plan.track, e, tuple(plan.pipelines), vers) for e in plan.episodes]
    n = len(jobs)
    walls: dict[str, float] = {}
    startup: dict[str, float] = {}
    records: dict[str, list[tuple]] = {}
    for workers in (1, 2):
        name = f"pool_{workers}"
        walls[name], startup[name], got = _timed(lambda j, w, f, lost, k=workers: run_pool(j, k, w, f, lost), jobs)
        records[name] = _untimed(plan, got)
    ex = ray_executor or RayExecutor(jobs=ray_jobs, num_cpus=ray_jobs)
    t0 = time.perf_counter()
    ex.connect()
    ray_start = time.perf_counter() - t0
    try:
        t0 = time.perf_counter()
        ray.get(ex.start_workers(n, plan_modules(plan)))
        ray_workers_start = time.perf_counter() - t0
        name = f"ray_{ray_jobs}"
        walls[name], startup[name], got = _timed(ex.run, jobs)
    finally:
        if ray_executor is None:
            ex.close()
    records[name] = _untimed(plan, got)
    per_episode = {k: (w - startup[k]) / n for k, w in walls.items()}
    overhead = per_episode[name] - per_episode["pool_2"]
    first = records["pool_1"]
    return {
        "track": plan.track.name,
        "suite": plan.suite,
        "episodes": n,
        "pipelines": [p.name for p in plan.pipelines],
        "episodes_per_s": {k: n / w for k, w in walls.items()},
        "wall_s": walls,
        "startup_s": startup,
        "per_episode_s": per_episode,
        "ray_start_s": ray_start,
        "ray_workers_start_s": ray_workers_start,
        "pool_2_over_pool_1_speedup": walls["pool_1"] / walls["pool_2"],
        "ray_overhead_s_per_episode": overhead,
        "ray_overhead_pct_of_pool_2": 100.0 * overhead / per_episode["pool_2"],
        "records_identical": all(r == first for r in records.values()) and len(first) == n * len(plan.pipelines),
    }
