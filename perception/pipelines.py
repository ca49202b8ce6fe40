"""Stairs-track pipelines: the paper's RTLS (general and HTVR) and a batch RANSAC baseline.

Every pipeline follows :class:`exobench.core.pipeline.Pipeline`. It consumes the encoder
states, the trunk IMU and the two calf ToF sensors of the climbing leg, turns each valid range
into a point of the ``stance_ground`` frame with :class:`TofKinematics` and estimates the
surfaces S0..S4. Frames of other sensors are ignored. Faulty input never raises; it is counted
in ``stats`` (:class:`exobench.core.frames.StreamStats` plus extras):

- ``n_no_return``: ToF status not VALID; ``n_nan``: VALID status but a non-finite range;
  ``n_bad_range``: negative range; ``n_without_state``: no encoder or IMU state yet;
  ``n_bad_state``: an encoder state with non-finite angles or an IMU quaternion that is not
  finite and about unit (the frame is ignored, the previous state kept);
  ``n_out_of_order``: a frame older than the previous one of the same sensor (skipped; a stale
  encoder or IMU state never replaces a newer one); ``n_ignored``: frames of other sensors.

Sensor flags: the paper's "right"/"left" sensor flags are the climbing leg's two calf sensors
by their side: for the right leg ``tof_r_lat`` is "r" and ``tof_r_med`` is "l"; for the left leg
``tof_l_med`` is "r" and ``tof_l_lat`` is "l".

``assignments`` hold one entry per ToF frame received (of any sensor, in arrival order), so
they line up with the episode's ToF ground truth; unused readings have index -2 and a NaN
point. ``compute_time_s`` holds, per used point, the time (``time.perf_counter_ns``) spent on
the work the paper times per point: the point's forward kinematics from the latest encoder and
IMU states (computed lazily, so a new state costs the first point that uses it) and
``Assign``/``SurfUpdate`` (RTLS); frame checks and bookkeeping are outside it. For the batch
baseline it is the kinematics time plus an equal share of the time spent in ``finalize``.

The online estimate that ``process`` returns is rebuilt only after a point was used, and only
the planes that changed are read out again (RTLS).
"""

from __future__ import annotations

import math
import time
from abc import ABC, abstractmethod
from dataclasses import asdict, dataclass
from typing import Any, ClassVar

import numpy as np

from exobench.core.calibration import Calibration
from exobench.core.errors import ConfigError, ExobenchError, check_range
from exobench.core.estimates import PlaneEstimate, PointAssignment, StaircaseEstimate
from exobench.core.frames import Frame, ImuSample, JointState, StreamStats, ToFReading, TofStatus

from .readout import MIN_TREAD_NZ, orient_normal, riser_height_m, tread_depth_m
from .rtls import PlaneFit, RtlsPlane
from .staircase import FLAGS, StaircaseAlgorithm, StaircaseParams
from .tof_kinematics import ESTIMATOR_FRAME, TofKinematics

__all__ = [
    "BatchRansacStairs",
    "RtlsHtvrStairs",
    "RtlsStairs",
    "ScanCloud",
    "connected_ransac_plane",
    "connected_support",
    "sensor_flags",
    "tls_plane",
]


def sensor_flags(leg: str) -> dict[str, str]:
    """ToF sensor id -> the paper's flag (``"r"``/``"l"``) for the calf sensors of ``leg``."""
    if leg == "r":
        return {"tof_r_lat": "r", "tof_r_med": "l"}
    if leg == "l":
        return {"tof_l_med": "r", "tof_l_lat": "l"}
    raise ConfigError("leg", leg, "'l' or 'r'")


