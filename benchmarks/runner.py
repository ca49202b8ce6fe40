"""Run a suite: (scenario, seed) episodes x pipelines, scored, stored episode by episode.

Two steps, so that nothing touches the disk until everything is valid:

- :func:`plan_run` validates the track, suite, pipelines and their configs, the ``--set``
  overrides (every case's scenario is validated with them) and the seeds, and returns a
  :class:`RunPlan`. It has no side effects.
- :func:`execute` creates the output folder, writes ``run_config.json`` and runs the episodes,
  in this process or a pool of ``jobs`` processes. Each episode is simulated once and each
  frame goes to every pipeline in turn (as it is simulated, when the track streams: a long
  walk is never held whole); its records are appended atomically to ``results.jsonl`` as
  soon as it is finished. A pipeline that raises is recorded as failed and the run goes on.
  A failure of the harness itself (the simulation or the scorer raised) is recorded as failed
  too, and its record carries the reason in ``harness_error`` (see :func:`harness_errors`).
  Every record of a pipeline that returned an estimate with input counters also holds them,
  as ``frames.<kind>.<counter>`` for every kind the track streams
  (:func:`exobench.core.counters.count_metrics`), the same in every track. The records (and
  the run configuration's entry) of a pipeline that is not deterministic
  (:func:`exobench.core.pipeline.is_deterministic`) hold ``"deterministic": false``.
  With ``resume=True`` finished episodes are skipped; Ctrl-C keeps them. The worker pool
  (:mod:`.pool`) retries the episode of a worker that died once, then records it as failed.
  An ``executor`` (:class:`.ray_executor.RayExecutor`) runs the same unit of work elsewhere
  under the same contract; ``run_config.json`` records which executor ran (``executor``), and
  a resume may use any. With ``recording`` (``--rerun``) the first episode's rerun recording is
  written from that episode's own frames when it is held whole (:func:`_run_job`).
  :mod:`.run_tracks` runs several plans in one pool with the pieces of this one
  (:func:`.run_folder.run_folder`, :class:`TrackWriter`).

Episode seeds are derived from the run seed and the case name, so a case keeps its seed when a
suite grows, and ``--jobs N`` gives the same results as ``--jobs 1``.
"""

from __future__ import annotations

import dataclasses
import datetime as _dt
import fnmatch
import os
import time
import zlib
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from exobench.core.counters import count_metrics
from exobench.core.episode import EpisodeStream
from exobench.core.errors import ConfigError, FolderError, UnknownNameError
from exobench.core.pipeline import coerce_like, is_deterministic

from .entry_points import load_entry_point
from .overrides import check_scenario_overrides, split_overrides
from .pool import run_pool
from .registry import PipelineRegistry, default_registry
from .results import (
    RESULTS_FILE,
    append_records,
    json_safe,
    read_records,
    sort_records,
    versions,
)
from .run_folder import FIGURES_DIR, check_resume, prepare_output, run_folder, save_figure  # noqa: F401 (FIGURES_DIR, check_resume, prepare_output: kept importable from here)
from .tracks import get_track
from .tracks.spec import Case, EpisodePlan, Track, scoring_of

MAX_SEEDS = 10_000


@dataclass(frozen=True)
class PipelineRun:
    """A pipeline as the workers build it: registry name, class entry point, config instance."""

    name: str
    entry_point: str
    config: Any
    setup: str | None = None  # "module:function" run once with the config before the episodes
    deterministic: bool = True  # False: two runs may differ (core.pipeline.is_deterministic)

    def config_dict(self) -> dict[str, Any]:
        return json_safe(dataclasses.asdict(self.config))


@dataclass
class RunPlan:
    """A validated run (see :func:`plan_run`)."""

    track: Any
    suite: str
    pipelines: list[PipelineRun]
    episodes: list[EpisodePlan]
    seeds: list[int]
    scenario_overrides: dict[str, Any]
    pipeline_overrides: dict[str, dict[str, Any]]
    skipped: dict[str, str] = field(default_factory=dict)  # pipelines of the track left out: name -> why
    cases: list[str] = field(default_factory=list)  # the --case patterns that chose the episodes (none: every case)

    def run_config(self) -> dict[str, Any]:
        return {
            "format": "exobench-run",
            "version": 1,
            "track": self.track.name,
            "suite": self.suite,
            "pipelines": [{"name": p.name, "entry_point": p.entry_point, "config": p.config_dict(),
                           **({} if p.deterministic else {"deterministic": False})} for p in self.pipelines],
            "seeds": list(self.seeds),
            "overrides": dict(self.scenario_overrides),
            "pipeline_overrides": self.pipeline_overrides,
            "cases": list(self.cases),
            "episodes": [e.key for e in self.episodes],
            "created": _dt.datetime.now().astimezone().isoformat(timespec="seconds"),
            "versions": versions(),
        }


