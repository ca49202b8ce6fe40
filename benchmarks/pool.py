"""Worker processes for a run's episodes (``--jobs N``) that neither outlive nor crash the run.

- Workers are spawned (they start clean: no inherited threads or GL contexts; results do not
  depend on it). Each chooses the OpenGL platform before it imports MuJoCo
  (:mod:`exobench.envs.gl_platform`) and watches its parent: when the parent dies (killed, even
  with SIGKILL) the worker exits within about :data:`WATCH_INTERVAL_S`.
- A worker that dies (killed, out of memory) breaks the pool. The pool is made again and the
  jobs that were not finished are submitted again, except the ones that were in the workers
  then: they are suspects, and are retried once each alone in a pool of one worker after the
  other jobs, so that a job that kills its worker again is named without doubt. A job that dies
  twice is handed to ``on_lost`` (which records it as failed) and the run goes on, with the
  reason (:func:`lost_reason`): a worker killed by SIGKILL (what the kernel's out-of-memory
  killer sends) is said to be likely out of memory, with its peak resident memory as last seen
  (the parent reads each worker's ``VmHWM`` in ``/proc`` about every :data:`WATCH_INTERVAL_S`).
- With more than one worker the jobs go longest first (:func:`longest_first`, from a cheap
  estimate: the scenario's length), so that a long episode does not start last and run alone
  at the end: the lidar-filter paper suite's five walks (one a third the length of the others)
  on two workers. With one worker the order is the run's (it changes nothing there). The
  records are the same; ``results.jsonl`` holds them in the order they finish, as before.
- Each worker's OpenMP and BLAS thread pools get the machine's CPUs over the number of workers
  (:func:`worker_threads_env`; a variable the user set is kept), as Ray does for its workers:
  with every worker keeping a pool as wide as the machine, two workers on two cores ran the
  stairs paper suite 1.15x as fast as one (9.5 / 8.3 s); with one thread each, 1.75x.
"""

from __future__ import annotations

import contextlib
import math
import multiprocessing
import os
import signal
import threading
import time
from collections.abc import Callable, Iterator, Mapping, Sequence
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from exobench.envs import gl_platform

WATCH_INTERVAL_S = 0.5
LOST_REASON = "the worker process running the episode died twice (killed, or out of memory)"


@dataclass(frozen=True)
class Death:
    """How a worker ended: its exit code (negative: the signal that killed it) and its peak
    resident memory as last seen, bytes (None: never seen)."""

    exitcode: int | None
    peak_bytes: int | None


def lost_reason(death: Death | None) -> str:
    """Why a job that died twice is lost, from how its worker died the second time (alone)."""
    if death is None or death.exitcode is None:
        return LOST_REASON
    peak = f", peak {death.peak_bytes / 1e9:.2f} GB" if death.peak_bytes else ""
    if death.exitcode == -signal.SIGKILL:
        return f"the worker process running the episode was killed (SIGKILL) twice, likely out of memory{peak}"
    if death.exitcode < 0:
        name = signal.Signals(-death.exitcode).name if -death.exitcode in signal.valid_signals() else str(-death.exitcode)
        return f"the worker process running the episode was killed ({name}) twice{peak}"
    return f"the worker process running the episode died twice (exit status {death.exitcode}){peak}"


def peak_rss_bytes(pid: int) -> int | None:
    """A live process's peak resident memory (``VmHWM`` of ``/proc/<pid>/status``), None where
    it cannot be read (the process is gone, or no /proc)."""
    try:
        text = Path(f"/proc/{pid}/status").read_text()
    except OSError:
        return None
    for line in text.splitlines():
        if line.startswith("VmHWM:"):
            return int(line.split()[1]) * 1024
    return None


def _watch_parent(parent_pid: int) -> None:
    while True:
        time.sleep(WATCH_INTERVAL_S)
        if os.getppid() != parent_pid:
            os._exit(1)  # the parent is gone: nobody will read our results


def _init_worker(parent_pid: int) -> None:
    gl_platform.install()
    threading.Thread(target=_watch_parent, args=(parent_pid,), daemon=True, name="exobench-parent-watch").start()


THREAD_VARS = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")


