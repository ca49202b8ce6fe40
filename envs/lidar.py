"""Scanning LiDAR (Velodyne VLP-16 by default) by MuJoCo ray casting, with ground truth per point.

One call of :meth:`LidarSensor.scan` simulates one sweep: every ray of the
:class:`~exobench.envs.lidar_pattern.LidarPattern` is cast with ``mj_multiRay`` from the sensor
pose at its firing time (``pose_at``, so a sensor that moves during the sweep sees the world
distorted as a walking person's LiDAR does; the points carry their firing time for deskewing).
Glass and mirrors follow :mod:`exobench.envs.lidar_optics`. Points are in the sensor frame at
their firing time, in firing order, with range noise, 2 mm range resolution and an intensity
byte from the Lambertian return strength (or the range-compensated reflectivity, see
``LidarConfig.intensity_mode``); returns below the detection threshold or outside the range
limits are dropped.

Timing model: each firing block has its own pose (``pose_blocks = 0``; the lasers of a block
share it, exact to within the 37 us a VLP-16 block takes), or blocks share one pose in
``pose_blocks`` groups when ``pose_at`` is expensive. Casting: ``mj_multiRay`` casts many rays
from one point and costs about 0.1 ms per call in a furnished scene, so the firings of each
``cast_period_s`` window are cast from one origin (the window's middle firing) along their exact
directions, and each range is then moved to the ray's own origin on the plane of the face hit:
``r = (p - o) . n / (u . n)``. That is exact on planar faces; only beams within the window's
motion (about 1 mm at walking speed) of a silhouette edge, or on curved geoms (error ~ d^2 / R),
differ from casting every firing from its own origin (``cast_period_s = 0``, slower). A static
sensor is cast in one call. The calls (or, for one call, slices of its rays) are spread over
``cast_threads`` threads (``mj_multiRay`` releases the GIL; every ray's result is independent of
the others, so the split never changes a result); threads other than the caller's cast on a
scratch ``MjData`` holding a copy of the geom poses. Two things make the casts cheaper without
changing a hit (tested against one plain pass on the simulation's model): they run on a private
copy of the ray-visible geoms with the static ones grouped in spatial zones
(:mod:`exobench.envs.ray_scene`, ``zoned_cast``), and each call first traces its rays against the
geoms within ``cast_near_m`` only, then the rays without a hit that near against all geoms. The
world geometry is frozen at the state of ``data`` for the sweep (the scene is static;
exoskeleton geoms keep the pose they had in ``data``).

Random streams (``sensor_rngs``): range noise from the noise generator, sweep and point dropout
from the dropout generator, glass/mirror events from a third generator keyed
``"<sensor_id>/optics"``. The number of draws per sweep is fixed by the pattern, so what the scene
contains never shifts the streams.
"""

from __future__ import annotations

import os
import threading
from collections.abc import Callable, Mapping
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field

import numpy as np

from exobench.core import ConfigError, LidarScan, SceneTruth, check_range
from exobench.models.materials import KINDS, LidarMaterial

from .lidar_optics import (
    RETRO_CODE,
    GeomOptics,
    ReturnKind,
    follow_beams,
    geom_optics,
    intensity_byte,
    return_signal,
)
from .lidar_pattern import LidarPattern, RayTable
from .ray_scene import RayScene, build_ray_scene
from .sensor_config import sensor_rngs
from .tof import EXO_GROUP, WORLD_GROUP

INTENSITY_MODES = ("signal", "reflectivity")

PoseFn = Callable[[np.ndarray], np.ndarray]
"""``pose_at(times_s) -> T_world_sensor``: absolute times (K,) to poses (K, 4, 4)."""

__all__ = ["LidarConfig", "LidarPattern", "LidarSensor", "LidarTruth", "PoseFn", "ReturnKind"]


