"""Stair-climbing scenarios: the parameters of one episode of the stairs track, validated.

:data:`PARAMS` lists every parameter (``name -> ParamSpec(default, low, high, unit, doc)``); the
command line lists it and sets values from it (``--set riser_m=0.17``), and
:meth:`StairScenario.from_dict` validates plain or string values against it.

Geometry of an episode (the staircase paper, section V-A): the exoskeleton stands at the
origin facing +x with both feet flat on the ground; the staircase's first riser is at
perpendicular distance ``distance_m`` (the paper's L) from the toe tip of the climbing (right)
foot, and the exoskeleton is turned by ``yaw_deg`` counter-clockwise relative to the stairs,
i.e. the staircase is yawed by ``-yaw_deg`` in the world. The paper's cases are
:data:`PAPER_CASES`: A frontal, L = 0.305 m; B turned +23 deg (the staircase on its right),
L = 0.27 m; C turned -23 deg, L = 0.49 m.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Any

from exobench.core import ConfigError, UnknownNameError, check_range
from exobench.models.exo_spec import ExoSpec
from exobench.models.world_params import ParamSpec, StaircaseParams, from_dict_checked, validate_fields

from .sensors import ContactConfig, EncoderConfig, ImuConfig, SensorsConfig, ToFConfig

PARAMS: dict[str, ParamSpec] = {
    "riser_m": ParamSpec(0.162, 0.0, 0.30, "m", "riser height", low_open=True),
    "tread_m": ParamSpec(0.28, 0.15, 0.60, "m", "tread depth (going)"),
    "n_steps": ParamSpec(4, 1, 30, "", "number of risers (the last tread is the top landing)"),
    "nosing_m": ParamSpec(0.0, 0.0, 0.05, "m", "overhang of each tread over the riser below it"),
    "width_m": ParamSpec(1.2, 0.5, 5.0, "m", "width of the flight"),
    "yaw_deg": ParamSpec(0.0, -45.0, 45.0, "deg", "exoskeleton turned counter-clockwise relative to the stairs (paper case B: +23)"),
    "distance_m": ParamSpec(0.305, 0.15, 0.8, "m", "perpendicular distance from the climbing foot's toe tip to the first riser (paper's L)"),
    "user_height_m": ParamSpec(1.75, 1.55, 1.95, "m", "user's standing height (scales every segment)"),
    "user_mass_kg": ParamSpec(75.0, 40.0, 130.0, "kg", "user's body mass"),
    "duration_s": ParamSpec(3.0, 1.2, 6.0, "s", "episode length: 0.3 s still, the swing, 0.3 s after touch-down (a 2.4 s climbing swing by default, as slow exoskeleton gaits are [A])"),
    "tof_noise_m": ParamSpec(1.5e-3, 0.0, 0.05, "m", "ToF static range noise, standard deviation"),
    "tof_rate_hz": ParamSpec(50.0, 1.0, 100.0, "Hz", "ToF ranging rate"),
    "tof_latency_s": ParamSpec(0.0, 0.0, 0.1, "s", "ToF delivery latency"),
    "tof_dropout": ParamSpec(0.0, 0.0, 0.9, "", "probability a ToF frame is lost"),
    "tof_cone_rays": ParamSpec(1, 1, 64, "", "rays per ToF reading: 1 = central beam, more = 27 deg cone mixture"),
    "imu_noise_scale": ParamSpec(1.0, 0.0, 20.0, "", "multiplier of the IMU noise densities and random walks (BMI055)"),
    "imu_orientation_deg": ParamSpec(0.2, 0.0, 10.0, "deg", "rms error of the IMU's orientation (AHRS)"),
    "encoder_noise_rad": ParamSpec(1e-4, 0.0, 0.05, "rad", "joint encoder white noise, standard deviation"),
}

# paper section V-A: case -> (distance_m, yaw_deg)
PAPER_CASES: dict[str, dict[str, float]] = {
    "A": {"distance_m": 0.305, "yaw_deg": 0.0},
    "B": {"distance_m": 0.27, "yaw_deg": 23.0},
    "C": {"distance_m": 0.49, "yaw_deg": -23.0},
}


@dataclass(frozen=True)
class StairScenario:
    """One stairs-track episode; see :data:`PARAMS` for units, ranges and meaning."""

    riser_m: float = PARAMS["riser_m"].default
    tread_m: float = PARAMS["tread_m"].default
    n_steps: int = PARAMS["n_steps"].default
    nosing_m: float = PARAMS["nosing_m"].default
    width_m: float = PARAMS["width_m"].default
    yaw_deg: float = PARAMS["yaw_deg"].default
    distance_m: float = PARAMS["distance_m"].default
    user_height_m: float = PARAMS["user_height_m"].default
    user_mass_kg: float = PARAMS["user_mass_kg"].default
    duration_s: float = PARAMS["duration_s"].default
    tof_noise_m: float = PARAMS["tof_noise_m"].default
    tof_rate_hz: float = PARAMS["tof_rate_hz"].default
    tof_latency_s: float = PARAMS["tof_latency_s"].default
    tof_dropout: float = PARAMS["tof_dropout"].default
    tof_cone_rays: int = PARAMS["tof_cone_rays"].default
    imu_noise_scale: float = PARAMS["imu_noise_scale"].default
    imu_orientation_deg: float = PARAMS["imu_orientation_deg"].default
    encoder_noise_rad: float = PARAMS["encoder_noise_rad"].default

    def __post_init__(self) -> None:
        validate_fields(self, PARAMS)

    @classmethod
    def from_dict(cls, values: dict[str, Any]) -> StairScenario:
        """Validated scenario from plain values (strings are converted); unknown names refused."""
        return from_dict_checked(cls, "stairs scenario", PARAMS, values)

    @classmethod
    def paper_case(cls, case: str, **overrides: Any) -> StairScenario:
        """Scenario of the paper's case ``"A"``, ``"B"`` or ``"C"`` (staircase 0.162 / 0.28 m)."""
        if case not in PAPER_CASES:
            raise UnknownNameError("paper case", case, PAPER_CASES)
        return cls.from_dict({**PAPER_CASES[case], **overrides})

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)

    def exo_spec(self) -> ExoSpec:
        return ExoSpec(user_height_m=self.user_height_m, user_mass_kg=self.user_mass_kg)

    def staircase_params(self, exo: ExoSpec | None = None) -> StaircaseParams:
        return staircase_params_for_case(
            self.riser_m, self.tread_m, self.distance_m, self.yaw_deg, exo or self.exo_spec(),
            n_steps=self.n_steps, nosing_m=self.nosing_m, width_m=self.width_m,
        )  # fmt: skip

    def sensors_config(self) -> SensorsConfig:
        return SensorsConfig(
            tof=ToFConfig(
                rate_hz=self.tof_rate_hz, latency_s=self.tof_latency_s, noise_m=self.tof_noise_m,
                dropout_prob=self.tof_dropout, n_cone_rays=self.tof_cone_rays,
            ),
            imu=ImuConfig(noise_scale=self.imu_noise_scale, orientation_rms_deg=self.imu_orientation_deg),
            encoders=EncoderConfig(noise_rad=self.encoder_noise_rad),
            contact=ContactConfig(),
        )  # fmt: skip


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
