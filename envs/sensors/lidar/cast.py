"""Casting a LiDAR sweep's rays: by the BVH caster (``LidarConfig.caster = "bvh"``, the default:
static boxes and planes by Embree with MuJoCo's exact hits, :mod:`exobench.envs.sensors.lidar.bvh`,
the other geoms by ``mj_multiRay`` below, the nearer hit; the same frames as the reference over whole
glazed loops) or all by ``mj_multiRay`` (``"mujoco"``, the reference). ``mj_multiRay``: batched,
zoned, near-first, threaded.

``mj_multiRay`` casts many rays from one point and costs about 0.1 ms per call in a furnished
scene, so the firings of each ``cast_period_s`` window are cast from one origin (the window's
middle firing) along their exact directions, and each range is then moved to the ray's own origin
on the plane of the face hit: ``r = (p - o) . n / (u . n)``. That is exact on planar faces; only
beams within the window's motion (about 1 mm at walking speed) of a silhouette edge, or on curved
geoms (error ~ d^2 / R), differ from casting every firing from its own origin
(``cast_period_s = 0``, slower). A static sensor is cast in one call. The calls (or, for one call,
slices of its rays) are spread over ``cast_threads`` threads (``mj_multiRay`` releases the GIL;
every ray's result is independent of the others, so the split never changes a result); threads
other than the caller's cast on a scratch ``MjData`` holding a copy of the geom poses. Two things
make the casts cheaper without changing a hit (tested against one plain pass on the simulation's
model): they run on a private copy of the ray-visible geoms with the static ones grouped in
spatial zones (:mod:`exobench.envs.sensors.lidar.ray_scene`, ``zoned_cast``), and each call first
traces its rays against the geoms within ``cast_near_m`` only, then the rays without a hit that
near against all geoms.
"""

from __future__ import annotations

import os
import threading
import warnings
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np

from .bvh import FewBoxes, Proxies, StaticBvh, embree_rays
from .config import LidarConfig
from .kernels import own_first, to_own_origins, world_boxes
from .optics import RayCastFn, cast_rays
from .pattern import RayTable
from .ray_scene import PRIMITIVE_TYPES, RayScene, build_ray_scene, ray_visible_geoms


@dataclass(eq=False)
class BvhParts:
    """The BVH caster of one model and sensor: static boxes and planes in Embree (``static``), the
    other ray-visible geoms (moving, curved) in a zoned private model for the primary rays
    (``rest``, None if there are none) and their ids (``others``, every body's, for the secondary
    rays, which exclude no body)."""

    static: StaticBvh
    rest: RayScene | None
    rest_geoms: np.ndarray
    others: np.ndarray
    rank: np.ndarray  # per geom, the order in which the primary-ray reference visits the geoms
    own: np.ndarray  # per BVH geom: on the sensor's own body (welded to the world), not hit by its beams
    own_others: np.ndarray  # of ``others``, those on the sensor's own body (the secondary rays' only extra ones)
    curved: FewBoxes  # the static ones of ``others`` (curved geoms welded to the world), whose poses never change


def build_bvh_parts(
    model: object, data: object, group: np.ndarray, body_exclude: int, max_range_m: float, zoned: bool = True
) -> tuple[BvhParts | None, str]:
    """The BVH caster's parts, or (None, why) for a scene it cannot take (meshes, height fields,
    SDFs, flexes, skins: MuJoCo casts those scenes whole)."""
    import mujoco

    m = model
    if int(getattr(m, "nflex", 0)) > 0 or int(getattr(m, "nskin", 0)) > 0:
        return None, "flexes or skins"
    visible = ray_visible_geoms(m, group, -1)
    types = np.asarray(m.geom_type)[visible]  # type: ignore[attr-defined]
    allowed = {int(getattr(mujoco.mjtGeom, f"mjGEOM_{t}")) for t in PRIMITIVE_TYPES}
    other = sorted({mujoco.mjtGeom(int(t)).name.removeprefix("mjGEOM_").lower() for t in types if int(t) not in allowed})
    if other:
        return None, f"geoms of type {', '.join(other)}"
    body = np.asarray(m.geom_bodyid)[visible]  # type: ignore[attr-defined]
    static = (np.asarray(m.body_weldid)[body] == 0) & (np.asarray(m.body_mocapid)[body] < 0)  # type: ignore[attr-defined]
    flat = np.isin(types, [int(mujoco.mjtGeom.mjGEOM_BOX), int(mujoco.mjtGeom.mjGEOM_PLANE)])
    in_bvh = visible[static & flat]
    others = visible[~(static & flat)]
    xpos = np.asarray(data.geom_xpos)[visible]  # type: ignore[attr-defined]
    extent = float(np.max(np.abs(xpos))) if len(xpos) else 0.0
    # infinite planes become quads reaching beyond any range from anywhere in the scene
    bvh = StaticBvh(m, data, in_bvh, far_m=2.0 * (extent + max_range_m) + 10.0)
    rest_geoms = np.intersect1d(others, ray_visible_geoms(m, group, body_exclude))  # not the sensor's own body
    rest = build_ray_scene(m, data, group, body_exclude, only=rest_geoms) if len(rest_geoms) else None
    # of equal hits at a seam the reference keeps the first geom it visits: the zoned copy's order
    rank = np.arange(int(m.ngeom))  # type: ignore[attr-defined]
    full = build_ray_scene(m, data, group, body_exclude) if zoned else None
    if full is not None:
        rank = np.full(int(m.ngeom), len(full.geom_of))  # type: ignore[attr-defined]
        rank[full.geom_of] = np.arange(len(full.geom_of))
    own = np.asarray(m.geom_bodyid)[in_bvh] == body_exclude  # type: ignore[attr-defined]
    static_others = others[np.asarray(m.body_weldid)[np.asarray(m.geom_bodyid)[others]] == 0]  # type: ignore[attr-defined]
    curved = FewBoxes(m, data, static_others)
    return BvhParts(bvh, rest, rest_geoms, others, rank, own, np.setdiff1d(others, rest_geoms), curved), ""


