"""Worker processes for a run's episodes (``--jobs N``) that neither outlive nor crash the run.

- Workers are spawned (they start clean: no inherited threads or GL contexts; results do not
  depend on it). Each chooses the OpenGL platform before it imports MuJoCo
  (:mod:`exobench.envs.gl_platform`) and watches its parent: when the parent dies (killed, even
  with SIGKILL) the worker exits within about :data:`WATCH_INTERVAL_S`.
- A worker that dies (killed, out of memory) breaks the pool. The pool is made again and the
  jobs that were not finished are submitted again, except the ones that were in the workers
  then: they are suspects, and are retried once each alone in a pool of one worker after the
  other jobs, so that a job that kills its worker again is named without doubt. A job that dies
  twice is handed to ``on_lost`` (which records it as failed) and the run goes on.
"""

from __future__ import annotations

import multiprocessing
import os
import threading
import time
from collections.abc import Callable, Sequence
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from typing import Any

from exobench.envs import gl_platform

WATCH_INTERVAL_S = 0.5
LOST_REASON = "the worker process running the episode died twice (killed, or out of memory)"


def _watch_parent(parent_pid: int) -> None:
    while True:
        time.sleep(WATCH_INTERVAL_S)
        if os.getppid() != parent_pid:
            os._exit(1)  # the parent is gone: nobody will read our results


def _init_worker(parent_pid: int) -> None:
    gl_platform.install()
    threading.Thread(target=_watch_parent, args=(parent_pid,), daemon=True, name="exobench-parent-watch").start()


def make_pool(workers: int) -> ProcessPoolExecutor:
    """A spawned pool of ``workers`` processes that choose the GL platform and watch the parent."""
    ctx = multiprocessing.get_context("spawn")
    return ProcessPoolExecutor(max_workers=workers, mp_context=ctx, initializer=_init_worker, initargs=(os.getpid(),))


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
    todo = list(jobs)
    suspects: list[Any] = []
    while todo:
        todo, broken = _run_batch(todo, workers, work, finish)
        suspects += broken
    for job in suspects:  # alone, so that a second death is this job's
        _, again = _run_batch([job], 1, work, finish)
        for lost in again:
            finish(*on_lost(lost, LOST_REASON))


def _run_batch(jobs: list[Any], workers: int, work: Callable[[Any], tuple], finish: Callable[..., None]) -> tuple[list[Any], list[Any]]:
    """Run ``jobs`` until all are done or the pool breaks; returns the jobs that did not finish:
    (those that had not started, those that may have been in a worker)."""
    workers = min(workers, len(jobs))
    pool = make_pool(workers)
    futures: list[Future] = []
    try:
        futures = [pool.submit(work, job) for job in jobs]
        pending, broken = set(futures), False
        while pending:
            finished, pending = wait(pending, return_when=FIRST_COMPLETED)
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
        return [], []
    # the pool hands jobs to its workers in submission order, at most one more than it has
    # workers at a time: the ones in a worker were the first unfinished ones
    unfinished = [job for job, fut in zip(jobs, futures, strict=True) if fut.exception() is not None]
    return unfinished[workers + 1 :], unfinished[: workers + 1]
