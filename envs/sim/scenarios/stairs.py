"""The staircase world: one climbing step of the staircase paper, with every sensor.

:data:`PARAMS` lists every parameter (``name -> ParamSpec(default, low, high, unit, doc)``); the
command line lists it and sets values from it (``--set riser_m=0.17``); :class:`StairScenario` is
generated from it (:mod:`exobench.envs.sim.scenario`).

Geometry of an episode (the staircase paper, section V-A): the exoskeleton stands at the
origin facing +x with both feet flat on the ground; the staircase's first riser is at
perpendicular distance ``distance_m`` (the paper's L) from the toe tip of the climbing (right)
foot, and the exoskeleton is turned by ``yaw_deg`` counter-clockwise relative to the stairs,
i.e. the staircase is yawed by ``-yaw_deg`` in the world. The paper's cases are
:data:`PAPER_CASES`: A frontal, L = 0.305 m; B turned +23 deg (the staircase on its right),
L = 0.27 m; C turned -23 deg, L = 0.49 m.

Default rig (:meth:`StairScenario.rig`): encoders, trunk IMU, insole pads, the four calf ToF
sensors (ties in that order: state before ranges). Compiled worlds are cached per (staircase,
body, extra sites), so a batch of episodes compiles each world once.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from functools import lru_cache
from typing import Any

import numpy as np

from exobench.core import ConfigError, Episode, EpisodeTruth, StairTruth, UnknownNameError, check_range
from exobench.core.transforms import make_T
from exobench.models.exo_spec import ExoSpec
from exobench.models.world_params import ParamSpec, StaircaseParams

from ...motion import Motion, climb_step
from ...sensors import ContactConfig, EncoderConfig, ImuConfig, SensorsConfig, ToFConfig, sample_times
from ...sensors.adapter import MountedSensor
from ...terrain import Terrain
from ..calibration import build_calibration
from ..compose import attached_sites, compose_rig
from ..recorder import TRACKED_BODIES, Recording, record
from ..rig import Rig, scalar_rig, with_presets
from ..scenario import scenario_base
from .common import COMMON_PARAMS

FOOT_TRACK_RATE_HZ = 100.0
PENETRATION_RATE_HZ = 1000.0

PARAMS: dict[str, ParamSpec] = {
    "riser_m": ParamSpec(0.162, 0.0, 0.30, "m", "riser height", low_open=True),
    "tread_m": ParamSpec(0.28, 0.15, 0.60, "m", "tread depth (going)"),
    "n_steps": ParamSpec(4, 1, 30, "", "number of risers (the last tread is the top landing)"),
    "nosing_m": ParamSpec(0.0, 0.0, 0.05, "m", "overhang of each tread over the riser below it"),
    "width_m": ParamSpec(1.2, 0.5, 5.0, "m", "width of the flight"),
    "yaw_deg": ParamSpec(0.0, -45.0, 45.0, "deg", "exoskeleton turned counter-clockwise relative to the stairs (paper case B: +23)"),
    "distance_m": ParamSpec(0.305, 0.15, 0.8, "m", "perpendicular distance from the climbing foot's toe tip to the first riser (paper's L)"),
    "user_height_m": COMMON_PARAMS["user_height_m"],
    "user_mass_kg": COMMON_PARAMS["user_mass_kg"],
    "duration_s": ParamSpec(3.0, 1.2, 6.0, "s", "episode length: 0.3 s still, the swing, 0.3 s after touch-down (a 2.4 s climbing swing by default, as slow exoskeleton gaits are [A])"),
    "tof_noise_m": ParamSpec(1.5e-3, 0.0, 0.05, "m", "ToF static range noise, standard deviation", feeds=("tof.noise_m",)),
    "tof_rate_hz": ParamSpec(50.0, 1.0, 100.0, "Hz", "ToF ranging rate", feeds=("tof.rate_hz",)),
    "tof_latency_s": ParamSpec(0.0, 0.0, 0.1, "s", "ToF delivery latency", feeds=("tof.latency_s",)),
    "tof_dropout": ParamSpec(0.0, 0.0, 0.9, "", "probability a ToF frame is lost", feeds=("tof.dropout_prob",)),
    "tof_cone_rays": ParamSpec(1, 1, 64, "", "rays per ToF reading: 1 = central beam, more = 27 deg cone mixture",
                               feeds=("tof.n_cone_rays",)),
    "imu_noise_scale": COMMON_PARAMS["imu_noise_scale"],
    "imu_orientation_deg": ParamSpec(0.2, 0.0, 10.0, "deg", "rms error of the IMU's orientation (AHRS)",
                                     feeds=("imu.orientation_rms_deg",)),
    "encoder_noise_rad": COMMON_PARAMS["encoder_noise_rad"],
    "extra_sensors": COMMON_PARAMS["extra_sensors"],
}

# paper section V-A: case -> (distance_m, yaw_deg)
PAPER_CASES: dict[str, dict[str, float]] = {
    "A": {"distance_m": 0.305, "yaw_deg": 0.0},
    "B": {"distance_m": 0.27, "yaw_deg": 23.0},
    "C": {"distance_m": 0.49, "yaw_deg": -23.0},
}


class StairScenario(scenario_base("StairScenario", "stairs", PARAMS)):  # type: ignore[misc]
    """One stairs-track episode; see :data:`PARAMS` for units, ranges and meaning."""

    @classmethod
    def paper_case(cls, case: str, **overrides: Any) -> StairScenario:
        """Scenario of the paper's case ``"A"``, ``"B"`` or ``"C"`` (staircase 0.162 / 0.28 m)."""
        if case not in PAPER_CASES:
            raise UnknownNameError("paper case", case, PAPER_CASES)
        return cls.from_dict({**PAPER_CASES[case], **overrides})

    def exo_spec(self) -> ExoSpec:
        return ExoSpec(user_height_m=self.user_height_m, user_mass_kg=self.user_mass_kg)

    def staircase_params(self, exo: ExoSpec | None = None) -> StaircaseParams:
        return staircase_params_for_case(
            self.riser_m, self.tread_m, self.distance_m, self.yaw_deg, exo or self.exo_spec(),
            n_steps=self.n_steps, nosing_m=self.nosing_m, width_m=self.width_m,
        )  # fmt: skip

    def sensors_config(self) -> SensorsConfig:
        return SensorsConfig(
            tof=self.configured("tof", ToFConfig), imu=self.configured("imu", ImuConfig),
            encoders=self.configured("encoders", EncoderConfig), contact=ContactConfig(),
        )  # fmt: skip

    def check_composition(self) -> None:
        """The rig (see the base class) and the staircase's parameters, without building it."""
        super().check_composition()
        self.staircase_params()

    def rig(self) -> Rig:
        """The default rig (encoders, trunk IMU, insoles, calf ToF) plus ``extra_sensors``."""
        return with_presets(scalar_rig(self.sensors_config()), self.extra_sensors)


