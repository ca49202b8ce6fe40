"""LEO-SLAM: submap-based 3D LiDAR SLAM with multi-level scan matching (seeds/003 4.2.1).

One loop of Algorithm 2 per LiDAR sweep (:meth:`LeoSlamPipeline.process`):

1. preprocessing (:mod:`exobench.mapping.odometry.preprocess`): NaN removal, constant-velocity deskew,
   crop boxes, voxel grid, statistical outlier rejection -> ``P_p`` (registration) and ``P_f``
   (map). The deskew moves every point to the sensor frame at mid-sweep with the velocity of
   the previous pair of sweeps (referencing the middle keeps a velocity error from biasing the
   pose, which at walking-to-running speeds otherwise makes the estimate zig-zag); the pose at
   ``sweep_start_s`` is reported. The sweeps before the first velocity estimate are processed
   again, deskewed, as soon as it is known, so the first submap is not distorted;
2. multi-level alignment with GICP (:mod:`exobench.mapping.odometry.gicp`):
   scan-to-scan ``s2s`` (``P_t`` onto ``P_{t-1}`` from the constant-velocity guess), whose
   result seeds scan-to-submaps ``s2S`` (``P_t`` onto the ``N_s`` previous submaps);
3. the scan joins the open submap; when the distance from the last node exceeds ``Delta_m`` or
   the rotation reaches ``Delta_theta`` a node is created (:mod:`exobench.mapping.odometry.submaps`):
   submap-to-submaps ``S2S`` aligns the submap with the ``N_s`` previous ones, fixes the keyframe
   and adds the node to the iSAM2 pose graph (:mod:`exobench.mapping.odometry.pose_graph`);
4. submap Scan Context++ with ceiling removal inside the growing search ellipsoid
   (eq. 4.11-4.12, :mod:`exobench.mapping.odometry.loop_closure`); a detected loop is verified by GICP
   of the set ``S_c`` (the current node and the ``v`` before it) against ``S_l`` (the loop node
   and ``v`` nodes on either side), starting from the current relative pose (which carries
   ``d_l`` of eq. 4.11; :func:`~exobench.mapping.odometry.loop_closure.verify_loop`). If it converges the current node is corrected (eq. 4.13), the loop
   factor of eq. (4.14) is added and iSAM2 re-optimises; node keyframes, scan poses (kept
   relative to their node) and the map follow the optimised nodes.

Points at a distance the LiDAR cannot report (:class:`exobench.core.limits.RangeLimits`) are
dropped as NaN ones. The input is counted on ``TrajectoryEstimate.counts``
(:mod:`exobench.core.counters`): frames of other kinds and sweeps of another LiDAR are ignored;
a repeated or out-of-order sweep (by ``sweep_start_s``) is not processed and has no pose. Faults
never raise: an empty sweep, too few points or NaN points, or failed alignments keep the
constant-velocity motion and are reported in ``status`` (``"ok"``, ``"s2s_only"`` when the
scan-to-submaps alignment failed, ``"lost"`` when both failed, ``"empty_scan"``,
``"too_few_points"``) and in ``stats``. Poses are given at ``sweep_start_s``;
the first is the identity. Open3D runs single-threaded inside :meth:`process` (deterministic).

Not in this implementation: the ground-aware intensity filter of the map branch (section 4.2.2,
see :mod:`exobench.perception.lidar_filter.filters`) and external odometry / IMU initial guesses.
"""

from __future__ import annotations

import math
import time
from dataclasses import replace
from typing import Any, ClassVar

import numpy as np
from scipy.spatial.transform import Rotation

from exobench.core.calibration import Calibration
from exobench.core.counters import StreamCounters, nan_values
from exobench.core.estimates import TrajectoryEstimate
from exobench.core.frames import Frame, LidarScan
from exobench.core.limits import RangeLimits, scrub_points
from exobench.core.pipeline import check_frame
from exobench.core.transforms import transform_points
from exobench.mapping.odometry.gicp import GicpCloud, align, single_threaded
from exobench.mapping.odometry.leo_config import LeoSlamConfig
from exobench.mapping.odometry.loop_closure import LoopDetector, verify_loop
from exobench.mapping.odometry.pose_graph import PoseGraph, PoseGraphConfig
from exobench.mapping.odometry.preprocess import clean_points, preprocess, voxel_downsample
from exobench.mapping.odometry.submaps import Node, OpenSubmap, keyframe_due, nodes_cloud