@dataclass(frozen=True)
class LidarConfig:
    """A LiDAR's pattern, noise, detection and optics switches (SENSORS.md; [A] = assumption).

    Attributes:
        pattern: channels, timing and range limits (default VLP-16 at 10 Hz).
        range_noise_m: standard deviation of the range noise, m [A: 0.015, reading the data
            sheet's +-3 cm accuracy as two sigma].
        resolution_m: range quantisation, m (0.002: the VLP-16 packet distance unit; 0 = off).
        detection_threshold: returns whose signal (intensity scale, unclipped) is below are
            dropped [A: 1.0, so white is seen frontally to 100 m, concrete to about 66 m].
        ref_reflectivity / ref_range_m: a surface of ``ref_reflectivity`` at ``ref_range_m``,
            frontal, has signal 100 (0.8 white at 10 m).
        intensity_mode: ``"signal"``: the byte is the Lambertian signal (cos / r^2; bright
            surfaces nearer than about 10 m saturate at 100); ``"reflectivity"``: the byte is the
            range-compensated calibrated reflectivity ``100 * G * rho * |cos(incidence)|`` (how the
            VLP-16 reports it; ``G`` < 1 only for ghosts and returns through glass, see
            :mod:`exobench.envs.lidar_optics`). Detection uses the signal in both.
        latency_s: delivery delay after the end of the sweep, s [A: 0].
        dropout_prob: probability a whole sweep is lost [A: 0].
        point_dropout_prob: probability a return is lost [A: 0].
        glass: model glass (transmission, pane reflection, ghosts); off = panes are opaque
            weak reflectors (what most simulators do).
        mirrors: model specular reflection of mirror materials (ghosts); off = opaque.
        max_interactions: glass/mirror events followed per beam.
        pose_blocks: firing blocks share a pose in this many groups per sweep (0 = one pose per
            firing block, exact; fewer = fewer ``pose_at`` times, the motion within a group is
            ignored).
        cast_period_s: firings within this window are cast from one origin and their ranges
            moved to their own origins on the face hit (see the module docstring) [A: 1 ms];
            0 = one ``mj_multiRay`` call per firing block.
        cast_threads: threads casting the rays (0 = one per available CPU, at most 8; 1 = the
            calling thread only); results do not depend on it.
        cast_near_m: rays are cast first against the geoms within this distance (``mj_multiRay``
            drops the farther ones before tracing), and those without a hit that near again
            against all: the same hits, faster where most returns are near (offices) [A: 8 m];
            0 = one pass.
        zoned_cast: cast on a private copy of the ray-visible geoms grouped in spatial zones
            (:mod:`exobench.envs.ray_scene`; a quarter less casting time in the office, same hits);
            False = cast on the simulation's model.
        materials: extra or replacement materials by name (on top of ``models.materials``).
    """

    pattern: LidarPattern = field(default_factory=LidarPattern.vlp16)
    range_noise_m: float = 0.015
    resolution_m: float = 0.002
    detection_threshold: float = 1.0
    ref_reflectivity: float = 0.8
    ref_range_m: float = 10.0
    intensity_mode: str = "reflectivity"
    latency_s: float = 0.0
    dropout_prob: float = 0.0
    point_dropout_prob: float = 0.0
    glass: bool = True
    mirrors: bool = True
    max_interactions: int = 3
    pose_blocks: int = 0
    cast_period_s: float = 1e-3
    cast_threads: int = 0
    cast_near_m: float = 8.0
    zoned_cast: bool = True
    materials: tuple[LidarMaterial, ...] = ()

    def __post_init__(self) -> None:
        if not isinstance(self.pattern, LidarPattern):
            raise ConfigError("lidar.pattern", self.pattern, "a LidarPattern")
        check_range("lidar.range_noise_m", self.range_noise_m, 0.0, 1.0)
        check_range("lidar.resolution_m", self.resolution_m, 0.0, 0.1)
        check_range("lidar.detection_threshold", self.detection_threshold, 0.0, 255.0)
        check_range("lidar.ref_reflectivity", self.ref_reflectivity, 0.0, 1.0, low_open=True)
        check_range("lidar.ref_range_m", self.ref_range_m, 0.0, 1000.0, low_open=True)
        if self.intensity_mode not in INTENSITY_MODES:
            raise ConfigError("lidar.intensity_mode", self.intensity_mode, " or ".join(INTENSITY_MODES))
        check_range("lidar.latency_s", self.latency_s, 0.0, 1.0)
        check_range("lidar.cast_period_s", self.cast_period_s, 0.0, 1.0)
        check_range("lidar.cast_near_m", self.cast_near_m, 0.0, 1e4)
        check_range("lidar.dropout_prob", self.dropout_prob, 0.0, 1.0, high_open=True)
        check_range("lidar.point_dropout_prob", self.point_dropout_prob, 0.0, 1.0, high_open=True)
        for name in ("glass", "mirrors", "zoned_cast"):
            if not isinstance(getattr(self, name), bool):
                raise ConfigError(f"lidar.{name}", getattr(self, name), "True or False")
        for name, high in (("max_interactions", 16), ("pose_blocks", 10**7), ("cast_threads", 64)):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or not 0 <= v <= high:
                raise ConfigError(f"lidar.{name}", v, f"an integer in [0, {high}]")
        mats = tuple(self.materials)
        for m in mats:
            if not isinstance(m, LidarMaterial) or m.kind not in KINDS:
                raise ConfigError("lidar.materials", m, f"LidarMaterial of kind {', '.join(KINDS)}")
            check_range(f"lidar.materials.{m.name}.reflectivity", m.reflectivity, 0.0, 1.0)
            check_range(f"lidar.materials.{m.name}.transmission", m.transmission, 0.0, 1.0)
            check_range(f"lidar.materials.{m.name}.specular", m.specular, 0.0, 1.0 - m.transmission)
        object.__setattr__(self, "materials", mats)

    def material_overrides(self) -> Mapping[str, LidarMaterial]:
        return {m.name: m for m in self.materials}

    def calibration_params(self) -> dict[str, object]:
        """What a pipeline may know about the sensor (for ``exo_calibration``)."""
        p = self.pattern
        return {
            "pattern": p.name, "vertical_angles_deg": list(p.vertical_angles_deg),
            "firing_order": list(p.firing_order), "azimuth_step_deg": p.azimuth_step_deg,
            "rate_hz": p.rate_hz, "firing_period_s": p.firing_period_s, "min_range_m": p.min_range_m,
            "max_range_m": p.max_range_m, "noise_sigma_m": self.range_noise_m,
            "resolution_m": self.resolution_m, "latency_s": self.latency_s,
            "intensity_mode": self.intensity_mode,
        }  # fmt: skip


