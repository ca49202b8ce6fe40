"""LEO-SLAM pose graph of submap nodes, optimised with iSAM2 (seeds/003 section 4.2.1).

The graph holds only pose factors: a prior on the first node, a ``BetweenFactorPose3`` between
consecutive nodes (the relative pose after the submap-to-submaps alignment) and one between a
node and its loop node (eq. 4.14), optionally with a Huber kernel. gtsam's tangent order is (rotation, translation).
"""

from __future__ import annotations

from dataclasses import dataclass

import gtsam
import numpy as np

from exobench.core.errors import check_range

__all__ = ["PoseGraph", "PoseGraphConfig"]


@dataclass(frozen=True)
class PoseGraphConfig:
    """Noise of the factors (standard deviations) and iSAM2 settings.

    Attributes:
        prior_sigma_rad / prior_sigma_m: prior on the first node.
        odom_sigma_rad / odom_sigma_m: consecutive-node factors.
        loop_sigma_rad / loop_sigma_m: loop factors.
        loop_huber_k: Huber threshold of the loop factors (whitened units); 0 disables the
            kernel (plain Gaussian loop factors, the default: loops are verified by GICP first).
        extra_updates: additional iSAM2 updates after a loop closure (relinearisation).
    """

    prior_sigma_rad: float = 1e-4
    prior_sigma_m: float = 1e-4
    odom_sigma_rad: float = 0.01
    odom_sigma_m: float = 0.05
    loop_sigma_rad: float = 0.01
    loop_sigma_m: float = 0.05
    loop_huber_k: float = 0.0
    extra_updates: int = 5

    def __post_init__(self) -> None:
        for name in ("prior_sigma_rad", "prior_sigma_m", "odom_sigma_rad", "odom_sigma_m",
                     "loop_sigma_rad", "loop_sigma_m"):
            check_range(name, getattr(self, name), 0.0, None, low_open=True)
        check_range("loop_huber_k", self.loop_huber_k, 0.0, None)
        check_range("extra_updates", self.extra_updates, 0, 100)


def _sigmas(rad: float, m: float) -> gtsam.noiseModel.Diagonal:
    return gtsam.noiseModel.Diagonal.Sigmas(np.array([rad, rad, rad, m, m, m]))


class PoseGraph:
    """Incremental pose graph over integer node keys ``0, 1, ...``."""

    def __init__(self, config: PoseGraphConfig | None = None) -> None:
        self.config = config or PoseGraphConfig()
        params = gtsam.ISAM2Params()
        params.setRelinearizeThreshold(0.01)
        params.relinearizeSkip = 1
        self._isam = gtsam.ISAM2(params)
        self._poses: dict[int, np.ndarray] = {}
        self.n_loops = 0

    def __len__(self) -> int:
        return len(self._poses)

    def add_node(self, key: int, T_map_node: np.ndarray, T_prev_node: np.ndarray | None = None) -> None:
        """Add node ``key`` at ``T_map_node``; with ``T_prev_node`` also the factor from ``key - 1``."""
        cfg = self.config
        graph = gtsam.NonlinearFactorGraph()
        values = gtsam.Values()
        values.insert(key, gtsam.Pose3(np.asarray(T_map_node, dtype=float)))
        if T_prev_node is None:
            graph.add(gtsam.PriorFactorPose3(key, gtsam.Pose3(np.asarray(T_map_node, dtype=float)),
                                             _sigmas(cfg.prior_sigma_rad, cfg.prior_sigma_m)))
        else:
            graph.add(gtsam.BetweenFactorPose3(key - 1, key, gtsam.Pose3(np.asarray(T_prev_node, dtype=float)),
                                               _sigmas(cfg.odom_sigma_rad, cfg.odom_sigma_m)))
        self._isam.update(graph, values)
        self._poses[key] = np.asarray(T_map_node, dtype=float).copy()

    def add_loop(self, key_a: int, key_b: int, T_a_b: np.ndarray) -> None:
        """Loop factor: pose of node ``key_b`` in node ``key_a`` (eq. 4.14); then optimise."""
        cfg = self.config
        noise = _sigmas(cfg.loop_sigma_rad, cfg.loop_sigma_m)
        if cfg.loop_huber_k > 0:
            noise = gtsam.noiseModel.Robust.Create(gtsam.noiseModel.mEstimator.Huber.Create(cfg.loop_huber_k), noise)
        graph = gtsam.NonlinearFactorGraph()
        graph.add(gtsam.BetweenFactorPose3(key_a, key_b, gtsam.Pose3(np.asarray(T_a_b, dtype=float)), noise))
        self._isam.update(graph, gtsam.Values())
        for _ in range(cfg.extra_updates):
            self._isam.update()
        self.n_loops += 1
        self._refresh()

    def _refresh(self) -> None:
        est = self._isam.calculateEstimate()
        for key in self._poses:
            self._poses[key] = est.atPose3(key).matrix()

    def pose(self, key: int) -> np.ndarray:
        """Current estimate of a node (4x4)."""
        return self._poses[key].copy()

    def poses(self) -> dict[int, np.ndarray]:
        """Current estimates of all nodes."""
        return {k: v.copy() for k, v in self._poses.items()}
