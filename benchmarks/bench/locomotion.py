"""`exobench bench locomotion`: the locomotion track's speed at 640x480 (RGB-D rendering, TSDF
integration and ray casting, per-prediction latency of each pipeline) beside the 31 ms per frame
of seeds/002, and the RGB-D frames per CPU-second of a whole 30 Hz episode against the three-pass
rendering of before (:mod:`.render_baseline`)."""

from __future__ import annotations

import hashlib
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager, nullcontext
from typing import Any

import numpy as np

from exobench.core.episode import Episode
from exobench.core.kinds import frame_kind

LOCOMOTION_BENCH_SCENARIO: dict[str, Any] = {
    "terrain": "stairs", "riser_m": 0.15, "mount": "head", "pattern": "walk", "n_steps": 3, "approach_m": 1.5,
    "landing_m": 1.2, "rate_hz": 15.0, "width_px": 640, "height_px": 480,
}  # fmt: skip
PAPER_MS_PER_PREDICTION = 31.0  # Tab. IV: D-VIO time per frame; Sec. III-A: prediction within 34 ms
RENDER_POSES = 8
EPISODE_RATE_HZ = 30.0  # issue 26: the quick suite's first case at 30 Hz, head camera, 424x240


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


def _rgbd_digest(episode: Episode) -> str:
    """SHA-256 of every RGB-D frame's colour and depth, and of the segmentation truth."""
    from exobench.core.frames import RgbdFrame

    h = hashlib.sha256()
    for f in episode.frames:
        if isinstance(f, RgbdFrame):
            h.update(f.rgb.tobytes())
            h.update(f.depth_m.tobytes())
    for s in episode.truth.segmentation:
        h.update(s.geom_id.tobytes())
        h.update(s.surface_id.tobytes())
    return h.hexdigest()


@contextmanager
def render_stage_clock(cpu_s: dict[str, float], calls: dict[str, int]) -> Iterator[None]:
    """Within the block, each RGB-D frame's stages add their CPU time (``time.process_time``:
    every thread of the process, llvmpipe's included) to ``cpu_s`` and their calls to ``calls``:
    ``scene`` (``mjv_updateScene``), ``depth_pass`` and ``colour_pass`` (``mjr_render`` and
    ``mjr_readPixels`` of each: llvmpipe draws when the pixels are read), ``depth_to_metres``
    and ``noise`` (the depth model)."""
    import mujoco

    from exobench.envs.sensors.rgbd.model import RgbdCamera
    from exobench.envs.sensors.rgbd.render import RgbdRenderer

    segment = int(mujoco.mjtRndFlag.mjRND_SEGMENT)

    def clocked(fn: Callable[..., Any], stage: Callable[..., str]) -> Callable[..., Any]:
        def call(*args: Any) -> Any:
            name = stage(*args)
            t0 = time.process_time()
            try:
                return fn(*args)
            finally:
                cpu_s[name] = cpu_s.get(name, 0.0) + time.process_time() - t0
                calls[name] = calls.get(name, 0) + 1

        return call

    patches: list[tuple[Any, str, Callable[..., str]]] = [
        (mujoco, "mjv_updateScene", lambda *a: "scene"),
        (mujoco, "mjr_render", lambda rect, scene, con: "depth_pass" if scene.flags[segment] else "colour_pass"),
        (mujoco, "mjr_readPixels", lambda rgb, depth, rect, con: "depth_pass" if depth is not None else "colour_pass"),
        (RgbdRenderer, "_metric_depth", lambda *a: "depth_to_metres"),
        (RgbdCamera, "measure", lambda *a: "noise"),
    ]  # fmt: skip
    saved = [(owner, name, getattr(owner, name)) for owner, name, _ in patches]
    try:
        for owner, name, stage in patches:
            setattr(owner, name, clocked(getattr(owner, name), stage))
        yield
    finally:
        for owner, name, fn in saved:
            setattr(owner, name, fn)


def _episode_rgbd_rate(seed: int, repeats: int) -> dict[str, Any]:
    """RGB-D frames per CPU-second (``time.process_time`` around the whole simulation: motion,
    IMU, odometry and the camera) of the locomotion quick suite's first case at 30 Hz, rendered
    by the two-pass renderer and by the three-pass baseline, alternately, ``repeats`` times each
    (the least CPU time of each counts); ``speedup`` is their ratio, ``identical_frames`` whether
    the two gave the same images bit for bit. ``cpu_ms_per_frame_two_pass``: one more two-pass
    run, untimed in the above, with each frame's stages clocked (:func:`render_stage_clock`;
    ``other``: the rest of the simulation, per RGB-D frame)."""
    from ..tracks.locomotion import LocomotionTrack
    from ..tracks.locomotion.track import quick_cases
    from .render_baseline import three_pass_rendering

    track = LocomotionTrack()
    case = quick_cases()[0]
    values = {**case.scenario, "rate_hz": EPISODE_RATE_HZ}
    track.simulate(track.validate_scenario({**values, "duration_cap_s": 2.0, "rate_hz": 1.0}), seed)  # plan, compile: untimed
    scenario = track.validate_scenario(values)
    cpu: dict[str, list[float]] = {"two_pass": [], "three_pass": []}
    digest: dict[str, str] = {}
    frames = 0
    for _ in range(max(1, repeats)):
        for name in ("three_pass", "two_pass"):
            with three_pass_rendering() if name == "three_pass" else nullcontext():
                t0 = time.process_time()
                episode = track.simulate(scenario, seed)
                cpu[name].append(time.process_time() - t0)
            digest[name] = _rgbd_digest(episode)
            frames = sum(frame_kind(f) == "rgbd" for f in episode.frames)
    stages: dict[str, float] = {}
    with render_stage_clock(stages, {}):
        t0 = time.process_time()
        track.simulate(scenario, seed)
        total = time.process_time() - t0
    stages["other"] = total - sum(stages.values())
    best = {k: min(v) for k, v in cpu.items()}
    return {
        "case": case.name, "rate_hz": EPISODE_RATE_HZ, "image_px": f"{scenario['width_px']}x{scenario['height_px']}",
        "rgbd_frames": frames, "cpu_s_two_pass": best["two_pass"], "cpu_s_three_pass": best["three_pass"],
        "frames_per_cpu_s_two_pass": frames / best["two_pass"], "frames_per_cpu_s_three_pass": frames / best["three_pass"],
        "speedup": best["three_pass"] / best["two_pass"], "identical_frames": digest["two_pass"] == digest["three_pass"],
        "cpu_ms_per_frame_two_pass": {k: 1e3 * v / max(1, frames) for k, v in stages.items()},
    }  # fmt: skip


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
    from ..registry import default_registry

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
      (all predictions; ``_ok`` only those with status ok);
    - ``episode_rgbd``: RGB-D frames per CPU-second of a whole 30 Hz episode (the quick suite's
      first case) with two render passes a frame against the three of before, and where the
      CPU time of a frame goes (:func:`_episode_rgbd_rate`).
    """
    from ..tracks.locomotion import LocomotionTrack

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
        "episode_rgbd": _episode_rgbd_rate(seed, repeats),
        "paper_ms_per_prediction": PAPER_MS_PER_PREDICTION,
    }
    return result