# --- batch baseline: connected sequential RANSAC on the two beams' scans ----------------------
@dataclass(frozen=True, eq=False)
class ScanCloud:
    """The points of two scanning beams, in arrival order, with what connectivity needs.

    Attributes:
        points: (N, 3) points.
        sensor: (N,) beam of each point, 0 or 1.
        stamps_s: (N,) arrival stamps, non-decreasing per beam.
        seq: (N,) position of each point in its own beam's sequence (scan order).
        by_sensor: per beam, the indices of its points in scan order.
        cell: (N,) id of the point's (beam, voxel) cell for voxels of ``voxel_m``: support is
            counted in distinct cells, as after a voxel-grid down-sampling, so that the dense
            spot a beam leaves while it barely moves (the still phase, the end of the swing)
            weighs no more than a few points of a swept surface.
    """

    points: np.ndarray
    sensor: np.ndarray
    stamps_s: np.ndarray
    seq: np.ndarray
    by_sensor: tuple[np.ndarray, np.ndarray]
    cell: np.ndarray

    @classmethod
    def of(cls, points: np.ndarray, sensor: np.ndarray, stamps_s: np.ndarray, voxel_m: float = 0.005) -> ScanCloud:
        P = np.asarray(points, dtype=float).reshape(-1, 3)
        s = np.asarray(sensor, dtype=int).reshape(-1)
        t = np.asarray(stamps_s, dtype=float).reshape(-1)
        if not len(s) == len(t) == len(P) or not np.all((s == 0) | (s == 1)):
            raise ConfigError("sensor", f"{len(s)} beams, {len(t)} stamps, {len(P)} points", "one beam (0 or 1) and one stamp per point")
        check_range("voxel_m", voxel_m, 0.0, None, low_open=True)
        by = (np.flatnonzero(s == 0), np.flatnonzero(s == 1))
        seq = np.zeros(len(P), dtype=int)
        for idx in by:
            seq[idx] = np.arange(len(idx))
        keys = np.column_stack([s, np.floor(P / voxel_m).astype(np.int64)]) if len(P) else np.zeros((0, 4), dtype=np.int64)
        cell = np.unique(keys, axis=0, return_inverse=True)[1].reshape(-1)
        return cls(P, s, t, seq, by, cell)

    def score(self, indices: np.ndarray) -> int:
        """Support of the points ``indices``: the number of distinct (beam, voxel) cells."""
        return len(np.unique(self.cell[indices]))

    def cell_means(self, indices: np.ndarray) -> np.ndarray:
        """(M, 3) mean of the points ``indices`` in each of their M cells: a voxel-grid
        down-sampling, which weighs a spot the beam dwelt on like a few swept points."""
        idx = np.asarray(indices, dtype=int)
        cells, inv = np.unique(self.cell[idx], return_inverse=True)
        out = np.zeros((len(cells), 3))
        np.add.at(out, inv.reshape(-1), self.points[idx])
        return out / np.bincount(inv.reshape(-1), minlength=len(cells))[:, None]


