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

__all__ = ["BatchRansacStairs", "RtlsHtvrStairs", "RtlsStairs", "ransac_plane", "sensor_flags"]


def sensor_flags(leg: str) -> dict[str, str]:
    """ToF sensor id -> the paper's flag (``"r"``/``"l"``) for the calf sensors of ``leg``."""
    if leg == "r":
        return {"tof_r_lat": "r", "tof_r_med": "l"}
    if leg == "l":
        return {"tof_l_med": "r", "tof_l_lat": "l"}
    raise ConfigError("leg", leg, "'l' or 'r'")


def ransac_plane(
    points: np.ndarray,
    threshold_m: float,
    iterations: int,
    rng: np.random.Generator,
    labels: np.ndarray | None = None,
    min_per_label: int = 0,
) -> np.ndarray:
    """Indices of the inliers of the best plane found by RANSAC on ``points`` (N, 3).

    Each iteration fits a plane through 3 random points and counts the points closer than
    ``threshold_m``; the first plane with the most inliers wins (deterministic for a seeded
    ``rng``). Degenerate samples are skipped. With ``labels`` (one per point), a plane counts
    only if it has at least ``min_per_label`` inliers of every label: a single ToF beam sweeps
    a plane of its own (its points on ground, riser and tread are nearly coplanar), which only
    the other sensor's points can rule out, as Sec. II of the paper explains.
    """
    P = np.asarray(points, dtype=float)
    masks = [] if labels is None else [np.asarray(labels) == v for v in np.unique(labels)]
    best, best_count = np.zeros(0, dtype=int), 0
    for start in range(0, iterations, 256):  # chunks bound the (N x chunk) distance matrix
        k = min(256, iterations - start)
        idx = rng.integers(0, len(P), size=(k, 3))
        a, b, c = P[idx[:, 0]], P[idx[:, 1]], P[idx[:, 2]]
        n = np.cross(b - a, c - a)
        norm = np.linalg.norm(n, axis=1)
        ok = norm > 1e-12
        if not np.any(ok):
            continue
        n, a = n[ok] / norm[ok, None], a[ok]
        inside = np.abs(P @ n.T - np.sum(n * a, axis=1)) <= threshold_m
        counts = inside.sum(axis=0)
        for m in masks:
            counts = np.where(inside[m].sum(axis=0) >= min_per_label, counts, 0)
        j = int(np.argmax(counts))
        if counts[j] > best_count:
            best, best_count = np.flatnonzero(inside[:, j]), int(counts[j])
    return best


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