class RayCaster:
    """Casts the primary rays of one LiDAR (its geom groups, its own body excluded)."""

    def __init__(self, config: LidarConfig, group: np.ndarray, body_exclude: int) -> None:
        self.config, self.group, self.body_exclude = config, group, body_exclude
        self._scratch: tuple[object, list[object]] | None = None
        self._ray_scene: tuple[object, RayScene | None] | None = None
        self._bvh_parts: tuple[object, BvhParts | None] | None = None
        # the proxies of the last primary cast, for that sweep's secondary rays (``secondary``)
        self._proxies: tuple[object, object, Proxies] | None = None
        self.fallback: str | None = None  # why the BVH caster fell back to MuJoCo's, once it did

    def cast(
        self, model: object, data: object, rays: RayTable, origins_w: np.ndarray, dirs_w: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Primary hits of every ray from its own origin: (geom, distance, normal), -1 if none."""
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
        max_r = self.config.pattern.max_range_m + 1.0
        o_ray = np.repeat(o_cast, ends - starts, axis=0)
        parts = self._bvh(model, data)
        if parts is None:
            jobs = [(o, int(s), int(e)) for o, s, e in zip(o_cast, starts, ends)]
            gid, dist, nrm = self._multi_ray(model, data, jobs, dirs_w, n, max_r)
        else:
            # static boxes and planes by Embree, the rest (moving, curved) by MuJoCo: the nearer hit
            k = self._n_threads(model)
            dirs_w = np.ascontiguousarray(dirs_w, dtype=float)
            rays_f = embree_rays(o_ray, dirs_w)  # one float32 copy for the static and the proxy casts
            gid, dist, nrm = parts.static.cast(o_ray, dirs_w, k, cutoff=max_r, rank=parts.rank,
                                               skip=parts.own if np.any(parts.own) else None, rays=rays_f)
            if parts.rest is not None:
                # only the rays that may meet a moving or curved geom before the static hit
                proxies = Proxies(model, data, parts.rest_geoms)
                self._proxies = (model, data, proxies)
                need = np.flatnonzero(proxies.may_hit_before(o_ray, dirs_w, dist, k, rays=rays_f))
                first = np.searchsorted(need, starts)
                last = np.append(first[1:], len(need))
                sub = [(o, int(a), int(b)) for o, a, b in zip(o_cast, first, last) if b > a]
                # one pass: these geoms are few, so a near pass first saves little and casts the rays
                # without a hit that near twice (the same hits either way)
                g2, d2, n2 = self._multi_ray(model, data, sub, np.ascontiguousarray(dirs_w[need]), len(need), max_r,
                                             scene=parts.rest, one_pass=True)  # fmt: skip
                take = (d2 >= 0.0) & (g2 >= 0) & ((dist[need] < 0.0) | (d2 < dist[need]))
                gid[need[take]], dist[need[take]], nrm[need[take]] = g2[take], d2[take], n2[take]
        # move each range from the cast origin to the ray's own origin, on the plane of the face hit
        to_own_origins(gid, dist, nrm, dirs_w, o_ray, origins_w)
        return gid, dist, nrm

    def _multi_ray(
        self, model: object, data: object, jobs: list[tuple[np.ndarray, int, int]], dirs_w: np.ndarray, n: int,
        max_r: float, scene: RayScene | None = None, one_pass: bool = False,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``mj_multiRay`` of each job (origin, first ray, end) on the zoned copy (or ``scene``, or the model);
        ``one_pass``: every ray against every geom at once, without the near pass first."""
        import mujoco

        scene = scene if scene is not None else self._zoned(model, data)
        if scene is not None:
            scene.sync(data)
            model, data, mask, exclude = scene.model, scene.data, scene.group, -1
        else:
            mask, exclude = self.group, self.body_exclude
        gid = np.full(n, -1, dtype=np.int32)
        dist = np.full(n, -1.0)
        nrm = np.zeros(3 * n)
        flat = dirs_w.reshape(-1)
        k = self._n_threads(model)
        if 1 < k and len(jobs) < k:  # few calls (a static sensor): cut them into slices of their rays
            jobs = [(o, a, b) for o, s, e in jobs for a, b in _slices(s, e, k) if b > a]
        groups = _partition(jobs, k)

        near = self.config.cast_near_m if 0.0 < self.config.cast_near_m < max_r else max_r
        if one_pass:
            near = max_r

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
                    g2, d2, n2 = (
                        np.full(len(far), -1, dtype=np.int32),
                        np.full(len(far), -1.0),
                        np.zeros(3 * len(far)),
                    )
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
        if scene is not None:
            gid = scene.original_geoms(gid)
        return gid, dist, nrm.reshape(-1, 3)

    def secondary(self, model: object, data: object) -> RayCastFn:
        """The caster of a sweep's secondary rays (``data`` is frozen for the sweep): ``mj_ray``
        semantics (no cut-off, no body excluded), all rays of a call in one batch with the BVH."""
        parts = self._bvh(model, data)
        if parts is None:
            return lambda o, d: cast_rays(model, data, self.group, o, d)
        # the primary cast's proxies, where the geoms have not moved since: building and committing an
        # Embree scene costs more than its casts of a sweep's secondary rays
        shared, self._proxies = self._proxies, None
        ok = shared is not None and shared[0] is model and shared[1] is data and shared[2].posed_as(data)
        return _SecondaryCast(model, data, self.group, parts, self._n_threads(model), shared[2] if ok else None)

    def _bvh(self, model: object, data: object) -> BvhParts | None:
        """The BVH caster's parts for ``model`` (built on first use); None when casting with MuJoCo."""
        if self.config.caster != "bvh":
            return None
        if self._bvh_parts is None or self._bvh_parts[0] is not model:
            parts, why = build_bvh_parts(
                model, data, self.group, self.body_exclude, self.config.pattern.max_range_m, self.config.zoned_cast
            )
            if parts is None and self.fallback is None:
                self.fallback = why
                warnings.warn(f"lidar: the BVH caster cannot take this scene ({why}); casting with MuJoCo",
                              RuntimeWarning, stacklevel=3)  # fmt: skip
            self._bvh_parts = (model, parts)
        return self._bvh_parts[1]

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


class _SecondaryCast:
    """A sweep's secondary rays by the BVH caster (:meth:`RayCaster.secondary`), a batch per call."""

    def __init__(self, model: object, data: object, group: np.ndarray, parts: BvhParts, nthreads: int,
                 primary: Proxies | None = None) -> None:  # fmt: skip
        self.model, self.data, self.group, self.parts, self.k = model, data, group, parts, nthreads
        self.small = _MJ_RAY_GEOM_RAYS // max(1, int(model.ngeom))  # type: ignore[attr-defined]
        # ``primary``: the primary cast's proxies (every geom of ``others`` but the sensor's own body's,
        # whose few boxes are tested in a compiled loop); else all proxies, built at the sweep's first
        # batch (most sweeps have none)
        self.primary = primary
        self.proxies: Proxies | None = None
        self.own: FewBoxes | None = None
        self._others_box: tuple[np.ndarray, np.ndarray] | None = None

    def __call__(self, o: np.ndarray, d: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        model, data = self.model, self.data
        if len(o) <= self.small:  # a few rays: mj_ray (the reference) costs less than a batch's set-up
            return cast_rays(model, data, self.group, o, d)
        o = np.ascontiguousarray(o, dtype=float)
        d = np.ascontiguousarray(d, dtype=float)
        rays_f = embree_rays(o, d)
        gid, r, nrm = self.parts.static.cast(o, d, self.k, inside=True, rays=rays_f)
        gid = gid.astype(np.int64)
        # the few rays that may meet a moving or curved geom first: exactly as the reference
        near = np.flatnonzero(self._may_meet_others(o, d, r, rays_f))
        if len(near) == 0:
            return r, gid, nrm
        # those that may meet a static curved geom: mj_ray on every geom; the others, nearly all, on the
        # moving geoms alone (flg_static 0: the bodies welded to the world, which the BVH holds, left
        # out), the nearer hit kept, of equal ones the lower geom id (mj_ray's order): the same hits
        curved = self.parts.curved.may_hit_before(o[near], d[near], r[near], np.zeros(len(near), dtype=bool))
        full, moving = near[curved], near[~curved]
        if len(full):
            r[full], gid[full], nrm[full] = cast_rays(model, data, self.group, o[full], d[full])
        if len(moving):
            r2, g2, n2 = cast_rays(model, data, self.group, o[moving], d[moving], flg_static=0)
            r1, g1 = r[moving], gid[moving]
            take = (r2 >= 0.0) & (g2 >= 0) & ((r1 < 0.0) | (g1 < 0) | (r2 < r1) | ((r2 == r1) & (g2 < g1)))
            w = moving[take]
            r[w], gid[w], nrm[w] = r2[take], g2[take], n2[take]
        return r, gid, nrm

    def _may_meet_others(self, o: np.ndarray, d: np.ndarray, r: np.ndarray, rays_f: object) -> np.ndarray:
        """Rays that may meet a moving or curved geom (``others``) nearer than ``r`` (-1: no hit)."""
        if self.primary is not None:
            if self.own is None:
                self.own = FewBoxes(self.model, self.data, self.parts.own_others)
            return self.own.may_hit_before(o, d, r, self.primary.may_hit_before(o, d, r, self.k, rays=rays_f))
        if self.proxies is None:
            self.proxies = Proxies(self.model, self.data, self.parts.others)
        return self.proxies.may_hit_before(o, d, r, self.k, rays=rays_f)

    def own_first(self, o: np.ndarray, d: np.ndarray, geoms: np.ndarray, x: np.ndarray) -> np.ndarray:
        """Rays starting in the static box ``geoms`` and leaving it at ``x`` (:meth:`exit_m`) whose cast
        would surely report that box at ``x`` (optics' ``_leave``: it then casts only the ray from just
        past it). Every geom met within the box overlaps it: none of the static ones that do is met as
        near by its exact hit, and no moving or curved geom's box overlaps it (their world boxes in this
        sweep's poses, 1 mm larger): :func:`kernels.own_first`, one compiled pass."""
        st = self.parts.static
        if self._others_box is None:
            g = np.ascontiguousarray(self.parts.others, dtype=np.int64)
            lo, hi = np.empty((len(g), 3)), np.empty((len(g), 3))
            world_boxes(g, np.asarray(self.model.geom_aabb), np.asarray(self.data.geom_xpos),  # type: ignore[attr-defined]
                        np.asarray(self.data.geom_xmat), 1e-3, lo, hi)  # type: ignore[attr-defined]  # fmt: skip
            self._others_box = (lo, hi)
        out = np.empty(len(o), dtype=bool)
        start, nb = st.neighbours
        own_first(np.ascontiguousarray(geoms, dtype=np.int64), st._row, np.ascontiguousarray(o, dtype=float),
                  np.ascontiguousarray(d, dtype=float), np.ascontiguousarray(x, dtype=float), start, nb, st.pos, st.mat,
                  st.size, st.plane, st.lo, st.hi, st.geom, *self._others_box, out)  # fmt: skip
        return out

    def exit_m(self, o: np.ndarray, d: np.ndarray, geoms: np.ndarray) -> np.ndarray:
        """Where each ray would meet the geom ``geoms`` (MuJoCo's distance: what a cast reports if that
        geom is the hit), -1 where it does not or is not a static box or plane (optics' ``_leave``)."""
        return self.parts.static.exact_on(geoms, o, d)


_MJ_RAY_GEOM_RAYS = 20_000
"""A secondary batch of at most this many rays times geoms is cast by ``mj_ray`` one ray at a time:
``mj_ray`` costs about (0.5 + 0.0075 x geoms) us per ray (3 us in the default office's 316 geoms, 6.5
us in 24 offices' 834), a batch through the BVH about 0.12-0.17 ms of fixed costs (Embree calls, exact
hits, seams, edge tubes, proxies) and 0.6 us a ray, so the two break even at about 20,000 rays times
geoms (measured on the bench's scenes: 60 rays at 6 offices, 20 at 24). It was 60,000 while a batch's
rays starting on a surface float32 rounds them back onto were listed whole (``StaticBvh._recast``)."""

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