@dataclass
class RunOutcome:
    out_dir: Path
    ran: list[str] = field(default_factory=list)
    skipped: list[str] = field(default_factory=list)
    records: list[dict[str, Any]] = field(default_factory=list)
    figure_errors: list[str] = field(default_factory=list)  # "episode: reason" of figures not saved
    recording: Path | None = None  # the rerun recording written from the run's own first episode
    recording_error: str | None = None  # why it could not be written (disk full)


def episode_seed(run_seed: int, case_name: str) -> int:
    """Simulation seed of a case under a run seed (stable, independent of the case's position)."""
    return int(np.random.SeedSequence([int(run_seed), zlib.crc32(case_name.encode())]).generate_state(1)[0])


def untimed_metrics(track: Track, metrics: Mapping[str, Any]) -> dict[str, Any]:
    """The metrics of a record without the track's wall-clock timings (``track.timing_metrics``):
    what two runs of the same plan must give identically."""
    return {k: v for k, v in metrics.items() if k not in track.timing_metrics}


def plan_run(
    track: str | Track,
    suite: str | None = None,
    pipelines: Sequence[str] | None = None,
    seeds: Sequence[int] = (0,),
    overrides: Mapping[str, Any] | None = None,
    *,
    registry: PipelineRegistry | None = None,
    cases: Sequence[str] = (),
) -> RunPlan:
    """Validate a run and list its episodes; raises ConfigError / UnknownNameError, writes nothing.

    ``overrides`` keys are scenario parameters (``riser_m``) or pipeline parameters prefixed by
    the pipeline name (``rtls.th_z_m``, ``kiss-icp.filter.band_m``: see :func:`split_overrides`);
    string values are converted to the parameter's type. ``cases`` (``--case``): keep only the
    suite's cases named by one of these patterns (a name, or a shell-style glob such as
    ``multi-direction/*``: :func:`case_matches`), in the suite's order, for every seed; a
    pattern that names no case of the suite is refused.
    """
    trk = get_track(track) if isinstance(track, str) else track
    suite = suite or trk.default_suite
    if suite not in trk.suites:
        raise UnknownNameError("suite", suite, trk.suites)
    reg = registry or default_registry()
    skipped: dict[str, str] = {}
    if pipelines:
        names = list(pipelines)
        for name in names:  # named, it must run: refused with what installs it
            why = reg.unavailable(name) if name in reg.names() else None
            if why:
                raise ConfigError("pipeline", name, f"an installed pipeline; {name} {why}")
    else:  # all of the track's: those that cannot run here are left out, and the plan says so
        names = []
        for name in reg.names(track=trk.name):
            why = reg.unavailable(name)
            if why:
                skipped[name] = why
            else:
                names.append(name)
    if not names:
        raise ConfigError("pipeline", "", f"at least one pipeline for track {trk.name!r} that can run here"
                          + "".join(f"; {n} {w}" for n, w in skipped.items()))  # fmt: skip
    if len(set(names)) != len(names):
        raise ConfigError("pipeline", ",".join(names), "each pipeline once")
    for name in names:
        if name not in reg.names():
            raise UnknownNameError(f"pipeline of track {trk.name!r}", name, reg.names(track=trk.name))
        cls = reg.load(name)
        if getattr(cls, "track", trk.name) != trk.name:
            raise ConfigError("pipeline", name, f"a pipeline of track {trk.name!r} (it serves {cls.track!r})")
    try:  # the count first: a huge range is refused before anything is built from it
        n_seeds = len(seeds)
    except OverflowError:
        n_seeds = MAX_SEEDS + 1
    if not 1 <= n_seeds <= MAX_SEEDS:
        raise ConfigError("seeds", f"{n_seeds if n_seeds <= MAX_SEEDS else 'more than ' + str(MAX_SEEDS)} seeds",
                          f"1 to {MAX_SEEDS} distinct integers >= 0")
    seeds = [int(coerce_like("seed", s, 0)) for s in seeds]
    if min(seeds) < 0 or len(set(seeds)) != len(seeds):
        raise ConfigError("seeds", seeds, f"1 to {MAX_SEEDS} distinct integers >= 0")

    scen_raw, pipe_raw = split_overrides(overrides or {}, names)
    scen = check_scenario_overrides(trk, scen_raw)
    runs = [PipelineRun(n, reg.spec(n).entry_point, reg.make_config(n, pipe_raw.get(n)), reg.spec(n).setup,
                        is_deterministic(reg.load(n))) for n in names]

    # case-major order (each case with every seed); a drawn suite has its own cases per seed
    planned: list[tuple[int, int, EpisodePlan]] = []
    typed: dict[str, Any] = {}
    defaults = {p.name: p.default for p in trk.params()} if scen else {}
    suite_cases = {s: trk.cases(suite, s) for s in seeds}
    patterns = [str(p) for p in cases]
    if patterns:  # each pattern must name a case (of some seed: a drawn suite differs per seed)
        names = {c.name for cs in suite_cases.values() for c in cs}
        for pattern in patterns:
            if not any(case_matches(n, [pattern]) for n in names):
                raise UnknownNameError(f"--case of suite {suite!r} of track {trk.name!r}", pattern, names)
        if len(set(patterns)) != len(patterns):
            raise ConfigError("--case", ",".join(patterns), "each pattern once")
    for j, s in enumerate(seeds):
        for i, case in enumerate(suite_cases[s]):
            if patterns and not case_matches(case.name, patterns):
                continue
            scenario = trk.validate_scenario({**case.scenario, **scen})
            # a scenario may leave out a parameter at its neutral default (segmentation_truth=false)
            typed = {k: scenario.get(k, defaults[k]) for k in scen}
            case = dataclasses.replace(case, group=trk.group_label(case, scenario))
            planned.append((i, j, EpisodePlan(f"{case.name}/s{s}", suite, case, scenario, s, episode_seed(s, case.name))))
    episodes = [e for _, _, e in sorted(planned, key=lambda x: (x[0], x[1]))]
    if len({e.key for e in episodes}) != len(episodes):
        raise ConfigError("suite", suite, "cases whose names are unique within each seed")
    return RunPlan(trk, suite, runs, episodes, seeds, typed, {k: dict(v) for k, v in pipe_raw.items()}, skipped, patterns)