def staircase_params_for_case(
    riser: float,
    tread: float,
    distance_m: float,
    yaw_deg: float,
    exo: ExoSpec,
    *,
    n_steps: int = 4,
    nosing_m: float = 0.0,
    width_m: float = 1.2,
    side: str = "r",
) -> StaircaseParams:
    """The staircase of a climbing-step episode, placed in the world of :func:`exobench.envs.motion.climb_step`.

    The exoskeleton stands at the origin facing +x; the toe tip of the ``side`` foot is at
    ``(foot_m - heel_to_ankle_m, -+hip_width/2, 0)``. The staircase is yawed by ``-yaw_deg`` and
    its first riser's plane lies at perpendicular distance ``distance_m`` from that toe tip; the
    centre of the riser's bottom edge is where the foot's line of travel (+x through the toe
    tip) meets the riser, so the climbing foot lands near the middle of the flight's width.
    """
    if side not in ("l", "r"):
        raise ConfigError("side", side, "'l' or 'r'")
    check_range("yaw_deg", yaw_deg, -80.0, 80.0)
    toe_x = exo.foot_m - exo.heel_to_ankle_m
    toe_y = (0.5 if side == "l" else -0.5) * exo.hip_width_m
    x = toe_x + distance_m / math.cos(math.radians(yaw_deg))
    return StaircaseParams(
        riser_m=riser, tread_m=tread, n_steps=n_steps, width_m=width_m, nosing_m=nosing_m,
        yaw_deg=-yaw_deg, position_m=(x, toe_y), direction="up",
    )  # fmt: skip


