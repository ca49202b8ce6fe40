"""Scanning LiDAR (Velodyne VLP-16 by default) by MuJoCo ray casting, with ground truth per point.

One call of :meth:`LidarSensor.scan` simulates one sweep: every ray of the
:class:`~exobench.envs.sensors.lidar.pattern.LidarPattern` is cast (Embree and MuJoCo, see
:mod:`~exobench.envs.sensors.lidar.cast`) from the sensor
pose at its firing time (``pose_at``, so a sensor that moves during the sweep sees the world
distorted as a walking person's LiDAR does; the points carry their firing time for deskewing).
Glass and mirrors follow :mod:`exobench.envs.sensors.lidar.optics`. Points are in the sensor frame at
their firing time, in firing order, with range noise, 2 mm range resolution and an intensity
byte from the Lambertian return strength (or the range-compensated reflectivity, see
``LidarConfig.intensity_mode``); returns below the detection threshold or outside the range
limits are dropped.

Timing model: each firing block has its own pose (``pose_blocks = 0``; the lasers of a block
share it, exact to within the 37 us a VLP-16 block takes), or blocks share one pose in
``pose_blocks`` groups when ``pose_at`` is expensive. The rays are cast by
:class:`~exobench.envs.sensors.lidar.cast.RayCaster` (batched per ``cast_period_s`` window, see
there). The world geometry is frozen at the state of ``data`` for the sweep (the scene is static;
exoskeleton geoms keep the pose they had in ``data``).

Random streams (``sensor_rngs``): range noise from the noise generator, sweep and point dropout
from the dropout generator, glass/mirror events from a third generator keyed
``"<sensor_id>/optics"``, NaN points (``nan_point_prob > 0``) from a fourth keyed
``"<sensor_id>/nan"``. The number of draws per sweep is fixed by the pattern, so what the scene
contains never shifts the streams. A NaN point is reported with x, y, z NaN and intensity 0; its
truth entry stays (the beam's true hit) with kind ``ReturnKind.NAN``. The faults of the stream
(duplicated, late and clock-shifted sweeps) are :mod:`exobench.envs.sensors.lidar.faults`.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace

import numpy as np

from exobench.core import ConfigError, LidarScan, LidarTruth, ReturnKind, SceneTruth

from ..common import EXO_GROUP, WORLD_GROUP, sensor_rngs
from .cast import RayCaster
from .config import LidarConfig
from .kernels import returns
from .labels import SurfaceTable, label_surfaces
from .optics import (
    KIND_CODE,
    RETRO_CODE,
    EchoChoice,
    GeomOptics,
    follow_beams,
    geom_optics,
    take_rows,
)
from .pane_shape import PaneShapes
from .pattern import RayTable

PoseFn = Callable[[np.ndarray], np.ndarray]
"""``pose_at(times_s) -> T_world_sensor``: absolute times (K,) to poses (K, 4, 4)."""

__all__ = ["LidarSensor", "PoseFn"]


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
        self.nan_rng = sensor_rngs(seed, f"{sensor_id}/nan")[0]
        pat = config.pattern
        self._static_rays = pat.rays(0.0) if pat.scan_kind == "spinning" else None
        self._optics_cache: tuple[SceneTruth, GeomOptics] | None = None
        self._surface_cache: tuple[SceneTruth, SurfaceTable] | None = None
        self.caster = RayCaster(config, self.group, self.body_exclude)
        self._echo = EchoChoice(config.return_mode, config.ref_reflectivity, config.ref_range_m,
                                config.detection_threshold, pat.min_range_m, pat.max_range_m)  # fmt: skip

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
        u_nan = self.nan_rng.random(n) if c.nan_point_prob > 0.0 else None
        if sweep_lost:
            return None

        bounds, t_pose = self._blocks(rays)
        T = _poses(pose_at, sweep_start_s + t_pose)
        origins_w, dirs_w = _rays_in_world(T, np.diff(bounds), rays.dirs_s)
        gid, dist, nrm = self.caster.cast(model, data, rays, origins_w, dirs_w)

        optics = self._optics(model, truth)
        beams = follow_beams(
            model, data, self.group, origins_w, dirs_w, gid, dist, nrm.reshape(-1, 3), optics, u_opt,
            glass=c.glass, mirrors=c.mirrors, echo=self._echo, cast=self.caster.secondary(model, data),
        )  # fmt: skip
        # detection, range noise and quantisation, intensity: one compiled pass (kernels.returns)
        idx, sig, points, intensity = np.empty(n, dtype=np.int64), np.empty(n), np.empty((n, 3)), np.empty(n, dtype=np.uint8)
        k = returns(beams.geom, beams.path_m, beams.cos_inc, beams.gain, optics.reflectivity, optics.kind == RETRO_CODE,
                    u_drop, z, np.ascontiguousarray(rays.dirs_s, dtype=float), pat.min_range_m, pat.max_range_m,
                    c.detection_threshold, c.point_dropout_prob, c.ref_reflectivity, c.ref_range_m,
                    c.intensity_mode == "signal", c.range_noise_m, c.resolution_m, idx, sig, points, intensity)  # fmt: skip
        # copies of the rows kept, so that a scan does not hold the whole sweep's buffers
        idx, sig, points, intensity = idx[:k].copy(), sig[:k].copy(), points[:k].copy(), intensity[:k].copy()
        gk = beams.geom[idx]
        stamp = float(sweep_start_s) + pat.sweep_period_s + c.latency_s
        kind = beams.kind[idx]
        if u_nan is not None:
            bad = u_nan[idx] < c.nan_point_prob
            points[bad] = np.nan
            intensity[bad] = 0
            kind[bad] = ReturnKind.NAN
        scan = LidarScan(
            stamp_s=stamp,
            sensor_id=self.sensor_id,
            points_xyz=points,
            intensity=intensity,
            ring=rays.channel[idx].astype(np.uint16),
            time_offset_s=rays.time_offset_s[idx].copy(),
            sweep_start_s=float(sweep_start_s),
        )
        hit_w = take_rows(beams.hit_w, idx)
        surface = label_surfaces(self._surface_table(truth), gk, hit_w)
        lt = LidarTruth(
            stamp_s=stamp,
            sensor_id=self.sensor_id,
            true_range_m=beams.path_m[idx],
            hit_w=hit_w,
            geom_id=gk,
            surface_id=surface,
            material=optics.name[gk],
            kind=kind,
            via_geom_id=beams.via_geom[idx],
            signal=sig,
            origin_w=take_rows(origins_w, idx),
            dir_w=take_rows(dirs_w, idx),
        )
        return scan, lt

    def _surface_table(self, truth: SceneTruth) -> SurfaceTable:
        if self._surface_cache is None or self._surface_cache[0] is not truth:
            self._surface_cache = (truth, SurfaceTable.build(truth, self.geom_names))
        return self._surface_cache[1]

    def _optics(self, model: object, truth: SceneTruth) -> GeomOptics:
        if self._optics_cache is None or self._optics_cache[0] is not truth:
            optics = geom_optics(self.geom_names, truth, self.config.material_overrides())
            c = self.config
            if c.glass_shaped:
                shape = PaneShapes(model, self.geom_names, optics.kind == KIND_CODE["glass"], 1e-3 * c.glass_bow_mm_per_m,
                                   1e-3 * c.glass_roller_wave_mm, c.glass_roller_wave_length_m, c.glass_shape_seed,
                                   optics.front_share)  # fmt: skip
                optics = replace(optics, shape=shape)
            self._optics_cache = (truth, optics)
        return self._optics_cache[1]


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
