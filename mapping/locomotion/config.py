"""Configs of the locomotion pipelines: footprints, walking direction, working resolution, stages.

A pipeline config nests the configs of its stages (``ahc``, ``planes``, ``terrain``,
``footprint``; ``tsdf`` for ``terrain-recon``), so ``--set terrain-recon.ahc.<field>=...``
reaches them. ``terrain-recon`` nests D-VIO's config too (``dvio``, :class:`DvioConfig`), used when
``odometry`` is ``"dvio"``: ``--set terrain-recon.odometry=dvio --set terrain-recon.dvio.window=10``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from exobench.core import ConfigError, check_int, check_range
from exobench.mapping.odometry.dvio.pipeline import DvioConfig
from exobench.mapping.tsdf import TsdfConfig
from exobench.perception.terrain.footprint import FootprintConfig
from exobench.perception.terrain.plane_extraction import AhcConfig
from exobench.perception.terrain.plane_tracking import PlaneTrackingConfig
from exobench.perception.terrain.terrain_types import TerrainConfig

__all__ = ["LocomotionConfig", "TerrainReconConfig", "TerrainReconDvioConfig", "check_locomotion_config"]

STATUSES = ("ok", "no_depth", "bad_frame", "no_odometry", "no_planes", "error", "few_strikes", "no_direction",
            "no_terrain", "extrapolated", "current_unknown")
# D-VIO's depth-enhanced SfM is metric, so its initialisation needs no long baseline for the
# scale (VINS-Mono's 10 keyframes): the visual-inertial alignment of M keyframes solves 3M + 4
# unknowns (velocities, gravity, scale) from 6(M - 1) equations, overdetermined from M = 4; 5
# keeps a margin. A walker sets off at the first frame and the predictor needs three heel
# strikes with a pose, so a chest camera's 10 keyframes (1.5-3 s of slow parallax at the start)
# left the first steps undecided (docs/tracks/locomotion.md, "Why D-VIO started late or never").
LOCOMOTION_INIT_KEYFRAMES = 5
MODE_REFERENCES = ("swing", "stance")
DIRECTIONS = ("stride", "velocity")
STRIKE_PADS = ("any", "heel")
LOOKUPS = ("midfoot", "ankle")
TRACK_POINTS = ("joint", "camera")
ODOMETRIES = ("given", "dvio")
REINIT_MAPS = ("keep", "reset")
LOSS_POSES = ("none", "imu")


def check_locomotion_config(cfg: Any) -> None:
    """Validate the fields of :class:`LocomotionConfig` (and of its subclasses)."""
    object.__setattr__(cfg, "every_k", check_int("every_k", cfg.every_k, 1))
    check_range("max_odometry_age_s", cfg.max_odometry_age_s, 0.0)
    check_range("lead_fraction", cfg.lead_fraction, 0.0, 1.0)
    check_range("foot_lead_m", cfg.foot_lead_m, -1.0, 1.0)
    if cfg.camera_ahead_m is not None:
        check_range("camera_ahead_m", cfg.camera_ahead_m, -1.0, 1.0)
    check_range("pause_s", cfg.pause_s, 0.0, low_open=True)
    check_range("start_step_fraction", cfg.start_step_fraction, 0.0, 2.0)
    if cfg.mode_reference not in MODE_REFERENCES:
        raise ConfigError("mode_reference", cfg.mode_reference, list(MODE_REFERENCES))
    check_range("min_speed_m_s", cfg.min_speed_m_s, 0.0)
    check_range("min_heel_off_s", cfg.min_heel_off_s, 0.0, 1.0)
    object.__setattr__(cfg, "max_work_width_px", check_int("max_work_width_px", cfg.max_work_width_px, 16))
    if cfg.standing_drop_m is not None:
        check_range("standing_drop_m", cfg.standing_drop_m, -0.5, 0.5)
    if cfg.track_point not in TRACK_POINTS:
        raise ConfigError("track_point", cfg.track_point, list(TRACK_POINTS))
    if cfg.lookup not in LOOKUPS:
        raise ConfigError("lookup", cfg.lookup, list(LOOKUPS))
    if cfg.strike_pads not in STRIKE_PADS:
        raise ConfigError("strike_pads", cfg.strike_pads, list(STRIKE_PADS))
    if cfg.direction not in DIRECTIONS:
        raise ConfigError("direction", cfg.direction, list(DIRECTIONS))



@dataclass(frozen=True)
class LocomotionConfig:
    """``rgbd_sensor_id``: camera used ("" = the calibration's first RGB-D mount).
    ``odometry_sensor_id``: odometry used ("" = the one whose mount tracks the camera, "*" = any). ``every_k``:
    process every k-th frame of the camera. ``max_odometry_age_s``: the latest odometry
    sample older than this (from a frame or heel strike) counts as missing. ``lead_fraction``,
    ``foot_lead_m``, ``camera_ahead_m`` (None: from the calibration, :func:`tracked_point_neutral`),
    ``track_point`` (``"joint"``, ``"camera"``), ``standing_drop_m``, ``strike_pads``
    (``"any"``, ``"heel"``), ``lookup`` (``"midfoot"``, ``"ankle"``), ``min_speed_m_s``,
    ``pause_s``, ``start_step_fraction``: footprints;
    ``mode_reference``: ``"swing"`` or ``"stance"`` (module docstring). ``observed_stride_px``: pixel stride of
    the points whose voxels make the update's scope. ``max_work_width_px``: wider depth
    images are decimated to every m-th pixel, m = ceil(width / max_work_width_px), before
    anything else. ``min_heel_off_s``: heel-strike debounce. ``toe_m``: a level step whose toes
    (this far ahead of the footprint; 0 = off) would be inside a riser goes onto the tread
    above (:meth:`TerrainDescription.tread_above`). ``crease_toe_m``: likewise, a step whose
    toes (this far ahead; 0 = off) would be across a crease goes past it
    (:meth:`TerrainDescription.crease_ahead`). ``direction``: walking
    direction at a strike, ``"stride"`` or ``"velocity"`` (module docstring). ``ahc``,
    ``planes``, ``terrain``, ``footprint``: configs of plane extraction, eq. 23, the terrain
    description, eq. 16-18."""

    rgbd_sensor_id: str = ""
    odometry_sensor_id: str = ""
    every_k: int = 1
    max_odometry_age_s: float = 0.25
    lead_fraction: float = 0.5
    foot_lead_m: float = 0.0
    camera_ahead_m: float | None = None
    track_point: str = "joint"
    standing_drop_m: float | None = 0.03
    mode_reference: str = "swing"
    pause_s: float = 1.2
    start_step_fraction: float = 0.6
    min_speed_m_s: float = 0.05
    min_heel_off_s: float = 0.1
    strike_pads: str = "any"
    lookup: str = "midfoot"
    direction: str = "stride"
    toe_m: float = 0.15
    crease_toe_m: float = 0.06
    max_work_width_px: int = 424
    observed_stride_px: int = 4
    ahc: AhcConfig = field(default_factory=AhcConfig)
    planes: PlaneTrackingConfig = field(default_factory=PlaneTrackingConfig)
    terrain: TerrainConfig = field(default_factory=TerrainConfig)
    footprint: FootprintConfig = field(default_factory=lambda: FootprintConfig(step_estimate="median", n_recent=4))

    def __post_init__(self) -> None:
        check_locomotion_config(self)


@dataclass(frozen=True)
class TerrainReconConfig(LocomotionConfig):
    """``raycast_downsample``: I_D^s is ray cast at 1/n of the input resolution (K scaled)
    and brought back to it by :func:`upsample_depth` (``upsample_jump_m``), so plane
    extraction and its pixel thresholds see the input resolution [A: 2: the ray cast and its
    refinement cost about a quarter; the planes stay those of the full-resolution cast on
    the quick suite]. ``odometry``: where the camera poses come from: ``"given"``, the odometry
    stream (``odometry_sensor_id``), or ``"dvio"``, D-VIO run inside the pipeline on the camera's
    RGB-D frames and IMU samples with the config ``dvio`` (:mod:`.own_odometry`; D-VIO's defaults but
    ``init_keyframes`` :data:`LOCOMOTION_INIT_KEYFRAMES`). ``reinit_map``: at a re-initialisation
    of D-VIO, ``"keep"`` the map built in the old frame or ``"reset"`` it and build a new one in
    the new frame, placing the strikes of the loss with the new window's poses [A: keep; reset
    decided fewer steps right on the paper cases measured, docs/tracks/locomotion.md].
    ``loss_pose``: a frame while D-VIO is lost has ``"none"`` (no pose: no mode, no footprint)
    or ``"imu"``, the pose of D-VIO's IMU propagation of its last good state (the one its next
    segment is anchored on) for the first ``max_dead_reckon_s`` of the loss, while it stays
    within D-VIO's failure bounds: the prediction and the strikes use it, the map does not (its
    depth is not fused) [A: imu, for D-VIO's own 3 s bound on that propagation; it decided the
    steps of the losses on the paper cases measured, docs/tracks/locomotion.md]."""

    tsdf: TsdfConfig = field(default_factory=TsdfConfig)
    raycast_downsample: int = 2
    upsample_jump_m: float = 0.05
    odometry: str = "given"
    reinit_map: str = "keep"
    loss_pose: str = "imu"
    max_dead_reckon_s: float = 3.0
    dvio: DvioConfig = field(default_factory=lambda: DvioConfig(init_keyframes=LOCOMOTION_INIT_KEYFRAMES))

    def __post_init__(self) -> None:
        check_locomotion_config(self)
        object.__setattr__(self, "raycast_downsample", check_int("raycast_downsample", self.raycast_downsample, 1))
        check_range("upsample_jump_m", self.upsample_jump_m, 0.0)
        if self.odometry not in ODOMETRIES:
            raise ConfigError("odometry", self.odometry, list(ODOMETRIES))
        if self.reinit_map not in REINIT_MAPS:
            raise ConfigError("reinit_map", self.reinit_map, list(REINIT_MAPS))
        if self.loss_pose not in LOSS_POSES:
            raise ConfigError("loss_pose", self.loss_pose, list(LOSS_POSES))
        check_range("max_dead_reckon_s", self.max_dead_reckon_s, 0.0, 3.0)


@dataclass(frozen=True)
class TerrainReconDvioConfig(TerrainReconConfig):
    """:class:`TerrainReconConfig` on D-VIO's poses by default (``terrain-recon-dvio``)."""

    odometry: str = "dvio"
