"""Config of the LEO-SLAM pipeline (:class:`~.leo_slam.LeoSlamPipeline`) and its validation.

One flat dataclass of every parameter (saved with the run config); it checks its own ranges
and builds the configs of the stages it feeds (:mod:`.preprocess`, :mod:`.gicp`,
:mod:`.loop_closure`), which check theirs when the config is made.
"""

from __future__ import annotations

from dataclasses import dataclass

from exobench.core.errors import check_int, check_range
from exobench.mapping.odometry.gicp import GicpConfig
from exobench.mapping.odometry.loop_closure import LoopDetectorConfig
from exobench.mapping.odometry.preprocess import PreprocessConfig

__all__ = ["LeoSlamConfig"]


@dataclass(frozen=True)
class LeoSlamConfig:
    """Parameters (the thesis gives the structure, small-GICP's 0.25 m leaf; the rest are
    small-GICP / SC++ defaults or chosen for indoor VLP-16-class sensors).

    Attributes:
        sensor_id: LiDAR to use; ``""`` takes the first one seen.
        self_box_min_m / self_box_max_m: robot crop box in the sensor frame, m.
        outer_box_min_m / outer_box_max_m: range crop box, m.
        sor_neighbors / sor_std_ratio: statistical outlier filter (0 neighbours: off).
        voxel_m: small-GICP voxel leaf of the registration clouds (thesis 5.2.1: 0.25 m).
        map_voxel_m: voxel leaf of the map.
        deskew: constant-velocity deskew with ``time_offset_s``.
        gicp_max_correspondence_m / gicp_max_iterations / gicp_neighbors: GICP settings.
        gicp_min_fitness / gicp_max_rmse_m: acceptance of an alignment.
        keyframe_distance_m: ``Delta_m``.
        keyframe_rotation_deg: ``Delta_theta``.
        submap_count: ``N_s``, previous submaps aligned against (s2S and S2S).
        loop_closure: enable submap loop closure.
        sc_rings / sc_sectors / sc_max_radius_m / sc_tau: Scan Context++ (eq. 4.20-4.25).
        sc_ceiling_above_sensor_m: ceiling removal height above the sensor, m (<= 0: off).
        ellipsoid_base_m / ellipsoid_growth: search area ``a_s = a_0 + growth * travelled``.
        loop_exclude_recent: newest nodes never used as loop candidates.
        loop_neighbors: ``v`` of the loop alignment sets ``S_c`` / ``S_l``.
        loop_max_correspondence_m: coarse GICP correspondence distance of the loop alignment.
        loop_min_fitness: inlier fraction needed to accept a loop alignment.
        loop_max_correction_m: larger corrections of the current node are rejected, m.
        min_points: sweeps with fewer valid points are not aligned.
        max_lost: consecutive failed alignments after which the s2S target is rebuilt
            around the current pose.
    """

    sensor_id: str = ""
    self_box_min_m: tuple[float, float, float] = (-0.5, -0.5, -1.6)
    self_box_max_m: tuple[float, float, float] = (0.5, 0.5, 0.3)
    outer_box_min_m: tuple[float, float, float] = (-50.0, -50.0, -10.0)
    outer_box_max_m: tuple[float, float, float] = (50.0, 50.0, 10.0)
    sor_neighbors: int = 20
    sor_std_ratio: float = 2.0
    voxel_m: float = 0.25
    map_voxel_m: float = 0.1
    deskew: bool = True
    gicp_max_correspondence_m: float = 1.0
    gicp_max_iterations: int = 20
    gicp_neighbors: int = 20
    gicp_min_fitness: float = 0.3
    gicp_max_rmse_m: float = 0.5
    keyframe_distance_m: float = 1.0
    keyframe_rotation_deg: float = 15.0
    submap_count: int = 5
    loop_closure: bool = True
    sc_rings: int = 20
    sc_sectors: int = 60
    sc_max_radius_m: float = 20.0
    sc_tau: float = 0.7
    sc_ceiling_above_sensor_m: float = 1.0
    ellipsoid_base_m: tuple[float, float, float] = (3.0, 3.0, 1.0)
    ellipsoid_growth: tuple[float, float, float] = (0.05, 0.05, 0.02)
    loop_exclude_recent: int = 10
    loop_neighbors: int = 2
    loop_max_correspondence_m: float = 2.0
    loop_min_fitness: float = 0.6
    loop_max_correction_m: float = 3.0
    min_points: int = 100
    max_lost: int = 5

    def __post_init__(self) -> None:
        check_range("keyframe_distance_m", self.keyframe_distance_m, 0.0, None, low_open=True)
        check_range("keyframe_rotation_deg", self.keyframe_rotation_deg, 0.0, 180.0, low_open=True)
        for name in ("submap_count", "loop_neighbors", "min_points", "max_lost"):
            low = 0 if name == "loop_neighbors" else 1
            object.__setattr__(self, name, check_int(name, getattr(self, name), low))
        check_range("loop_max_correspondence_m", self.loop_max_correspondence_m, 0.0, 100.0, low_open=True)
        check_range("loop_min_fitness", self.loop_min_fitness, 0.0, 1.0)
        check_range("loop_max_correction_m", self.loop_max_correction_m, 0.0, None, low_open=True)
        self.preprocess_config()
        self.gicp_config()
        self.loop_config()

    def preprocess_config(self) -> PreprocessConfig:
        return PreprocessConfig(self.self_box_min_m, self.self_box_max_m, self.outer_box_min_m,
                                self.outer_box_max_m, self.sor_neighbors, self.sor_std_ratio, self.voxel_m,
                                self.map_voxel_m, self.deskew)

    def gicp_config(self) -> GicpConfig:
        return GicpConfig(max_correspondence_m=self.gicp_max_correspondence_m,
                          max_iterations=self.gicp_max_iterations, covariance_neighbors=self.gicp_neighbors,
                          min_fitness=self.gicp_min_fitness, max_rmse_m=self.gicp_max_rmse_m)

    def loop_config(self) -> LoopDetectorConfig:
        ceiling = self.sc_ceiling_above_sensor_m if self.sc_ceiling_above_sensor_m > 0 else None
        return LoopDetectorConfig(n_rings=self.sc_rings, n_sectors=self.sc_sectors,
                                  max_radius_m=self.sc_max_radius_m, tau=self.sc_tau,
                                  ceiling_above_sensor_m=ceiling, ellipsoid_base_m=self.ellipsoid_base_m,
                                  ellipsoid_growth=self.ellipsoid_growth,
                                  exclude_recent=self.loop_exclude_recent)

    def loop_gicp_configs(self) -> tuple[GicpConfig, GicpConfig]:
        """GICP settings of a loop's verification: the coarse pass (``loop_max_correspondence_m``,
        accepts any converged result) and the fine pass (accepted by ``loop_min_fitness``)."""
        coarse = GicpConfig(max_correspondence_m=self.loop_max_correspondence_m,
                            max_iterations=self.gicp_max_iterations, covariance_neighbors=self.gicp_neighbors,
                            min_fitness=0.0, max_rmse_m=1e9)
        fine = GicpConfig(max_correspondence_m=self.gicp_max_correspondence_m,
                          max_iterations=self.gicp_max_iterations, covariance_neighbors=self.gicp_neighbors,
                          min_fitness=self.loop_min_fitness, max_rmse_m=self.gicp_max_rmse_m)
        return coarse, fine
