"""Micro-benchmarks behind `exobench bench`: the RTLS update cost, the simulator's speed.

- :func:`bench_rtls`: on the case-A stream (simulated, or a recorded session), the points the
  RTLS pipeline put into each surface are replayed in arrival order twice: once through the
  recursive plane (:class:`exobench.perception.stairs.rtls.RtlsPlane`: add, then read normal and
  sigma), once by refitting a batch total least squares plane (SVD of all the surface's points
  so far) after each point; the same is done with all the points as one sequence, where the
  batch cost grows with the count. Medians per point and their ratios come from the same run.
- :func:`bench_sim`: real-time factor of :func:`exobench.envs.sim.simulate_stairs` (simulated
  seconds per wall-clock second) with every sensor of the scenario on.
- :func:`bench_lidar`: one full VLP-16 sweep of the default office from the exoskeleton's
  ``lidar_trunk`` site, by exobench's :class:`exobench.envs.sensors.lidar.LidarSensor` (static, and
  walking at 0.5 m/s) and by the ``mujoco-lidar`` package's CPU backend (``MjLidarCPU``) on the
  same model, pose and ray directions; throughput and the exobench / mujoco-lidar ratio come
  from the same run.
"""

from __future__ import annotations

import dataclasses
import time
from typing import Any

import numpy as np

from exobench.core.episode import Episode
from exobench.core.frames import frame_kind

PAPER_MS_PER_POINT = {"rtls": 0.685, "rtls-htvr": 0.427}  # Cortex-M4 at 168 MHz, Sec. V-B


def case_a_episode(seed: int = 0) -> Episode:
    from .tracks.stairs.track import CASES, StairsTrack

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
    from .tracks.stairs.track import CASES, StairsTrack

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


WALK_SPEED_M_S = 0.5


def _interleaved_medians_s(fns: dict[str, Any], repeats: int) -> dict[str, float]:
    """Median wall time of each ``fn()`` over ``repeats`` rounds after one untimed warm-up round.

    The functions run in turn within each round, so a change of machine load during the run
    affects all of them alike (the ratios come from the same rounds).
    """
    for fn in fns.values():
        fn()
    walls: dict[str, list[float]] = {k: [] for k in fns}
    for _ in range(max(1, repeats)):
        for key, fn in fns.items():
            t0 = time.perf_counter()
            fn()
            walls[key].append(time.perf_counter() - t0)
    return {k: float(np.median(v)) for k, v in walls.items()}


def _throughput(n_rays: int, n_returns: int, wall_s: float) -> dict[str, float | int]:
    return {
        "ms_per_sweep": wall_s * 1e3,
        "rays_per_s": n_rays / wall_s,
        "returns_per_s": n_returns / wall_s,
        "returns": int(n_returns),
    }