__all__ = ["LeoSlamPipeline"]


def _twist(T_rel: np.ndarray, dt_s: float) -> np.ndarray:
    """Constant velocity (v, w) per second, in the frame at the start of ``T_rel``."""
    if not dt_s > 0:
        return np.zeros(6)
    return np.concatenate([T_rel[:3, 3], Rotation.from_matrix(T_rel[:3, :3]).as_rotvec()]) / dt_s


def _motion(twist_per_s: np.ndarray, dt_s: float) -> np.ndarray:
    """Relative pose after ``dt_s`` at constant velocity (first order in translation)."""
    T = np.eye(4)
    T[:3, :3] = Rotation.from_rotvec(twist_per_s[3:] * dt_s).as_matrix()
    T[:3, 3] = twist_per_s[:3] * dt_s
    return T


class LeoSlamPipeline:
    """LEO-SLAM on :class:`LidarScan` frames; other frames are ignored (config: :class:`LeoSlamConfig`)."""

    name: ClassVar[str] = "leo-slam"
    track: ClassVar[str] = "odometry"

    Config: ClassVar[type[LeoSlamConfig]] = LeoSlamConfig

    def __init__(self, config: LeoSlamConfig | None = None) -> None:
        self.config = config or self.Config()
        self._pre = self.config.preprocess_config()
        self._gicp = self.config.gicp_config()
        self.reset(None)
        self._was_reset = False  # reset(None) above only initialises; a caller must reset

    # ------------------------------------------------------------------------------ protocol

    def reset(self, calibration: Calibration | None) -> None:
        """Forget everything; the calibration is not needed (poses are of the LiDAR itself)."""
        cfg = self.config
        self._was_reset = True
        self._sensor_id = cfg.sensor_id
        lidars = calibration.mounts_of_kind("lidar") if calibration is not None else ()
        self._limits = {m.sensor_id: RangeLimits.of_mount(m) for m in lidars}
        self._counters = StreamCounters.of(calibration)
        self._stamps: list[float] = []
        self._times: list[float] = []
        self._status: list[str] = []
        self._T_map_scan: list[np.ndarray] = []  # tracking pose of each scan at mid-sweep (map frame)
        self._T_mid_start: list[np.ndarray] = []  # sweep-start pose in the mid-sweep frame
        self._scan_node: list[int] = []  # node the scan belongs to (-1: open submap)
        self._T_node_scan: dict[int, np.ndarray] = {}
        self._nodes: list[Node] = []
        self._open = OpenSubmap()
        self._graph = PoseGraph(PoseGraphConfig())
        self._loops = LoopDetector(cfg.loop_config())
        self._loop_edges: list[tuple[int, int]] = []
        self._prev_cloud: GicpCloud | None = None
        self._prev_T_map: np.ndarray | None = None  # pose of the scan in _prev_cloud
        self._prev_stamp: float | None = None
        self._twist = np.zeros(6)  # constant velocity per second, sensor frame
        self._target: GicpCloud | None = None
        self._travelled = 0.0
        self._travel_at_loop = 0.0
        self._lost_run = 0
        # sweeps before the first velocity estimate, replayed deskewed once it is known
        self._first_scans: list[LidarScan] | None = [] if cfg.deskew else None
        self._stats: dict[str, Any] = {
            "n_scans": 0, "n_empty": 0, "n_too_few_points": 0,
            "n_s2s_failed": 0, "n_s2map_failed": 0, "n_lost": 0, "n_S2S_failed": 0,
            "n_loop_candidates": 0, "n_loop_rejected": 0,
        }

    def process(self, frame: Frame) -> None:
        """Consume one frame; LiDAR sweeps are processed, everything else is ignored."""
        check_frame(self, frame, self._was_reset)
        if isinstance(frame, LidarScan) and self._sensor_id == "":
            self._sensor_id = frame.sensor_id
        c = self._counters.admit(frame, consumed=isinstance(frame, LidarScan) and frame.sensor_id == self._sensor_id)
        if c is None:
            return None
        c.add_nan(nan_values(frame))
        c.used += 1
        t0 = time.perf_counter()
        pts, n_absurd = scrub_points(frame.points_xyz, self._limits.get(frame.sensor_id) or RangeLimits())
        if n_absurd:
            c.add_absurd(n_absurd)
            frame = replace(frame, points_xyz=pts)
        n_before = len(self._stamps)
        try:
            with single_threaded():  # Open3D single-threaded: deterministic (see gicp.py)
                status = self._process_scan(frame)
                if self._first_scans is not None:
                    status = self._replay_first_scans(frame, status)
        except (ValueError, IndexError, np.linalg.LinAlgError, RuntimeError) as e:  # never raise on data
            status = "error"
            self._stats.setdefault("errors", []).append(f"{type(e).__name__}: {e}")
            if len(self._stamps) == n_before:
                self._record(float(frame.sweep_start_s), self._predict(float(frame.sweep_start_s)))
        self._status.append(status)
        self._times.append(time.perf_counter() - t0)
        return None

    def finalize(self) -> TrajectoryEstimate:
        """Trajectory of every sweep after the last optimisation, the corrected map, stats."""
        n = len(self._stamps)
        poses = np.empty((n, 4, 4))
        node_pose = {nd.index: nd.T_map_node for nd in self._nodes}
        for i in range(n):
            k = self._scan_node[i]
            T_map_mid = node_pose[k] @ self._T_node_scan[i] if k >= 0 else self._T_map_scan[i]
            poses[i] = T_map_mid @ self._T_mid_start[i]
        parts = [transform_points(nd.T_map_node, nd.map_points_node) for nd in self._nodes]
        parts += self._open.map_points_map
        cloud = np.concatenate(parts) if parts else np.zeros((0, 3))
        map_points = voxel_downsample(cloud, self.config.map_voxel_m)
        stats = dict(self._stats)
        stats.update(n_keyframes=len(self._nodes), n_submaps=len(self._nodes), n_loops=len(self._loop_edges),
                     loop_closure=self.config.loop_closure, sensor_id=self._sensor_id,
                     mean_time_per_scan_s=float(np.mean(self._times)) if self._times else math.nan)
        return TrajectoryEstimate(
            stamps_s=np.asarray(self._stamps, dtype=float), T_world_sensor=poses,
            time_per_scan_s=np.asarray(self._times, dtype=float), loop_edges=tuple(self._loop_edges),
            status=tuple(self._status), stats=stats, map_points=map_points, counts=self._counters.snapshot())

    # ------------------------------------------------------------------------------ one scan

    def _predict(self, stamp_s: float) -> np.ndarray:
        """Constant-velocity pose of the sensor at ``stamp_s`` (identity for the first scan)."""
        if self._prev_T_map is None:
            return self._T_map_scan[-1].copy() if self._T_map_scan else np.eye(4)
        dt = stamp_s - self._prev_stamp if self._prev_stamp is not None else 0.0
        return self._prev_T_map @ _motion(self._twist, max(dt, 0.0))

    def _replay_first_scans(self, frame: LidarScan, status: str) -> str:
        """Re-process the sweeps before the first velocity estimate, deskewed with it.

        Without it the first sweep (the first node and the initial map) keeps its full motion
        distortion. Happens once per episode, at the first sweep with a velocity.
        """
        assert self._first_scans is not None
        self._first_scans.append(frame)
        if not np.any(self._twist):
            if len(self._first_scans) > 10:  # no motion estimate yet: give up replaying
                self._first_scans = None
            return status
        frames, twist = self._first_scans, self._twist.copy()
        statuses, times, sensor_id = self._status, self._times, self._sensor_id
        limits, counters = self._limits, self._counters
        self.reset(None)
        self._limits, self._counters = limits, counters
        self._first_scans = None
        self._sensor_id, self._twist, self._times = sensor_id, twist, times
        replayed = [self._process_scan(f) for f in frames]
        self._status = statuses[: len(statuses) - (len(frames) - 1)] + replayed[:-1]
        self._stats["n_replayed_first_scans"] = len(frames)
        return replayed[-1]

    def _record(self, stamp_s: float, T_map: np.ndarray, T_mid_start: np.ndarray | None = None,
                p_reg: np.ndarray | None = None, p_map: np.ndarray | None = None) -> int:
        """Store a scan's pose; it joins the open submap (with its clouds, if any) so that loop
        corrections move it with its node."""
        index = len(self._stamps)
        self._stamps.append(stamp_s)
        self._T_map_scan.append(T_map)
        self._T_mid_start.append(np.eye(4) if T_mid_start is None else T_mid_start)
        self._scan_node.append(-1)
        empty = np.zeros((0, 3))
        self._open.add(index, T_map, empty if p_reg is None else p_reg, empty if p_map is None else p_map)
        return index

    def _process_scan(self, scan: LidarScan) -> str:
        cfg = self.config
        self._stats["n_scans"] += 1
        stamp = float(scan.sweep_start_s)
        pts = np.asarray(scan.points_xyz, dtype=float).reshape(-1, 3)
        valid = clean_points(pts)
        T_pred = self._predict(stamp)
        if int(valid.sum()) == 0 or int(valid.sum()) < cfg.min_points:
            key = "n_empty" if int(valid.sum()) == 0 else "n_too_few_points"
            self._stats[key] += 1
            self._record(stamp, T_pred)
            return "empty_scan" if key == "n_empty" else "too_few_points"
        # deskew into the frame at mid-sweep (velocity errors then hardly bias the pose)
        tau = np.asarray(scan.time_offset_s, dtype=float).reshape(-1)
        tau_ok = tau[np.isfinite(tau)] if len(tau) == len(pts) else np.zeros(0)
        tau_mid = 0.5 * float(tau_ok.min() + tau_ok.max()) if (cfg.deskew and len(tau_ok)) else 0.0
        T_mid_start = _motion(self._twist, -tau_mid)
        stamp_mid = stamp + tau_mid
        T_pred = self._predict(stamp_mid)
        p_reg, p_map = preprocess(pts, tau - tau_mid if len(tau_ok) else None, self._pre,
                                  self._twist if tau_mid > 0 else None)
        if len(p_reg) < self._gicp.min_points:
            self._stats["n_too_few_points"] += 1
            self._record(stamp, T_pred @ T_mid_start, None)
            return "too_few_points"
        cloud = GicpCloud(p_reg, cfg.gicp_neighbors)

        status = "ok"
        if self._prev_cloud is None:  # first usable scan: it defines the map frame (or continues)
            T_map = T_pred if self._T_map_scan else np.linalg.inv(T_mid_start)
        else:
            T_prev_pred = np.linalg.inv(self._prev_T_map) @ T_pred
            s2s = align(cloud, self._prev_cloud, T_prev_pred, self._gicp)  # scan-to-scan
            if not s2s.converged:
                self._stats["n_s2s_failed"] += 1
            T_guess = self._prev_T_map @ (s2s.T_target_source if s2s.converged else T_prev_pred)
            s2m = align(cloud, self._target, T_guess, self._gicp) if self._target is not None else None
            if s2m is not None and s2m.converged:  # scan-to-submaps
                T_map = s2m.T_target_source
                self._lost_run = 0
            else:
                self._stats["n_s2map_failed"] += 1
                if s2s.converged:
                    T_map, status = T_guess, "s2s_only"
                else:
                    T_map, status = T_pred, "lost"
                    self._stats["n_lost"] += 1
                self._lost_run += 1
            if status != "lost":
                dt = stamp_mid - self._prev_stamp
                self._twist = _twist(np.linalg.inv(self._prev_T_map) @ T_map, dt)
            self._travelled += float(np.linalg.norm(T_map[:3, 3] - self._prev_T_map[:3, 3]))
        lost = status == "lost"  # a sweep at a guessed pose does not go into the map
        index = self._record(stamp, T_map, T_mid_start, None if lost else p_reg, None if lost else p_map)
        self._prev_cloud, self._prev_T_map, self._prev_stamp = cloud, T_map, stamp_mid

        if not self._nodes:
            self._close_node(index, T_map)
        elif keyframe_due(self._nodes[-1].T_map_node, T_map, cfg.keyframe_distance_m,
                          math.radians(cfg.keyframe_rotation_deg)):
            self._close_node(index, T_map)
        elif self._lost_run >= cfg.max_lost:
            self._close_node(index, T_map)  # re-anchor the s2S target on the current scans
            self._lost_run = 0
        return status

    # ------------------------------------------------------------------------------ submaps

    def _close_node(self, scan_index: int, T_map_key: np.ndarray) -> None:
        """Finalise the open submap as node ``n_c`` with keyframe ``scan_index`` (S2S, graph, LCD)."""
        cfg = self.config
        pts_node, map_node = self._open.clouds_in(T_map_key, cfg.voxel_m, cfg.map_voxel_m)
        T_node = T_map_key
        if self._nodes:  # submap-to-submaps alignment against the N_s previous submaps
            res = align(GicpCloud(pts_node, cfg.gicp_neighbors), self._target, T_map_key, self._gicp)
            if res.converged:
                T_node = res.T_target_source
            else:
                self._stats["n_S2S_failed"] += 1
        # scans of this submap keep their pose relative to the (uncorrected) keyframe
        T_key_map = np.linalg.inv(T_map_key)
        key = len(self._nodes)
        for i, T in zip(self._open.scan_indices, self._open.T_map_scans):
            self._scan_node[i] = key
            self._T_node_scan[i] = T_key_map @ T
        node = Node(key, scan_index, T_node, pts_node, map_node, self._travelled)
        self._nodes.append(node)
        self._open = OpenSubmap()
        prev = self._nodes[-2].T_map_node if key > 0 else None
        self._graph.add_node(key, T_node, None if prev is None else np.linalg.inv(prev) @ T_node)
        self._set_current(T_node)
        if cfg.loop_closure:
            self._detect_loop(node)
        self._rebuild_target()

    def _set_current(self, T_map_node: np.ndarray) -> None:
        """The current scan is the keyframe: move the tracking state with the node."""
        i = len(self._T_map_scan) - 1
        self._T_map_scan[i] = T_map_node.copy()
        self._prev_T_map = T_map_node.copy()

    def _rebuild_target(self) -> None:
        cfg = self.config
        recent = self._nodes[-cfg.submap_count:]
        self._target = GicpCloud(nodes_cloud(recent, np.eye(4), cfg.voxel_m), cfg.gicp_neighbors)

    # ------------------------------------------------------------------------------ loops

    def _detect_loop(self, node: Node) -> None:
        cfg = self.config
        desc = self._loops.describe(node.map_points_node, node.T_map_node)
        self._loops.add(desc)
        t_nodes = np.asarray([nd.T_map_node[:3, 3] for nd in self._nodes])
        match, _ = self._loops.query(desc, t_nodes, node.index, self._travelled - self._travel_at_loop)
        if not match.accepted:
            return
        self._stats["n_loop_candidates"] += 1
        c, l_idx = node.index, match.index
        res = verify_loop(self._nodes, c, l_idx, cfg.loop_neighbors, cfg.loop_exclude_recent, cfg.voxel_m,
                          cfg.gicp_neighbors, *cfg.loop_gicp_configs())
        T_map_l = self._nodes[l_idx].T_map_node
        T_map_c = node.T_map_node
        if res is None:
            self._stats["n_loop_rejected"] += 1
            return
        T_map_c_new = T_map_l @ res.T_target_source  # eq. (4.13): H_icp * mH_nc
        if np.linalg.norm(T_map_c_new[:3, 3] - T_map_c[:3, 3]) > cfg.loop_max_correction_m:
            self._stats["n_loop_rejected"] += 1
            return
        self._stats.setdefault("loops", []).append(
            {"node": c, "loop_node": l_idx, "similarity": round(match.similarity, 4), "fitness": round(res.fitness, 4),
             "correction_m": round(float(np.linalg.norm(T_map_c_new[:3, 3] - T_map_c[:3, 3])), 4)})
        self._graph.add_loop(c, l_idx, np.linalg.inv(T_map_c_new) @ T_map_l)  # eq. (4.14)
        for nd in self._nodes:
            nd.T_map_node = self._graph.pose(nd.index)
        self._set_current(self._nodes[-1].T_map_node)
        self._loop_edges.append((self._nodes[l_idx].scan_index, node.scan_index))
        self._travel_at_loop = self._travelled
