"""`exobench bench lidar`: one full VLP-16 sweep of the default office from the exoskeleton's
``lidar_trunk`` site, by exobench's :class:`exobench.envs.sensors.lidar.LidarSensor` (static, and
walking at 0.5 m/s) and by the ``mujoco-lidar`` package's CPU backend (``MjLidarCPU``) on the
same model, pose and ray directions; throughput and the exobench / mujoco-lidar ratio come from
the same run.
"""

from __future__ import annotations

import dataclasses
import time
from typing import Any

import numpy as np

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


def bench_lidar(seed: int = 0, repeats: int = 5, *, office: Any = None, config: Any = None) -> dict[str, Any]:
    """Time one VLP-16 sweep of the default office: exobench's LiDAR vs mujoco-lidar's CPU backend.

    ``office`` (an :class:`~exobench.models.office_params.OfficeParams`) and ``config`` (a
    :class:`~exobench.envs.sensors.lidar.LidarConfig`) replace the default office and VLP-16,
    e.g. a small office and a coarse pattern for a quick check.

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
    from exobench.envs.sim.pose import site_pose
    from exobench.models.exo_spec import ExoSpec
    from exobench.models.office import build_office
    from exobench.models.worlds import compose

    world = build_office(office)
    scene = compose(world, ExoSpec())
    model, truth = scene.model, scene.truth
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    T0 = site_pose(model, data, "lidar_trunk")
    pelvis = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "pelvis")
    heading_w = np.asarray(data.xmat[pelvis]).reshape(3, 3)[:, 0].copy()
    heading_w[2] = 0.0
    heading_w /= np.linalg.norm(heading_w)

    def walking(times_s: np.ndarray) -> np.ndarray:
        T = np.repeat(T0[None], len(times_s), axis=0)
        T[:, :3, 3] += (WALK_SPEED_M_S * np.asarray(times_s, dtype=float))[:, None] * heading_w
        return T

    default_bench = office is None and config is None
    config = config if config is not None else LidarConfig(caster="bvh")  # the BVH caster against the MuJoCo reference
    pat = config.pattern
    dirs_s = pat.rays(0.0).dirs_s
    n_rays = len(dirs_s)
    poses: dict[str, Any] = {"static": T0, "walking": walking, "static_one_thread": T0, "static_mujoco_caster": T0,
                             "walking_mujoco_caster": walking}  # fmt: skip
    # exobench casts on every CPU by default; mujoco-lidar's CPU backend uses one, so the
    # single-thread figure is reported beside it for a per-core comparison
    one = dataclasses.replace(config, cast_threads=1)
    ref = dataclasses.replace(config, caster="mujoco")
    configs = {name: one if name.endswith("one_thread") else ref if name.endswith("mujoco_caster") else config for name in poses}
    sensors = {name: LidarSensor("lidar_trunk", configs[name], model, seed) for name in poses}

    def exo_sweep(name: str) -> Any:
        return lambda: sensors[name].scan(model, data, poses[name], 0.0, truth)

    fns = {name: exo_sweep(name) for name in poses}
    result: dict[str, Any] = {
        "scene": f"office ({'default OfficeParams' if office is None else office}), exoskeleton standing at the start",
        "sensor": "lidar_trunk",
        "pattern": pat.name,
        "rays_per_sweep": n_rays,
        "sweep_period_s": pat.sweep_period_s,
        "repeats": repeats,
        "seed": seed,
        "walk_speed_m_s": WALK_SPEED_M_S,
    }
    if default_bench:  # the default bench: both casters as the building grows
        result["scaling"] = bench_lidar_scaling(seed, repeats)
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
    result["ratio_static_mujoco_caster"] = exo["static_mujoco_caster"]["rays_per_s"] / mjl["rays_per_s"]
    result["meets_ratio_target"] = bool(result["ratio_static"] >= 3.0)
    return result


def bench_lidar_scaling(seed: int = 0, repeats: int = 5, n_offices: tuple[int, ...] = (6, 12, 24)) -> dict[str, Any]:
    """A VLP-16 sweep (static, every effect, glass and mirrors) of the default office at ``n_offices``
    offices, by the BVH caster and by MuJoCo's (``LidarConfig.caster``), and a glazed loop's scan.

    The glazed scan is the ``ring-windows-lowe`` building of the lidar-filter track (windows along
    every corridor in low-e glass, clear glass partitions, matt floors) swept by a walking VLP-16
    at 0.68 m reporting its strongest echo, where most beams meet glass (secondary rays). Each
    figure is a median over ``repeats`` interleaved sweeps; ratios come from the same rounds.
    """
    import mujoco

    from exobench.envs.sensors.lidar import LidarConfig, LidarSensor
    from exobench.envs.sim.pose import site_pose
    from exobench.models.exo_spec import ExoSpec
    from exobench.models.office import build_office
    from exobench.models.office_params import OfficeParams
    from exobench.models.worlds import compose

    def setup(params: Any, height_m: float | None) -> tuple[Any, Any, Any, np.ndarray]:
        scene = compose(build_office(params), ExoSpec())
        data = mujoco.MjData(scene.model)
        mujoco.mj_forward(scene.model, data)
        T0 = site_pose(scene.model, data, "lidar_trunk")
        if height_m is not None:
            T0[2, 3] = height_m
        return scene.model, data, scene.truth, T0

    out: dict[str, Any] = {"repeats": repeats, "seed": seed}
    fns: dict[str, Any] = {}
    for n in n_offices:
        # the building grows with its offices: 4 m of corridor per office (24 m at 6), at most 80 m
        model, data, truth, T0 = setup(OfficeParams(n_offices=n, corridor_length_m=min(4.0 * n, 80.0)), None)
        for caster in ("bvh", "mujoco"):
            s = LidarSensor("lidar_trunk", LidarConfig(caster=caster), model, seed)
            fns[f"{caster}_{n}"] = (lambda s=s, m=model, d=data, t=truth, p=T0: s.scan(m, d, p, 0.0, t))
    glazed = OfficeParams(facade="windows", facade_glass="lowe_glass", glass_fraction=1.0,
                          partition_glass="float_glass", polished_fraction=0.0)  # fmt: skip
    model, data, truth, T0 = setup(glazed, 0.68)

    def walking(times_s: np.ndarray, T0: np.ndarray = T0) -> np.ndarray:
        T = np.repeat(T0[None], len(times_s), axis=0)
        T[:, :3, 3] += (WALK_SPEED_M_S * np.asarray(times_s, dtype=float))[:, None] * T0[:3, 0]
        return T

    for caster in ("bvh", "mujoco"):
        s = LidarSensor("lidar_trunk", LidarConfig(caster=caster, return_mode="strongest"), model, seed)
        fns[f"{caster}_glazed"] = (lambda s=s, m=model, d=data, t=truth: s.scan(m, d, walking, 0.0, t))
    walls = _interleaved_medians_s(fns, repeats)
    for caster in ("bvh", "mujoco"):
        out[caster] = {f"ms_per_sweep_{n}_offices": walls[f"{caster}_{n}"] * 1e3 for n in n_offices}
        out[caster]["ms_per_glazed_scan"] = walls[f"{caster}_glazed"] * 1e3
        lo, hi = min(n_offices), max(n_offices)
        out[caster][f"growth_{hi}_vs_{lo}"] = walls[f"{caster}_{hi}"] / walls[f"{caster}_{lo}"]
    out["glazed_speedup_bvh_vs_mujoco"] = walls["mujoco_glazed"] / walls["bvh_glazed"]
    out["meets_growth_target"] = bool(out["bvh"][f"growth_{max(n_offices)}_vs_{min(n_offices)}"] <= 1.25)
    return out


# ---------------------------------------------------------------- locomotion (seeds/002)