@dataclass(frozen=True, eq=False)
class LidarTruth:
    """Ground truth of one :class:`LidarScan`, point by point (same order, same length N).

    Attributes:
        stamp_s, sensor_id: as the scan.
        true_range_m: noise-free distance along the original ray at which the point lies, m
            (for a ghost the total reflected path length).
        hit_w: the surface point that returned the light, world frame, (N, 3) (for a ghost the
            real surface seen in the mirror, not where the point appears).
        geom_id: MuJoCo geom of that surface, (N,).
        surface_id: ``SceneTruth`` surface of that point, -1 if none, (N,).
        material: material name of that surface, (N,) str.
        kind: :class:`ReturnKind` code, (N,).
        via_geom_id: the glass / mirror geom the beam crossed or bounced on, -1 if none, (N,).
        signal: unclipped return strength on the intensity scale, (N,), with the path's energy
            share (``G`` of :mod:`exobench.envs.lidar_optics`: ghosts keep the specular fraction
            squared of their light, returns through glass the transmission squared).
        origin_w / dir_w: the original ray in the world at its firing pose, (N, 3).
    """

    stamp_s: float
    sensor_id: str
    true_range_m: np.ndarray
    hit_w: np.ndarray
    geom_id: np.ndarray
    surface_id: np.ndarray
    material: np.ndarray
    kind: np.ndarray
    via_geom_id: np.ndarray
    signal: np.ndarray
    origin_w: np.ndarray
    dir_w: np.ndarray

    @property
    def genuine(self) -> np.ndarray:
        """Points on a real surface along the straight ray (directly or through glass)."""
        return (self.kind == ReturnKind.GENUINE) | (self.kind == ReturnKind.THROUGH_GLASS)