def bench_lidar(seed: int = 0, repeats: int = 5) -> dict[str, Any]:
    """Time one VLP-16 sweep of the default office: exobench's LiDAR vs mujoco-lidar's CPU backend.

    The exoskeleton stands at the office start; the sensor is the ``lidar_trunk`` site. Both
    simulators cast the same rays (``LidarPattern.vlp16().rays(0.0).dirs_s``, converted to
    mujoco-lidar's azimuth/elevation angles) from the same pose, in the same geom groups, with
    the sensor's own body excluded. Wall times are medians over ``repeats`` sweeps after one
    warm-up. Throughput is in rays cast per second (the pattern's points; equal for both, so the
    ratio is the inverse ratio of the sweep times) and in returns per second.

    What each side does per sweep: exobench draws noise, follows glass and mirrors, computes
    the return signal, drops weak and out-of-range (< 0.9 m) returns, quantises ranges and labels
    every point with its ground-truth surface; mujoco-lidar casts the rays and returns the hit
    points (no noise, no range limits but its cutoff, glass is an opaque surface). Both cast with
    ``mj_multiRay``; exobench on its private zoned copy of the ray-visible geoms (built once per
    sensor, not timed), near geoms first, with the same hits as one pass on the model
    (``LidarConfig.zoned_cast``, ``cast_near_m``); mujoco-lidar in one pass on the model. Walking, the
    sensor moves at 0.5 m/s along the user's heading and exobench casts each 1 ms window from
    its own pose; mujoco-lidar has no motion model and is timed once per sweep from one pose.
    If ``mujoco_lidar`` cannot be imported, ``result["mujoco_lidar"]`` says so and only the
    exobench figures are given.
    """
    import mujoco

    from exobench.envs.sensors.lidar import LidarConfig, LidarSensor
    from exobench.models.exo_spec import ExoSpec
    from exobench.models.office import build_office
    from exobench.models.worlds import compose

    world = build_office()
    scene = compose(world, ExoSpec())
    model, truth = scene.model, scene.truth
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    site = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, "lidar_trunk")
    T0 = np.eye(4)
    T0[:3, :3] = np.asarray(data.site_xmat[site]).reshape(3, 3)
    T0[:3, 3] = data.site_xpos[site]
    pelvis = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "pelvis")
    heading_w = np.asarray(data.xmat[pelvis]).reshape(3, 3)[:, 0].copy()
    heading_w[2] = 0.0
    heading_w /= np.linalg.norm(heading_w)

    def walking(times_s: np.ndarray) -> np.ndarray:
        T = np.repeat(T0[None], len(times_s), axis=0)
        T[:, :3, 3] += (WALK_SPEED_M_S * np.asarray(times_s, dtype=float))[:, None] * heading_w
        return T

    config = LidarConfig()
    pat = config.pattern
    dirs_s = pat.rays(0.0).dirs_s
    n_rays = len(dirs_s)
    poses: dict[str, Any] = {"static": T0, "walking": walking, "static_one_thread": T0}
    # exobench casts on every CPU by default; mujoco-lidar's CPU backend uses one, so the
    # single-thread figure is reported beside it for a per-core comparison
    one = dataclasses.replace(config, cast_threads=1)
    sensors = {name: LidarSensor("lidar_trunk", one if name.endswith("one_thread") else config, model, seed) for name in poses}

    def exo_sweep(name: str) -> Any:
        return lambda: sensors[name].scan(model, data, poses[name], 0.0, truth)

    fns = {name: exo_sweep(name) for name in poses}
    result: dict[str, Any] = {
        "scene": "office (default OfficeParams), exoskeleton standing at the start",
        "sensor": "lidar_trunk",
        "pattern": pat.name,
        "rays_per_sweep": n_rays,
        "sweep_period_s": pat.sweep_period_s,
        "repeats": repeats,
        "seed": seed,
        "walk_speed_m_s": WALK_SPEED_M_S,
    }
    lidar = None
    try:
        from mujoco_lidar.core_cpu import MjLidarCPU
    except Exception as e:  # noqa: BLE001 - any import failure means "not available"
        result["mujoco_lidar"] = f"not installed: {type(e).__name__}: {e} (pip install 'exobench[bench]')"
    else:
        lidar = MjLidarCPU(model, cutoff_dist=pat.max_range_m + 1.0, geomgroup=sensors["static"].group,
                           bodyexclude=sensors["static"].body_exclude)  # fmt: skip
        lidar.update(data)
        theta = np.arctan2(dirs_s[:, 1], dirs_s[:, 0])
        phi = np.arcsin(np.clip(dirs_s[:, 2], -1.0, 1.0))

        def mjl_sweep() -> np.ndarray:
            lidar.trace_rays(T0, theta, phi)
            return np.asarray(lidar.get_distances())

        fns["mujoco_lidar"] = mjl_sweep
    walls = _interleaved_medians_s(fns, repeats)

    exo: dict[str, Any] = {}
    for name in poses:
        out = fns[name]()
        n_ret = 0 if out is None else len(out[0].points_xyz)
        exo[name] = _throughput(n_rays, n_ret, walls[name])
        if out is not None:
            exo[name]["returns_genuine"] = int(np.count_nonzero(out[1].genuine))
            exo[name]["returns_via_glass_or_mirror"] = int(np.count_nonzero(out[1].via_geom_id >= 0))
    result["exobench"] = exo
    result["meets_50ms_target"] = bool(max(exo[k]["ms_per_sweep"] for k in ("static", "walking")) < 50.0)
    if lidar is None:
        return result

    from importlib.metadata import version

    dist = fns["mujoco_lidar"]()
    hits = dist > 0.0
    mjl = _throughput(n_rays, int(np.count_nonzero(hits)), walls["mujoco_lidar"])
    mjl["returns_within_range_limits"] = int(np.count_nonzero(hits & (dist >= pat.min_range_m) & (dist <= pat.max_range_m)))
    result["mujoco_lidar"] = {"version": version("mujoco-lidar"), "backend": "cpu (MjLidarCPU)", **mjl}
    result["ratio_static"] = exo["static"]["rays_per_s"] / mjl["rays_per_s"]
    result["ratio_walking"] = exo["walking"]["rays_per_s"] / mjl["rays_per_s"]
    result["ratio_static_one_thread"] = exo["static_one_thread"]["rays_per_s"] / mjl["rays_per_s"]
    result["meets_ratio_target"] = bool(result["ratio_static"] >= 1.0)
    return result


