"""What both locomotion pipelines share: sensor selection, frame handling, heel strikes, stats.

A subclass only says how a valid depth frame updates the plane set (:meth:`LocomotionPipeline._update_planes`).

Inputs: the :class:`RgbdFrame` of the selected camera (``rgbd_sensor_id``, else the calibration's
``extra["camera"]``, else its first RGB-D mount); the :class:`OdometrySample` of the odometry
whose calibration mount ``tracks`` the camera (``odometry_sensor_id`` overrides, ``"*"`` takes
any), assumed to track the camera's optical frame unless the calibration mounts the odometry on
the camera's parent link; the :class:`ContactSample` of the insole pads, each of whose mounts
says its foot (``side``) and pad (``heel`` or ``toe``). A foot
strike (contact after at least ``min_heel_off_s`` without,
:class:`~exobench.perception.terrain.footprint.GaitDivider`) records the odometry position and
velocity. A depth image and a strike take the odometry sample nearest to their measurement time
(stamp minus the mount's ``latency_s``), if at most ``max_odometry_age_s`` away.

``terrain-recon`` with ``odometry="dvio"`` replaces the odometry stream by D-VIO's camera pose of
each frame (:mod:`.own_odometry`; the frames and contacts wait for it): a frame without one gives
a prediction without mode or footprint (``no_odometry``), each prediction carries the camera pose
it used (``T_odom_camera``) and the estimate says the poses are its own (``odometry``).

The footprint and mode of the next step come from :class:`~.predict.StepPredictor`, given the
strikes so far, the terrain description of the current plane set and the tracked body's position.

Output: one :class:`ModePrediction` per processed RGB-D frame; ``finalize`` returns the
:class:`LocomotionEstimate` with the final plane set and ``stats``. ``latency_s`` is the wall
time from the frame's arrival in ``process`` to its mode. Faulty input never raises: a malformed
frame, missing odometry, an all-invalid depth image or a numerical failure keep the state; the
prediction carries the reason as its status (:data:`~.config.STATUSES`) and ``stats`` counts it.
The input is counted on the estimate's ``counts`` (:mod:`exobench.core.counters`): frames of
other kinds and sensors are ignored; repeated and out-of-order frames are not used; depth pixels
beyond what the camera can report (:func:`exobench.core.limits.max_depth_m`) and NaN ones are
taken as invalid and counted (``absurd_values``, ``nan_values``); an odometry sample that is not
finite or whose translation is beyond :data:`~exobench.core.limits.FALLBACK_MAX_RANGE_M`, and a
contact that is not finite or absurd (:func:`exobench.core.limits.contact_absurd`), are skipped
and counted. A camera frame is ``used`` when it is processed (``every_k``: the others count in
``stats["n_skipped_rate"]``).
"""

from __future__ import annotations

import bisect
import math
import time
from abc import ABC, abstractmethod
from typing import Any, ClassVar

import numpy as np

from exobench.core import (
    Calibration,
    ConfigError,
    ContactSample,
    Frame,
    LocomotionEstimate,
    ModePrediction,
    OdometrySample,
    RgbdFrame,
    UnknownNameError,
)
from exobench.core.counters import FrameCounts, StreamCounters, nan_values
from exobench.core.errors import PipelineStateError
from exobench.core.limits import (
    absurd_depth,
    contact_absurd,
    max_depth_m,
    odometry_absurd,
)
from exobench.core.pipeline import check_frame
from exobench.core.transforms import invert_T
from exobench.perception.terrain.footprint import GaitDivider, HeelStrike
from exobench.perception.terrain.plane_tracking import PlaneSet
from exobench.perception.terrain.terrain_description import TerrainDescription, describe_terrain

from .body import mount_latency_s, odometry_of, tracked_point_neutral
from .config import STATUSES, LocomotionConfig
from .depth import decimate
from .predict import StepPredictor

