"""Office walks with a worn RGB-D camera and its IMU, moving as the course cameras do (the vio track).

:class:`CameraOfficeScenario` is the office walk of :mod:`.office` (same world, route planner and
truth) with another rig: an RGB-D camera on the ``mount`` (head, chest or right thigh; D455 at
424x240 by default) and its IMU, nothing else (no trunk LiDAR, encoders or insoles). The camera
rows (resolution, rate, depth noise, dropout, exposure, the IMU's rate, extrinsics and clock
offset) are the course scenario's own (:data:`exobench.envs.sim.scenarios.course.PARAMS`), so
both worlds take the same values the same way; the office's LiDAR rows, which would act on
nothing here, are left out. ``out_and_back`` makes any walk a closed loop (there and back along
the route), for the loop errors of the paper's Table V on short walks.

The camera moves as on the courses (:mod:`exobench.envs.motion.view`): the head camera follows
the neck's seeded pitch and yaw process (mean ``head_pitch_mean_rad``, spread
``head_pitch_std_rad``; there are no terrain transitions to look down at in an office, so the
gaze is the terrain-blind process), the chest camera sits on its turning rig (``chest_yaw``,
``chest_pitch``) swaying with a third of that spread, the thigh camera moves with the thigh.
``view="unconventional"`` adds the slow large excursions. The realism options of
docs/vio-realism.md all reach this rig: ``imu_extrinsics``, ``imu_time_offset_s``,
``heel_strike_scale`` (the IMU config), ``surfaces`` and ``light_level`` (the office's look,
textures drawn from ``office_seed``), ``exposure_s`` and ``depth_through_glass`` (the camera config).

Truth (as every office walk with a camera, :func:`.office._office_episode`): the optical frame's
pose at every frame's measurement time (``body_tracks[<camera>]``, ``extra["camera_T_world"]``,
``extra["camera_stamps_s"]``) and the IMU's pose at every IMU sample (``body_tracks[<imu>]``).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from exobench.core import ConfigError
from exobench.models.exo_spec import ExoSpec
from exobench.models.world_params import ParamSpec

from ...motion import Motion
from ...sensors import ImuConfig, RgbdConfig, sensor_rngs
from ..rig import Rig, camera_rig
from ..scenario import scenario_base
from . import course
from .office import PARAMS as OFFICE_PARAMS
from .office import OfficeScenario, route_waypoints

# office rows that act only on the LiDAR, its truth, or sensors this rig does not carry
OFFICE_ONLY_LIDAR = ("facade_glass", "partition_glass", "glass_bow_mm_per_m", "glass_roller_wave_mm", "lidar_truth",
                     "lidar", "lidar_mount", "lidar_height_m", "lidar_rate_hz", "lidar_return", "lidar_noise_m",
                     "lidar_resolution_m", "lidar_scan_dropout", "lidar_point_dropout", "lidar_nan_points",
                     "lidar_duplicate_scans", "lidar_out_of_order", "lidar_time_jump_prob", "lidar_time_jump_s",
                     "encoder_noise_rad", "extra_sensors", "segmentation_truth")  # fmt: skip
# the course's camera rows, taken as they are
CAMERA_ROWS = ("mount", "view", "head_pitch_mean_rad", "head_pitch_std_rad", "width_px", "height_px", "fx_px", "rate_hz",
               "latency_s", "depth_noise_scale", "min_depth_m", "max_depth_m", "frame_dropout", "exposure_s",
               "imu_rate_hz", "imu_extrinsics", "imu_time_offset_s")  # fmt: skip

# the office's glass is the only glass a camera meets (the courses have none), so the row is here
DEPTH_THROUGH_GLASS = ParamSpec(True, None, None, "", "the depth image looks through the glass partitions, doors and "
                                "windows to the surface behind, as a D455's active IR stereo does through clear glass; "
                                "False: the pane's depth (docs/vio-realism.md, Depth through glass)", choices=(False, True),
                                feeds=("rgbd.depth_through_glass",))
IMU_DROPOUT = ParamSpec(0.0, 0.0, 0.9, "", "probability a sample of the camera's IMU is lost", feeds=("imu.dropout_prob",))

PARAMS: dict[str, ParamSpec] = {
    **{k: v for k, v in OFFICE_PARAMS.items() if k not in OFFICE_ONLY_LIDAR},
    "out_and_back": ParamSpec(False, None, None, "", "walk half of max_distance_m along the route, turn round on the spot "
                              "and walk back to the start, facing as at the start: a closed loop of any length",
                              choices=(False, True)),
    **{k: course.PARAMS[k] for k in CAMERA_ROWS},
    "depth_through_glass": DEPTH_THROUGH_GLASS,
    "imu_dropout": IMU_DROPOUT,
}


class CameraOfficeScenario(scenario_base("CameraOfficeScenario", "office camera walk", PARAMS, OfficeScenario)):  # type: ignore[misc]
    """An office walk with a worn RGB-D camera and its IMU; see :data:`PARAMS`."""

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.min_depth_m >= self.max_depth_m:
            raise ConfigError("min_depth_m", self.min_depth_m, f"less than max_depth_m = {self.max_depth_m}")

    def exo_spec(self) -> ExoSpec:
        return ExoSpec(user_height_m=self.user_height_m, user_mass_kg=self.user_mass_kg)

    def rgbd_config(self) -> RgbdConfig:
        return self.configured("rgbd", RgbdConfig, subpixel=0.08 * self.depth_noise_scale)

    def rig(self) -> Rig:
        """The camera's IMU, then the camera (ties in that order)."""
        return camera_rig(self.mount, self.rgbd_config(), self.configured("imu", ImuConfig))

    def route_polyline(self, waypoints: list[tuple[float, float]]) -> tuple[tuple[float, float], ...]:
        """The route cut at ``max_distance_m``, or with ``out_and_back`` at half of it and walked
        back (the planner ends a closed polyline facing as it started)."""
        if not self.out_and_back:
            return route_waypoints(waypoints, self.max_distance_m)
        out = route_waypoints(waypoints, 0.5 * self.max_distance_m)
        return (*out, *out[-2::-1])

    def step_factors(self) -> tuple[float, ...]:
        """As the courses plan (:data:`.course.PLAN_TRIES`): the step asked for, then 0.9, 1.1 and
        0.8 of it while the walker finds no foothold (the office's doorways refuse a few
        combinations of step and height), so that every drawn walk can be walked."""
        return (1.0, 0.9, 1.1, 0.8)

    def moves_cameras(self) -> bool:
        return True

    def recording_hooks(self, exo: ExoSpec, motion: Motion, seed: int) -> tuple[Any, ...]:
        """The head or chest camera's view process (seeded by ``office_view``); the thigh camera
        has none (it moves with the thigh)."""
        from exobench.models.exo_spec import JOINT_RANGES_RAD

        from ...motion.view import view_motion
        from ..hooks import ViewHook

        if self.mount == "thigh":
            return ()
        rng = sensor_rngs(seed, "office_view")[0]
        mount_pitch = np.radians(0.5 * exo.camera_pitch_deg if self.mount == "head" else exo.camera_pitch_deg)

        def trunk_pitch(t: np.ndarray) -> np.ndarray:
            return motion.state(np.atleast_1d(t), solve_legs=False).pitch

        view = view_motion(self.mount, self.view, self.head_pitch_mean_rad, self.head_pitch_std_rad, float(mount_pitch),
                           trunk_pitch, {k: JOINT_RANGES_RAD[k] for k in ("neck_pitch", "neck_yaw")},
                           float(motion.duration_s), rng, None)  # fmt: skip
        return (ViewHook(view),)
