"""Locomotion-mode episodes (seeds/002): a walker with an RGB-D camera, IMU, insoles and odometry
on stair, ramp and side-by-side stair/ramp courses.

:class:`LocomotionScenario` holds the parameters (:data:`PARAMS`, validated like
:mod:`exobench.envs.sim.scenario`: ``ConfigError(field, value, allowed)``, unknown names refused with
``UnknownNameError``); :func:`simulate_locomotion` builds the course
(:mod:`exobench.envs.sim.scenarios.course_world`), plans a stop-and-go walk along it
(:func:`plan_locomotion`), moves the camera like a walking person's head or chest
(:mod:`exobench.envs.motion.view`) and records an :class:`~exobench.core.Episode`.

Courses (paper section III-B 1): ``stairs`` LG -> SA -> LG -> SD -> LG (a flight of ``n_steps``
risers up, a ``landing_m`` landing, the same flight down); ``ramp`` LG -> RA -> LG -> RD -> LG
(``slope_deg``, ``ramp_length_m`` run each way); ``parallel`` (III-B 3, Fig. 3(b)): the stair
course and the ramp course side by side; the walker walks the ``parallel_first`` lane out, makes a
U-turn on the floor beyond its end and walks back along the other lane (LG SA LG SD LG, U-turn,
LG RA LG RD LG or the reverse). Side walls (``walls``) run along the lanes so that walls fill the
view when the camera turns. By default (``stops="none"``) the course is walked through every
transition without stopping, as the paper's subjects walked; with ``stops="transitions"`` the
walker stops (standing, feet together) about 8 cm before every transition from level ground to
stairs or a ramp, as exoskeleton users often do (the short step that brings the feet together
is not what eq. 17 extrapolates: mode prediction is harder there).

Limits of the walker (:mod:`exobench.envs.motion.walk`, kinematic, stop-and-go), measured: 0.15, 0.20
and 0.25 m risers with 0.25, 0.30 and 0.32 m treads (and 0.18 m risers with 0.30 m treads), and
11.8/15.8/17.8 deg ramps work for every pattern and user height 1.65-1.88 m. Risers of 0.20-0.25 m
are descended with forefoot landings and the trailing heel up to 40 deg off the step; 0.25 m ones
need a stance knee of up to 115 deg (see the walk module); on treads shorter than the foot
(0.148 x height) the toes overhang the nosing on the way down. An unwalkable course raises
``ConfigError`` naming ``riser_m`` (stairs) or ``slope_deg`` (ramps) after at most
``course_world.MAX_PLANS`` planner calls (about 20-60 s).

Walking patterns (docs/sensor-reference.md "Walking"): the walker is stop-and-go, so a pattern is a step length
and a step period = swing + double support (:data:`PATTERNS`): cadence 90 (wander), 110 (walk)
and 164 (jog) steps/min. Step lengths are what the walker can reach on stairs and ramps (0.35,
0.40, 0.45 m at 1.75 m, scaled by height; real walking takes ~0.7 m and jogging 0.9-1.1 m
steps), so level speeds are about 0.52, 0.73 and 1.2 m/s (paper Fig. 4(c): mean 0.78 m/s).

Camera motion (section IV-A 2, Fig. 4(b)): the trunk follows the gait (vertical excursion, lean
on stairs, heading); the ``head`` mount moves with the model's own neck joints (``neck_pitch``,
``neck_yaw``; so rendering, the IMU and the truth agree): the camera's pitch below the horizon is
a smooth seeded random process with mean ``head_pitch_mean_rad`` (0.14) and standard deviation
``head_pitch_std_rad`` (0.26), clipped to the paper's range -0.66..1.18 rad and to the neck's joint
range. With ``gaze="transitions"`` (default) the wearer also looks down at each terrain transition
it approaches, as people do (two steps ahead; :mod:`exobench.envs.motion.view`), the
random part shrunk so the episode's pitch keeps that mean and spread; ``gaze="random"`` is the
terrain-blind pitch alone (with it, a head camera at 0.14 rad never sees a ramp down from its
landing: 60 % on a head-mounted jog down the 17.8 deg ramp). The ``chest`` camera sits on a two-hinge rig on the pelvis (``chest_yaw``, ``chest_pitch``)
that sways with a third of that spread around the mount's 30 deg pitch; the ``thigh`` mount
(``rgbd_thigh_r``) moves with the right thigh only. ``view="unconventional"`` (III-B 2) adds slow
yaw excursions of up to +-43.5 deg (the walking direction at the image's edge: "the terrain only
partially captured") and +-0.35 rad pitch ones (head and chest), turning the camera to the walls;
``"unconventional-wide"`` turns up to +-60 deg (:mod:`exobench.envs.motion.view`).

Pedestrians (III-B 4): ``pedestrians`` kinematic people (capsule + head, 1.6-1.9 m tall, mocap
bodies in the compiled model, rendered) walk straight at 0.8-1.4 m/s towards or away from the
walker, drifting across the lane, passing 1.2-2.5 m in front of it at a seeded time.

Frames (time-ordered; ties: IMU, contacts, odometry, camera):

- ``rgbd_<m>`` :class:`~exobench.core.RgbdFrame` at ``rate_hz`` (``width_px`` x ``height_px``,
  D455 intrinsics and noise of :mod:`exobench.envs.sensors.rgbd`), stamped at measurement time +
  ``latency_s``, lost with probability ``frame_dropout``; ``<m>`` is ``head``, ``chest`` or
  ``thigh_r`` (:func:`sensor_ids`);
- ``imu_<m>`` :class:`~exobench.core.ImuSample` at ``imu_rate_hz`` from a site at the camera's
  optical frame (the D455's BMI055, docs/sensor-reference.md noise x ``imu_noise_scale``), or with
  ``imu_extrinsics="d455"`` where a D455's IMU sits; its calibration mount has that pose and
  ``calibration.extra["T_camera_imu"]`` the IMU's pose in the optical frame; stamps shifted by
  ``imu_time_offset_s`` (``calibration.extra["timeshift_cam_imu_s"]`` when not 0); heel-strike
  transients with ``heel_strike_scale`` (docs/vio-realism.md);
- ``contact_{l,r}_{heel,toe}`` insole pads (:mod:`exobench.envs.sensors.contact`), 100 Hz;
- ``odom_<m>`` :class:`~exobench.core.OdometrySample` at each camera measurement time (also for
  lost frames): the true optical-frame pose degraded by
  :func:`~exobench.envs.motion.odometry.drift_odometry` (translation error ``odom_drift_pct`` %
  of the horizontal distance travelled, heading error ``odom_yaw_drift_deg_per_m`` per metre,
  seeded directions), in a gravity-aligned odometry frame whose origin and heading are the
  camera's at t = 0. ``calibration.extra["odometry"]`` (and a ``SensorMount`` of kind
  ``"odometry"``) give the convention: the tracked body is the ``rgbd_<m>`` optical frame
  (``T_camera_body`` = identity).

Truth: ``steps`` (:class:`~exobench.core.truth.StepTruth` per step up to the cap; modes: see
:func:`~exobench.envs.sim.scenarios.course_world.step_truths`), ``events`` (``liftoff_s``, ``end_s``,
``join_<k>_s`` where the walker stopped, and ``transition_<k>_<from>_<to>_s`` at the heel strike of
each step k whose mode differs from the previous step's), ``trajectory_w`` (true optical-frame pose
at each camera measurement time, rows [t, x, y, z, qw, qx, qy, qz]), ``T_world_estimator`` (the
odometry frame), ``scene`` (surfaces of the course; the parallel course's second lane in
``scene.params["lane_b"]``), and ``extra``: ``camera_T_world`` (N, 4, 4), ``camera_stamps_s`` (N,),
``camera_pitch_rad`` (N,), ``distance_travelled_m`` (N,), ``odom_T_world`` (4, 4),
``pedestrian_tracks`` (P, N, 5) rows [t, x, y, yaw, z of the feet], ``pedestrian_height_m`` (P,),
``pedestrian_pixel_fraction`` (N, P) (share of the image each person covers),
``pedestrian_geom_names`` (their MuJoCo geoms),
``route_waypoints_xy``, ``pattern`` (step length, swing, double support, cadence, planner
retries) and ``walk_duration_s`` (the whole planned walk; the episode ends at ``duration_cap_s``).

Speed: rendering dominates (two passes a frame with software OpenGL: depth, with the geom ids
when pedestrians or ``segmentation_truth`` ask for them, then the multisampled colour pass, about
15 of the 20 ms a frame takes at 424x240). Whole episodes including IMU, contacts and odometry, on
the 2-core machine with other jobs running: the quick suite's first case at 30 Hz (424x240) 50
frames per CPU-second (37 with the three passes of before; `exobench bench locomotion`,
``episode_rgbd``); earlier, under load ~11, 424x240 gave 7.7 frames per wall-second and 640x480
3.5 (11 per CPU-second, three passes). A default stairs episode is
13-14 s of walking (about 400 frames at 30 Hz); planning takes 2-10 s once per course and user
(cached). Same scenario and seed, same frames bit for bit.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from functools import lru_cache
from typing import Any

import numpy as np

from exobench.core import ConfigError, Episode, EpisodeTruth
from exobench.core.episode import EpisodeStream
from exobench.models.exo_spec import ExoSpec
from exobench.models.vision_look import WorldLook
from exobench.models.world_params import ParamSpec

from ...motion import GaitError, Motion
from ...sensors import ContactConfig, ImuConfig, RgbdConfig, sample_times, sensor_rngs
from ...sensors.adapter import MountedSensor
from ...sensors.imu.config import CAMERA_IMU_EXTRINSICS, MAX_TIME_OFFSET_S
from ...sensors.odometry import OdometryConfig
from ...terrain import Terrain
from ..calibration import build_calibration
from ..compose import CHEST_CAMERA, attached_sites, compose_rig
from ..hooks import PedestrianHook, ViewHook
from ..pose import pose_rows
from ..recorder import record, stream_record
from ..rig import Rig, camera_rig, segmentation_truths, with_presets, with_segmentation_truth
from ..scenario import scenario_base
from .common import COMMON_PARAMS
from .course_world import step_truths

TERRAINS = ("stairs", "ramp", "parallel")
MOUNTS = ("head", "chest", "thigh")
PATTERNS_NAMES = ("wander", "walk", "jog")
VIEWS = ("normal", "unconventional", "unconventional-wide")
PARALLEL_FIRST = ("stairs", "ramp")
STOPS = ("none", "transitions")
GAZES = ("transitions", "random")
ENCLOSURES = ("open", "stairwell", "auto")

PARAMS: dict[str, ParamSpec] = {
    "terrain": ParamSpec("stairs", None, None, "", "course: stairs (LG SA LG SD LG), ramp (LG RA LG RD LG), parallel (a stair lane beside a ramp lane, up one, down the other)", choices=TERRAINS),
    "riser_m": ParamSpec(0.15, 0.05, 0.25, "m", "riser height (paper: 0.15, 0.20, 0.25; limits of the walker: see the module docstring)"),
    "tread_m": ParamSpec(0.30, 0.25, 0.45, "m", "tread depth (going)"),
    "n_steps": ParamSpec(4, 2, 8, "", "risers per flight"),
    "slope_deg": ParamSpec(11.8, 3.0, 20.0, "deg", "ramp inclination (paper: 11.8, 15.8, 17.8)"),
    "ramp_length_m": ParamSpec(2.5, 1.0, 6.0, "m", "horizontal run of each ramp (parallel: the ramp rises to the stairs' height instead)"),
    "landing_m": ParamSpec(1.8, 1.2, 4.0, "m", "level landing between the way up and the way down"),
    "approach_m": ParamSpec(1.5, 1.0, 5.0, "m", "level walk before the first transition and after the last"),
    "width_m": ParamSpec(1.2, 0.9, 3.0, "m", "width of a flight / ramp lane"),
    "walls": ParamSpec(True, None, None, "", "side walls along the course", choices=(False, True)),
    "enclosure": ParamSpec("open", None, None, "", "open: the course between its side walls, open at its ends and above "
                           "(sky beyond); stairwell: end walls 1 m beyond its ends and a ceiling 2.4 m over its landing, "
                           "as indoors (stairs and ramp courses with walls; course_enclosure); auto: stairwell where it "
                           "can be, open for the parallel course (the paper's outdoor walks) and a course without walls",
                           choices=ENCLOSURES),
    "parallel_first": ParamSpec("stairs", None, None, "", "parallel course: the lane walked first (out along +x; back along the other after a U-turn)", choices=PARALLEL_FIRST),
    "stops": ParamSpec("none", None, None, "", "none: walk through every transition without stopping, as the paper's subjects did; transitions: stop-and-go, standing with the feet together just before every transition from level ground to stairs or a ramp (and after the parallel course's U-turn), as exoskeleton users often do", choices=STOPS),
    "mount": ParamSpec("head", None, None, "", "camera mount: head (helmet), chest (chest bag), thigh", choices=MOUNTS),
    "pattern": ParamSpec("walk", None, None, "", "walking pattern: wander, walk, jog (step length and cadence, see PATTERNS)", choices=PATTERNS_NAMES),
    "user_height_m": COMMON_PARAMS["user_height_m"],  # the paper's subjects: 1.65-1.88 m
    "user_mass_kg": COMMON_PARAMS["user_mass_kg"],
    "view": ParamSpec("normal", None, None, "", "camera view: normal, unconventional (the paper's: slow yaw excursions to +-43.5 deg, the walk's direction at the image's edge, walls fill it), or unconventional-wide (+-60 deg, the terrain ahead out of view)", choices=VIEWS),
    "head_pitch_mean_rad": ParamSpec(0.14, -0.3, 0.6, "rad", "mean camera pitch below the horizon of the head mount (paper Fig. 4(b): 0.14)"),
    "head_pitch_std_rad": ParamSpec(0.26, 0.0, 0.5, "rad", "standard deviation of the head-mount camera pitch (paper: 0.26); the chest sways with a third of it"),
    "gaze": ParamSpec("transitions", None, None, "", "head mount: transitions, the wearer looks down at each terrain transition about two steps ahead (the pitch keeps head_pitch_mean_rad and head_pitch_std_rad over the episode); random, the pitch ignores the terrain", choices=GAZES),
    "pedestrians": ParamSpec(0, 0, 4, "", "people walking across the view (paper: 2 in the disturbance test)"),
    "width_px": ParamSpec(424, 16, 1280, "px", "image width (D455 424x240 / 640x480 / 848x480)", feeds=("rgbd.width_px",)),
    "height_px": ParamSpec(240, 16, 720, "px", "image height", feeds=("rgbd.height_px",)),
    "fx_px": ParamSpec(None, 0.0, 1e5, "px", "focal length (None: the D455 value for the resolution)", low_open=True,
                       feeds=("rgbd.fx_px", "rgbd.fy_px")),
    "rate_hz": ParamSpec(30.0, 1.0, 90.0, "Hz", "RGB-D frame rate (the odometry runs at the same rate)",
                         feeds=("rgbd.rate_hz", "odometry.rate_hz")),
    "latency_s": ParamSpec(0.0, 0.0, 0.5, "s", "RGB-D delivery latency", feeds=("rgbd.latency_s",)),
    "depth_noise_scale": ParamSpec(1.0, 0.0, 10.0, "", "multiplier of the D455 stereo depth noise (subpixel 0.08)"),
    "min_depth_m": ParamSpec(0.4, 0.0, 5.0, "m", "no depth closer than this (D455: 0.4)", feeds=("rgbd.min_depth_m",)),
    "max_depth_m": ParamSpec(6.0, 0.5, 20.0, "m", "no depth farther than this (D455: about 6)", feeds=("rgbd.max_depth_m",)),
    "frame_dropout": ParamSpec(0.0, 0.0, 0.9, "", "probability an RGB-D frame is lost", feeds=("rgbd.dropout_prob",)),
    "exposure_s": ParamSpec(0.0, 0.0, 0.1, "s", "colour exposure time: > 0 blurs the colour images with the camera's motion "
                            "(at most one frame period; 0: sharp; envs.sensors.rgbd.blur)", feeds=("rgbd.exposure_s",)),
    "surfaces": COMMON_PARAMS["surfaces"],
    "texture_seed": ParamSpec(0, 0, 2**31 - 1, "", "seed of the course's textures (surfaces=textured)"),
    "light_level": COMMON_PARAMS["light_level"],
    "imu_rate_hz": ParamSpec(200.0, 200.0, 400.0, "Hz", "camera IMU rate (BMI055 in the D455: 200-400)", feeds=("imu.rate_hz",)),
    "imu_noise_scale": COMMON_PARAMS["imu_noise_scale"],
    "imu_extrinsics": ParamSpec("identity", None, None, "", "pose of the camera's IMU in its optical frame: identity "
                                "(at the optical frame) or d455 (a D455's BMI055: 27.5 mm left, 3.1 mm up, 23.6 mm behind "
                                "the colour camera, kalibr; docs/vio-realism.md)", choices=tuple(CAMERA_IMU_EXTRINSICS),
                                feeds=("imu.extrinsics",)),
    "imu_time_offset_s": ParamSpec(0.0, -MAX_TIME_OFFSET_S, MAX_TIME_OFFSET_S, "s", "camera IMU clock minus camera clock "
                                   "(t_imu = t_cam + offset, kalibr's timeshift_cam_imu; a D455: 0.0025)",
                                   feeds=("imu.time_offset_s",)),
    "heel_strike_scale": COMMON_PARAMS["heel_strike_scale"],
    "odom_drift_pct": ParamSpec(1.0, 0.0, 20.0, "%", "odometry translation drift, percent of the distance travelled",
                                feeds=("odometry.drift_pct",)),
    "odom_yaw_drift_deg_per_m": ParamSpec(0.5, 0.0, 20.0, "deg/m", "odometry heading drift per metre travelled",
                                          feeds=("odometry.yaw_drift_deg_per_m",)),
    "duration_cap_s": ParamSpec(60.0, 2.0, 600.0, "s", "the episode is cut after this time (frames and steps)"),
    "extra_sensors": COMMON_PARAMS["extra_sensors"],
    "segmentation_truth": COMMON_PARAMS["segmentation_truth"],
}  # fmt: skip


class LocomotionScenario(scenario_base("LocomotionScenario", "locomotion", PARAMS)):  # type: ignore[misc]
    """One locomotion-track episode; see :data:`PARAMS` for units, ranges and meaning."""

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.min_depth_m >= self.max_depth_m:
            raise ConfigError("min_depth_m", self.min_depth_m, f"less than max_depth_m = {self.max_depth_m}")
        if self.enclosure == "stairwell" and (self.terrain == "parallel" or not self.walls):
            raise ConfigError("enclosure", self.enclosure, "open for the parallel course (outdoors) or a course without walls")

    def exo_spec(self) -> ExoSpec:
        return ExoSpec(user_height_m=self.user_height_m, user_mass_kg=self.user_mass_kg)

    def rig(self) -> Rig:
        """The default rig (:func:`default_rig`)."""
        return default_rig(self)


# pattern -> (step length at a 1.75 m user, m; swing, s; double support, s). Cadence = 60 /
# (swing + double support): wander 90, walk 110, jog 164 steps/min (docs/sensor-reference.md "Walking"). The
# step lengths are what the stop-and-go kinematic walker can reach on stairs and ramps (about
# 0.35-0.45 m; real walking takes 0.7 m and jogging 0.9-1.1 m steps), scaled by height / 1.75;
# the speeds are therefore about 0.52 (wander), 0.73 (walk) and 1.2 (jog) m/s on level ground
# (paper Fig. 4(c): mean 0.78 m/s, 0.05-2.12 m/s).
PATTERNS: dict[str, tuple[float, float, float]] = {
    "wander": (0.35, 0.55, 60.0 / 90.0 - 0.55),
    "walk": (0.40, 0.42, 60.0 / 110.0 - 0.42),
    "jog": (0.45, 0.30, 60.0 / 164.0 - 0.30),
}
MOUNT_KEYS = {"head": "head", "chest": "chest", "thigh": "thigh_r"}
# planning retries: (clearance over nosings, m; shift of the start along the route, m; step length factor)
PLAN_TRIES = tuple(
    (clr, shift, fac) for fac in (1.0, 0.9, 1.1, 0.8) for clr in (0.04, 0.02) for shift in (0.0, -0.15, 0.1)
)
PENETRATION_RATE_HZ = 250.0
CONTACT_ORDER = ("contact_l_heel", "contact_l_toe", "contact_r_heel", "contact_r_toe")


def enclosure_of(sc: Any) -> str:
    """The enclosure a scenario's course is built with (``open`` or ``stairwell``): ``auto`` is a
    stairwell around a stair or ramp course with walls, as indoors, and open for the parallel
    course (the paper's multi-direction walks were outdoors) and a course without walls, so
    that ``--set terrain=parallel`` or ``--set walls=false`` on an indoor case gives an open
    course rather than a refusal."""
    enc = getattr(sc, "enclosure", "open")
    if enc == "auto":
        return "stairwell" if sc.terrain != "parallel" and bool(sc.walls) else "open"
    return str(enc)


def sensor_ids(mount: str) -> tuple[str, str, str]:
    """(RGB-D camera, IMU, odometry) sensor ids of a mount name."""
    k = MOUNT_KEYS[mount]
    return f"rgbd_{k}", f"imu_{k}", f"odom_{k}"


def _world_key(sc: LocomotionScenario) -> tuple:
    return (sc.terrain, sc.riser_m, sc.tread_m, sc.n_steps, sc.slope_deg, sc.ramp_length_m, sc.landing_m,
            sc.approach_m, sc.width_m, bool(sc.walls), sc.parallel_first, sc.stops)  # fmt: skip


@lru_cache(maxsize=8)
def _plan_cached(key: tuple, exo: ExoSpec, pattern: str) -> tuple[Any, tuple, Any, dict[str, float]]:
    from .course_world import build_locomotion_world, plan_pieces

    sc = LocomotionScenario(**dict(zip(_WORLD_FIELDS, key)))
    toe = exo.foot_m - exo.heel_to_ankle_m
    step0, swing, ds = PATTERNS[pattern]
    step = step0 * exo.user_height_m / 1.75
    world, pieces = build_locomotion_world(sc, toe)
    try:
        motion, got = plan_pieces(exo, world.truth, pieces, step, swing, ds, PLAN_TRIES)
    except GaitError as err:
        field = "riser_m" if sc.terrain in ("stairs", "parallel") else "slope_deg"
        value = sc.riser_m if field == "riser_m" else sc.slope_deg
        raise ConfigError(field, value, f"a course the walker can walk with pattern {pattern!r} and user_height_m="
                          f"{exo.user_height_m} (every planning attempt failed; last: {err})") from None
    info = {**got, "swing_s": swing, "double_support_s": ds, "cadence_steps_per_min": 60.0 / (swing + ds)}
    wps = tuple(tuple(map(float, p)) for piece in pieces for p in piece)
    return world, wps, motion, info


_WORLD_FIELDS = ("terrain", "riser_m", "tread_m", "n_steps", "slope_deg", "ramp_length_m", "landing_m",
                 "approach_m", "width_m", "walls", "parallel_first", "stops")  # fmt: skip


def plan_locomotion(scenario: LocomotionScenario) -> tuple[Any, tuple, Motion, dict[str, float]]:
    """(built world, route waypoints, walking motion, pattern numbers) of a scenario, without sensing.

    Tries :data:`PLAN_TRIES` (clearance, start shift, shorter steps) until the walker of
    :func:`exobench.envs.motion.plan_walk` finds footholds for the whole course; raises
    :class:`ConfigError` naming ``riser_m`` (stairs) or ``slope_deg`` (ramps) when none works.
    """
    return _plan_cached(_world_key(scenario), scenario.exo_spec(), scenario.pattern)


@lru_cache(maxsize=8)
def _enclosed(key: tuple, exo: ExoSpec, pattern: str, enclosure: str) -> Any:
    """The built world of a scenario with its ``enclosure``: the walk is planned on the open
    course (the enclosure adds no walkable surface), so both have the same walk and steps."""
    world = _plan_cached(key, exo, pattern)[0]
    if enclosure == "open":
        return world
    from .course_enclosure import enclose_stairwell

    return enclose_stairwell(world, float(dict(zip(_WORLD_FIELDS, key))["width_m"]))


@lru_cache(maxsize=8)
def _compiled(key: tuple, exo: ExoSpec, pattern: str, sites: tuple[tuple[str, Any], ...], chest_rig: bool,
              ped_heights: tuple[float, ...], look: WorldLook | None = None, texture_seed: int = 0,
              enclosure: str = "open") -> Any:  # fmt: skip
    world = _enclosed(key, exo, pattern, enclosure)
    return compose_rig(world, exo, sites, chest_rig=chest_rig, ped_heights_m=list(ped_heights), look=look,
                       look_seed=texture_seed)  # fmt: skip


def _rgbd_config(sc: LocomotionScenario) -> RgbdConfig:
    try:
        return sc.configured("rgbd", RgbdConfig, subpixel=0.08 * sc.depth_noise_scale)
    except ConfigError as err:  # name the scenario's field
        name = err.field.split(".", 1)[-1] if hasattr(err, "field") else "width_px"
        raise ConfigError(name, getattr(err, "value", None), getattr(err, "allowed", str(err))) from None


def default_rig(sc: LocomotionScenario) -> Rig:
    """The camera's IMU, the insoles, the camera's odometry and the camera (ties in that order), plus
    ``extra_sensors``."""
    imu, odom, cam = camera_rig(
        sc.mount, _rgbd_config(sc), sc.configured("imu", ImuConfig), sc.configured("odometry", OdometryConfig)
    )
    contacts = tuple(MountedSensor(pid, "contact", ContactConfig()) for pid in CONTACT_ORDER)
    return with_presets((imu, *contacts, odom, cam), sc.extra_sensors)


def _view_hook(sc: LocomotionScenario, exo: ExoSpec, motion: Motion, info: dict[str, float], truth: Any, dur: float,
               seed: int) -> ViewHook:  # fmt: skip
    """The head or chest camera's view motion (seeded by ``locomotion_view``)."""
    from exobench.models.exo_spec import JOINT_RANGES_RAD

    from ...motion.view import GAZE_WIDTH_STEPS, GazeDown, gaze_looks, view_motion

    view_rng = sensor_rngs(seed, "locomotion_view")[0]
    mount_pitch = np.radians(0.5 * exo.camera_pitch_deg if sc.mount == "head" else exo.camera_pitch_deg)

    def trunk_pitch(t: np.ndarray) -> np.ndarray:
        return motion.state(np.atleast_1d(t), solve_legs=False).pitch

    gaze = None
    if sc.gaze == "transitions":
        all_steps = step_truths(motion, truth, exo)
        period = float(info["swing_s"] + info["double_support_s"])
        looks = gaze_looks([s.mode for s in all_steps], [s.liftoff_s for s in all_steps])
        gaze = GazeDown(looks, GAZE_WIDTH_STEPS * period, dur)
    view = view_motion(sc.mount, sc.view, sc.head_pitch_mean_rad, sc.head_pitch_std_rad, float(mount_pitch),
                       trunk_pitch, {k: JOINT_RANGES_RAD[k] for k in ("neck_pitch", "neck_yaw")}, dur, view_rng,
                       gaze)  # fmt: skip
    return ViewHook(view)


def simulate_locomotion(scenario: LocomotionScenario, seed: int, rig: Sequence[MountedSensor] | None = None) -> Episode:
    """One walk along the scenario's course with every sensor of ``rig`` (default: the camera of
    ``mount``, its IMU, insoles and odometry, :func:`default_rig`)."""
    setup = _locomotion_setup(scenario, seed, rig)
    rec = record(setup.scene.model, setup.world.truth, setup.exo, setup.motion, setup.rig, seed, duration_s=setup.dur,
                 hooks=setup.hooks, watch_geoms=setup.ped_hook.geom_groups(setup.scene.model))  # fmt: skip
    lidars = [s.sensor_id for s in setup.rig if s.kind == "lidar"]
    return _locomotion_episode(scenario, seed, setup, rec, rec.frames, rec.frame_truth(lidars), segmentation_truths(rec, setup.rig))


def stream_locomotion(scenario: LocomotionScenario, seed: int, rig: Sequence[MountedSensor] | None = None) -> EpisodeStream:
    """:func:`simulate_locomotion` as a stream (:func:`~exobench.envs.sim.recorder.stream_record`):
    the same frames in the same order, handed out as they are rendered, and the same episode at
    the end without its frames, so a long walk is never held whole. A rig with a LiDAR, or a
    scenario keeping segmentation truth (per-frame truths the episode would hold), is refused."""
    if getattr(scenario, "segmentation_truth", False):
        raise ConfigError("segmentation_truth", True, "false for a streamed course walk (its per-frame truth is not kept)")
    setup = _locomotion_setup(scenario, seed, rig)
    lidars = [s.sensor_id for s in setup.rig if s.kind == "lidar"]
    if lidars:
        raise ConfigError("extra_sensors", getattr(scenario, "extra_sensors", lidars), "no LiDAR on a streamed course walk")
    srec = stream_record(setup.scene.model, setup.world.truth, setup.exo, setup.motion, setup.rig, seed,
                         duration_s=setup.dur, hooks=setup.hooks, watch_geoms=setup.ped_hook.geom_groups(setup.scene.model))  # fmt: skip
    cal = build_calibration(setup.exo, setup.rig)

    def frames() -> Iterator[Any]:
        for f, _ in srec.items():
            yield f

    def finish() -> Episode:
        return _locomotion_episode(scenario, seed, setup, srec, (), (), ())

    return EpisodeStream(scenario.as_dict(), int(seed), cal, frames(), finish)


@dataclass(frozen=True)
class _Setup:
    """What a course walk is recorded from: the rig, the device, the planned walk and the scene."""

    rig: Rig
    exo: ExoSpec
    world: Any
    wps: tuple
    motion: Motion
    info: dict[str, float]
    dur: float
    scene: Any
    ped_hook: PedestrianHook
    hooks: tuple[Any, ...]


def _locomotion_setup(sc: LocomotionScenario, seed: int, rig: Sequence[MountedSensor] | None) -> _Setup:
    from ...motion.pedestrians import pedestrian_paths

    rig = tuple(default_rig(sc) if rig is None else rig)
    if getattr(sc, "segmentation_truth", False):  # a scenario class may leave the row out (the vio track's)
        rig = with_segmentation_truth(rig)
    exo = sc.exo_spec()
    _, wps, motion, info = plan_locomotion(sc)
    enclosure = enclosure_of(sc)
    world = _enclosed(_world_key(sc), exo, sc.pattern, enclosure)
    dur = float(min(motion.duration_s, sc.duration_cap_s))
    ped_rng = sensor_rngs(seed, "locomotion_pedestrians")[0]

    def walker_xy(t: float) -> np.ndarray:
        return motion.state(t, solve_legs=False).pelvis_w[0, :2]

    def walker_heading(t: float) -> float:
        return float(motion.state(t, solve_legs=False).yaw[0])

    peds = pedestrian_paths(sc.pedestrians, walker_xy, walker_heading, dur, ped_rng)
    chest = any(s.sensor_id == CHEST_CAMERA for s in rig)
    look = WorldLook(sc.surfaces, sc.light_level)
    scene = _compiled(_world_key(sc), exo, sc.pattern, attached_sites(rig), chest, tuple(p.height_m for p in peds),
                      *((look, sc.texture_seed) if not look.is_default else ()),
                      **({"enclosure": enclosure} if enclosure != "open" else {}))  # fmt: skip
    ped_hook = PedestrianHook(peds, Terrain(world.truth))
    hooks = (_view_hook(sc, exo, motion, info, world.truth, dur, seed), ped_hook)
    return _Setup(rig, exo, world, wps, motion, info, dur, scene, ped_hook, hooks)


def _locomotion_episode(sc: LocomotionScenario, seed: int, setup: _Setup, rec: Any, frames: Sequence[Any],
                        lidar_truth: Sequence[Any], segmentation: Sequence[Any]) -> Episode:  # fmt: skip
    """The episode of a recording (``rec``: its ``outputs``' truth and ``context``)."""
    rig, exo, motion, dur, ped_hook = setup.rig, setup.exo, setup.motion, setup.dur, setup.ped_hook
    truth_scene = setup.world.truth
    peds = ped_hook.paths
    cam_id = sensor_ids(sc.mount)[0]
    steps = tuple(s for s in step_truths(motion, truth_scene, exo) if s.heel_strike_s <= dur + 1e-9)
    events: dict[str, float] = {"liftoff_s": float(motion.events.get("liftoff_s", 0.0)), "end_s": dur}
    prev = "LG"
    for s in steps:
        if s.mode != prev:
            events[f"transition_{s.index}_{prev}_{s.mode}_s"] = s.heel_strike_s
        prev = s.mode
    extra: dict[str, Any] = {}
    tracks: dict[str, np.ndarray] = {}
    trajectory = np.zeros((0, 8))
    T_world_est = np.eye(4)
    if cam_id in rec.outputs:
        cam = rec.outputs[cam_id].truth
        t_cam, T_cam = cam["t_s"], cam["T_world_sensor"]
        ped_xy, ped_z = ped_hook.positions(t_cam)
        z_opt = T_cam[:, :3, 2]
        trajectory = pose_rows(t_cam, T_cam)
        tracks[cam_id] = pose_rows(t_cam, T_cam)
        extra.update({
            "camera_T_world": T_cam,
            "camera_pitch_rad": np.arcsin(np.clip(-z_opt[:, 2], -1.0, 1.0)),
            "camera_stamps_s": t_cam,
        })  # fmt: skip
        odom = [s.sensor_id for s in rig if s.kind == "odometry" and s.attached_to == cam_id]
        if odom:
            o = rec.outputs[odom[0]].truth
            T_world_est = o["T_world_odom"]
            extra.update({"distance_travelled_m": o["distance_m"], "odom_T_world": o["T_world_odom"]})
        extra.update({
            "pedestrian_tracks": np.array(
                [np.column_stack([t_cam, ped_xy[i], np.full(len(t_cam), p.yaw), ped_z[i]]) for i, p in enumerate(peds)]
            ).reshape(len(peds), len(t_cam), 5),
            "pedestrian_height_m": np.array([p.height_m for p in peds]),
            "pedestrian_pixel_fraction": cam["watch_fraction"],
            "pedestrian_geom_names": [[f"ped{k}_body", f"ped{k}_head"] for k in range(len(peds))],
        })  # fmt: skip
    for s in rig:  # a camera's IMU: its pose at its own rate
        if s.kind == "imu" and s.attached_to is not None and s.sensor_id in rec.outputs:
            tracks[s.sensor_id] = rec.outputs[s.sensor_id].truth["pose_rows"]
    extra.update({"route_waypoints_xy": np.asarray(setup.wps, dtype=float), "pattern": dict(setup.info),
                  "walk_duration_s": float(motion.duration_s)})  # fmt: skip
    lidars = [s.sensor_id for s in rig if s.kind == "lidar"]
    if lidars:
        pose_at = rec.context.pose_fn(lidars[0])
        starts = np.array([f.sweep_start_s for f in rec.outputs[lidars[0]].frames])
        tracks[lidars[0]] = pose_rows(starts, pose_at(starts)) if len(starts) else np.zeros((0, 8))
    ep_truth = EpisodeTruth(
        scene=truth_scene,
        T_world_estimator=T_world_est,
        body_tracks=tracks,
        max_penetration_m=motion.max_penetration_m(truth_scene, sample_times(PENETRATION_RATE_HZ, dur)),
        events=events,
        trajectory_w=trajectory,
        steps=steps,
        lidar=tuple(lidar_truth),
        segmentation=tuple(segmentation),
        extra=extra,
    )
    cal = build_calibration(exo, rig)
    return Episode(scenario=sc.as_dict(), seed=int(seed), calibration=cal, frames=frames, truth=ep_truth)  # type: ignore[arg-type]
