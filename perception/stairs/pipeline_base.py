"""What the stairs-track pipelines share: frame checks, ToF kinematics, bookkeeping, read-out.

Every pipeline follows :class:`exobench.core.pipeline.Pipeline`. It consumes the encoder
states, the trunk IMU and the two calf ToF sensors of the climbing leg, turns each valid range
into a point of the ``stance_ground`` frame with :class:`TofKinematics` and estimates the
surfaces S0..S4. Faulty input never raises; it is counted on the estimate's ``counts``
(:mod:`exobench.core.counters`: frames of other sensors are ignored; repeated and out-of-order
frames are not used, so a stale encoder or IMU state never replaces a newer one; ``nan``: a
VALID ToF status with a non-finite range, an encoder state or IMU sample with a non-finite
value; ``absurd``: a finite range the sensor cannot report (not positive, or outside the mount's
limits: :class:`exobench.core.limits.RangeLimits`), encoder angles beyond the URDF limits, an
IMU sample no IMU can report (:func:`exobench.core.limits.imu_absurd`); such a state is skipped,
the previous one kept). ``stats`` adds what only these pipelines know: ``n_no_return`` (ToF
status not VALID) and ``n_without_state`` (a reading before any encoder and IMU state).

Sensor flags: the paper's "right"/"left" sensor flags are the climbing leg's two calf sensors
by their side: for the right leg ``tof_r_lat`` is "r" and ``tof_r_med`` is "l"; for the left leg
``tof_l_med`` is "r" and ``tof_l_lat`` is "l".

``assignments`` hold one entry per ToF frame received (of any sensor, in arrival order), so
they line up with the episode's ToF ground truth; unused readings have index -2 and a NaN
point. ``compute_time_s`` holds, per used point, the time (``time.perf_counter_ns``) spent on
the work the paper times per point: the point's forward kinematics from the latest encoder and
IMU states (computed lazily, so a new state costs the first point that uses it) and
``Assign``/``SurfUpdate`` (RTLS); frame checks and bookkeeping are outside it. For the batch
baseline it is the kinematics time plus an equal share of the time spent in ``finalize``.

The online estimate that ``process`` returns is rebuilt only after a point was used, and only
the planes that changed are read out again (RTLS).
"""


from __future__ import annotations

import math
import time
from abc import ABC, abstractmethod
from dataclasses import asdict
from typing import Any, ClassVar

import numpy as np

from exobench.core.calibration import Calibration
from exobench.core.counters import FrameCounts, StreamCounters
from exobench.core.errors import ConfigError, PipelineStateError, check_int, check_range
from exobench.core.estimates import PlaneEstimate, PointAssignment, StaircaseEstimate
from exobench.core.frames import Frame, ImuSample, JointState, ToFReading, TofStatus
from exobench.core.limits import JointLimits, RangeLimits, imu_absurd
from exobench.core.pipeline import check_frame
from exobench.perception.kinematics.tof_kinematics import ESTIMATOR_FRAME, TofKinematics

from .readout import orient_normal, riser_height_m, tread_depth_m
from .rtls import PlaneFit
from .staircase import FLAGS


def sensor_flags(leg: str) -> dict[str, str]:
    """ToF sensor id -> the paper's flag (``"r"``/``"l"``) for the calf sensors of ``leg``."""
    if leg == "r":
        return {"tof_r_lat": "r", "tof_r_med": "l"}
    if leg == "l":
        return {"tof_l_med": "r", "tof_l_lat": "l"}
    raise ConfigError("leg", leg, "'l' or 'r'")


def check_common_config(cfg: Any) -> None:
    if cfg.leg not in ("l", "r"):
        raise ConfigError("leg", cfg.leg, "'l' or 'r'")
    if cfg.stance_side not in ("l", "r"):
        raise ConfigError("stance_side", cfg.stance_side, "'l' or 'r'")
    check_range("th_pl_m", cfg.th_pl_m, 0.0, 2.0)
    object.__setattr__(cfg, "reliable_n", check_int("reliable_n", cfg.reliable_n, 1))