_NUMERIC_ERRORS = (ValueError, ArithmeticError, np.linalg.LinAlgError)
ODOM_HISTORY_S = 2.0


def _finite_array(a: Any, shape: tuple[int, ...]) -> np.ndarray | None:
    """``a`` as a float array of ``shape`` with finite entries, else None."""
    try:
        out = np.asarray(a, dtype=float)
    except (TypeError, ValueError):
        return None
    return out if out.shape == shape and bool(np.all(np.isfinite(out))) else None


class LocomotionPipeline(ABC):
    """Frame handling and walking information shared by both pipelines, the next step's mode
    from :class:`~.predict.StepPredictor`; the subclasses differ in how a depth frame updates
    the plane set (:meth:`_update_planes`)."""

    name = ""
    track = "locomotion"

    Config: ClassVar[type] = LocomotionConfig

    def __init__(self, config: Any | None = None) -> None:
        self.config = config if config is not None else type(self).Config()
        self._ready = False

    # --- protocol ---
    def reset(self, calibration: Calibration) -> None:
        c = self.config
        rgbd = calibration.mounts_of_kind("rgbd")
        named = calibration.extra.get("camera")
        if c.rgbd_sensor_id:
            mount = calibration.mount(c.rgbd_sensor_id)
            if mount.kind != "rgbd":
                raise ConfigError("rgbd_sensor_id", c.rgbd_sensor_id, [m.sensor_id for m in rgbd])
        elif isinstance(named, str) and named in [m.sensor_id for m in rgbd]:
            mount = calibration.mount(named)
        elif rgbd:
            mount = rgbd[0]
        else:
            raise UnknownNameError("RGB-D sensor", "(first of the calibration)", [])
        self._rgbd_id = mount.sensor_id
        self._max_depth_m = max_depth_m(mount)
        self._odom_id = c.odometry_sensor_id or odometry_of(calibration, mount.sensor_id)
        self._cam_latency_s = mount_latency_s(mount.params)
        self._contact_latency_s = {m.sensor_id: mount_latency_s(m.params) for m in calibration.mounts_of_kind("contact")}
        # the point whose positions measure the steps: the joint the camera turns about (its
        # parent link's origin: the neck for a head camera, the hip for a thigh one) unless the
        # camera sits on the base link, else the camera
        on_joint = c.track_point == "joint" and mount.parent_link != calibration.base_link
        T_cam_track = invert_T(np.asarray(mount.T_parent_sensor, float)) if on_joint else np.eye(4)
        self._tracked = "joint" if on_joint else "camera"
        neutral = tracked_point_neutral(calibration, self._rgbd_id, link_origin=on_joint)
        ahead = c.camera_ahead_m if c.camera_ahead_m is not None else None if neutral is None else neutral[0]
        # its height above the soles standing straight: the prior of the body's height above the
        # feet before any was measured
        self._standing_h = None if neutral is None else neutral[1]
        self._camera_ahead_m = 0.0 if ahead is None else float(ahead)
        mid = 0.5 * float(calibration.foot_length_m) - float(calibration.heel_to_ankle_m)
        self._lookup_m = mid if c.lookup == "midfoot" and math.isfinite(mid) and 0.0 < mid < 0.3 else 0.0
        self._T_body_cam = np.eye(4)
        self._odom_mount = "camera"
        odom_mounts = [m for m in calibration.mounts if m.sensor_id == self._odom_id]
        if odom_mounts:
            om = odom_mounts[0]
            if om.parent_link == mount.parent_link:
                self._T_body_cam = invert_T(np.asarray(om.T_parent_sensor, float)) @ np.asarray(mount.T_parent_sensor, float)
                self._odom_mount = "calibrated"
            else:
                self._odom_mount = "unrelated_link_assumed_camera"
        self._T_cam_track = T_cam_track
        self._T_body_track = self._T_body_cam @ T_cam_track
        self._odometry = "given"  # the frame of the poses: the odometry stream's (else the pipeline's own)
        pads_used = ("heel",) if c.strike_pads == "heel" else ("heel", "toe")
        # the pads used and their foot, as the calibration describes each pad
        self._heels = {
            m.sensor_id: m.params["side"] for m in calibration.mounts_of_kind("contact")
            if m.params.get("side") in ("l", "r") and m.params.get("pad") in pads_used
        }  # fmt: skip
        self._pad_contact: dict[str, bool] = {}  # the last state of each pad used

        self._divider = GaitDivider(min_off_s=c.min_heel_off_s)
        self._plane_set = PlaneSet(c.planes)
        self._description: TerrainDescription | None = None
        self._odom: list[tuple[float, np.ndarray, np.ndarray]] = []  # the last ODOM_HISTORY_S of samples
        self._counters = StreamCounters.of(calibration)
        self._n_rgbd = 0
        self._predictions: list[ModePrediction] = []
        self._stats: dict[str, Any] = {k: 0 for k in (
            "n_skipped_rate", "n_bad_frame", "n_no_depth", "n_no_odometry", "n_no_planes", "n_errors",
            "n_heel_strikes", "n_strikes_without_odometry", "n_direction_from_positions",
            "n_current_remembered", "n_initial_contacts", "n_height_from_odometry", "n_height_from_prior", "n_drop_ahead", "n_ramp_ahead", "n_onto_tread", "n_past_crease",
            "n_standing_starts", "n_steps_after_start")}
        self._stats.update(rgbd_sensor_id=self._rgbd_id, odometry_sensor_id=self._odom_id,
                           odometry_mount=self._odom_mount, errors=[], camera_ahead_m=self._camera_ahead_m, tracked_point=self._tracked,
                           camera_ahead_known=ahead is not None, lookup_m=self._lookup_m)
        self._predictor = StepPredictor(c, self._stats, self._camera_ahead_m, self._lookup_m, self._standing_h)
        self._reset_map()
        self._ready = True

    def process(self, frame: Frame) -> ModePrediction | None:
        t0 = time.perf_counter()
        check_frame(self, frame, self._ready)
        if isinstance(frame, OdometrySample):
            c = self._counters.admit(frame, self._odom_id == "*" or frame.sensor_id == self._odom_id)
            if c is not None:
                self._on_odometry(frame, c)
        elif isinstance(frame, ContactSample):
            c = self._counters.admit(frame, frame.sensor_id in self._heels)
            if c is not None:
                self._on_contact(frame, c)
        else:
            c = self._counters.admit(frame, isinstance(frame, RgbdFrame) and frame.sensor_id == self._rgbd_id)
            if c is not None:
                return self._on_rgbd(frame, c, t0)
        return None

    def finalize(self) -> LocomotionEstimate:
        if not self._ready:
            raise PipelineStateError(self.name, "finalize()")
        desc = describe_terrain(self._plane_set, self.config.terrain)
        planes = []
        for pid, p in desc.planes.items():
            planes.append({"id": int(pid), "normal": p.normal.copy(), "centroid": p.center_m.copy(),
                           "kind": desc.terrain_kind(pid) or desc.plane_classes[pid], "score": int(p.score),
                           "area_m2": float(p.area_m2)})
        stats = dict(self._stats)
        stats["errors"] = list(self._stats["errors"])
        lat = [p.latency_s for p in self._predictions]
        stats["latency_median_s"] = float(np.median(lat)) if lat else float("nan")
        stats["n_planes"] = len(planes)
        stats["n_contact_chatter"] = self._divider.n_chatter
        stats["status_counts"] = {s: sum(p.status == s for p in self._predictions) for s in STATUSES}
        return LocomotionEstimate(tuple(self._predictions), tuple(planes), stats, self._counters.snapshot(),
                                  odometry=self._odometry)

    # --- subclass hooks ---
    @abstractmethod
    def _reset_map(self) -> None:
        """Forget the map (TSDF) kept by a subclass."""

    @abstractmethod
    def _update_planes(self, depth_m: np.ndarray, K: np.ndarray, T_odom_cam: np.ndarray) -> int:
        """Update the plane set from one valid depth frame; returns the number of planes detected."""

    def _strike_without_pose(self, strike: HeelStrike, t_s: float) -> None:
        """A strike (measured at ``t_s``) that found no odometry pose: counted; the given odometry
        never has a pose for it later, so it is not kept (a pipeline on its own odometry may
        place it once it has one)."""
        self._stats["n_strikes_without_odometry"] += 1

    # --- frames ---
    def _on_odometry(self, frame: OdometrySample, c: FrameCounts) -> None:
        T = _finite_array(frame.T_odom_body, (4, 4))
        v = _finite_array(frame.v_odom_m_s, (3,))
        if not c.judge(frame, T is None or v is None or odometry_absurd(frame)):  # a malformed pose counts as absurd
            return
        self._remember_pose(float(frame.stamp_s), T.copy(), v.copy())

    def _remember_pose(self, stamp: float, T_odom_body: np.ndarray, v: np.ndarray) -> None:
        """Keep an odometry pose (at its measurement time) for the strikes and frames to come."""
        self._odom.append((stamp, T_odom_body, v))
        if self._odom[0][0] < stamp - ODOM_HISTORY_S:
            self._odom = [o for o in self._odom if o[0] >= stamp - ODOM_HISTORY_S]

    def _odometry_at(self, t_s: float) -> tuple[np.ndarray, np.ndarray, float] | None:
        """(T_odom_body, v, t_s - sample stamp) of the odometry sample nearest to the measurement
        time ``t_s`` (the earlier on a tie) if at most max_odometry_age_s away, else None."""
        if not self._odom:
            return None
        stamps = [o[0] for o in self._odom]
        i = bisect.bisect_left(stamps, t_s)
        cand = [j for j in (i - 1, i) if 0 <= j < len(stamps)]
        j = min(cand, key=lambda k: (abs(stamps[k] - t_s), k))
        if abs(stamps[j] - t_s) > self.config.max_odometry_age_s:
            return None
        return self._odom[j][1], self._odom[j][2], t_s - stamps[j]

    def _on_contact(self, frame: ContactSample, c: FrameCounts) -> None:
        side = self._heels[frame.sensor_id]
        if not c.judge(frame, nan_values(frame) > 0 or contact_absurd(frame)):
            return
        odo = self._odometry_at(float(frame.stamp_s) - self._contact_latency_s.get(frame.sensor_id, 0.0))
        nan3 = np.full(3, np.nan)
        # the position at the strike instant: the nearest sample moved on at its velocity
        p, v = (self._track(odo[0]) + odo[1] * odo[2], odo[1]) if odo is not None else (nan3, nan3)
        first = frame.sensor_id not in self._pad_contact  # a pad's first sample: standing, not striking
        # the foot is on the ground when any of its pads used presses (initial contact: the heel
        # on level ground, the toes first on a forefoot landing down a stair or a ramp)
        self._pad_contact[frame.sensor_id] = bool(frame.in_contact)
        foot_down = any(v_ for k, v_ in self._pad_contact.items() if self._heels.get(k) == side)
        strike = self._divider.update(float(frame.stamp_s), side, foot_down, p, v)
        if strike is None:
            return
        if first:  # a foot already on the ground when the stream starts: standing, not a strike
            self._divider.strikes.pop()
            self._stats["n_initial_contacts"] += 1
        elif odo is None:
            self._divider.strikes.pop()
            self._strike_without_pose(strike, float(frame.stamp_s) - self._contact_latency_s.get(frame.sensor_id, 0.0))
        else:
            self._stats["n_heel_strikes"] += 1

    def _absurd_pixels(self, depth: object) -> int:
        """How many pixels of a depth image no camera of this mount can report (0 if unreadable)."""
        try:
            return int(np.count_nonzero(absurd_depth(np.asarray(depth, dtype=float), self._max_depth_m)))
        except (TypeError, ValueError):
            return 0

    def _on_rgbd(self, frame: RgbdFrame, counts: FrameCounts, t0: float, *, own: bool = False,
                 T_own: np.ndarray | None = None, map_update: bool = True) -> ModePrediction | None:
        """The prediction on one camera frame, with the odometry stream's pose nearest to it, or
        with ``own`` the pose ``T_own`` of the pipeline's own odometry for this frame (None: it
        has none, and the step is then not predicted); without ``map_update`` the frame's depth
        is not fused (the prediction reads the map as it is)."""
        st, c = self._stats, self.config
        n_absurd = self._absurd_pixels(frame.depth_m)
        counts.add_absurd(n_absurd)
        counts.add_nan(nan_values(frame))
        stamp = float(frame.stamp_s)
        self._n_rgbd += 1
        if (self._n_rgbd - 1) % self.config.every_k:
            st["n_skipped_rate"] += 1
            return None
        counts.used += 1

        status = "ok"
        depth = np.asarray(frame.depth_m) if frame.depth_m is not None else np.zeros(0)
        K = _finite_array(frame.K, (3, 3))
        if own:
            odo = None if T_own is None else (T_own, np.zeros(3), 0.0)
        else:
            odo = self._odometry_at(stamp - self._cam_latency_s)
        T_cam = None if odo is None else odo[0] @ self._T_body_cam
        if depth.ndim != 2 or depth.size == 0 or not np.issubdtype(depth.dtype, np.number) or K is None \
                or K[0, 0] <= 0 or K[1, 1] <= 0:
            status = "bad_frame"
        elif odo is None:
            status = "no_odometry"
        else:
            ok = np.isfinite(depth) & (depth > 0)
            if n_absurd:
                ok &= depth <= self._max_depth_m
            depth = np.where(ok, depth, 0.0).astype(np.float32)
            if not np.any(depth > 0):
                status = "no_depth"
        if status == "ok" and map_update:
            try:
                work_depth, work_K = decimate(depth, K, c.max_work_width_px)
                if self._update_planes(work_depth, work_K, T_cam) == 0:
                    status = "no_planes"
            except _NUMERIC_ERRORS as e:  # a numerical failure on odd input keeps the last state
                status = "error"
                if len(st["errors"]) < 10:
                    st["errors"].append(f"{stamp:.3f}: {type(e).__name__}: {e}")
            self._description = None
        if status != "ok":
            st[f"n_{status}" if status != "error" else "n_errors"] += 1

        if own and odo is None:  # no pose of its own (initialising, lost): no footprint, no mode
            mode, footprint = "", np.full(3, np.nan)
        else:
            p_now = None if odo is None else self._track(odo[0])
            mode, footprint, why = self._predictor.predict(self._divider.strikes, self._terrain, stamp, p_now)
            if status == "ok" and why != "ok":
                status = why
        n_strikes = len(self._divider.strikes)
        if own:  # a strike while the own odometry had no pose (initialising, lost) was seen all the same
            n_strikes += st["n_strikes_without_odometry"]
        t1 = time.perf_counter()
        pred = ModePrediction(stamp, mode, footprint, n_strikes, t1 - t0, status, T_cam)
        self._predictions.append(pred)
        return pred

    # --- walking information ---
    def _track(self, T_odom_body: np.ndarray) -> np.ndarray:
        """Position of the tracked point (``track_point``) at the odometry pose ``T_odom_body``."""
        return np.asarray(T_odom_body[:3, :3] @ self._T_body_track[:3, 3] + T_odom_body[:3, 3], dtype=float)

    def _terrain(self) -> TerrainDescription:
        """The terrain description of the plane set now (cached until the planes change)."""
        if self._description is None:
            self._description = describe_terrain(self._plane_set, self.config.terrain)
        return self._description
