"""Scenario parameters every world has, defined once: the user, the device's own sensors' noise,
the sensors added to a rig and the segmentation truth kept. Each world's table (:mod:`.stairs`,
:mod:`.office`, :mod:`.course`) takes its rows from :data:`COMMON_PARAMS` by name, in its own
order; a world changes a row only by ``_replace`` in its table, never by copying it.

The user's height is 1.55-1.95 m in every world (the courses had 1.60-1.90 m, the staircase and
the offices 1.55-1.95 m: the wider range refuses nothing that was accepted).
"""

from __future__ import annotations

from exobench.models.vision_look import SURFACES
from exobench.models.world_params import ParamSpec

from ..rig import PRESETS

COMMON_PARAMS: dict[str, ParamSpec] = {
    "user_height_m": ParamSpec(1.75, 1.55, 1.95, "m", "user's standing height (scales every segment)"),
    "user_mass_kg": ParamSpec(75.0, 40.0, 130.0, "kg", "user's body mass"),
    "imu_noise_scale": ParamSpec(1.0, 0.0, 20.0, "", "multiplier of the IMU noise densities and random walks (BMI055)",
                                 feeds=("imu.noise_scale",)),
    "heel_strike_scale": ParamSpec(0.0, 0.0, 5.0, "", "heel-strike shock transients in the IMUs, times the published "
                                   "walking peaks (1: Light et al. 1980, hard heels, 5 g tibia / 0.5 g skull; 0.5: their "
                                   "resilient heels; 0: none; envs.sensors.imu.impact)", feeds=("imu.heel_strike_scale",)),
    "surfaces": ParamSpec("default", None, None, "", "what cameras see on the surfaces: default (as built); textured "
                          "(posters and notice boards on the walls, wood grain, patterned carpet, drawn from the world's "
                          "seed); textured_floors (textured, and the plain floors carpet-tiled too); featureless (flat white walls and ceilings, flat grey floors: a tracker finds nothing "
                          "on them); models.vision_look", choices=SURFACES),
    "light_level": ParamSpec(1.0, 0.02, 2.0, "", "every light scaled by this (1: as built; 0.2-0.4: a dim room); "
                             "models.vision_look"),
    "encoder_noise_rad": ParamSpec(1e-4, 0.0, 0.05, "rad", "joint encoder white noise, standard deviation",
                                   feeds=("encoders.noise_rad",)),
    "extra_sensors": ParamSpec("", None, None, "", "sensor presets added to the rig, comma-separated "
                               f"(envs.sim.rig.PRESETS: {', '.join(PRESETS)}; not those already on it)"),
    "segmentation_truth": ParamSpec(False, None, None, "", "keep per-pixel segmentation truth of every RGB-D frame "
                                    "(EpisodeTruth.segmentation)", choices=(False, True)),
}  # fmt: skip