@lru_cache(maxsize=16)
def compiled_staircase(params: StaircaseParams, exo: ExoSpec, sites: tuple[tuple[str, Any], ...] = ()) -> Any:
    """The composed staircase world (``models.worlds.CompiledScene``), compiled once per key."""
    from exobench.models.worlds import build_staircase

    return compose_rig(build_staircase(params), exo, sites)


def plan_climb(scenario: StairScenario, rig: Sequence[MountedSensor] = ()) -> tuple[Any, Motion]:
    """(compiled staircase scene, climbing-step motion) of a scenario, without sensing.

    Cheap (milliseconds once the world is compiled); raises :class:`ConfigError` naming
    ``distance_m``/``tread_m`` when the step cannot be made, so scenario grids can be checked.
    """
    exo = scenario.exo_spec()
    scene = compiled_staircase(scenario.staircase_params(exo), exo, attached_sites(rig))
    motion = climb_step(
        exo, scene.truth, distance_m=scenario.distance_m, yaw_deg=scenario.yaw_deg, duration_s=scenario.duration_s
    )
    return scene, motion


def record_climb(scene: Any, exo: ExoSpec, motion: Motion, rig: Sequence[MountedSensor], seed: int) -> Recording:
    """The rig over a climbing step, with the link tracks of :data:`TRACKED_BODIES`."""
    return record(scene.model, scene.truth, exo, motion, rig, seed, track_bodies=TRACKED_BODIES)


def simulate_stairs(scenario: StairScenario, seed: int, rig: Sequence[MountedSensor] | None = None) -> Episode:
    """One climbing step of the staircase paper in the scenario's world, with every sensor of
    ``rig`` (default :meth:`StairScenario.rig`).

    Truth: the estimator frame ``stance_ground`` (world axes, origin on the ground below the
    left ankle), the ToF truth, the right foot's sole point over time and at touch-down, link
    poses at 50 Hz, the deepest foot penetration (sole grid every 1 ms) and the lift-off/touch-down
    events.
    """
    rig = tuple(scenario.rig() if rig is None else rig)
    exo = scenario.exo_spec()
    scene, motion = plan_climb(scenario, rig)
    truth = scene.truth
    rec = record_climb(scene, exo, motion, rig, seed)

    stance = motion.stance_side
    swing = "r" if stance == "l" else "l"
    terrain = Terrain(truth)
    a0 = motion.state(0.0).ankle_w[stance][0]
    T_world_est = make_T(np.eye(3), np.array([a0[0], a0[1], terrain.height(a0[None, :2])[0]]))
    t_ft = sample_times(FOOT_TRACK_RATE_HZ, motion.duration_s)
    foot_track = np.column_stack([t_ft, motion.sole_point_w(swing, t_ft)])
    t_pen = sample_times(PENETRATION_RATE_HZ, motion.duration_s)
    tofs = [s.sensor_id for s in rig if s.kind == "tof"]
    ep_truth = EpisodeTruth(
        scene=truth,
        T_world_estimator=T_world_est,
        stairs=StairTruth(
            tof=rec.frame_truth(tofs), stance_side=stance, touchdown_w=motion.footsteps[0].sole_w.copy(), foot_track_w=foot_track
        ),
        body_tracks=rec.body_tracks,
        max_penetration_m=motion.max_penetration_m(truth, t_pen),
        events=dict(motion.events),
        lidar=tuple(rec.frame_truth([s.sensor_id for s in rig if s.kind == "lidar"])),
    )
    cal = build_calibration(exo, rig)
    return Episode(scenario=scenario.as_dict(), seed=int(seed), calibration=cal, frames=rec.frames, truth=ep_truth)