def case_matches(name: str, patterns: Sequence[str]) -> bool:
    """Whether a case is chosen by one of ``patterns``: its name exactly (a name may hold ``[``),
    or a shell-style glob of it, case-sensitive (``*`` also spans ``/``: ``h1.60/*``)."""
    return any(name == p or fnmatch.fnmatchcase(name, p) for p in patterns)


# ---------------------------------------------------------------- one episode (runs in workers)


def run_pipelines(
    track: Track,
    episode: Any,
    pipelines: Sequence[PipelineRun],
    *,
    scoring: Mapping[str, Any] | None = None,
    timeline_every_s: float | None = None,
    scorer_errors: dict[str, str] | None = None,
) -> tuple[dict[str, Any], dict[str, dict[str, Any]], dict[str, float], dict[str, list]]:
    """Feed the same frames to every pipeline in lockstep; estimates, metrics, wall times and
    online timelines.

    ``episode`` is an :class:`~exobench.core.Episode` or an
    :class:`~exobench.core.episode.EpisodeStream`: each frame goes to every pipeline as it comes,
    so a streamed episode is never held whole, and is scored as its ``finish()`` once the
    frames are exhausted (an exception of the stream itself is raised as :class:`StreamError`).
    Estimates are scored under ``scoring`` (the track's scoring settings, see
    :func:`~.tracks.spec.scoring_of`; None: their defaults). A pipeline that raises, or whose
    ``finalize()`` returns anything but an instance of ``track.estimate_type``, is scored with
    ``track.failed_metrics`` and the reason, and the others go on; so is a scorer that raises,
    whose reasons also go to ``scorer_errors`` (pipeline name -> reason) when it is given. A
    score with no headline metric finite is failed (:func:`unscored_failed`). With
    ``timeline_every_s`` the online estimates are kept at most that often (for rerun). A
    pipeline's wall time is the sum of its own calls and its scoring.
    """
    estimates: dict[str, Any] = {}
    errors: dict[str, str] = {}
    walls: dict[str, float] = {p.name: 0.0 for p in pipelines}
    timelines: dict[str, list] = {p.name: [] for p in pipelines}
    last_t: dict[str, float] = {p.name: -np.inf for p in pipelines}
    live: dict[str, Any] = {}

    def call(name: str, fn: Callable[[], Any]) -> Any:
        t0 = time.perf_counter()
        try:
            return fn()
        except Exception as e:  # a failing pipeline is a result, not a crash
            errors[name] = f"pipeline raised {type(e).__name__}: {e}"
            live.pop(name, None)
            return None
        finally:
            walls[name] += time.perf_counter() - t0

    for p in pipelines:
        pipe = call(p.name, lambda p=p: load_entry_point(p.entry_point)(p.config))
        if p.name not in errors:
            live[p.name] = pipe
            call(p.name, lambda pipe=pipe: pipe.reset(episode.calibration))
    frames = iter(episode.frames)
    while True:
        try:
            frame = next(frames)
        except StopIteration:
            break
        except Exception as e:
            raise StreamError(f"simulation raised {type(e).__name__}: {e}") from e
        for name, pipe in list(live.items()):
            online = call(name, lambda pipe=pipe, frame=frame: pipe.process(frame))
            if timeline_every_s is not None and online is not None and frame.stamp_s - last_t[name] >= timeline_every_s:
                timelines[name].append((float(frame.stamp_s), online))
                last_t[name] = frame.stamp_s
    for name, pipe in list(live.items()):
        est = call(name, pipe.finalize)
        if name in live:
            estimates[name] = est
    if isinstance(episode, EpisodeStream):
        try:
            episode = episode.finish()
        except Exception as e:
            raise StreamError(f"simulation raised {type(e).__name__}: {e}") from e
    metrics: dict[str, dict[str, Any]] = {}
    for p in pipelines:
        t0 = time.perf_counter()
        est = estimates.get(p.name)
        if p.name in errors:
            metrics[p.name] = track.failed_metrics(episode, errors[p.name])
        elif not isinstance(est, track.estimate_type):  # a missing estimate is never scored as one
            reason = f"finalize() returned {type(est).__name__}, not {track.estimate_type.__name__}"
            metrics[p.name] = track.failed_metrics(episode, reason)
        else:
            try:
                metrics[p.name] = unscored_failed(track, track.score(episode, est, scoring))
            except Exception as e:  # a failure of the benchmark, not of the pipeline
                reason = f"scorer raised {type(e).__name__}: {e}"
                metrics[p.name] = track.failed_metrics(episode, reason)
                if scorer_errors is not None:
                    scorer_errors[p.name] = reason
            counts = getattr(est, "counts", None)
            if counts:
                metrics[p.name].update(count_metrics(counts, getattr(track, "streams", ())))
        walls[p.name] += time.perf_counter() - t0
    return estimates, metrics, walls, timelines