def compact_truth(t: LidarTruth) -> LidarTruth:
    """The labels of a scan's truth without its per-point geometry, for long walks.

    Keeps, per point, ``true_range_m`` and ``signal`` (float32), ``geom_id``, ``surface_id`` and
    ``via_geom_id`` (int32) and ``kind`` (int8): about 21 bytes a point instead of ~170. ``hit_w``,
    ``origin_w`` and ``dir_w`` become empty (0, 3) arrays and ``material`` an empty array (a
    surface's material is ``SceneTruth.geom_materials`` of its geoms).
    """
    empty3 = np.zeros((0, 3), dtype=np.float32)
    return LidarTruth(
        stamp_s=t.stamp_s,
        sensor_id=t.sensor_id,
        true_range_m=np.asarray(t.true_range_m, dtype=np.float32),
        hit_w=empty3,
        geom_id=np.asarray(t.geom_id, dtype=np.int32),
        surface_id=np.asarray(t.surface_id, dtype=np.int32),
        material=np.zeros(0, dtype="<U1"),
        kind=np.asarray(t.kind, dtype=np.int8),
        via_geom_id=np.asarray(t.via_geom_id, dtype=np.int32),
        signal=np.asarray(t.signal, dtype=np.float32),
        origin_w=empty3,
        dir_w=empty3.copy(),
    )