# ---------------------------------------------------------------- locomotion (seeds/002)

LOCOMOTION_BENCH_SCENARIO: dict[str, Any] = {
    "terrain": "stairs", "riser_m": 0.15, "mount": "head", "pattern": "walk", "n_steps": 3, "approach_m": 1.5,
    "landing_m": 1.2, "rate_hz": 15.0, "width_px": 640, "height_px": 480,
}  # fmt: skip
PAPER_MS_PER_PREDICTION = 31.0  # Tab. IV: D-VIO time per frame; Sec. III-A: prediction within 34 ms
RENDER_POSES = 8


def _render_fps(terrain: str, seed: int, repeats: int, segmentation: bool = False) -> dict[str, Any]:
    """RGB-D frames per second at 640x480 (render colour and depth, with ``segmentation`` also
    the geom-id truth, then the depth noise model: :meth:`RgbdCamera.capture`) of the head camera
    on one course, the walker standing on the level approach facing the course at RENDER_POSES
    positions and headings."""
    import mujoco

    from exobench.envs.sensors.rgbd import RgbdCamera, RgbdConfig
    from exobench.envs.sim.compose import compose_rig
    from exobench.envs.sim.scenarios.course import LocomotionScenario
    from exobench.envs.sim.scenarios.course_world import build_locomotion_world

    sc = LocomotionScenario.from_dict({"terrain": terrain, "width_px": 640, "height_px": 480})
    world, wps = build_locomotion_world(sc)
    scene = compose_rig(world, sc.exo_spec(), (("imu_head", "rgbd_head"),))
    model = scene.model
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    root = int(model.jnt_qposadr[0])
    x0 = data.qpos[root : root + 3].copy()
    q0 = data.qpos[root + 3 : root + 7].copy()
    cam = RgbdCamera("rgbd_head", RgbdConfig(width_px=640, height_px=480, segmentation=segmentation), model, seed)
    try:
        cam.capture(model, data, 0.0)  # warm-up: GL context and buffers
        walls, valid = [], []
        for r in range(max(1, repeats)):
            for k in range(RENDER_POSES):
                yaw = np.deg2rad(-20.0 + 40.0 * k / max(1, RENDER_POSES - 1))
                dq = np.array([np.cos(yaw / 2), 0.0, 0.0, np.sin(yaw / 2)])
                q = np.empty(4)
                mujoco.mju_mulQuat(q, dq, q0)
                data.qpos[root : root + 3] = x0 + np.array([0.8 * k / RENDER_POSES, 0.0, 0.0])
                data.qpos[root + 3 : root + 7] = q
                mujoco.mj_forward(model, data)
                t0 = time.perf_counter()
                frame, _ = cam.capture(model, data, (r * RENDER_POSES + k) / 30.0)
                walls.append(time.perf_counter() - t0)
                if frame is not None:
                    valid.append(float(np.mean(frame.depth_m > 0)))
    finally:
        cam.close()
    med = float(np.median(walls))
    return {"frames": len(walls), "ms_per_frame": med * 1e3, "frames_per_s": 1.0 / med, "valid_depth_fraction": float(np.mean(valid))}


