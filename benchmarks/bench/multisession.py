"""`exobench bench multisession`: the peak memory of LT-Exosense merging two and ten sessions.

Issue 28's target: peak memory merging ten sessions at most 1.5 times that of merging two. One
episode of ten short sessions of the quick suite's office (:data:`SESSION_COUNTS`; day 0, then
nine sessions of day 1 with the quick suite's stack of boxes, each :data:`BENCH_DISTANCE_M` along
its walk) is streamed once. Per pipeline (``lt-exosense``, ``lt-exosense-dufomap``) one instance
is fed the frames of the first two sessions and another all ten, in lockstep, so the ten
sessions are simulated once. After the stream each instance merges (``finalize``) in turn, and
each merge gives:

- ``peak_memory_mb``: the pipeline's own figure, the peak of the allocations :mod:`tracemalloc`
  traces during the merge (NumPy's and Python's, not OpenCV's or OctoMap's own heaps);
- ``peak_rss_mb``: this process's peak resident memory during the merge (Linux's ``VmHWM``,
  reset before the merge through ``/proc/self/clear_refs``) and ``rss_before_mb`` (``VmRSS``
  before it): the untraced heaps show here; NaN where the kernel offers neither;
- ``merge_time_s``, ``keyframes``, ``inter_edges``, ``sessions_merged``.

``ratio_peak_memory`` is ten's ``peak_memory_mb`` over two's, ``ratio_rss_growth`` the same of
``peak_rss_mb - rss_before_mb`` (the resident memory the merge added; the peak itself is mostly
the simulator's and the libraries', the same for both).
"""

from __future__ import annotations

import gc
import importlib
import time
from pathlib import Path
from typing import Any

from exobench.core.frames import SessionStart
from exobench.mapping.multisession.change import load_stage

BENCH_DISTANCE_M = 2.0
SESSION_COUNTS = (2, 10)
PIPELINES = ("lt-exosense", "lt-exosense-dufomap")
_STATUS = Path("/proc/self/status")
_CLEAR_REFS = Path("/proc/self/clear_refs")


def bench_scenario(n_sessions: int = max(SESSION_COUNTS), distance_m: float = BENCH_DISTANCE_M) -> dict[str, Any]:
    """The quick suite's case with ``n_sessions`` sessions of ``distance_m`` (day 0, then day 1)."""
    from exobench.benchmarks.tracks.multisession.track import QUICK

    sessions = ";".join(f"{0 if i == 0 else 1}:office0" for i in range(n_sessions))
    return {**QUICK, "sessions": sessions, "max_distance_m": float(distance_m)}


def _status_mb(field: str) -> float:
    try:
        for line in _STATUS.read_text().splitlines():
            if line.startswith(field + ":"):
                return int(line.split()[1]) / 1024.0  # kB
    except OSError:
        pass
    return float("nan")


def _reset_peak_rss() -> bool:
    try:
        _CLEAR_REFS.write_text("5")  # 5: reset the peak resident set size (proc(5))
    except OSError:
        return False
    return True


def _merge(pipe: Any) -> dict[str, Any]:
    gc.collect()
    before = _status_mb("VmRSS")
    reset = _reset_peak_rss()
    t0 = time.perf_counter()
    est = pipe.finalize()
    wall = time.perf_counter() - t0
    peak = _status_mb("VmHWM") if reset else float("nan")
    return {
        "sessions_merged": len(est.sessions), "keyframes": int(sum(len(s) for s in est.keyframe_stamps_s)),
        "inter_edges": len(est.inter_edges), "separate_sessions": len(est.separate_sessions),
        "merge_time_s": float(est.merge_time_s), "finalize_wall_s": wall, "peak_memory_mb": float(est.peak_memory_mb),
        "rss_before_mb": before, "peak_rss_mb": peak,
    }  # fmt: skip


def bench_multisession(seed: int = 0, distance_m: float = BENCH_DISTANCE_M,
                       pipelines: tuple[str, ...] = PIPELINES) -> dict[str, Any]:
    """Peak memory of each pipeline merging two and ten sessions of one office (module docstring)."""
    from exobench.benchmarks.registry import default_registry
    from exobench.benchmarks.runner import episode_seed
    from exobench.benchmarks.tracks import get_track

    track = get_track("multisession")
    lo, hi = SESSION_COUNTS
    scenario = track.validate_scenario(bench_scenario(hi, distance_m))
    stream = track.stream(scenario, episode_seed(seed, "bench-multisession"))
    registry = default_registry()
    pipes = {(name, n): registry.make(name) for name in pipelines for n in SESSION_COUNTS}
    for pipe in pipes.values():
        pipe.reset(stream.calibration)
    t0 = time.perf_counter()
    started = 0
    for frame in stream.frames:
        started += isinstance(frame, SessionStart)
        for (_, n), pipe in pipes.items():
            if started <= n:
                pipe.process(frame)
    sim_s = time.perf_counter() - t0
    # the modules the merges import, before any merge's RSS window opens: else the first merge's
    # RSS growth holds them (the pipeline's traced peak leaves them out on its own)
    importlib.import_module("sklearn.cluster")
    for pipe in pipes.values():
        load_stage(pipe.config.change.kind)
    out: dict[str, Any] = {"seed": seed, "session_distance_m": float(distance_m), "sessions_streamed": started,
                           "stream_s": sim_s}  # fmt: skip
    for name in pipelines:
        figures = {}
        for n in SESSION_COUNTS:
            figures[f"sessions_{n}"] = _merge(pipes.pop((name, n)))
            gc.collect()
        a, b = figures[f"sessions_{lo}"], figures[f"sessions_{hi}"]
        grow = {k: f["peak_rss_mb"] - f["rss_before_mb"] for k, f in figures.items()}
        figures["ratio_peak_memory"] = b["peak_memory_mb"] / a["peak_memory_mb"] if a["peak_memory_mb"] else float("nan")
        g_lo, g_hi = grow[f"sessions_{lo}"], grow[f"sessions_{hi}"]
        figures["ratio_rss_growth"] = g_hi / g_lo if g_lo > 0 else float("nan")
        out[name] = figures
    return out
