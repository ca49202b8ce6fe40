"""The stairs track's offline baseline ``batch-ransac``: planes segmented once the stream has ended.

Frame handling is shared with the other stairs pipelines (:mod:`.pipeline_base`); the
segmentation is the connected sequential RANSAC of :mod:`.ransac`.
"""


from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from exobench.core.errors import check_int, check_range
from exobench.core.estimates import StaircaseEstimate

from .pipeline_base import StairsPipeline, check_common_config
from .ransac import ScanCloud, connected_ransac_plane, tls_plane
from .readout import MIN_TREAD_NZ
from .rtls import RtlsPlane
from .staircase import FLAGS


class BatchRansacStairs(StairsPipeline):
    """Offline baseline: all points kept, planes segmented at ``finalize``, same read-out.

    The dense offline comparison of the paper (Sec. V-C), done as point-cloud segmentation is:

    1. Sequential RANSAC (:func:`connected_ransac_plane`, seeded numpy): each plane is the best
       hypothesis by its *connected* support -- the largest cluster of inlier runs that are
       contiguous in each beam's scan order, linked within ``link_radius_m`` and holding both
       beams (:func:`connected_support`), counted in distinct voxels of ``voxel_m`` -- so that
       planes through the stair corners, along one beam's sweep, or through one beam's track on
       a tread and the other's on the level below, which hold many inliers, lose against real
       surfaces; each new best is refined by TLS fits on its support (LO-RANSAC). Its support
       leaves the pool; extraction stops after ``max_planes`` planes or when the best support
       is below ``min_plane_cells``.
    2. Labels in walking order (:meth:`_label`): planes with ``|n_z| >= cos 45 deg`` are treads,
       taken by ascending height; a tread opens a new level (index 0, 2, 4) when it lies more
       than ``th_pl_m`` above the current level (which starts at the ground, z = 0 of
       ``stance_ground``), else it joins the current level. A riser takes the index between the
       two tread levels its centroid height lies between: ``2 k + 1`` for the ``k``-th level
       below it, with the level heights spaced by the first tread's height when upper levels
       were not seen. Indices above 4 are not reported.
    3. Planes of the same index are merged. Every used point goes to the nearest extracted
       plane within ``distance_threshold_m`` (``-1`` when there is none or that plane has no
       index) and the planes are refitted by TLS on the voxel means
       (:meth:`ScanCloud.cell_means`) of the points near them alone, until the assignment is
       stable (:meth:`_refine`): voxel means keep a spot the beam dwelt on just beyond an edge
       from tilting a plane towards it. The reported plane is the TLS fit of the points of
       its index that are near no other plane (all of them when fewer than 3).

    Reliability: a plane is reliable with at least ``reliable_n`` points of each sensor. The
    method is offline -- nothing is known before the last point is in -- so
    ``reliable_stamp_s`` is the stamp of the last used point (the end of the stream) for every
    reliable plane; the stamp at which a plane's ``reliable_n``-th point of each sensor arrived
    is reported in ``stats["data_complete_stamp_s"]`` (key ``"S<i>"``). ``process`` returns
    None.
    """

    name: ClassVar[str] = "batch-ransac"

    @dataclass(frozen=True)
    class Config:
        """Parameters (SI units).

        Attributes:
            leg, stance_side, imu_sensor_id: as for :class:`RtlsStairs.Config`.
            th_pl_m: smallest riser height separating two tread levels (paper: 0.13 m).
            reliable_n: points needed from each sensor for a reliable plane (as RTLS's ``N``).
            distance_threshold_m: inlier distance of RANSAC and of the final assignment, about
                3 sigma of the 1.5 mm ToF noise.
            ransac_iterations: hypotheses drawn per plane.
            sample_window: readings around a sample's first point, in scan order, from which
                its other two points are drawn (its own beam, the other beam).
            min_run_points: shortest run of one beam's inliers, contiguous in scan order, that
                counts as support.
            max_run_gap: readings of a beam that may be missing (not inliers) inside a run.
            link_radius_m: runs of inliers closer than this are connected (:func:`connected_support`):
                above the spacing of the two beams' tracks on a surface (0.11-0.14 m here), below
                the distance from a tread to the level below (a riser, 0.15 m or more).
            voxel_m: edge of the voxels in which support is counted (:class:`ScanCloud`).
            min_plane_cells: smallest support of an extracted plane, in distinct cells.
            max_planes: most planes extracted.
            refine_iterations: rounds of assigning the points to their nearest plane and
                refitting the planes after the extraction (:meth:`_refine`).
            seed: seed of the RANSAC sampling (``numpy.random.default_rng``); same input and
                config give the same estimate.
        """

        leg: str = "r"
        stance_side: str = "l"
        imu_sensor_id: str = "imu_trunk"
        th_pl_m: float = 0.13
        reliable_n: int = 5
        distance_threshold_m: float = 0.005
        ransac_iterations: int = 1000
        sample_window: int = 8
        min_run_points: int = 3
        max_run_gap: int = 2
        link_radius_m: float = 0.16
        voxel_m: float = 0.005
        min_plane_cells: int = 6
        max_planes: int = 8
        refine_iterations: int = 10
        seed: int = 0

        def __post_init__(self) -> None:
            check_common_config(self)
            check_range("distance_threshold_m", self.distance_threshold_m, 0.0, 1.0, low_open=True)
            check_range("link_radius_m", self.link_radius_m, 0.0, 10.0, low_open=True)
            check_range("voxel_m", self.voxel_m, 0.0, 1.0, low_open=True)
            for name, low, high in (
                ("ransac_iterations", 1, 10**6),  # every hypothesis is drawn (no early exit): bound the time
                ("sample_window", 1, None),
                ("min_run_points", 2, None),
                ("max_run_gap", 0, None),
                ("min_plane_cells", 3, None),
                ("max_planes", 1, None),
                ("refine_iterations", 0, None),
                ("seed", 0, None),
            ):
                object.__setattr__(self, name, check_int(name, getattr(self, name), low, high))

    def _reset_estimator(self) -> None:
        self._points: list[tuple[float, float, float]] = []
        self._point_flags: list[str] = []
        self._result: StaircaseEstimate | None = None

    def _consume(self, uid: int, p: tuple[float, float, float], flag: str) -> None:
        self._points.append(p)
        self._point_flags.append(flag)
        self._result = None

    def _finalize(self) -> StaircaseEstimate:
        if self._result is not None:
            return self._result
        t0 = time.perf_counter_ns()
        cfg = self.config
        pts = np.array(self._points, dtype=float).reshape(-1, 3)
        flags = np.array(self._point_flags, dtype=str)
        cloud = ScanCloud.of(pts, flags == FLAGS[1], np.array(self._uid_stamp, dtype=float), cfg.voxel_m)
        groups = self._segment(cloud)
        labels = self._label([tls_plane(cloud.cell_means(g)) for g in groups])
        # one plane per label (pieces of a surface merged), the unlabelled ones kept apart
        members: dict[int, list[np.ndarray]] = {}
        for k, g in enumerate(groups):
            members.setdefault(labels.get(k, -1 - k), []).append(g)
        keys = sorted(members, key=lambda i: (i < 0, abs(i)))
        fits = [tls_plane(cloud.cell_means(np.concatenate(members[i])))[:2] for i in keys]
        near, unique = self._refine(cloud, fits)
        label_of = np.array([max(i, -1) for i in keys] + [-1])
        where = label_of[near]
        planes, complete = [], {}
        last_uid = len(pts) - 1
        for index in sorted(set(where[where >= 0].tolist())):
            idx = np.flatnonzero(where == index)
            used = idx[unique[idx]] if np.count_nonzero(unique[idx]) >= 3 else idx
            fit = RtlsPlane()
            for k in used:
                fit.add(pts[k])
            counts = {f: int(np.sum(flags[idx] == f)) for f in FLAGS}
            done = self._complete_uid(idx, flags)
            if done is not None:
                complete[f"S{index}"] = self._uid_stamp[done]
            ok_uid = last_uid if done is not None else None
            planes.append(self._plane(index, fit, counts, done is not None, ok_uid))
        share_ns = (time.perf_counter_ns() - t0) / max(len(pts), 1)
        self._times_ns = [t + share_ns for t in self._times_ns]
        extra = {"n_planes_found": len(groups), "data_complete_stamp_s": complete}
        self._result = self._estimate(planes, where, extra)
        return self._result

    def _refine(self, cloud: ScanCloud, fits: list[tuple[np.ndarray, np.ndarray]]) -> tuple[np.ndarray, np.ndarray]:
        """Assign every point to its nearest plane within the threshold and refit, until stable.

        Returns, per point, the index of its plane in ``fits`` (``len(fits)`` for none) and
        whether it lies within the threshold of that plane only. Fits use only such points
        (their voxel means): those near the intersection of two planes (the stair edges) are
        ambiguous and would tilt both planes towards each other. ``fits`` is updated in place.
        """
        thr = self.config.distance_threshold_m
        pts, beam = cloud.points, cloud.sensor
        near = np.full(len(pts), len(fits))
        unique = np.zeros(len(pts), dtype=bool)
        if not fits or not len(pts):
            return near, unique
        for _ in range(self.config.refine_iterations + 1):
            dist = np.abs(np.stack([(pts - c) @ n for n, c in fits], axis=1))
            order = np.argsort(dist, axis=1, kind="stable")
            d1 = dist[np.arange(len(pts)), order[:, 0]]
            d2 = dist[np.arange(len(pts)), order[:, 1]] if len(fits) > 1 else np.full(len(pts), np.inf)
            new = np.where(d1 <= thr, order[:, 0], len(fits))
            unique = (d1 <= thr) & (d2 > thr)
            if np.array_equal(new, near):
                break
            near = new
            for k in range(len(fits)):
                sel = (near == k) & unique
                if all(np.count_nonzero(sel & (beam == b)) >= 2 for b in (0, 1)):
                    fits[k] = tls_plane(cloud.cell_means(np.flatnonzero(sel)))[:2]
        return near, unique

    def _complete_uid(self, idx: np.ndarray, flags: np.ndarray) -> int | None:
        """The point (in arrival order) that gave the plane its ``reliable_n``-th of each sensor."""
        seen = dict.fromkeys(FLAGS, 0)
        for k in idx:  # idx is sorted, i.e. in arrival order
            seen[str(flags[k])] += 1
            if all(v >= self.config.reliable_n for v in seen.values()):
                return int(k)
        return None

    def _segment(self, cloud: ScanCloud) -> list[np.ndarray]:
        """Sequential connected RANSAC: the supports of the extracted planes, in order."""
        cfg = self.config
        rng = np.random.default_rng(cfg.seed)
        active = np.ones(len(cloud.points), dtype=bool)
        groups: list[np.ndarray] = []
        while np.count_nonzero(active) >= cfg.min_plane_cells and len(groups) < cfg.max_planes:
            support, score = connected_ransac_plane(
                cloud,
                active,
                threshold_m=cfg.distance_threshold_m,
                iterations=cfg.ransac_iterations,
                rng=rng,
                window=cfg.sample_window,
                min_run=cfg.min_run_points,
                max_gap=cfg.max_run_gap,
                link_radius_m=cfg.link_radius_m,
                min_score=cfg.min_plane_cells,
            )
            if score < cfg.min_plane_cells:
                break
            groups.append(support)
            active[support] = False
        return groups

    def _label(self, fits: list[tuple[np.ndarray, np.ndarray, float]]) -> dict[int, int]:
        """Surface index (0..4) of each extracted plane (by position in ``fits``) that has one."""
        th_pl = self.config.th_pl_m
        treads = sorted((float(c[2]), k) for k, (n, c, _s) in enumerate(fits) if abs(n[2]) >= MIN_TREAD_NZ)
        risers = [(float(c[2]), k) for k, (n, c, _s) in enumerate(fits) if abs(n[2]) < MIN_TREAD_NZ]
        labels: dict[int, int] = {}
        levels: dict[int, float] = {0: 0.0}  # tread index -> height of its level (ground at z = 0)
        index, level_z = 0, 0.0
        for z, k in treads:
            if z > level_z + th_pl:
                index, level_z = index + 2, z
                levels[index] = z
            labels[k] = index
        # level heights for the risers: seen levels, the rest spaced like the first step above
        step = next((z / (i // 2) for i, z in sorted(levels.items()) if i > 0), None)
        for z, k in risers:
            below = [i for i, lz in levels.items() if lz < z]
            i = max(below) if below else 0
            if step is not None and step > th_pl:
                i = max(i, 2 * int(math.floor(z / step)))
            labels[k] = i + 1
        return {k: i for k, i in labels.items() if i <= 4}
