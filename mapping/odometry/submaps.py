"""LEO-SLAM submap nodes and keyframe decisions (seeds/003 section 4.2.1).

A node ``n`` is a submap ``S`` (the scans collected since the previous node, expressed in the
node frame) and its keyframe pose ``mH_n``: the pose of the last scan of the submap. A new node
is due when the distance ``d_m`` from the last node exceeds ``Delta_m`` or the rotation
``d_theta`` reaches ``Delta_theta``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from exobench.core.transforms import transform_points
from exobench.mapping.odometry.preprocess import voxel_downsample

__all__ = ["Node", "OpenSubmap", "keyframe_due", "nodes_cloud", "rotation_angle"]


def rotation_angle(R: np.ndarray) -> float:
    """Angle of a rotation matrix, rad in [0, pi]."""
    c = (float(np.trace(np.asarray(R)[:3, :3])) - 1.0) / 2.0
    return float(np.arccos(min(1.0, max(-1.0, c))))


def keyframe_due(T_map_last_node: np.ndarray, T_map_sensor: np.ndarray, delta_m: float, delta_rad: float) -> bool:
    """``d_m > Delta_m`` or ``d_theta >= Delta_theta`` since the last node."""
    T = np.linalg.inv(T_map_last_node) @ T_map_sensor
    return bool(np.linalg.norm(T[:3, 3]) > delta_m or rotation_angle(T[:3, :3]) >= delta_rad)


@dataclass(eq=False)
class Node:
    """One pose-graph node.

    Attributes:
        index: node key in the pose graph.
        scan_index: index of its keyframe scan.
        T_map_node: current (optimised) keyframe pose.
        points_node: registration cloud of the submap in the node frame, (M, 3).
        map_points_node: map cloud of the submap in the node frame, (K, 3).
        travelled_m: path length of the trajectory at the node, m.
    """

    index: int
    scan_index: int
    T_map_node: np.ndarray
    points_node: np.ndarray
    map_points_node: np.ndarray
    travelled_m: float


@dataclass(eq=False)
class OpenSubmap:
    """Scans collected since the last node, in the map frame at their tracking poses."""

    scan_indices: list[int] = field(default_factory=list)
    T_map_scans: list[np.ndarray] = field(default_factory=list)
    points_map: list[np.ndarray] = field(default_factory=list)
    map_points_map: list[np.ndarray] = field(default_factory=list)

    def add(self, scan_index: int, T_map_sensor: np.ndarray, points_sensor: np.ndarray, map_points_sensor: np.ndarray) -> None:
        self.scan_indices.append(scan_index)
        self.T_map_scans.append(np.asarray(T_map_sensor, dtype=float).copy())
        self.points_map.append(transform_points(T_map_sensor, points_sensor))
        self.map_points_map.append(transform_points(T_map_sensor, map_points_sensor))

    def clouds_in(self, T_map_node: np.ndarray, voxel_m: float, map_voxel_m: float) -> tuple[np.ndarray, np.ndarray]:
        """The collected registration and map clouds in the frame of ``T_map_node``, voxelised."""
        T_node_map = np.linalg.inv(T_map_node)
        reg = np.concatenate(self.points_map) if self.points_map else np.zeros((0, 3))
        mp = np.concatenate(self.map_points_map) if self.map_points_map else np.zeros((0, 3))
        return (voxel_downsample(transform_points(T_node_map, reg), voxel_m),
                voxel_downsample(transform_points(T_node_map, mp), map_voxel_m))


def nodes_cloud(nodes: Sequence[Node], T_frame_map: np.ndarray, voxel_m: float) -> np.ndarray:
    """Registration clouds of ``nodes`` in the frame ``T_frame_map @ map``, voxelised."""
    parts = [transform_points(T_frame_map @ n.T_map_node, n.points_node) for n in nodes]
    if not parts:
        return np.zeros((0, 3))
    return voxel_downsample(np.concatenate(parts), voxel_m)