class StreamError(Exception):
    """A streamed episode's simulation raised while its frames were being read."""


class _TimedFrames:
    """The frames of a stream, with the time spent producing them (the simulation's wall time)."""

    def __init__(self, frames: Any) -> None:
        self.frames, self.wall_s = iter(frames), 0.0

    def __iter__(self) -> _TimedFrames:
        return self

    def __next__(self) -> Any:
        t0 = time.perf_counter()
        try:
            return next(self.frames)
        finally:
            self.wall_s += time.perf_counter() - t0


def unscored_reason(track: Track, metrics: Mapping[str, Any]) -> str:
    """Why a record scored nothing: every one of the track's ``headline_metrics`` is missing or
    NaN (empty when one is finite, or when the track names none)."""
    keys = tuple(getattr(track, "headline_metrics", ()))

    def finite(v: Any) -> bool:
        return isinstance(v, (int, float, np.number)) and not isinstance(v, bool) and bool(np.isfinite(v))

    if not keys or any(finite(metrics.get(k)) for k in keys):
        return ""
    return f"no metric could be computed ({', '.join(keys)}: none finite)"


def unscored_failed(track: Track, metrics: dict[str, Any]) -> dict[str, Any]:
    """``metrics``, failed with :func:`unscored_reason` (before the scorer's own note, if any)
    when it scored nothing: a record without a figure is never "0 failed"."""
    reason = "" if metrics.get("failed") else unscored_reason(track, metrics)
    if not reason:
        return metrics
    note = metrics.get("failed_reason") or ""
    return {**metrics, "failed": True, "failed_reason": f"{reason}; {note}" if note else reason}