def _tsdf_fps(episode: Episode, repeats: int) -> dict[str, Any]:
    """TSDF integration (eq. 19-22) of every RGB-D frame of ``episode`` at its odometry pose, and
    the ray cast of the smoothed depth at half resolution, on the frames at their full resolution
    (the issue's 640x480 figure; ``terrain-recon`` itself decimates frames wider than
    ``max_work_width_px`` first, which its latency figure includes)."""
    from exobench.core.frames import OdometrySample, RgbdFrame
    from exobench.mapping.locomotion.depth import scale_intrinsics
    from exobench.mapping.tsdf import Tsdf, TsdfConfig

    odom = {round(float(f.stamp_s), 6): np.asarray(f.T_odom_body, dtype=float) for f in episode.frames
            if isinstance(f, OdometrySample)}  # fmt: skip
    pairs = [(f, odom[round(float(f.stamp_s), 6)]) for f in episode.frames
             if isinstance(f, RgbdFrame) and round(float(f.stamp_s), 6) in odom]  # fmt: skip
    if not pairs:
        return {"frames": 0, "error": "no RGB-D frame with an odometry sample at its stamp"}
    h, w = pairs[0][0].depth_m.shape
    integ, cast = [], []
    for _ in range(max(1, repeats)):
        tsdf = Tsdf(TsdfConfig())
        for f, T in pairs:
            t0 = time.perf_counter()
            tsdf.integrate(f.depth_m, f.K, T)
            integ.append(time.perf_counter() - t0)
        K2 = scale_intrinsics(np.asarray(pairs[-1][0].K, dtype=float), 0.5)
        for _, T in pairs[-5:]:
            t0 = time.perf_counter()
            tsdf.raycast_depth(K2, T, w // 2, h // 2)
            cast.append(time.perf_counter() - t0)
    med = float(np.median(integ))
    return {
        "frames": len(pairs), "image_px": f"{w}x{h}", "integrate_ms_per_frame": med * 1e3, "integrate_frames_per_s": 1.0 / med,
        "raycast_ms_half_resolution": float(np.median(cast) * 1e3), "active_blocks": int(tsdf.stats.active_blocks),
    }  # fmt: skip


def _pipeline_latency(name: str, episode: Episode) -> dict[str, Any]:
    """Median and p95 latency per prediction (``ModePrediction.latency_s``) of a registered pipeline."""
    from .registry import default_registry

    pipe = default_registry().make(name)
    pipe.reset(episode.calibration)
    t0 = time.perf_counter()
    for frame in episode.frames:
        pipe.process(frame)
    est = pipe.finalize()
    wall = time.perf_counter() - t0
    lat = np.array([p.latency_s for p in est.predictions if np.isfinite(p.latency_s)], dtype=float)
    ok = np.array([p.latency_s for p in est.predictions if p.status == "ok" and np.isfinite(p.latency_s)], dtype=float)
    return {
        "predictions": int(lat.size),
        "latency_ms_median": float(np.median(lat) * 1e3) if lat.size else float("nan"),
        "latency_ms_p95": float(np.percentile(lat, 95) * 1e3) if lat.size else float("nan"),
        "latency_ms_median_ok": float(np.median(ok) * 1e3) if ok.size else float("nan"),
        "predictions_ok": int(ok.size),
        "wall_s": wall,
    }


def bench_locomotion(seed: int = 0, *, repeats: int = 2, pipelines: tuple[str, ...] = ("terrain-recon",)) -> dict[str, Any]:
    """Speed of the locomotion track at 640x480 (seeds/002 reports 31 ms per frame).

    - ``render``: RGB-D (colour + depth) frames per second of the head camera on the stairs,
      ramp and parallel courses (:func:`_render_fps`); ``render_with_segmentation`` with the
      geom-id truth pass the simulation also renders;
    - ``tsdf``: TSDF integration frames per second on the frames of one episode
      (:data:`LOCOMOTION_BENCH_SCENARIO`: short stair course, head camera, 640x480, 15 Hz),
      plus the half-resolution ray cast;
    - ``latency``: median / p95 ``latency_s`` per prediction of each pipeline on that episode
      (all predictions; ``_ok`` only those with status ok).
    """
    from .tracks.locomotion import LocomotionTrack

    track = LocomotionTrack()
    t0 = time.perf_counter()
    episode = track.simulate(track.validate_scenario(LOCOMOTION_BENCH_SCENARIO), seed)
    sim_wall = time.perf_counter() - t0
    n_rgbd = sum(frame_kind(f) == "rgbd" for f in episode.frames)
    result: dict[str, Any] = {
        "scenario": dict(LOCOMOTION_BENCH_SCENARIO),
        "seed": seed,
        "episode": {"rgbd_frames": n_rgbd, "steps": len(episode.truth.steps), "simulate_wall_s": sim_wall},
        "latency": {name: _pipeline_latency(name, episode) for name in pipelines},
        "tsdf": _tsdf_fps(episode, repeats),
        "render": {t: _render_fps(t, seed, repeats) for t in ("stairs", "ramp", "parallel")},
        "render_with_segmentation": {t: _render_fps(t, seed, repeats, segmentation=True) for t in ("stairs", "ramp", "parallel")},
        "paper_ms_per_prediction": PAPER_MS_PER_PREDICTION,
    }
    return result
