"""The vio track's sequences: office walks and course walks with a worn RGB-D camera and its IMU.

One parameter table over two worlds: ``world`` picks the office
(:class:`~exobench.envs.sim.scenarios.office_camera.CameraOfficeScenario`) or the stair and ramp
courses (:class:`VioCourseScenario`, the locomotion course with the camera's IMU and the camera
only: no insoles, no odometry stream). The camera's rows (mount, resolution, rate, depth noise,
dropout, exposure, the IMU's rate, extrinsics and clock offset, heel strikes, surfaces, light,
the user) are the same in both worlds, and so are the delivery faults (:mod:`.faults`); a row of one world only (the office's route, a course's
riser) set away from its default for the other world is refused naming the row, the value and
the world it needs, never silently dropped.

Both worlds stream (:func:`stream_vio`): frames go through the pipelines as they are rendered and
the episode keeps the truth alone: the camera's optical-frame pose at every frame
(``body_tracks[<camera>]``) and the IMU's pose at every IMU sample (``body_tracks[<imu>]``), as
pose rows, so a walk's memory stays flat in its length.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from functools import lru_cache
from typing import Any

from exobench.core.episode import Episode, EpisodeStream
from exobench.core.errors import ConfigError, UnknownNameError
from exobench.models.world_params import ParamSpec

from ..spec import ParamInfo, param_infos
from .faults import FAULT_ROWS, DeliveryFaults, fault_settings

WORLDS = ("office", "course")
WORLD_ROW = ParamSpec("office", None, None, "", "where the sequence is walked: office (an office route, "
                      "envs.sim.scenarios.office_camera) or course (stairs and ramps, envs.sim.scenarios.course)",
                      choices=WORLDS)  # fmt: skip
# course rows that act on sensors the vio rig does not carry, or on truth it does not keep
COURSE_LEFT_OUT = ("odom_drift_pct", "odom_yaw_drift_deg_per_m", "extra_sensors", "segmentation_truth")


@lru_cache(maxsize=1)
def scenario_classes() -> dict[str, type]:
    """world -> its scenario class (built once: importing the simulation is slow)."""
    from exobench.envs.sensors import ImuConfig
    from exobench.envs.sim.rig import Rig, camera_rig
    from exobench.envs.sim.scenario import scenario_base
    from exobench.envs.sim.scenarios import course
    from exobench.envs.sim.scenarios.office_camera import IMU_DROPOUT, CameraOfficeScenario

    table = {**{k: v for k, v in course.PARAMS.items() if k not in COURSE_LEFT_OUT}, "imu_dropout": IMU_DROPOUT}
    base = scenario_base("VioCourseScenario", "vio course walk", table, course.LocomotionScenario)

    class VioCourseScenario(base):  # type: ignore[misc,valid-type]
        """A course walk with the camera of ``mount`` and its IMU only."""

        def rig(self) -> Rig:
            return camera_rig(self.mount, course._rgbd_config(self), self.configured("imu", ImuConfig))

    return {"office": CameraOfficeScenario, "course": VioCourseScenario}


def vio_table() -> dict[str, Any]:
    """name -> ParamSpec of every vio parameter: ``world``, the office's, then the course's own."""
    cls = scenario_classes()
    return {"world": WORLD_ROW, **cls["office"].PARAMS, **cls["course"].PARAMS, **FAULT_ROWS}


def vio_params() -> list[ParamInfo]:
    return param_infos(vio_table())


def validate_vio(values: Mapping[str, Any]) -> dict[str, Any]:
    """Typed values: ``world`` and the rows of its scenario (defaults filled in); rows of the other
    world are refused unless at their default (then left out). The rig is checked on the user's
    device (``check_composition``) without building anything."""
    from exobench.envs.sim.scenario import check_scenario
    from exobench.models.world_params import check_param

    table = vio_table()
    for k in values:
        if k not in table:
            raise UnknownNameError("vio scenario parameter", k, list(table))
    world = values.get("world", WORLD_ROW.default)
    if world not in WORLDS:
        raise ConfigError("world", world, " or ".join(WORLDS))
    classes = scenario_classes()
    cls, other = classes[world], classes[WORLDS[1 - WORLDS.index(world)]]
    faults = {k: check_param(k, values.get(k, spec.default), spec) for k, spec in FAULT_ROWS.items()}
    for k, v in values.items():
        if k == "world" or k in cls.PARAMS or k in FAULT_ROWS:
            continue
        typed = getattr(other.from_dict({k: v}), k)  # refused here when outside its own range
        if typed != table[k].default:
            raise ConfigError(k, v, f"{table[k].default!r} with world={world!r} (it acts with world="
                              f"{'course' if world == 'office' else 'office'!r} only)")  # fmt: skip
    scenario = cls.from_dict({k: v for k, v in values.items() if k in cls.PARAMS})
    check_scenario(scenario)
    return {"world": world, **scenario.as_dict(), **faults}


def _scenario(values: Mapping[str, Any]) -> Any:
    world = values.get("world", WORLD_ROW.default)
    cls = scenario_classes()[world]
    return cls.from_dict({k: v for k, v in values.items() if k in cls.PARAMS})


def simulate_vio(scenario: Mapping[str, Any], seed: int) -> Episode:
    """The whole episode (frames held; for sessions and recordings)."""
    from exobench.envs.sim.scenarios.course import simulate_locomotion
    from exobench.envs.sim.scenarios.office import simulate_office

    sc = _scenario(scenario)
    ep = simulate_office(sc, seed) if scenario.get("world", "office") == "office" else simulate_locomotion(sc, seed, sc.rig())
    frames = tuple(DeliveryFaults(fault_settings(scenario), seed).apply(ep.frames))
    return dataclasses.replace(ep, scenario=dict(scenario), frames=frames)


def stream_vio(scenario: Mapping[str, Any], seed: int) -> EpisodeStream:
    """The episode as a stream (module docstring)."""
    from exobench.envs.sim.scenarios.course import stream_locomotion
    from exobench.envs.sim.scenarios.office import stream_office

    sc = _scenario(scenario)
    office = scenario.get("world", "office") == "office"
    stream = stream_office(sc, seed, lidar_truth=False) if office else stream_locomotion(sc, seed, sc.rig())

    def finish() -> Episode:
        return dataclasses.replace(stream.finish(), scenario=dict(scenario))

    frames = DeliveryFaults(fault_settings(scenario), seed).apply(stream.frames)
    return EpisodeStream(dict(scenario), stream.seed, stream.calibration, frames, finish)