@dataclass(frozen=True)
class _Job:
    track: Any
    plan: EpisodePlan
    pipelines: tuple[PipelineRun, ...]
    versions: dict[str, str]
    recording: str | None = None  # --rerun: write this episode's recording there (from a worker too)


RERUN_EVERY_S = 0.1  # a recording's online estimates, at most this often


def _run_job(job: _Job) -> tuple[str, list[dict[str, Any]], dict[str, Any] | None]:
    """Simulate an episode and run every pipeline on it; a track that streams (``stream``, see
    :class:`~.tracks.spec.Track`) hands its frames to the pipelines as they are produced.

    With ``job.recording`` the episode's rerun recording is written from these very frames and
    estimates (a fourth item: :func:`_recording_result`), unless the track streams: a stream's
    frames are gone once read (holding them for it would undo the streaming), and
    :func:`rerun_first_episode` simulates it again instead."""
    plan, track = job.plan, job.track
    stream = getattr(track, "stream", None)
    t0 = time.perf_counter()
    try:
        episode = stream(plan.scenario, plan.seed) if stream is not None else track.simulate(plan.scenario, plan.seed)
    except Exception as e:  # scored as a failure of every pipeline; the run goes on
        return _failed_job(job, f"simulation raised {type(e).__name__}: {e}", time.perf_counter() - t0)
    sim_wall = time.perf_counter() - t0
    harness: dict[str, str] = {}
    scoring = scoring_of(track, plan.scenario)
    every = None
    if isinstance(episode, EpisodeStream):
        timed = _TimedFrames(episode.frames)
        episode = dataclasses.replace(episode, frames=timed)
        try:
            estimates, metrics, walls, _ = run_pipelines(track, episode, job.pipelines, scoring=scoring, scorer_errors=harness)
        except StreamError as e:
            return _failed_job(job, str(e), sim_wall + timed.wall_s)
        sim_wall += timed.wall_s
        episode = episode.finish()
    else:
        every = RERUN_EVERY_S if job.recording is not None else None
        estimates, metrics, walls, timelines = run_pipelines(track, episode, job.pipelines, scoring=scoring,
                                                             scorer_errors=harness, timeline_every_s=every)  # fmt: skip
    figure = None
    if plan.case.figure:
        try:
            figure = track.figure_data(episode, estimates, scoring)
        except Exception:  # a figure is a convenience; never lose the episode's scores to it
            figure = None
    records = _records(job, metrics, walls, sim_wall, harness)
    if every is not None:  # held whole, not streamed: the recording from these frames
        return plan.key, records, figure, _recording_result(track, episode, estimates, timelines, str(job.recording), scoring)
    return plan.key, records, figure


def _recording_result(track: Track, episode: Any, estimates: dict[str, Any], timelines: dict[str, list], path: str,
                      scoring: Mapping[str, Any]) -> dict[str, str]:  # fmt: skip
    """``{"path": ...}`` of the recording written, or ``{"error": ...}`` (plain strings: it
    comes back from a worker)."""
    try:
        return {"path": str(write_rerun(track, episode, estimates, timelines, path, scoring))}
    except FolderError as e:
        return {"error": str(e)}


def _failed_job(job: _Job, reason: str, sim_wall: float = 0.0) -> tuple[str, list[dict[str, Any]], None]:
    """The records of an episode the harness could not run (simulation raised, worker died)."""
    metrics = {p.name: job.track.failed_metrics(None, reason) for p in job.pipelines}
    walls = {p.name: 0.0 for p in job.pipelines}
    return job.plan.key, _records(job, metrics, walls, sim_wall, {p.name: reason for p in job.pipelines}), None