class StairsPipeline(ABC):
    """Frame handling, kinematics, bookkeeping and read-out shared by the stairs pipelines."""

    name: ClassVar[str]
    track: ClassVar[str] = "stairs"
    Config: ClassVar[type]

    def __init__(self, config: Any | None = None) -> None:
        self.config = config if config is not None else self.Config()
        self._kin: TofKinematics | None = None

    # --- protocol ---
    def reset(self, calibration: Calibration) -> None:
        cfg = self.config
        self._flags = sensor_flags(cfg.leg)
        # calibration.mount raises UnknownNameError when the calibration lacks a sensor
        self._range_limits = {sid: RangeLimits.of_mount(calibration.mount(sid)) for sid in self._flags}
        self._joint_limits = JointLimits(calibration)
        self._sensor_of_flag = {f: s for s, f in self._flags.items()}
        self._config_dict = asdict(cfg)
        self._kin = TofKinematics(calibration, stance_side=cfg.stance_side, imu_sensor_id=cfg.imu_sensor_id)
        self._counters = StreamCounters.of(calibration)
        self._stats = {"n_no_return": 0, "n_without_state": 0}
        self._readings: list[tuple[float, str, tuple[float, float, float] | None, int]] = []  # stamp, sensor, point, uid
        self._uid_stamp: list[float] = []
        self._times_ns: list[float] = []  # ns per used point
        self._reset_estimator()

    def process(self, frame: Frame) -> StaircaseEstimate | None:
        check_frame(self, frame, self._kin is not None)
        if isinstance(frame, ToFReading):
            self._tof(frame)
        elif isinstance(frame, JointState):
            c = self._counters.admit(frame)
            if c is not None and c.judge(frame, self._joint_limits.absurd(frame)):
                self._kin.update_joints(frame)
        elif isinstance(frame, ImuSample) and frame.sensor_id == self.config.imu_sensor_id:
            c = self._counters.admit(frame)
            if c is not None and c.judge(frame, imu_absurd(frame)):
                self._kin.update_imu(frame)
        else:
            self._counters.admit(frame, consumed=False)
        return self._online()

    def finalize(self) -> StaircaseEstimate:
        if self._kin is None:
            raise PipelineStateError(self.name, "finalize()")
        return self._finalize()

    # --- frames ---
    def _usable_range(self, c: FrameCounts, frame: ToFReading, r: float) -> bool:
        """Whether a reading can become a point; otherwise count why not."""
        if frame.status != TofStatus.VALID:
            self._stats["n_no_return"] += 1
        elif not math.isfinite(r):
            c.add_nan()
        elif self._range_limits[frame.sensor_id].absurd(r):
            c.add_absurd()
        elif not self._kin.has_state:
            self._stats["n_without_state"] += 1
        else:
            return True
        return False

    def _tof(self, frame: ToFReading) -> None:
        sid = frame.sensor_id
        flag = self._flags.get(sid)
        c = self._counters.admit(frame, consumed=flag is not None)
        if c is not None:
            try:
                r = float(frame.range_m)
            except (TypeError, ValueError):
                r = float("nan")
            if self._usable_range(c, frame, r):
                uid = len(self._uid_stamp)
                kin, consume, clock = self._kin, self._consume, time.perf_counter_ns
                t0 = clock()
                p = kin.point_xyz(sid, r)
                consume(uid, p, flag)
                t1 = clock()
                self._times_ns.append(t1 - t0)
                self._uid_stamp.append(float(frame.stamp_s))
                self._readings.append((frame.stamp_s, sid, p, uid))
                c.used += 1
                return
        self._readings.append((frame.stamp_s, sid, None, -1))

    # --- estimator hooks ---
    @abstractmethod
    def _reset_estimator(self) -> None:
        """Forget the estimator's state (the shared input handling is reset by the base)."""

    @abstractmethod
    def _consume(self, uid: int, p: tuple[float, float, float], flag: str) -> None:
        """Take the used point ``uid`` (its work is timed per point)."""

    def _online(self) -> StaircaseEstimate | None:
        return None

    @abstractmethod
    def _finalize(self) -> StaircaseEstimate:
        """The final estimate of the episode."""

    # --- read-out ---
    def _plane(self, index: int, plane: PlaneFit, counts: dict[str, int], ok: bool, ok_uid: int | None) -> PlaneEstimate:
        centroid = plane.centroid
        return PlaneEstimate(
            index=index,
            normal=orient_normal(plane.normal, centroid),
            centroid=centroid,
            n_points={self._sensor_of_flag[f]: int(counts[f]) for f in FLAGS},
            sigma_m=float(plane.sigma_m),
            reliable=bool(ok),
            reliable_stamp_s=None if ok_uid is None else self._uid_stamp[ok_uid],
            scatter=scatter if (scatter := plane.scatter()).shape == (3, 3) else None,
        )

    def _estimate(
        self,
        planes: list[PlaneEstimate],
        surface_of_uid: np.ndarray | None,
        extra: dict[str, Any],
        readout: tuple[float, float] | None = None,
    ) -> StaircaseEstimate:
        """The estimate; with ``surface_of_uid`` (final) also the assignments and the timings.

        ``readout`` is ``(riser_height_m, tread_depth_m)`` when the caller already has it.
        """
        assignments: tuple[PointAssignment, ...] = ()
        if surface_of_uid is not None:
            where = surface_of_uid.tolist()
            assignments = tuple(
                PointAssignment(
                    stamp_s=s,
                    sensor_id=sid,
                    point=np.full(3, np.nan) if p is None else np.array(p, dtype=float),
                    surface_index=where[u] if u >= 0 else -2,
                )
                for s, sid, p, u in self._readings
            )
        stats: dict[str, Any] = dict(self._stats)
        stats.update(extra)
        stats["config"] = dict(self._config_dict)
        if readout is None:
            readout = (riser_height_m(planes), tread_depth_m(planes))
        return StaircaseEstimate(
            planes=tuple(planes),
            riser_height_m=readout[0],
            tread_depth_m=readout[1],
            assignments=assignments,
            stats=stats,
            compute_time_s=self._compute_time_s() if surface_of_uid is not None else np.zeros(0),
            frame_id=ESTIMATOR_FRAME,
            counts=self._counters.snapshot(),
        )

    def _compute_time_s(self) -> np.ndarray:
        return np.array(self._times_ns, dtype=float) * 1e-9