class _StairsPipeline:
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
        if not self._in_order(frame):
            pass
        elif frame.status != TofStatus.VALID:
            st.n_no_return += 1
        elif not math.isfinite(r):
            st.n_nan += 1
        elif r < 0.0:
            st.extra["n_bad_range"] += 1
        elif not self._kin.has_state:
            st.n_without_state += 1
        else:
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
    def _reset_estimator(self) -> None:
        raise NotImplementedError

    def _consume(self, uid: int, p: tuple[float, float, float], flag: str) -> None:
        """Take the used point ``uid`` (its work is timed per point)."""
        raise NotImplementedError

    def _online(self) -> StaircaseEstimate | None:
        return None

    def _finalize(self) -> StaircaseEstimate:
        raise NotImplementedError

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
    """Offline baseline: all points, sequential RANSAC planes at ``finalize``, same read-out.

    Planes are extracted one after the other by RANSAC (:func:`ransac_plane`, seeded numpy; or
    Open3D's ``segment_plane`` with ``backend="open3d"``) until fewer than ``min_plane_points``
    points remain or ``max_planes`` planes were found; each is refitted by TLS on its inliers. Labelling follows
    Algorithm 1's ordering: treads (``|n_z| >= cos 45 deg``) in ascending height, a new tread
    index (0, 2, 4) whenever a plane lies more than ``th_pl_m`` above the current tread level
    (which starts at the ground, z = 0), otherwise merged into the current one; a riser takes
    the index after the highest tread level below its mean height. Planes with the same index
    are merged and refitted; indices above 4 are dropped. A plane is reliable with at least
    ``reliable_n`` inliers of each sensor; its reliable time is the stamp of the point that
    completed that count.
    """

    name: ClassVar[str] = "batch-ransac"

    @dataclass(frozen=True)
    class Config:
        """Parameters (SI units).

        Attributes:
            leg, stance_side, imu_sensor_id: as for :class:`RtlsStairs.Config`.
            th_pl_m: minimum riser height separating two tread levels (paper: 0.13 m).
            reliable_n: inliers needed from each sensor for a reliable plane.
            distance_threshold_m: RANSAC inlier distance (about 3 sigma of 1.5 mm noise).
            ransac_iterations: RANSAC iterations per plane.
            min_plane_points: smallest plane accepted.
            min_points_per_sensor: inliers a RANSAC plane needs from each of the two sensors
                (numpy backend): one beam's sweep is itself nearly planar.
            max_planes: most planes extracted.
            seed: seed of the RANSAC sampling.
            backend: ``"numpy"`` (seeded, bit-for-bit reproducible) or ``"open3d"``
                (``PointCloud.segment_plane``; seeded, but its multi-threaded sampling varies
                from run to run).
        """

        leg: str = "r"
        stance_side: str = "l"
        imu_sensor_id: str = "imu_trunk"
        th_pl_m: float = 0.13
        reliable_n: int = 5
        distance_threshold_m: float = 0.005
        ransac_iterations: int = 1000
        min_plane_points: int = 10
        min_points_per_sensor: int = 3
        max_planes: int = 8
        seed: int = 0
        backend: str = "numpy"

        def __post_init__(self) -> None:
            _check_common(self)
            if self.backend not in ("numpy", "open3d"):
                raise ConfigError("backend", self.backend, "'numpy' or 'open3d'")
            check_range("distance_threshold_m", self.distance_threshold_m, 0.0, 1.0, low_open=True)
            for name, low in (("ransac_iterations", 1), ("min_plane_points", 3), ("min_points_per_sensor", 0), ("max_planes", 1), ("seed", 0)):
                v = getattr(self, name)
                if isinstance(v, bool) or not isinstance(v, int) or v < low:
                    raise ConfigError(name, v, f"an integer >= {low}")

    def _reset_estimator(self) -> None:
        self._points: list[np.ndarray] = []
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
        pts = np.array(self._points, dtype=float).reshape(-1, 3)
        flags = np.array(self._point_flags)
        groups = self._ransac(pts, flags)
        labels = self._label(pts, groups)
        where = np.full(len(pts), -1, dtype=int)
        planes = []
        for index in sorted(labels):
            idx = np.sort(labels[index])
            where[idx] = index
            fit = RtlsPlane()
            for k in idx:
                fit.add(pts[k])
            counts = {f: int(np.sum(flags[idx] == f)) for f in FLAGS}
            ok_uid = self._reliable_uid(idx, flags)
            planes.append(self._plane(index, fit, counts, ok_uid is not None, ok_uid))
        share_ns = (time.perf_counter_ns() - t0) / max(len(pts), 1)
        self._times_ns = [t + share_ns for t in self._times_ns]
        self._result = self._estimate(planes, where, {"n_planes_found": len(groups)})
        return self._result

    def _reliable_uid(self, idx: np.ndarray, flags: np.ndarray) -> int | None:
        seen = dict.fromkeys(FLAGS, 0)
        for k in idx:  # idx is sorted, i.e. in arrival order
            seen[str(flags[k])] += 1
            if all(v >= self.config.reliable_n for v in seen.values()):
                return int(k)
        return None

    def _ransac(self, pts: np.ndarray, flags: np.ndarray) -> list[np.ndarray]:
        cfg = self.config
        groups: list[np.ndarray] = []
        remaining = np.arange(len(pts))
        if cfg.backend == "open3d":
            import open3d as o3d

            o3d.utility.random.seed(cfg.seed)
        rng = np.random.default_rng(cfg.seed)
        while len(remaining) >= cfg.min_plane_points and len(groups) < cfg.max_planes:
            if cfg.backend == "open3d":
                pcd = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(pts[remaining]))
                _, inl = pcd.segment_plane(
                    distance_threshold=cfg.distance_threshold_m, ransac_n=3, num_iterations=cfg.ransac_iterations
                )
                inliers = np.asarray(inl, dtype=int)
            else:
                inliers = ransac_plane(
                    pts[remaining], cfg.distance_threshold_m, cfg.ransac_iterations, rng, flags[remaining], cfg.min_points_per_sensor
                )
            if len(inliers) < cfg.min_plane_points:
                break
            groups.append(remaining[inliers])
            remaining = np.delete(remaining, inliers)
        return groups

    def _label(self, pts: np.ndarray, groups: list[np.ndarray]) -> dict[int, np.ndarray]:
        treads, risers = [], []
        for g in groups:
            fit = RtlsPlane()
            for k in g:
                fit.add(pts[k])
            (treads if abs(fit.normal[2]) >= MIN_TREAD_NZ else risers).append((float(fit.centroid[2]), g))
        labels: dict[int, list[np.ndarray]] = {}
        levels: list[tuple[int, float]] = []  # (index, height of the level)
        index, level_z = 0, 0.0
        for z, g in sorted(treads, key=lambda t: t[0]):
            if z > level_z + self.config.th_pl_m:
                index, level_z = index + 2, z
            if not levels or levels[-1][0] != index:
                levels.append((index, level_z))
            labels.setdefault(index, []).append(g)
        for z, g in risers:
            below = [i for i, lz in levels if lz < z]
            labels.setdefault((max(below) if below else 0) + 1, []).append(g)
        return {i: np.concatenate(gs) for i, gs in labels.items() if i <= 4}