def _records(
    job: _Job, metrics: dict[str, dict[str, Any]], walls: dict[str, float], sim_wall: float, harness: dict[str, str]
) -> list[dict[str, Any]]:
    plan, track = job.plan, job.track
    base = {
        "track": track.name,
        "suite": plan.suite,
        "episode": plan.key,
        "case": plan.case.name,
        "group": plan.case.group,
        "scenario": plan.scenario,
        "seed": plan.seed,
        "run_seed": plan.run_seed,
    }
    records = [
        {
            **base,
            "pipeline": p.name,
            "config": p.config_dict(),
            "metrics": metrics[p.name],
            "versions": job.versions,
            "wall_s": walls[p.name],
            "sim_wall_s": sim_wall,
            **({} if p.deterministic else {"deterministic": False}),
            **({"harness_error": harness[p.name]} if p.name in harness else {}),
        }
        for p in job.pipelines
    ]
    return json_safe(records)


# ---------------------------------------------------------------- the run


def execute(
    plan: RunPlan,
    out_dir: str | os.PathLike,
    *,
    jobs: int = 1,
    resume: bool = False,
    on_start: Callable[[int, int], None] | None = None,
    on_episode: Callable[[str, list[dict[str, Any]]], None] | None = None,
    executor: Any = None,
    recording: str | os.PathLike | None = None,
) -> RunOutcome:
    """Run the plan into ``out_dir`` (see the module docstring).

    ``recording`` (``--rerun``): the first episode, when this run runs it on this machine, also
    writes its rerun recording there (``RunOutcome.recording``, or ``recording_error``); else
    ``RunOutcome.recording`` stays None (:func:`rerun_first_episode` makes it).

    ``executor``: None runs the episodes in this process (``jobs`` 1) or the local pool; else
    an object with ``run(jobs, work, finish, on_lost)`` and ``describe()`` (a connected
    :class:`.ray_executor.RayExecutor`), which gets every episode, whatever ``jobs`` says.

    One writer per run folder: the folder's lock (:func:`.out_paths.exclusive_lock`) is held
    for the whole run, and a second writer gets FolderError before anything runs.
    ``on_start(n_to_run, n_skipped)`` and ``on_episode(key, records)`` report progress.
    KeyboardInterrupt propagates after the finished episodes are on disk; so does FolderError
    when the records cannot be written (disk full), the file cut back to whole episodes. An
    episode's figure is written after its records, and a figure that cannot be written costs
    only itself (``RunOutcome.figure_errors``).
    """
    jobs = check_jobs(jobs)
    with run_folder(plan, out_dir, resume=resume, executor=executor_entry(executor, jobs)) as out:
        return _execute(plan, out, jobs, on_start, on_episode, executor, recording)


def check_jobs(jobs: Any) -> int:
    jobs = int(coerce_like("jobs", jobs, 1))
    if jobs < 1:
        raise ConfigError("jobs", jobs, "jobs >= 1")
    return jobs


def executor_entry(executor: Any, jobs: int) -> dict[str, Any]:
    """What ``run_config.json`` says ran the episodes (``executor``)."""
    return executor.describe() if executor is not None else {"name": "local" if jobs == 1 else "pool", "jobs": jobs}


def _execute(
    plan: RunPlan,
    out: Path,
    jobs: int,
    on_start: Callable[[int, int], None] | None,
    on_episode: Callable[[str, list[dict[str, Any]]], None] | None,
    executor: Any = None,
    recording: str | os.PathLike | None = None,
) -> RunOutcome:
    writer = TrackWriter(plan, out, on_episode)
    if on_start:
        on_start(len(writer.todo), len(writer.outcome.skipped))
    job_list = writer.jobs(recording if executor is None else None)  # a Ray worker may be on another machine
    if job_list:
        setup_pipelines(plan.pipelines)
    if executor is not None:
        executor.run(job_list, _run_job, writer.finish, _failed_job)
    elif jobs == 1 or len(job_list) <= 1:
        for job in job_list:
            writer.finish(*_run_job(job))
    else:
        _run_pool(job_list, jobs, writer.finish)
    return writer.close()