class LidarSensor:
    """One LiDAR. Call :meth:`scan` once per sweep (sweeps start at ``k / rate_hz``)."""

    def __init__(self, sensor_id: str, config: LidarConfig, model: object, seed: int) -> None:
        import mujoco

        self.sensor_id, self.config = sensor_id, config
        site = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, sensor_id)
        # the mount's own body (the trunk) would block the beams; without a site nothing is excluded
        self.body_exclude = int(model.site_bodyid[site]) if site >= 0 else -1  # type: ignore[attr-defined]
        self.group = np.zeros(6, dtype=np.uint8)
        self.group[[WORLD_GROUP, EXO_GROUP]] = 1
        ngeom = int(model.ngeom)  # type: ignore[attr-defined]
        self.geom_names = [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, g) or "" for g in range(ngeom)]
        self.noise_rng, self.drop_rng = sensor_rngs(seed, sensor_id)
        self.optics_rng = sensor_rngs(seed, f"{sensor_id}/optics")[0]
        pat = config.pattern
        self._static_rays = pat.rays(0.0) if pat.scan_kind == "spinning" else None
        self._optics_cache: tuple[SceneTruth, GeomOptics] | None = None
        self._surface_cache: tuple[SceneTruth, _SurfaceTable] | None = None
        self._scratch: tuple[object, list[object]] | None = None
        self._ray_scene: tuple[object, RayScene | None] | None = None

    def rays(self, sweep_start_s: float) -> RayTable:
        return self._static_rays if self._static_rays is not None else self.config.pattern.rays(sweep_start_s)

    def _blocks(self, rays: RayTable) -> tuple[np.ndarray, np.ndarray]:
        """(first ray index of each pose group + end, time offset of each group's pose)."""
        F = len(rays.firing_time_s)
        nb = self.config.pose_blocks
        nb = F if nb == 0 or nb >= F else nb
        first_firing = (np.arange(nb) * F) // nb
        last_firing = np.append(first_firing[1:], F) - 1
        starts = np.searchsorted(rays.firing, first_firing)
        t_pose = 0.5 * (rays.firing_time_s[first_firing] + rays.firing_time_s[last_firing])
        return np.append(starts, len(rays)), t_pose

    def scan(
        self,
        model: object,
        data: object,
        pose_at: PoseFn | np.ndarray,
        sweep_start_s: float,
        truth: SceneTruth,
    ) -> tuple[LidarScan, LidarTruth] | None:
        """Simulate the sweep starting at ``sweep_start_s``; None when the sweep is dropped.

        Args:
            model, data: the MuJoCo model and a data whose kinematics are current (geom poses).
            pose_at: ``T_world_sensor`` at absolute times (K,) -> (K, 4, 4), or one fixed 4x4 pose.
            sweep_start_s: time of the sweep's first firing, s.
            truth: the scene's ground truth (surfaces and materials).
        """

        c, pat = self.config, self.config.pattern
        rays = self.rays(sweep_start_s)
        n = len(rays)
        # fixed-size draws first: the streams do not depend on what the beams hit
        z = self.noise_rng.standard_normal(n)
        u_opt = self.optics_rng.random((n, c.max_interactions))
        sweep_lost = self.drop_rng.random() < c.dropout_prob
        u_drop = self.drop_rng.random(n)
        if sweep_lost:
            return None

        bounds, t_pose = self._blocks(rays)
        T = _poses(pose_at, sweep_start_s + t_pose)
        origins_w, dirs_w = _rays_in_world(T, np.diff(bounds), rays.dirs_s)
        gid, dist, nrm = self._cast(model, data, rays, origins_w, dirs_w)

        optics = self._optics(truth)
        beams = follow_beams(
            model, data, self.group, origins_w, dirs_w, gid, dist, nrm.reshape(-1, 3), optics, u_opt,
            glass=c.glass, mirrors=c.mirrors,
        )  # fmt: skip
        ok = beams.geom >= 0
        g = np.where(ok, beams.geom, 0)
        path = np.where(ok, beams.path_m, 1.0)
        signal = return_signal(optics.reflectivity[g], beams.cos_inc, path, c.ref_reflectivity, c.ref_range_m, beams.gain)
        ok &= (path >= pat.min_range_m) & (path <= pat.max_range_m) & (signal >= c.detection_threshold)
        ok &= u_drop >= c.point_dropout_prob
        idx = np.flatnonzero(ok)
        level = signal if c.intensity_mode == "signal" else 100.0 * beams.gain * optics.reflectivity[g] * beams.cos_inc

        r_m = path[idx] + c.range_noise_m * z[idx]
        if c.resolution_m > 0.0:
            r_m = np.round(r_m / c.resolution_m) * c.resolution_m
        r_m = np.maximum(r_m, 0.0)
        gk = g[idx]
        stamp = float(sweep_start_s) + pat.sweep_period_s + c.latency_s
        scan = LidarScan(
            stamp_s=stamp,
            sensor_id=self.sensor_id,
            points_xyz=r_m[:, None] * rays.dirs_s[idx],
            intensity=intensity_byte(level[idx], optics.kind[gk] == RETRO_CODE),
            ring=rays.channel[idx].astype(np.uint16),
            time_offset_s=rays.time_offset_s[idx].copy(),
            sweep_start_s=float(sweep_start_s),
        )
        surface = self._label(truth, gk, beams.hit_w[idx])
        lt = LidarTruth(
            stamp_s=stamp,
            sensor_id=self.sensor_id,
            true_range_m=path[idx],
            hit_w=beams.hit_w[idx],
            geom_id=gk,
            surface_id=surface,
            material=optics.name[gk],
            kind=beams.kind[idx],
            via_geom_id=beams.via_geom[idx],
            signal=signal[idx],
            origin_w=origins_w[idx],
            dir_w=dirs_w[idx],
        )
        return scan, lt

    def _cast(
        self, model: object, data: object, rays: RayTable, origins_w: np.ndarray, dirs_w: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Primary hits of every ray from its own origin: (geom, distance, normal), -1 if none."""
        import mujoco

        scene = self._zoned(model, data)
        if scene is not None:
            scene.sync(data)
            model, data, mask, exclude = scene.model, scene.data, scene.group, -1
        else:
            mask, exclude = self.group, self.body_exclude
        n = len(rays)
        period = self.config.cast_period_s
        key = np.floor(rays.firing_time_s[rays.firing] / period + 1e-9) if period > 0 else rays.firing
        starts = np.flatnonzero(np.append(True, key[1:] != key[:-1]))
        ends = np.append(starts[1:], n)
        o_cast = origins_w[(starts + ends) // 2]
        # neighbouring windows cast from the same point (a sensor that does not move) share a call
        keep = np.append(True, np.any(o_cast[1:] != o_cast[:-1], axis=1))
        starts, o_cast = starts[keep], o_cast[keep]
        ends = np.append(starts[1:], n)
        gid = np.full(n, -1, dtype=np.int32)
        dist = np.full(n, -1.0)
        nrm = np.zeros(3 * n)
        flat = dirs_w.reshape(-1)
        max_r = self.config.pattern.max_range_m + 1.0
        jobs = [(o, int(s), int(e)) for o, s, e in zip(o_cast, starts, ends)]
        k = self._n_threads(model)
        if 1 < k and len(jobs) < k:  # few calls (a static sensor): cut them into slices of their rays
            jobs = [(o, a, b) for o, s, e in jobs for a, b in _slices(s, e, k) if b > a]
        groups = _partition(jobs, k)

        near = self.config.cast_near_m if 0.0 < self.config.cast_near_m < max_r else max_r

        def run(d: object, group: list[tuple[np.ndarray, int, int]]) -> None:
            for o, s, e in group:
                mujoco.mj_multiRay(
                    model, d, o, flat[3 * s : 3 * e], mask, 1, exclude,
                    gid[s:e], dist[s:e], nrm[3 * s : 3 * e], e - s, near,
                )  # fmt: skip
                if near >= max_r:
                    continue
                # a hit within `near` is the nearest: every geom the cut-off dropped lies farther
                far = s + np.flatnonzero((gid[s:e] < 0) | (dist[s:e] > near))
                if len(far):
                    g2, d2, n2 = np.full(len(far), -1, dtype=np.int32), np.full(len(far), -1.0), np.zeros(3 * len(far))
                    v = np.ascontiguousarray(dirs_w[far]).reshape(-1)
                    mujoco.mj_multiRay(model, d, o, v, mask, 1, exclude, g2, d2, n2, len(far), max_r)
                    gid[far], dist[far] = g2, d2
                    nrm.reshape(-1, 3)[far] = n2.reshape(-1, 3)

        if len(groups) > 1:
            scratch = self._scratch_data(model, data, len(groups) - 1)
            futures = [_pool().submit(run, d, g) for d, g in zip(scratch, groups[1:])]
            run(data, groups[0])
            for f in futures:
                f.result()
        else:
            run(data, jobs)
        nrm = nrm.reshape(-1, 3)
        if scene is not None:
            gid = scene.original_geoms(gid)
        # move each range from the cast origin to the ray's own origin, on the plane of the face hit
        o_ray = np.repeat(o_cast, ends - starts, axis=0)
        delta = o_ray - origins_w
        fix = np.flatnonzero((gid >= 0) & (dist >= 0.0) & np.any(delta != 0.0, axis=1))
        if len(fix):
            u, nv, dl = dirs_w[fix], nrm[fix], delta[fix]
            un = np.einsum("ij,ij->i", u, nv)
            grazing = np.abs(un) < 1e-6
            r = dist[fix] + np.einsum("ij,ij->i", dl, nv) / np.where(grazing, 1.0, un)
            r = np.where(grazing, dist[fix] + np.einsum("ij,ij->i", dl, u), r)
            gid[fix] = np.where(r >= 0.0, gid[fix], -1)
            dist[fix] = np.where(r >= 0.0, r, -1.0)
        return gid, dist, nrm

    def _zoned(self, model: object, data: object) -> RayScene | None:
        """The private zoned casting model of ``model`` (built on first use), None if not used."""
        if not self.config.zoned_cast:
            return None
        if self._ray_scene is None or self._ray_scene[0] is not model:
            self._ray_scene = (model, build_ray_scene(model, data, self.group, self.body_exclude))
        return self._ray_scene[1]

    def _n_threads(self, model: object) -> int:
        k = self.config.cast_threads or _available_cpus()
        # flexes and skins keep ray-relevant state beyond the geom poses: cast those in one thread
        return 1 if int(getattr(model, "nflex", 0)) > 0 else max(1, min(k, 64))

    def _scratch_data(self, model: object, data: object, k: int) -> list[object]:
        """``k`` MjData for the extra casting threads, with the geom poses of ``data``."""
        import mujoco

        if self._scratch is None or self._scratch[0] is not model:
            self._scratch = (model, [])
        pool = self._scratch[1]
        while len(pool) < k:
            pool.append(mujoco.MjData(model))
        for d in pool[:k]:
            for name in _POSE_FIELDS:
                getattr(d, name)[:] = getattr(data, name)
        return pool[:k]

    def _label(self, truth: SceneTruth, geom: np.ndarray, hit_w: np.ndarray, tol_m: float = 1e-4) -> np.ndarray:
        """Surface id of each hit, as ``SceneTruth.surface_of_hit`` decides it, all hits at once.

        Of a geom's surfaces, those whose plane passes within ``tol_m`` of the point and whose
        polygon contains it qualify; the nearest plane wins, the last listed of equally near ones
        (the order ``surface_of_hit`` visits them in).
        """
        tab = self._surface_table(truth)
        n = len(geom)
        out = np.full(n, -1, dtype=np.int64)
        cnt = tab.count[geom]
        pt = np.repeat(np.arange(n), cnt)  # one row per (point, candidate surface)
        if len(pt) == 0:
            return out
        slot = np.arange(len(pt)) - np.repeat(np.cumsum(cnt) - cnt, cnt)
        row = tab.cand[geom[pt], slot]
        p = np.take(hit_w, pt, axis=0)
        pn = np.take(tab.point_normal, row, axis=0)
        d = np.abs(_dot3(p - pn[:, 0], pn[:, 1]))
        near = np.flatnonzero(d <= tol_m)
        pt, slot, row, p, d = pt[near], slot[near], row[near], p[near], d[near]
        # the edge test of PlanarSurface.contains: the edges not within tol_m of the point must
        # all see it on the same side (zero-length padding edges are always within)
        c = _dot3(p[:, None, :] - np.take(tab.edge_a, row, axis=0), np.take(tab.edge_m, row, axis=0))
        within = tol_m * np.take(tab.edge_len, row, axis=0)
        ok = ~(np.any(c > within, axis=1) & np.any(c < -within, axis=1))
        pt, slot, row, d = pt[ok], slot[ok], row[ok], d[ok]
        single = np.bincount(pt, minlength=n)[pt] == 1
        out[pt[single]] = tab.sid[row[single]]
        multi = np.flatnonzero(~single)
        if len(multi):  # several qualify: the nearest plane, the last listed of ties
            pts, at = np.unique(pt[multi], return_inverse=True)
            dd = np.full((len(pts), tab.cand.shape[1]), np.inf)
            dd[at, slot[multi]] = d[multi]
            best = dd.min(axis=1)
            last = dd.shape[1] - 1 - np.argmax((dd == best[:, None])[:, ::-1], axis=1)
            out[pts] = tab.sid[tab.cand[geom[pts], last]]
        return out

    def _surface_table(self, truth: SceneTruth) -> _SurfaceTable:
        if self._surface_cache is None or self._surface_cache[0] is not truth:
            self._surface_cache = (truth, _SurfaceTable.build(truth, self.geom_names))
        return self._surface_cache[1]

    def _optics(self, truth: SceneTruth) -> GeomOptics:
        if self._optics_cache is None or self._optics_cache[0] is not truth:
            self._optics_cache = (truth, geom_optics(self.geom_names, truth, self.config.material_overrides()))
        return self._optics_cache[1]


@dataclass(frozen=True, eq=False)
class _SurfaceTable:
    """A scene's surfaces as arrays, for labelling hits (rows index ``sid``).

    ``cand[g, :count[g]]`` are the rows of geom ``g``'s surfaces in ``geom_surfaces`` order;
    polygons are padded with zero-length edges, which the edge test skips.
    """

    sid: np.ndarray  # (S,) surface id of each row
    point_normal: np.ndarray  # (S, 2, 3) a point of the plane and its normal
    edge_a: np.ndarray  # (S, V, 3) first vertex of each edge
    edge_m: np.ndarray  # (S, V, 3) cross(normal, edge)
    edge_len: np.ndarray  # (S, V) edge length, m
    cand: np.ndarray  # (ngeom, K) candidate rows per geom, padded with 0
    count: np.ndarray  # (ngeom,)

    @staticmethod
    def build(truth: SceneTruth, geom_names: list[str]) -> _SurfaceTable:
        surfaces = list(truth.surfaces)
        row_of = {sf.surface_id: i for i, sf in enumerate(surfaces)}
        S, V = len(surfaces), max((len(sf.polygon_w) for sf in surfaces), default=1)
        edge_a, edge_m, edge_len = np.zeros((S, V, 3)), np.zeros((S, V, 3)), np.zeros((S, V))
        for i, sf in enumerate(surfaces):
            poly, nv = np.asarray(sf.polygon_w, dtype=float), np.asarray(sf.normal_w, dtype=float)
            edge_a[i] = poly[-1] if len(poly) else 0.0
            for j in range(len(poly)):
                a, b = poly[j], poly[(j + 1) % len(poly)]
                e = b - a
                edge_a[i, j] = a
                edge_m[i, j] = [nv[1] * e[2] - nv[2] * e[1], nv[2] * e[0] - nv[0] * e[2], nv[0] * e[1] - nv[1] * e[0]]
                edge_len[i, j] = float(np.sqrt(e @ e))
        rows = [[row_of[sid] for sid in truth.geom_surfaces.get(name, ())] for name in geom_names]
        K = max((len(r) for r in rows), default=0)
        cand = np.zeros((len(geom_names), max(K, 1)), dtype=np.int64)
        for g, r in enumerate(rows):
            cand[g, : len(r)] = r
        return _SurfaceTable(
            sid=np.array([sf.surface_id for sf in surfaces], dtype=np.int64),
            point_normal=np.array([[sf.point_w, sf.normal_w] for sf in surfaces], dtype=float).reshape(S, 2, 3),
            edge_a=edge_a, edge_m=edge_m, edge_len=edge_len, cand=cand,
            count=np.array([len(r) for r in rows], dtype=np.int64),
        )  # fmt: skip


def _dot3(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Dot products over the last axis (length 3), ``(a0 b0 + a1 b1) + a2 b2`` elementwise."""
    return a[..., 0] * b[..., 0] + a[..., 1] * b[..., 1] + a[..., 2] * b[..., 2]


_POSE_FIELDS = ("xpos", "xmat", "xquat", "xipos", "ximat", "geom_xpos", "geom_xmat")
"""The ``MjData`` state ``mj_multiRay`` reads (poses of bodies and geoms), copied to scratch data."""

_POOL: ThreadPoolExecutor | None = None
_POOL_LOCK = threading.Lock()


def _pool() -> ThreadPoolExecutor:
    """The process's casting threads (created on first use; idle threads cost nothing)."""
    global _POOL
    with _POOL_LOCK:
        if _POOL is None:
            _POOL = ThreadPoolExecutor(max_workers=64, thread_name_prefix="exobench-lidar")
        return _POOL


def _available_cpus() -> int:
    try:
        k = len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        k = os.cpu_count() or 1
    return max(1, min(k, 8))


def _slices(start: int, end: int, k: int) -> list[tuple[int, int]]:
    cuts = start + (np.arange(k + 1) * (end - start)) // k
    return [(int(a), int(b)) for a, b in zip(cuts[:-1], cuts[1:])]


def _partition(jobs: list[tuple[np.ndarray, int, int]], k: int) -> list[list[tuple[np.ndarray, int, int]]]:
    """Consecutive groups of jobs, at most ``k``, of about equal ray counts."""
    if k <= 1 or len(jobs) <= 1:
        return [jobs]
    rays = np.cumsum([e - s for _, s, e in jobs])
    cut = np.searchsorted(rays, rays[-1] * np.arange(1, k) / k, side="right")
    bounds = np.unique(np.concatenate([[0], cut, [len(jobs)]]))
    return [jobs[a:b] for a, b in zip(bounds[:-1], bounds[1:]) if b > a]


def _rays_in_world(T: np.ndarray, sizes: np.ndarray, dirs_s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Origins and directions (N, 3) of rays in consecutive blocks of ``sizes`` rays posed by ``T`` (B, 4, 4)."""
    n, nb = len(dirs_s), len(T)
    if nb == 0 or np.all(T == T[0]):  # one pose (a sensor at rest)
        R = T[0, :3, :3] if nb else np.eye(3)
        return np.broadcast_to(T[0, :3, 3] if nb else np.zeros(3), (n, 3)), np.ascontiguousarray(dirs_s @ R.T)
    if np.all(sizes == sizes[0]):  # blocks of equal size (spinning patterns): one batched product
        m = int(sizes[0])
        dirs_w = np.matmul(dirs_s.reshape(nb, m, 3), T[:, :3, :3].transpose(0, 2, 1)).reshape(n, 3)
        return np.repeat(T[:, :3, 3], m, axis=0), dirs_w
    block = np.repeat(np.arange(nb), sizes)
    return T[block, :3, 3], np.ascontiguousarray(np.einsum("nij,nj->ni", T[block, :3, :3], dirs_s))


def _poses(pose_at: PoseFn | np.ndarray, times_s: np.ndarray) -> np.ndarray:
    if callable(pose_at):
        T = np.asarray(pose_at(times_s), dtype=float)
    else:
        T = np.broadcast_to(np.asarray(pose_at, dtype=float), (len(times_s), 4, 4))
    if T.shape != (len(times_s), 4, 4) or not np.all(np.isfinite(T)):
        raise ConfigError("lidar.pose_at", T.shape, f"finite poses of shape ({len(times_s)}, 4, 4)")
    return T
