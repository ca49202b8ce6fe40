"""The simulation core: a scenario names a world, a route and gait, and a sensor rig.

- :mod:`.rig`: rigs (sequences of :class:`~exobench.envs.sensors.adapter.MountedSensor`) and
  named sensor presets that any world can carry (``extra_sensors``).
- :mod:`.hooks`: view joints and pedestrians as recorder hooks.
- :mod:`.recorder`: :class:`Recorder`, one loop scheduling every mounted sensor at its rate over a
  motion and merging the frames in time order, run over a whole motion by :func:`record` or
  stepped while the motion grows by :meth:`Recorder.advance_to` (the gymnasium environment);
  :class:`Hook` adds view joints and pedestrians.
- :mod:`.calibration`: :func:`build_calibration`, the one calibration builder.
- :mod:`.compose`: the world with the exoskeleton and what the rig needs beyond the device.
- :mod:`.scenario`: scenario dataclasses generated from their parameter tables.
- :mod:`.scenarios`: the worlds (stairs, office, course) as scenario definitions.
"""

from .calibration import build_calibration
from .recorder import Hook, Recorder, Recording, record
from .rig import PRESETS, Rig, camera_rig, scalar_rig, with_presets
from .scenarios.course import LocomotionScenario, plan_locomotion, simulate_locomotion
from .scenarios.office import OfficeScenario, plan_office_walk, simulate_office
from .scenarios.stairs import (
    PAPER_CASES,
    StairScenario,
    plan_climb,
    simulate_stairs,
    staircase_params_for_case,
)

__all__ = [
    "PAPER_CASES",
    "PRESETS",
    "OfficeScenario",
    "Hook",
    "LocomotionScenario",
    "Recorder",
    "Recording",
    "Rig",
    "StairScenario",
    "build_calibration",
    "camera_rig",
    "plan_climb",
    "plan_locomotion",
    "plan_office_walk",
    "record",
    "scalar_rig",
    "simulate_locomotion",
    "simulate_office",
    "simulate_stairs",
    "staircase_params_for_case",
    "with_presets",
]
