"""How a sensor kind plugs into the simulation core (:mod:`exobench.envs.sim`).

A rig is a sequence of :class:`MountedSensor` (sensor id, kind, config, mount). For each, the
recorder builds the kind's adapter (a :class:`SensorAdapter`, registered in :mod:`.kinds`) and
asks it three things: the instants at which it needs MuJoCo's state (:meth:`~SensorAdapter.instants`,
with velocities and accelerations when ``needs_dynamics``), to observe the state there
(:meth:`~SensorAdapter.observe`), and at the end its frames and truth
(:meth:`~SensorAdapter.finish`, a :class:`SensorOutput`). A kind whose noise is drawn reading by
reading in time order may also stream (``streams``): :meth:`~SensorAdapter.take` gives the frames
of the instants observed since the last call, so a recording stepped while its motion grows
(:meth:`exobench.envs.sim.recorder.Recorder.advance_to`) gives the frames of one ``finish``.
A kind whose frames are big (``chunked``: LiDAR sweeps, RGB-D images) hands over the frames
observed so far with :meth:`~SensorAdapter.take` (the same frames one ``finish`` would give, its
noise already drawn), ``finish`` then the rest and the whole truth: a recording then streams
(:func:`exobench.envs.sim.recorder.stream_record`) without holding every frame.
The calibration builder asks the adapter
class for the parameters a pipeline may know (:meth:`~SensorAdapter.calibration_params`) and any
calibration ``extra`` entries. What an adapter may read while recording is a :class:`RecordContext`.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, ClassVar, Protocol

import numpy as np

from exobench.core import Frame, SceneTruth

if TYPE_CHECKING:
    from exobench.models.exo_spec import ExoSpec


@dataclass(frozen=True)
class Mount:
    """Where a sensor sits on the exoskeleton when the device has no mount of its id: a body of
    the robot description and the sensor frame's pose in it.

    Attributes:
        parent: body (URDF link) the sensor is rigidly attached to, e.g. ``"shank_l"``.
        xyz_m: position of the sensor frame in the parent body's frame, m.
        quat_wxyz: orientation of the sensor frame in the parent body's frame (unit quaternion).
    """

    parent: str
    xyz_m: tuple[float, float, float] = (0.0, 0.0, 0.0)
    quat_wxyz: tuple[float, float, float, float] = (1.0, 0.0, 0.0, 0.0)

    def T_parent_sensor(self) -> np.ndarray:
        """The 4x4 pose of the sensor frame in the parent body's frame."""
        from exobench.core.transforms import make_T, quat_wxyz_to_matrix

        q = np.asarray(self.quat_wxyz, dtype=float)
        return make_T(quat_wxyz_to_matrix(q / np.linalg.norm(q)), np.asarray(self.xyz_m, dtype=float))


@dataclass(frozen=True)
class MountedSensor:
    """One sensor of a rig.

    Attributes:
        sensor_id: the stream's id (also the MuJoCo site or camera it is read from).
        kind: the sensor kind (a key of :data:`exobench.envs.sensors.kinds.SENSOR_KINDS`).
        config: the kind's config (``ToFConfig``, ``ImuConfig``, ``LidarConfig``, ...).
        attached_to: None: the device's own mount of ``sensor_id`` (:func:`exobench.models.exo.sensor_mounts`);
            else the id of an RGB-D camera whose optical frame this sensor shares (a camera's IMU
            or odometry; the simulation adds a site ``sensor_id`` there).
        mount: an explicit :class:`Mount` anywhere on the exoskeleton (the simulation adds a site
            ``sensor_id`` there, the calibration a mount); None: ``attached_to`` or the device's own.
    """

    sensor_id: str
    kind: str
    config: Any
    attached_to: str | None = None
    mount: Mount | None = None

    def __post_init__(self) -> None:
        if self.mount is not None and self.attached_to is not None:
            from exobench.core import ConfigError

            raise ConfigError(f"{self.sensor_id}.mount", self.mount, "either a mount or attached_to, not both")


@dataclass
class SensorOutput:
    """What one sensor recorded: ``frames`` in time order; ``frame_truth`` (if any) one truth
    object per frame, in the same order; ``truth`` named arrays of the sensor's own truth."""

    frames: list[Frame]
    frame_truth: list[Any] | None = None
    truth: dict[str, Any] = field(default_factory=dict)


PoseFn = Callable[[np.ndarray], np.ndarray]


class RecordContext(Protocol):
    """What an adapter may read while a motion is recorded."""

    model: Any  # mujoco.MjModel of the composed world
    scene_truth: SceneTruth
    exo: ExoSpec
    motion: Any  # exobench.envs.motion.Motion
    seed: int
    duration_s: float
    rig: Sequence[MountedSensor]
    watch_geoms: Sequence[Sequence[int]]  # geom id groups whose image share cameras report

    def pose_fn(self, site: str) -> PoseFn:
        """``T_world_sensor`` of a site rigid with the pelvis at any times of the motion."""
        ...

    def shared(self, key: str, compute: Callable[[], Any]) -> Any:
        """A value computed once per recording for every sensor that asks by ``key``."""
        ...


class SensorAdapter(Protocol):
    """One mounted sensor inside the recorder."""

    needs_dynamics: ClassVar[bool]  # its instants need qvel/qacc and mj_rnePostConstraint
    calibration_shared: ClassVar[bool]  # its params also describe the device's unmounted sensors of the kind
    has_mount: ClassVar[bool]  # it appears in Calibration.mounts
    streams: ClassVar[bool]  # take() gives its frames step by step, equal to those of one finish()
    chunked: ClassVar[bool]  # take() hands over the frames so far; finish() the rest and the whole truth

    def __init__(self, sensor: MountedSensor, ctx: RecordContext) -> None: ...

    def instants(self) -> np.ndarray:
        """Times (s, sorted) at which :meth:`observe` must see the state; empty: none."""
        ...

    def observe(self, model: Any, data: Any, t: float) -> None: ...

    def finish(self) -> SensorOutput: ...

    def take(self) -> SensorOutput:
        """The frames and truth of the instants observed since the last call (kinds that stream)."""
        ...

    def close(self) -> None: ...

    @staticmethod
    def calibration_params(sensor: MountedSensor) -> dict[str, Any]: ...

    @staticmethod
    def calibration_extra(sensor: MountedSensor, rig: Sequence[MountedSensor]) -> dict[str, Any]: ...


class BaseAdapter:
    """Defaults of :class:`SensorAdapter`: no instants, no streaming, no calibration extra, nothing to close."""

    needs_dynamics: ClassVar[bool] = False
    calibration_shared: ClassVar[bool] = False
    has_mount: ClassVar[bool] = True
    streams: ClassVar[bool] = False
    chunked: ClassVar[bool] = False

    def __init__(self, sensor: MountedSensor, ctx: RecordContext) -> None:
        self.sensor, self.ctx = sensor, ctx
        self.sensor_id, self.config = sensor.sensor_id, sensor.config

    def instants(self) -> np.ndarray:
        return np.zeros(0)

    def observe(self, model: Any, data: Any, t: float) -> None:
        raise NotImplementedError(type(self).__name__)

    def finish(self) -> SensorOutput:
        raise NotImplementedError(type(self).__name__)

    def take(self) -> SensorOutput:
        raise NotImplementedError(f"{type(self).__name__} does not stream")

    def close(self) -> None:
        return None

    @staticmethod
    def calibration_params(sensor: MountedSensor) -> dict[str, Any]:
        return {}

    @staticmethod
    def calibration_extra(sensor: MountedSensor, rig: Sequence[MountedSensor]) -> dict[str, Any]:
        return {}