def tls_plane(points: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """Total least squares plane of (N >= 3, 3) points: unit normal, centroid, sigma of distances."""
    P = np.asarray(points, dtype=float)
    c = P.mean(axis=0)
    w, U = np.linalg.eigh((P - c).T @ (P - c))
    return U[:, 0], c, float(math.sqrt(max(w[0], 0.0) / len(P)))


def connected_support(
    cloud: ScanCloud,
    inliers: np.ndarray,
    *,
    min_run: int,
    max_gap: int,
    link_radius_m: float,
    min_score: int = 1,
) -> np.ndarray:
    """Indices (ascending) of the largest connected cluster among the inliers of a plane.

    ``inliers`` is a boolean mask over the cloud. Each beam's inliers are split into runs that
    are contiguous in its scan order (at most ``max_gap`` of its readings missing inside a run);
    runs shorter than ``min_run`` are dropped. Runs (of either beam) closer than
    ``link_radius_m`` at their nearest points are connected; the cluster of connected runs
    with the highest :meth:`ScanCloud.score` that holds runs of both beams wins (ties: the
    earliest). The radius must bridge the spacing of the two beams' tracks on a surface and
    stay below the gap between a tread and the level below it: the accidental planes of a
    two-beam scan -- through the stair corners, along one beam's own (nearly planar) sweep,
    or "rolled" through one beam's track on a tread and the other's on the level below --
    then give only short runs, runs of one beam, or runs too far apart. Empty when no
    cluster reaches ``min_score``.
    """
    runs: list[np.ndarray] = []
    beams: list[int] = []
    for b, by in enumerate(cloud.by_sensor):
        idx = by[inliers[by]]
        cut = np.flatnonzero(np.diff(cloud.seq[idx]) > max_gap + 1) + 1
        for r in np.split(idx, cut):
            if len(r) >= min_run:
                runs.append(r)
                beams.append(b)
    if len(set(beams)) < 2 or cloud.score(np.concatenate(runs)) < min_score:
        return np.zeros(0, dtype=int)
    pts = cloud.points[np.concatenate(runs)]
    starts = np.cumsum([0] + [len(r) for r in runs[:-1]])
    d2 = np.sum((pts[:, None, :] - pts[None, :, :]) ** 2, axis=2)
    d2 = np.minimum.reduceat(np.minimum.reduceat(d2, starts, axis=0), starts, axis=1)
    near = d2 <= link_radius_m**2
    cluster = list(range(len(runs)))  # union-find over the runs
    for a, b in zip(*np.nonzero(np.triu(near, 1)), strict=True):
        ra, rb = _root(cluster, int(a)), _root(cluster, int(b))
        cluster[max(ra, rb)] = min(ra, rb)
    best, best_score = np.zeros(0, dtype=int), max(min_score, 1) - 1
    roots = [_root(cluster, k) for k in range(len(runs))]
    for root in sorted(set(roots)):
        members = [k for k in range(len(runs)) if roots[k] == root]
        if len({beams[k] for k in members}) < 2:
            continue
        idx = np.sort(np.concatenate([runs[k] for k in members]))
        score = cloud.score(idx)
        if score > best_score:
            best, best_score = idx, score
    return best


def _root(parent: list[int], k: int) -> int:
    while parent[k] != k:
        parent[k] = parent[parent[k]]
        k = parent[k]
    return k


def _local_samples(cloud: ScanCloud, active: np.ndarray, rng: np.random.Generator, k: int, window: int) -> np.ndarray:
    """(m <= k, 3) index triples: a random active point, an active point of the same beam within
    ``window`` readings in scan order, and an active point of the other beam within ``window``
    readings of the same moment (NAPSAC-style local sampling; invalid draws are dropped)."""
    pool = np.flatnonzero(active)
    i = pool[rng.integers(0, len(pool), size=k)]
    off = np.stack(
        [rng.integers(1, window + 1, size=k) * np.where(rng.random(k) < 0.5, -1, 1), rng.integers(-window, window + 1, size=k)],
        axis=1,
    )
    s = cloud.sensor[i]
    j = np.full(k, -1)
    m = np.full(k, -1)
    for b in (0, 1):
        sel = s == b
        same, other = cloud.by_sensor[b], cloud.by_sensor[1 - b]
        pj = cloud.seq[i[sel]] + off[sel, 0]
        ok = (pj >= 0) & (pj < len(same))
        j[np.flatnonzero(sel)[ok]] = same[pj[ok]]
        if len(other):
            pm = np.searchsorted(cloud.stamps_s[other], cloud.stamps_s[i[sel]]) + off[sel, 1]
            ok = (pm >= 0) & (pm < len(other))
            m[np.flatnonzero(sel)[ok]] = other[pm[ok]]
    good = (j >= 0) & (m >= 0)
    good[good] &= active[j[good]] & active[m[good]]
    return np.stack([i, j, m], axis=1)[good]


def _run_cells_bound(
    cloud: ScanCloud, act: np.ndarray, inside: np.ndarray, min_run: int, max_gap: int, link: np.ndarray
) -> np.ndarray:
    """An upper bound of the score of every hypothesis at once (see :func:`connected_support`).

    ``inside`` holds the inlier masks (columns) of the hypotheses over the points ``act``;
    ``link`` says which points of beam 0 and beam 1 (rows, columns; in the order of ``act``)
    are within the link radius. The bound is the number of distinct cells of the inliers in
    runs of at least ``min_run``, or 0 when no such run of one beam is near one of the other.
    """
    k = inside.shape[1]
    n_cells = int(cloud.cell.max()) + 1 if len(cloud.cell) else 1
    keys, kept_masks = [], []
    for b in (0, 1):
        rows = np.flatnonzero(cloud.sensor[act] == b)
        col, pos = np.nonzero(inside[rows].T)  # by hypothesis, then scan order
        seq = cloud.seq[act[rows[pos]]]
        kept = np.zeros(len(col), dtype=bool)
        if len(col):
            run = np.cumsum(np.r_[True, (np.diff(col) != 0) | (np.diff(seq) > max_gap + 1)]) - 1
            kept = np.bincount(run)[run] >= min_run
        mask = np.zeros((k, len(rows)))
        mask[col[kept], pos[kept]] = 1.0
        kept_masks.append(mask)
        keys.append(col[kept].astype(np.int64) * n_cells + cloud.cell[act[rows[pos[kept]]]])
    linked = np.einsum("ij,ij->i", kept_masks[0] @ link, kept_masks[1]) > 0
    cols = np.unique(np.concatenate(keys)) // n_cells
    return np.where(linked, np.bincount(cols, minlength=k), 0)


def connected_ransac_plane(
    cloud: ScanCloud,
    active: np.ndarray,
    *,
    threshold_m: float,
    iterations: int,
    rng: np.random.Generator,
    window: int,
    min_run: int,
    max_gap: int,
    link_radius_m: float,
    min_score: int = 1,
    refine_iterations: int = 5,
) -> tuple[np.ndarray, int]:
    """The connected support of the best plane among the ``active`` points, and its score.

    RANSAC with local sampling (:func:`_local_samples`); a hypothesis scores the size, in
    distinct cells (:meth:`ScanCloud.score`), of its :func:`connected_support` among the active
    points within ``threshold_m``, not its raw inlier count. Every new best is refined
    (LO-RANSAC): a TLS fit on its support, new inliers, new support, until the support stops
    growing (at most ``refine_iterations`` times).
    Hypotheses scoring below ``min_score`` are not examined; none found gives ``([], 0)``.
    Deterministic for a seeded ``rng``: hypotheses are drawn in chunks and examined in the
    order of their inliers' distinct cells (ties by draw order), which bound the score.
    """
    P = cloud.points
    support_kw = {"min_run": min_run, "max_gap": max_gap, "link_radius_m": link_radius_m}
    best, best_score = np.zeros(0, dtype=int), max(min_score, 1) - 1
    if np.count_nonzero(active) < 3:
        return best, 0

    def support_of(normal: np.ndarray, point: np.ndarray, need: int) -> np.ndarray:
        inliers = active & (np.abs((P - point) @ normal) <= threshold_m)
        return connected_support(cloud, inliers, min_score=need, **support_kw)

    act = np.flatnonzero(active)
    beam = cloud.sensor[act]
    d2 = np.sum((P[act[beam == 0], None, :] - P[None, act[beam == 1], :]) ** 2, axis=2)
    link = (d2 <= link_radius_m**2).astype(float)
    for start in range(0, iterations, 256):  # chunks bound the (N x chunk) distance matrix
        tri = _local_samples(cloud, active, rng, min(256, iterations - start), window)
        if not len(tri):
            continue
        a, b, c = P[tri[:, 0]], P[tri[:, 1]], P[tri[:, 2]]
        n = np.cross(b - a, c - a)
        norm = np.linalg.norm(n, axis=1)
        ok = norm > 1e-9
        n, a = n[ok] / norm[ok, None], a[ok]
        inside = np.abs(P[act] @ n.T - np.sum(n * a, axis=1)) <= threshold_m
        bound = _run_cells_bound(cloud, act, inside, min_run, max_gap, link)
        for h in np.argsort(-bound, kind="stable"):
            if bound[h] <= best_score:
                break
            sup = support_of(n[h], a[h], best_score + 1)
            if not len(sup):
                continue
            score = cloud.score(sup)
            for _ in range(refine_iterations):  # local optimisation of the new best
                normal, centroid, _s = tls_plane(cloud.cell_means(sup))
                grown = support_of(normal, centroid, score + 1)
                if not len(grown):
                    break
                sup, score = grown, cloud.score(grown)
            best, best_score = sup, score
    return (best, best_score) if len(best) else (best, 0)


def _floats(values: Any) -> list[float]:
    """A state vector (array or sequence) as a flat list of Python floats.

    Frame checks run on every encoder and IMU frame; plain floats keep them cheap.
    """
    if isinstance(values, np.ndarray) and values.dtype == np.float64:
        return values.ravel().tolist()
    return np.asarray(values, dtype=float).ravel().tolist()


def _check_common(cfg: Any) -> None:
    if cfg.leg not in ("l", "r"):
        raise ConfigError("leg", cfg.leg, "'l' or 'r'")
    if cfg.stance_side not in ("l", "r"):
        raise ConfigError("stance_side", cfg.stance_side, "'l' or 'r'")
    check_range("th_pl_m", cfg.th_pl_m, 0.0, 2.0)
    if isinstance(cfg.reliable_n, bool) or not isinstance(cfg.reliable_n, int) or cfg.reliable_n < 1:
        raise ConfigError("reliable_n", cfg.reliable_n, "an integer >= 1")


class _StairsPipeline(ABC):
    """Frame handling, kinematics, bookkeeping and read-out shared by the stairs pipelines."""

    name: ClassVar[str]
    track: ClassVar[str] = "stairs"
    Config: ClassVar[type]

    def __init__(self, config: Any | None = None) -> None:
        self.config = config if config is not None else self.Config()
        self._kin: TofKinematics | None = None

    # --- protocol ---
    def reset(self, calibration: Calibration) -> None:
        cfg = self.config
        self._flags = sensor_flags(cfg.leg)
        for sid in self._flags:
            calibration.mount(sid)  # raises UnknownNameError when the calibration lacks it
        self._sensor_of_flag = {f: s for s, f in self._flags.items()}
        self._config_dict = asdict(cfg)
        self._kin = TofKinematics(calibration, stance_side=cfg.stance_side, imu_sensor_id=cfg.imu_sensor_id)
        self._stats = StreamStats(extra={"n_ignored": 0, "n_bad_range": 0, "n_bad_state": 0, "n_used": 0})
        self._last_stamp: dict[str, float] = {}
        self._readings: list[tuple[float, str, tuple[float, float, float] | None, int]] = []  # stamp, sensor, point, uid
        self._uid_stamp: list[float] = []
        self._times_ns: list[float] = []  # ns per used point
        self._reset_estimator()

    def process(self, frame: Frame) -> StaircaseEstimate | None:
        if self._kin is None:
            raise ExobenchError("process() called before reset()")
        st = self._stats
        st.n_frames += 1
        if isinstance(frame, ToFReading):
            self._tof(frame)
        elif isinstance(frame, JointState):
            if self._in_order(frame) and self._valid_joints(frame):
                self._kin.update_joints(frame)
        elif isinstance(frame, ImuSample) and frame.sensor_id == self.config.imu_sensor_id:
            if self._in_order(frame) and self._valid_imu(frame):
                self._kin.update_imu(frame)
        else:
            st.extra["n_ignored"] += 1
        return self._online()

    def finalize(self) -> StaircaseEstimate:
        if self._kin is None:
            raise ExobenchError("finalize() called before reset()")
        return self._finalize()

    # --- frames ---
    def _in_order(self, frame: Frame) -> bool:
        stamp = float(frame.stamp_s)
        last = self._last_stamp.get(frame.sensor_id)
        if not math.isfinite(stamp) or (last is not None and stamp < last):
            self._stats.n_out_of_order += 1
            return False
        self._last_stamp[frame.sensor_id] = stamp
        return True

    def _valid_joints(self, frame: JointState) -> bool:
        q = _floats(frame.position_rad)
        if len(q) != len(frame.names) or not all(map(math.isfinite, q)):
            self._stats.extra["n_bad_state"] += 1
            return False
        return True

    def _valid_imu(self, frame: ImuSample) -> bool:
        q = _floats(frame.quat_wxyz)
        if len(q) != 4 or not all(map(math.isfinite, q)) or not 0.5 < math.hypot(*q) < 1.5:
            self._stats.extra["n_bad_state"] += 1
            return False
        return True

    def _usable_range(self, frame: ToFReading, r: float) -> bool:
        """Whether a reading can become a point; otherwise count why not."""
        st = self._stats
        if frame.status != TofStatus.VALID:
            st.n_no_return += 1
        elif not math.isfinite(r):
            st.n_nan += 1
        elif r < 0.0:
            st.extra["n_bad_range"] += 1
        elif not self._kin.has_state:
            st.n_without_state += 1
        else:
            return True
        return False

    def _tof(self, frame: ToFReading) -> None:
        st = self._stats
        sid = frame.sensor_id
        flag = self._flags.get(sid)
        if flag is None:
            st.extra["n_ignored"] += 1
            self._readings.append((frame.stamp_s, sid, None, -1))
            return
        try:
            r = float(frame.range_m)
        except (TypeError, ValueError):
            r = float("nan")
        if self._in_order(frame) and self._usable_range(frame, r):
            uid = len(self._uid_stamp)
            kin, consume, clock = self._kin, self._consume, time.perf_counter_ns
            t0 = clock()
            p = kin.point_xyz(sid, r)
            consume(uid, p, flag)
            t1 = clock()
            self._times_ns.append(t1 - t0)
            self._uid_stamp.append(float(frame.stamp_s))
            self._readings.append((frame.stamp_s, sid, p, uid))
            st.extra["n_used"] += 1
            return
        self._readings.append((frame.stamp_s, sid, None, -1))

    # --- estimator hooks ---
    @abstractmethod
    def _reset_estimator(self) -> None:
        """Forget the estimator's state (the shared input handling is reset by the base)."""

    @abstractmethod
    def _consume(self, uid: int, p: tuple[float, float, float], flag: str) -> None:
        """Take the used point ``uid`` (its work is timed per point)."""

    def _online(self) -> StaircaseEstimate | None:
        return None

    @abstractmethod
    def _finalize(self) -> StaircaseEstimate:
        """The final estimate of the episode."""

    # --- read-out ---
    def _plane(self, index: int, plane: PlaneFit, counts: dict[str, int], ok: bool, ok_uid: int | None) -> PlaneEstimate:
        centroid = plane.centroid
        return PlaneEstimate(
            index=index,
            normal=orient_normal(plane.normal, centroid),
            centroid=centroid,
            n_points={self._sensor_of_flag[f]: int(counts[f]) for f in FLAGS},
            sigma_m=float(plane.sigma_m),
            reliable=bool(ok),
            reliable_stamp_s=None if ok_uid is None else self._uid_stamp[ok_uid],
        )

    def _estimate(
        self,
        planes: list[PlaneEstimate],
        surface_of_uid: np.ndarray | None,
        extra: dict[str, Any],
        readout: tuple[float, float] | None = None,
    ) -> StaircaseEstimate:
        """The estimate; with ``surface_of_uid`` (final) also the assignments and the timings.

        ``readout`` is ``(riser_height_m, tread_depth_m)`` when the caller already has it.
        """
        assignments: tuple[PointAssignment, ...] = ()
        if surface_of_uid is not None:
            where = surface_of_uid.tolist()
            assignments = tuple(
                PointAssignment(
                    stamp_s=s,
                    sensor_id=sid,
                    point=np.full(3, np.nan) if p is None else np.array(p, dtype=float),
                    surface_index=where[u] if u >= 0 else -2,
                )
                for s, sid, p, u in self._readings
            )
        stats: dict[str, Any] = self._stats.as_dict()
        stats.update(extra)
        stats["config"] = dict(self._config_dict)
        if readout is None:
            readout = (riser_height_m(planes), tread_depth_m(planes))
        return StaircaseEstimate(
            planes=tuple(planes),
            riser_height_m=readout[0],
            tread_depth_m=readout[1],
            assignments=assignments,
            stats=stats,
            compute_time_s=self._compute_time_s() if surface_of_uid is not None else np.zeros(0),
            frame_id=ESTIMATOR_FRAME,
        )

    def _compute_time_s(self) -> np.ndarray:
        return np.array(self._times_ns, dtype=float) * 1e-9


class RtlsStairs(_StairsPipeline):
    """The paper's Algorithm 1 with general planes (Sec. V-A), point by point, online.

    ``process`` returns the current estimate (planes with at least 3 points and the read-out;
    no per-point assignments or timings, which ``finalize`` adds) once a surface has points.
    """

    name: ClassVar[str] = "rtls"
    htvr: ClassVar[bool] = False

    @dataclass(frozen=True)
    class Config:
        """Parameters (SI units).

        Attributes:
            leg: climbing leg whose calf sensors ``tof_<leg>_med``/``tof_<leg>_lat`` are used.
            stance_side: supporting foot; origin of the ``stance_ground`` frame.
            imu_sensor_id: trunk IMU giving ``R_world_imu``.
            th_z_m, th_pl_m: the paper's thresholds (8e-3 m, 0.13 m).
            queue_q, buffer_b, reliable_n: ``q``, ``b``, ``N`` of Algorithm 1; not given by the
                paper, defaults 5, 10, 5 (see :mod:`exobench.perception.staircase`).
            riser_flat_low: ``"assign"`` (listing of Algorithm 1) or ``"discard"`` (prose of
                Sec. IV-A) for a flat queue below ``S_{id-1}.e_z + th_pl`` on a riser.
        """

        leg: str = "r"
        stance_side: str = "l"
        imu_sensor_id: str = "imu_trunk"
        th_z_m: float = 8e-3
        th_pl_m: float = 0.13
        queue_q: int = 5
        buffer_b: int = 10
        reliable_n: int = 5
        riser_flat_low: str = "assign"

        def __post_init__(self) -> None:
            _check_common(self)
            self.params(False)  # validates the algorithm's parameters

        def params(self, htvr: bool) -> StaircaseParams:
            return StaircaseParams(
                th_z_m=self.th_z_m,
                th_pl_m=self.th_pl_m,
                queue_q=self.queue_q,
                buffer_b=self.buffer_b,
                reliable_n=self.reliable_n,
                htvr=htvr,
                riser_flat_low=self.riser_flat_low,
            )

    def _reset_estimator(self) -> None:
        self.algorithm = StaircaseAlgorithm(self.config.params(self.htvr))
        self._assign = self.algorithm.assign
        self._cache: StaircaseEstimate | None = None
        self._stale = True
        # read-outs kept between online estimates: per surface (version, ok) -> PlaneEstimate,
        # and the riser/tread read-out of the reliable planes it was computed from
        self._plane_memo: dict[int, tuple[tuple[int, bool], PlaneEstimate]] = {}
        self._readout_memo: tuple[tuple[PlaneEstimate, ...], tuple[float, float]] | None = None

    def _consume(self, uid: int, p: tuple[float, float, float], flag: str) -> None:
        # the algorithm numbers its points in arrival order, like the pipeline's used readings
        self._assign(p, flag)
        self._stale = True

    def _planes(self) -> list[PlaneEstimate]:
        out = []
        memo = self._plane_memo
        for S in self.algorithm.surfaces:
            if S.plane.n >= 3:
                key = (S.plane.version, S.ok)
                hit = memo.get(S.index)
                if hit is None or hit[0] != key:
                    hit = memo[S.index] = (key, self._plane(S.index, S.plane, S.n_by_flag, S.ok, S.reliable_uid))
                out.append(hit[1])
        return out

    def _readout(self, planes: list[PlaneEstimate]) -> tuple[float, float]:
        reliable = tuple(p for p in planes if p.reliable)
        memo = self._readout_memo
        if memo is None or len(memo[0]) != len(reliable) or any(a is not b for a, b in zip(memo[0], reliable, strict=True)):
            memo = self._readout_memo = (reliable, (riser_height_m(reliable), tread_depth_m(reliable)))
        return memo[1]

    def _extra(self) -> dict[str, Any]:
        return {**self.algorithm.counts, "current_id": self.algorithm.current_id}

    def _online(self) -> StaircaseEstimate | None:
        if self._stale:
            self._stale = False
            planes = self._planes()
            self._cache = self._estimate(planes, None, self._extra(), self._readout(planes)) if planes else None
        return self._cache

    def _finalize(self) -> StaircaseEstimate:
        planes = self._planes()
        return self._estimate(planes, self.algorithm.point_surfaces(), self._extra(), self._readout(planes))


class RtlsHtvrStairs(RtlsStairs):
    """Algorithm 1 with horizontal treads and vertical risers (HTVR, Sec. V-B)."""

    name: ClassVar[str] = "rtls-htvr"
    htvr: ClassVar[bool] = True


class BatchRansacStairs(_StairsPipeline):
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
            _check_common(self)
            check_range("distance_threshold_m", self.distance_threshold_m, 0.0, 1.0, low_open=True)
            check_range("link_radius_m", self.link_radius_m, 0.0, 10.0, low_open=True)
            check_range("voxel_m", self.voxel_m, 0.0, 1.0, low_open=True)
            for name, low in (
                ("ransac_iterations", 1),
                ("sample_window", 1),
                ("min_run_points", 2),
                ("max_run_gap", 0),
                ("min_plane_cells", 3),
                ("max_planes", 1),
                ("refine_iterations", 0),
                ("seed", 0),
            ):
                v = getattr(self, name)
                if isinstance(v, bool) or not isinstance(v, int) or v < low:
                    raise ConfigError(name, v, f"an integer >= {low}")

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
