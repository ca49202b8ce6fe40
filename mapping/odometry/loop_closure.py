"""Submap-based Scan Context++ loop detection of LEO-SLAM (seeds/003 section 4.2.1).

Every finalised node's submap is described with Scan Context++
(:class:`exobench.perception.place_recognition.scan_context.ScanContextPP`) in the level frame of its keyframe,
after removing the ceiling (points higher than ``ceiling_above_sensor_m`` above the sensor).
The search is restricted to the node set ``K`` inside the search ellipsoid ``a_s`` centred at
the current node (eq. 4.11-4.12)::

    d_j = t_{n_c} - t_{n_j}                                    (4.11)
    (d_j^x / a_s^x)^2 + (d_j^y / a_s^y)^2 + (d_j^z / a_s^z)^2 <= 1   (4.12)

The ellipsoid grows with the motion uncertainty, modelled as proportional to the distance
travelled since the last accepted loop (or the start): ``a_s = a_0 + growth * travelled``.
Within ``K`` the ``num_candidates`` nearest ring keys (eq. 4.23) are compared in full at every
column shift (eq. 4.24) and the best is accepted when its similarity exceeds ``tau`` (4.25).
The most recent ``exclude_recent`` nodes are never candidates (a loop joins non-consecutive
nodes).

A detected loop is verified by GICP (:func:`verify_loop`): the set ``S_c`` (the current node
and the ``v`` before it) against ``S_l`` (the loop node and ``v`` nodes on either side), a coarse
pass then a fine one, starting from the current relative pose (which carries ``d_l`` of eq. 4.11).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from exobench.core.errors import ConfigError, check_int, check_range
from exobench.mapping.odometry.gicp import GicpCloud, GicpConfig, GicpResult, align
from exobench.mapping.odometry.submaps import Node, nodes_cloud
from exobench.perception.place_recognition.recognizer import ScanContextPP
from exobench.perception.place_recognition.scan_context import (
    ContextDescriptor,
    PlaceMatch,
    ScanContextConfig,
    best_shift,
    level_frame,
)

__all__ = ["LoopDetector", "LoopDetectorConfig", "in_search_ellipsoid", "verify_loop"]


@dataclass(frozen=True)
class LoopDetectorConfig:
    """Descriptor, search-area and acceptance parameters.

    Attributes:
        n_rings / n_sectors: SC++ grid (SC++ paper: 20 x 60).
        max_radius_m: SC++ radius; 80 m in the SC++ paper (outdoor), 20 m here for rooms.
        tau: similarity threshold of eq. (4.25).
        num_candidates: ring-key nearest neighbours compared in full.
        height_offset_m: added to heights before binning (so the floor is positive).
        ceiling_above_sensor_m: points higher than this above the sensor are removed (ceiling);
            None keeps them.
        ellipsoid_base_m: ``a_0`` (x, y, z) of the search ellipsoid, m.
        ellipsoid_growth: growth of each semi-axis per metre travelled (m/m).
        exclude_recent: most recent nodes that are never loop candidates.
        min_points: submaps with fewer points have no descriptor.
    """

    n_rings: int = 20
    n_sectors: int = 60
    max_radius_m: float = 20.0
    tau: float = 0.7
    num_candidates: int = 10
    height_offset_m: float = 2.0
    ceiling_above_sensor_m: float | None = 1.0
    ellipsoid_base_m: tuple[float, float, float] = (3.0, 3.0, 1.0)
    ellipsoid_growth: tuple[float, float, float] = (0.05, 0.05, 0.02)
    exclude_recent: int = 10
    min_points: int = 50

    def __post_init__(self) -> None:
        for name in ("ellipsoid_base_m", "ellipsoid_growth"):
            v = np.asarray(getattr(self, name), dtype=float)
            if v.shape != (3,) or not np.all(np.isfinite(v)) or np.any(v < 0):
                raise ConfigError(name, getattr(self, name), "three finite non-negative numbers (x, y, z)")
        if np.any(np.asarray(self.ellipsoid_base_m) <= 0):
            raise ConfigError("ellipsoid_base_m", self.ellipsoid_base_m, "three positive semi-axes, m")
        object.__setattr__(self, "exclude_recent", check_int("exclude_recent", self.exclude_recent, 1))
        if self.ceiling_above_sensor_m is not None:
            check_range("ceiling_above_sensor_m", self.ceiling_above_sensor_m, 0.0, None, low_open=True)
        self.sc_config()  # validates the descriptor fields

    def sc_config(self) -> ScanContextConfig:
        max_h = None if self.ceiling_above_sensor_m is None else self.height_offset_m + self.ceiling_above_sensor_m
        return ScanContextConfig(n_rings=self.n_rings, n_sectors=self.n_sectors, max_radius_m=self.max_radius_m,
                                 height_offset_m=self.height_offset_m, max_height_m=max_h,
                                 num_candidates=self.num_candidates, tau=self.tau, min_points=self.min_points)


def in_search_ellipsoid(d_xyz: np.ndarray, a_xyz: np.ndarray) -> np.ndarray:
    """Eq. (4.12) for distance vectors ``d`` (K, 3) and semi-axes ``a`` (3,): (K,) bool."""
    d = np.asarray(d_xyz, dtype=float).reshape(-1, 3)
    return np.sum((d / np.asarray(a_xyz, dtype=float)) ** 2, axis=1) <= 1.0


class LoopDetector:
    """SC++ descriptors of the nodes and the ellipsoid-restricted query."""

    def __init__(self, config: LoopDetectorConfig | None = None) -> None:
        self.config = config or LoopDetectorConfig()
        self.recognizer = ScanContextPP(self.config.sc_config())

    def describe(self, points_node: np.ndarray, T_map_node: np.ndarray) -> ContextDescriptor:
        """Descriptor of a submap given in its node frame (level frame of the keyframe)."""
        T_level_node = np.linalg.inv(level_frame(T_map_node)) @ np.asarray(T_map_node, dtype=float)
        p = np.asarray(points_node, dtype=float).reshape(-1, 3)
        return self.recognizer.describe(p @ T_level_node[:3, :3].T + T_level_node[:3, 3])

    def add(self, descriptor: ContextDescriptor) -> int:
        """Store the descriptor of the next node (indices follow the node keys)."""
        return self.recognizer.add(descriptor)

    def search_axes(self, travelled_since_loop_m: float) -> np.ndarray:
        """Semi-axes ``a_s`` of the search ellipsoid, m."""
        cfg = self.config
        return np.asarray(cfg.ellipsoid_base_m) + np.asarray(cfg.ellipsoid_growth) * max(0.0, travelled_since_loop_m)

    def query(self, descriptor: ContextDescriptor, t_map_nodes: np.ndarray, current: int,
              travelled_since_loop_m: float) -> tuple[PlaceMatch, int]:
        """Best match of node ``current`` among the nodes in the ellipsoid; ``(match, |K|)``.

        ``t_map_nodes`` (N, 3): current positions of all stored nodes (row = node key).
        """
        cfg = self.config
        ns = cfg.n_sectors
        if not descriptor.valid:
            return PlaceMatch(-1, math.nan, 0, math.nan, False, "no_descriptor", ns), 0
        last = current - cfg.exclude_recent  # candidates: keys < last
        if last <= 0:
            return PlaceMatch(-1, math.nan, 0, math.nan, False, "no_candidates", ns), 0
        t = np.asarray(t_map_nodes, dtype=float)
        d = t[current][None, :] - t[:last]  # eq. (4.11)
        inside = np.flatnonzero(in_search_ellipsoid(d, self.search_axes(travelled_since_loop_m)))
        db = self.recognizer.database.descriptors
        cand = [int(j) for j in inside if db[j].valid]
        if not cand:
            return PlaceMatch(-1, math.nan, 0, math.nan, False, "no_candidates", ns), 0
        keys = np.asarray([db[j].ring_key for j in cand])
        order = np.argsort(np.linalg.norm(keys - descriptor.ring_key[None, :], axis=1), kind="stable")
        best = (-math.inf, -1, 0)
        for j in (cand[i] for i in order[: cfg.num_candidates]):
            sim, shift = best_shift(descriptor.matrix, db[j].matrix)
            if sim > best[0]:
                best = (sim, j, shift)
        sim, j, shift = best
        accepted = sim > cfg.tau
        match = PlaceMatch(j, 1.0 - sim, shift, sim, accepted, "match" if accepted else "below_threshold", ns,
                           min(len(cand), cfg.num_candidates))
        return match, len(cand)


def verify_loop(nodes: Sequence[Node], c: int, l_idx: int, neighbors: int, exclude_recent: int, voxel_m: float,
                covariance_neighbors: int, coarse_cfg: GicpConfig, fine_cfg: GicpConfig) -> GicpResult | None:
    """GICP of ``S_c`` (node ``c`` and ``neighbors`` before) onto ``S_l`` (node ``l_idx`` and
    ``neighbors`` either side, none of the ``exclude_recent`` newest), clouds at ``voxel_m``;
    the fine result in the loop node's frame, None when a pass does not converge."""
    T_map_c, T_map_l = nodes[c].T_map_node, nodes[l_idx].T_map_node
    v = neighbors
    src = nodes_cloud(nodes[max(0, c - v): c + 1], np.linalg.inv(T_map_c), voxel_m)
    tgt_nodes = nodes[max(0, l_idx - v): min(l_idx + v + 1, c - exclude_recent + 1)]
    tgt = nodes_cloud(tgt_nodes, np.linalg.inv(T_map_l), voxel_m)
    source, target = GicpCloud(src, covariance_neighbors), GicpCloud(tgt, covariance_neighbors)
    T0 = np.linalg.inv(T_map_l) @ T_map_c  # translation = d_l of eq. (4.11) in the loop node frame
    coarse = align(source, target, T0, coarse_cfg)
    if not coarse.converged:
        return None
    fine = align(source, target, coarse.T_target_source, fine_cfg)
    return fine if fine.converged else None
