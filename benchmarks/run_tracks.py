"""Several tracks' plans in one pool: ``exobench run`` of every track (``make run``).

One track after the other, a track of one or few episodes left a worker idle until it was done
(``make run`` at ``--jobs 2``: 1.55 cores busy on average). Here every track's episodes go to
one pool of ``jobs`` workers (or one executor's), so that a worker takes the next track's
episode as soon as it is free; each track's folder is written as a run of that track alone
writes it (:func:`.runner.execute`):

- Every plan's run folder is checked, created, locked and given its ``run_config.json``
  (:func:`.run_folder.run_folder`) before any episode runs, and held until the end.
- The order: the tracks' own, each track's episodes longest first with more than one worker
  (:func:`.pool.longest_first`, by the scenario's length), and the pool keeps it (each job
  carries its rank as its ``cost``). Across tracks there is no common estimate: a scenario's
  length is each track's own measure (4 m of a lidar-filter corridor and 20 s of locomotion do
  not compare), and what an episode costs per metre or second differs by a hundred times
  between tracks.
- Records are appended to each track's ``results.jsonl`` as its episodes finish (the same
  records as a run of the track alone: episode seeds depend only on the run seed and the case
  name, not on the jobs or the order); a track's figure goes to its folder.
- ``on_done(i, outcome)`` is called once per track from the driver as soon as its last episode
  is in (at once, before any episode, for a track with none left), while the other tracks'
  episodes go on in the workers: its table, report and recording can be made then.
- With ``jobs`` 1 and no executor the episodes run in this process, track after track, as
  before; one episode left in all runs there too.
- ``recordings`` (``--rerun``): each track's first episode writes its recording from its own
  frames, in whichever worker runs it (:func:`.runner._run_job`); not on an executor, whose
  worker may be on another machine.
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

from .pool import longest_first, run_pool
from .run_folder import run_folder
from .runner import (
    RunOutcome,
    RunPlan,
    TrackWriter,
    _failed_job,
    _Job,
    _run_job,
    check_jobs,
    executor_entry,
    setup_pipelines,
)


@dataclass(frozen=True)
class TrackJob:
    """An episode of the ``slot``-th plan; ``cost`` ranks it in the run's order (higher first)."""

    slot: int
    job: _Job
    cost: float


def run_track_job(tj: TrackJob) -> tuple:
    """The runner's unit of work, keyed by (plan, episode): two tracks may have an episode of
    the same name (``corridor-4m/s0``)."""
    key, *rest = _run_job(tj.job)
    return (tj.slot, key), *rest


def lost_track_job(tj: TrackJob, reason: str) -> tuple[tuple[int, str], list[dict[str, Any]], None]:
    key, records, figure = _failed_job(tj.job, reason)
    return (tj.slot, key), records, figure


def ranked_jobs(writers: Sequence[TrackWriter], workers: int, recordings: Sequence[Any]) -> list[TrackJob]:
    """Every episode left, in the order the pool should take them (see the module doc)."""
    per_track = [w.jobs(rec) for w, rec in zip(writers, recordings, strict=True)]
    ordered = [(i, job) for i, jobs in enumerate(per_track) for job in (longest_first(jobs) if workers > 1 else jobs)]
    return [TrackJob(i, job, float(len(ordered) - n)) for n, (i, job) in enumerate(ordered)]


def execute_tracks(
    runs: Sequence[tuple[RunPlan, str | os.PathLike, bool]],
    *,
    jobs: int = 1,
    on_start: Callable[[list[tuple[int, int]]], None] | None = None,
    on_episode: Callable[[int, str, list[dict[str, Any]]], None] | None = None,
    on_done: Callable[[int, RunOutcome], None] | None = None,
    executor: Any = None,
    recordings: Sequence[str | os.PathLike | None] | None = None,
) -> list[RunOutcome]:
    """Run each ``(plan, run folder, resume)`` of ``runs`` in one pool (see the module doc).

    ``on_start([(n_to_run, n_skipped) per plan])`` once every folder is ready, before any
    episode; ``on_episode(i, key, records)`` after each episode's records are stored;
    ``on_done(i, outcome)`` when plan ``i`` is complete. An exception of a callback, a
    KeyboardInterrupt or a write that fails stops the run with the finished episodes kept, as
    :func:`.runner.execute` does. ``recordings``: each plan's ``--rerun`` path (or None), as
    :func:`.runner.execute` takes it. Returns every plan's outcome, in ``runs``' order.
    """
    jobs = check_jobs(jobs)
    used = executor_entry(executor, jobs)
    with contextlib.ExitStack() as held:
        writers: list[TrackWriter] = []
        for i, (plan, out, resume) in enumerate(runs):
            folder = held.enter_context(run_folder(plan, out, resume=resume, executor=used))
            told = None if on_episode is None else (lambda key, records, i=i: on_episode(i, key, records))
            writers.append(TrackWriter(plan, folder, told))
        if on_start:
            on_start([(len(w.todo), len(w.outcome.skipped)) for w in writers])
        outcomes: list[RunOutcome | None] = [None] * len(writers)
        left = [len(w.todo) for w in writers]

        def done(i: int) -> None:
            outcomes[i] = writers[i].close()
            if on_done:
                on_done(i, outcomes[i])

        def finish(slot_key: tuple[int, str], records: list[dict[str, Any]], *rest: Any) -> None:
            i, key = slot_key
            writers[i].finish(key, records, *rest)
            left[i] -= 1
            if left[i] == 0:
                done(i)

        for i, w in enumerate(writers):
            if not w.todo:
                done(i)
        recs = [None] * len(writers) if recordings is None or executor is not None else list(recordings)  # see the module doc
        job_list = ranked_jobs(writers, jobs if executor is None else 2, recs)  # an executor: several workers
        for w in writers:
            if w.todo:
                setup_pipelines(w.plan.pipelines)
        if executor is not None:
            executor.run(job_list, run_track_job, finish, lost_track_job)
        elif jobs == 1 or len(job_list) <= 1:
            for tj in job_list:
                finish(*run_track_job(tj))
        else:
            run_pool(job_list, jobs, run_track_job, finish, lost_track_job)
    return [o for o in outcomes if o is not None]