class TrackWriter:
    """The driver's side of one plan's run folder (already prepared, its lock held): which
    episodes are left, and each finished episode's records (appended at once) and figure."""

    def __init__(self, plan: RunPlan, out: Path, on_episode: Callable[[str, list[dict[str, Any]]], None] | None = None) -> None:
        self.plan, self.results, self.on_episode = plan, out / RESULTS_FILE, on_episode
        done = {r["episode"] for r in read_records(self.results)}
        self.todo = [e for e in plan.episodes if e.key not in done]
        self.outcome = RunOutcome(out, skipped=[e.key for e in plan.episodes if e.key in done])

    def jobs(self, recording: str | os.PathLike | None = None) -> list[_Job]:
        """The jobs of the episodes left; with ``recording``, the plan's first episode (if it is
        left) writes its rerun recording there."""
        vers, first = versions(), self.plan.episodes[0].key if self.plan.episodes else None
        rec = None if recording is None else str(recording)
        return [_Job(self.plan.track, e, tuple(self.plan.pipelines), vers, rec if e.key == first else None) for e in self.todo]

    def finish(self, key: str, records: list[dict[str, Any]], figure: dict[str, Any] | None,
               recording: dict[str, str] | None = None) -> None:  # fmt: skip
        append_records(self.results, records)  # the records first: a figure is a convenience
        self.outcome.ran.append(key)
        if recording is not None:
            self.outcome.recording = Path(recording["path"]) if "path" in recording else None
            self.outcome.recording_error = recording.get("error")
        if figure is not None:
            try:
                save_figure(self.outcome.out_dir, key, figure)
            except OSError as e:
                self.outcome.figure_errors.append(f"{key}: {e.strerror or e}")
        if self.on_episode:
            self.on_episode(key, records)

    def close(self) -> RunOutcome:
        """The outcome, with every record of the folder (those kept from before too)."""
        self.outcome.records = sort_records(read_records(self.results), [p.name for p in self.plan.pipelines])
        return self.outcome


def setup_pipelines(pipelines: Sequence[PipelineRun]) -> None:
    """Run each pipeline's ``setup(config)`` (its registry entry's; once, in this process, before
    any episode: what it prepares, e.g. a file in the user's cache, is then there for every worker
    of this machine)."""
    for p in pipelines:
        if p.setup:
            load_entry_point(p.setup)(p.config)


def _run_pool(job_list: list[_Job], jobs: int, finish: Callable[..., None]) -> None:
    run_pool(job_list, jobs, _run_job, finish, _failed_job)


def harness_errors(records: Sequence[Mapping[str, Any]]) -> list[str]:
    """``"episode pipeline: reason"`` of the records whose simulation or scorer raised."""
    return [f"{r['episode']} {r['pipeline']}: {r['harness_error']}" for r in records if r.get("harness_error")]


def rerun_first_episode(plan: RunPlan, path: str | os.PathLike, *, every_s: float = RERUN_EVERY_S) -> Path:
    """Simulate the plan's first episode again and write a rerun recording of it (what a run
    does when its own first episode could not be recorded: streamed, run elsewhere, or kept
    from before a resume)."""

    first = plan.episodes[0]
    episode = plan.track.simulate(first.scenario, first.seed)
    scoring = scoring_of(plan.track, first.scenario)
    estimates, _, _, timelines = run_pipelines(plan.track, episode, plan.pipelines, scoring=scoring, timeline_every_s=every_s)
    return write_rerun(plan.track, episode, estimates, timelines, path, scoring)


def write_rerun(track: Track, episode: Any, estimates: dict[str, Any], timelines: dict[str, list], path: str | os.PathLike,
                scoring: Mapping[str, Any] | None) -> Path:  # fmt: skip
    """The track's rerun recording of an episode, its pipelines' online ``timelines`` each
    ended by the final estimate; FolderError, nothing half-written, when it cannot be written."""
    series = {n: timelines[n] + [(float(episode.frames[-1].stamp_s), e)] for n, e in estimates.items()}
    try:
        return track.write_recording(episode, series, Path(path), scoring)
    except OSError as e:  # disk full: no half-written recording
        Path(path).unlink(missing_ok=True)
        raise FolderError(f"{path}: cannot be written ({e.strerror or e})") from None


def load_case(track: Track, suite: str, name: str, run_seed: int = 0) -> Case:
    """A case of a suite by name, as drawn under ``run_seed`` in a drawn suite (UnknownNameError
    lists the valid ones)."""
    cases = {c.name: c for c in track.cases(suite, run_seed)}
    if name not in cases:
        raise UnknownNameError(f"case of suite {suite!r}", name, cases)
    return cases[name]
