"""`exobench bench rtls` and `bench sim`: the RTLS update cost, the stairs simulator's speed.

- :func:`bench_rtls`: on the case-A stream (simulated, or a recorded session), the points the
  RTLS pipeline put into each surface are replayed in arrival order twice: once through the
  recursive plane (:class:`exobench.perception.stairs.rtls.RtlsPlane`: add, then read normal and
  sigma), once by refitting a batch total least squares plane (SVD of all the surface's points
  so far) after each point; the same is done with all the points as one sequence, where the
  batch cost grows with the count. Medians per point and their ratios come from the same run.
- :func:`bench_sim`: real-time factor of :func:`exobench.envs.sim.simulate_stairs` (simulated
  seconds per wall-clock second) with every sensor of the scenario on.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from exobench.core.episode import Episode
from exobench.core.kinds import frame_kind

PAPER_MS_PER_POINT = {"rtls": 0.685, "rtls-htvr": 0.427}  # Cortex-M4 at 168 MHz, Sec. V-B


def case_a_episode(seed: int = 0) -> Episode:
    from ..tracks.stairs.track import CASES, StairsTrack

    return StairsTrack().simulate(dict(CASES["A"]), seed)


def _surface_streams(episode: Episode) -> tuple[list[np.ndarray], np.ndarray]:
    from exobench.perception.stairs import RtlsStairs

    pipe = RtlsStairs()
    pipe.reset(episode.calibration)
    for frame in episode.frames:
        pipe.process(frame)
    est = pipe.finalize()
    streams = []
    for idx in sorted({a.surface_index for a in est.assignments if a.surface_index >= 0}):
        pts = np.array([a.point for a in est.assignments if a.surface_index == idx and np.all(np.isfinite(a.point))])
        if len(pts) >= 3:
            streams.append(pts)
    return streams, np.asarray(est.compute_time_s, dtype=float)


def _time_sequence(pts: np.ndarray, first: int = 0) -> tuple[list[float], list[float], list[float]]:
    """Per point from ``first`` on, seconds of: the recursive update (eq. 15-16 + eigen step);
    a batch refit on all points so far with numpy (centre + SVD); and the same batch refit in
    the recursion's own scalar arithmetic (re-accumulating ``V`` and ``e`` over all points,
    as a device without the recursion would). The points before ``first`` are added untimed."""
    from exobench.perception.stairs.rtls import RtlsPlane

    rec_t, batch_t, scalar_t = [], [], []
    plane = RtlsPlane()
    for p in pts[:first]:
        plane.add(p)
    for k in range(first, len(pts)):
        t0 = time.perf_counter()
        plane.add(pts[k])
        _ = plane.normal, plane.sigma_m
        rec_t.append(time.perf_counter() - t0)
        t0 = time.perf_counter()
        P = pts[: k + 1]
        c = P.mean(axis=0)
        _, s, vt = np.linalg.svd(P - c, full_matrices=False)
        _ = vt[-1], s[-1] / np.sqrt(k + 1)
        batch_t.append(time.perf_counter() - t0)
        t0 = time.perf_counter()
        refit = RtlsPlane()
        for p in P:
            refit.add(p)
        _ = refit.normal, refit.sigma_m
        scalar_t.append(time.perf_counter() - t0)
    return rec_t, batch_t, scalar_t


def _scaling(sizes: tuple[int, ...] = (100, 1000, 10000), probes: int = 20) -> dict[str, dict[str, float]]:
    """Cost of adding the N-th point: recursion vs batch refit, for surfaces of N points.

    A batch refit is O(N) per point, the recursion O(1): the ratio grows with the number of
    points a surface has collected (the protocol's surfaces hold about 10-100; a slow approach,
    a faster sensor or a longer stair hold more).
    """
    rng = np.random.default_rng(0)
    out = {}
    for n in sizes:
        pts = np.column_stack([rng.uniform(0, 0.3, n), rng.uniform(-0.1, 0.1, n), 0.162 + rng.normal(0, 1.5e-3, n)])
        rec, bat, sca = _time_sequence(pts, first=n - probes)
        r, b, c = (float(np.median(v) * 1e6) for v in (rec, bat, sca))
        out[str(n)] = {"rtls_us": r, "batch_us": b, "batch_over_rtls": b / r, "scalar_batch_over_rtls": c / r}
    return out


def bench_rtls(episode: Episode | None = None, *, repeats: int = 5) -> dict[str, Any]:
    """Median time per point of the recursive update vs a batch refit, and their ratio.

    Two sequences: each surface's points in arrival order (what the estimator maintains), and
    all used points of the stream as one sequence (where the batch cost grows with N).
    """
    episode = episode if episode is not None else case_a_episode()
    streams, pipeline_times = _surface_streams(episode)
    if not streams:
        return {"points": 0, "error": "the RTLS pipeline assigned no points on this stream"}
    whole = np.vstack(streams)
    rec_t, batch_t, scalar_t, rec_w, batch_w, scalar_w = [], [], [], [], [], []
    for _ in range(repeats):
        for pts in streams:
            r, b, c = _time_sequence(pts)
            rec_t += r
            batch_t += b
            scalar_t += c
        r, b, c = _time_sequence(whole)
        rec_w += r
        batch_w += b
        scalar_w += c
    med = {
        k: float(np.median(v) * 1e6)
        for k, v in (("r", rec_t), ("b", batch_t), ("c", scalar_t), ("rw", rec_w), ("bw", batch_w), ("cw", scalar_w))
    }
    return {
        "points": int(len(whole)),
        "surfaces": len(streams),
        "repeats": repeats,
        "rtls_update_median_us": med["r"],
        "batch_tls_refit_median_us": med["b"],
        "batch_over_rtls": med["b"] / med["r"],
        "scalar_batch_refit_median_us": med["c"],
        "scalar_batch_over_rtls": med["c"] / med["r"],
        "stream_rtls_update_median_us": med["rw"],
        "stream_batch_tls_refit_median_us": med["bw"],
        "stream_batch_over_rtls": med["bw"] / med["rw"],
        "stream_scalar_batch_over_rtls": med["cw"] / med["rw"],
        "rtls_pipeline_median_us": float(np.median(pipeline_times) * 1e6) if pipeline_times.size else float("nan"),
        "scaling_by_surface_points": _scaling(),
        "paper_ms_per_point_cortex_m4": PAPER_MS_PER_POINT,
    }


def bench_sim(scenario: dict[str, Any] | None = None, seed: int = 0, *, repeats: int = 5) -> dict[str, Any]:
    """Real-time factor of the stairs episode (case A unless ``scenario`` is given).

    The first episode of a process builds and compiles the world (cold); later episodes on the
    same staircase reuse the compiled model, as a suite does. Both are reported; the warm figure
    is the median over ``repeats`` episodes with different seeds.
    """
    from ..tracks.stairs.track import CASES, StairsTrack

    track = StairsTrack()
    values = track.validate_scenario(scenario if scenario is not None else dict(CASES["A"]))
    walls = []
    for k in range(1 + repeats):
        t0 = time.perf_counter()
        episode = track.simulate(values, seed + k)
        walls.append(time.perf_counter() - t0)
    stamps = [f.stamp_s for f in episode.frames]
    sim_s = float(max(stamps) - min(stamps)) if stamps else 0.0
    counts: dict[str, int] = {}
    for f in episode.frames:
        counts[frame_kind(f)] = counts.get(frame_kind(f), 0) + 1
    warm = float(np.median(walls[1:]))
    return {
        "simulated_s": sim_s,
        "cold_wall_s": walls[0],
        "cold_real_time_factor": sim_s / walls[0],
        "warm_wall_s": warm,
        "real_time_factor": sim_s / warm,
        "frames": counts,
        "frames_per_s": len(stamps) / warm,
        "scenario": values,
        "seed": seed,
    }