@contextlib.contextmanager
def worker_threads_env(workers: int) -> Iterator[None]:
    """While workers are spawned (they read it as they load OpenMP and BLAS), the thread-pool
    variables the user has not set say ``cpu_count // workers`` (at least 1)."""
    threads = str(max(1, (os.cpu_count() or 1) // max(1, workers)))
    unset = [v for v in THREAD_VARS if v not in os.environ]
    os.environ.update(dict.fromkeys(unset, threads))
    try:
        yield
    finally:
        for v in unset:
            os.environ.pop(v, None)


def make_pool(workers: int) -> ProcessPoolExecutor:
    """A spawned pool of ``workers`` processes that choose the GL platform and watch the parent."""
    ctx = multiprocessing.get_context("spawn")
    return ProcessPoolExecutor(max_workers=workers, mp_context=ctx, initializer=_init_worker, initargs=(os.getpid(),))


COST_KEYS = ("max_distance_m", "duration_s", "duration_cap_s")  # a scenario's length, first one given


def episode_cost(job: Any) -> float:
    """A cheap estimate of how long a job runs, for ordering only: its own ``cost`` when it has
    one (the jobs of a run of several tracks, ranked by :mod:`.run_tracks`), else its
    scenario's length (the first of :data:`COST_KEYS` it gives; the cases of one suite give the
    same one), 0 without."""
    own = getattr(job, "cost", None)
    if isinstance(own, (int, float)) and not isinstance(own, bool):
        return float(own)
    scenario = getattr(getattr(job, "plan", None), "scenario", None)
    if isinstance(scenario, Mapping):
        for key in COST_KEYS:
            v = scenario.get(key)
            if isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v):
                return float(v)
    return 0.0


def longest_first(jobs: Sequence[Any]) -> list[Any]:
    """``jobs`` by decreasing :func:`episode_cost`, equal ones in their given order (a stable
    sort: the same order on every run)."""
    return sorted(jobs, key=lambda job: -episode_cost(job))


def run_pool(
    jobs: Sequence[Any],
    workers: int,
    work: Callable[[Any], tuple],
    finish: Callable[..., None],
    on_lost: Callable[[Any, str], tuple],
) -> None:
    """``finish(*work(job))`` for every job, ``work`` in ``workers`` processes (see module doc).

    ``work`` returns a tuple whose first item is the job's key (results finished together are
    handed on in key order); ``on_lost(job, reason)`` returns the tuple for a job that died twice.
    """
    todo = longest_first(jobs) if workers > 1 else list(jobs)
    suspects: list[Any] = []
    while todo:
        todo, broken, _ = _run_batch(todo, workers, work, finish)
        suspects += broken
    for job in suspects:  # alone, so that a second death is this job's
        _, again, deaths = _run_batch([job], 1, work, finish)
        for lost in again:
            finish(*on_lost(lost, lost_reason(deaths[0] if deaths else None)))


def _run_batch(
    jobs: list[Any], workers: int, work: Callable[[Any], tuple], finish: Callable[..., None]
) -> tuple[list[Any], list[Any], list[Death]]:
    """Run ``jobs`` until all are done or the pool breaks; returns the jobs that did not finish:
    (those that had not started, those that may have been in a worker), and how the workers
    that died ended."""
    workers = min(workers, len(jobs))
    pool = make_pool(workers)
    futures: list[Future] = []
    procs: dict[int, Any] = {}  # pid -> multiprocessing.Process, kept after the pool drops them
    peaks: dict[int, int] = {}
    try:
        with worker_threads_env(workers):  # a spawning pool starts its processes as jobs come
            futures = [pool.submit(work, job) for job in jobs]
        procs.update(getattr(pool, "_processes", None) or {})
        pending, broken = set(futures), False
        while pending:
            finished, pending = wait(pending, timeout=WATCH_INTERVAL_S, return_when=FIRST_COMPLETED)
            procs.update(getattr(pool, "_processes", None) or {})  # the executor's own table of its workers
            for pid in procs:
                peak = peak_rss_bytes(pid)
                if peak is not None:
                    peaks[pid] = max(peak, peaks.get(pid, 0))
            for fut in finished:
                err = fut.exception()
                if err is not None and not isinstance(err, BrokenProcessPool):
                    raise err  # a bug of the harness itself: let it show
            done = [f for f in finished if f.exception() is None]
            for fut in sorted(done, key=lambda f: f.result()[0]):
                finish(*fut.result())
            broken = broken or len(done) < len(finished)  # then every unfinished job fails this way
    except BaseException:
        for fut in futures:
            fut.cancel()
        pool.shutdown(wait=False, cancel_futures=True)
        raise
    pool.shutdown(wait=True)
    if not broken:
        return [], [], []
    deaths = [Death(p.exitcode, peaks.get(pid)) for pid, p in procs.items() if p.exitcode not in (0, None)]
    # the pool hands jobs to its workers in submission order, at most one more than it has
    # workers at a time: the ones in a worker were the first unfinished ones
    unfinished = [job for job, fut in zip(jobs, futures, strict=True) if fut.exception() is not None]
    return unfinished[workers + 1 :], unfinished[: workers + 1], deaths
