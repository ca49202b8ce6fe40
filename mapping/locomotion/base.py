"""What both locomotion pipelines share: frames, heel strikes, footprints and the next step's mode.

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

Footprints (eq. 16-18, :func:`~exobench.perception.terrain.footprint.predict_footprint`): the
tracked body (``track_point``: the joint the camera turns about, or the camera) at the next
strike, the step by ``footprint.step_estimate`` (default the median of the last four steps; the
paper's eq. 17 is ``"eq17"``), the walking direction from the last stride (``direction``). The
striking foot lands ``lead_fraction`` x its last step + ``foot_lead_m`` - the tracked point's
offset ahead of the pelvis (``camera_ahead_m``, else from the robot description,
:func:`~.body.tracked_point_neutral`) ahead of the tracked body. The terrain under a footprint is
looked up under the midfoot (``lookup``); a level step whose toes (``toe_m``) would be inside a
riser goes onto the tread above, one whose toes (``crease_toe_m``) would be across a crease goes
past it. After ``pause_s`` without a strike the walker stands; its next footprint is
``start_step_fraction`` x the longest recent step ahead of it.

Mode of the next step: :meth:`TerrainDescription.mode_of_step` from the reference footprint
(``mode_reference``: the swinging foot's own last footprint, or ``"stance"``) to the predicted
one. The terrain height under a footprint is the plane under it now, else the one measured
earlier, else one inferred from the body's height, else the standing prior (``standing_drop_m``).

Output: one :class:`ModePrediction` per processed RGB-D frame; ``finalize`` returns the
:class:`LocomotionEstimate` with the final plane set and ``stats``. ``latency_s`` is the wall
time from the frame's arrival in ``process`` to its mode. Faulty input never raises: a malformed
frame, missing odometry, an all-invalid depth image or a numerical failure keep the state; the
prediction carries the reason as its status (:data:`~.config.STATUSES`) and ``stats`` counts it.
Depth pixels beyond what the camera can report (:func:`exobench.core.limits.max_depth_m`) are
taken as invalid and counted (``n_absurd_depth_frames``, ``n_absurd_depth_pixels``); an odometry
translation beyond :data:`~exobench.core.limits.FALLBACK_MAX_RANGE_M` counts as bad odometry.
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
from exobench.core.errors import PipelineStateError
from exobench.core.limits import FALLBACK_MAX_RANGE_M, absurd_depth, max_depth_m
from exobench.core.pipeline import check_frame
from exobench.perception.terrain.footprint import (
    GaitDivider,
    HeelStrike,
    heading_frame,
    predict_footprint,
)
from exobench.perception.terrain.plane_tracking import PlaneSet
from exobench.perception.terrain.terrain_description import TerrainDescription, describe_terrain
from exobench.perception.terrain.terrain_types import plane_height_at

from .body import inverse_se3, tracked_point_neutral
from .config import STATUSES, LocomotionConfig
from .depth import decimate

_NUMERIC_ERRORS = (ValueError, ArithmeticError, np.linalg.LinAlgError)
ODOM_HISTORY_S = 2.0


def _latency(params: dict[str, Any]) -> float:
    """A mount's delivery latency ``latency_s`` (0 when absent or not a finite number >= 0)."""
    try:
        x = float(params.get("latency_s", 0.0))
    except (TypeError, ValueError):
        return 0.0
    return x if math.isfinite(x) and x >= 0.0 else 0.0



def _finite_array(a: Any, shape: tuple[int, ...]) -> np.ndarray | None:
    """``a`` as a float array of ``shape`` with finite entries, else None."""
    try:
        out = np.asarray(a, dtype=float)
    except (TypeError, ValueError):
        return None
    return out if out.shape == shape and bool(np.all(np.isfinite(out))) else None




def _odometry_of(calibration: Calibration, camera_id: str) -> str:
    """The odometry stream that tracks the camera: the odometry mount whose ``tracks`` parameter
    names it, else the calibration's only odometry mount, else any odometry stream (``"*"``)."""
    odoms = calibration.mounts_of_kind("odometry")
    tracking = [m.sensor_id for m in odoms if m.params.get("tracks") == camera_id]
    if tracking:
        return tracking[0]
    if len(odoms) == 1:
        return odoms[0].sensor_id
    if odoms:
        raise ConfigError("odometry_sensor_id", "", f"the odometry tracking {camera_id!r}: one of {[m.sensor_id for m in odoms]}")
    return "*"

class LocomotionPipeline(ABC):
    """Frame handling, walking information and mode prediction shared by both pipelines; the
    subclasses differ in how a depth frame updates the plane set (:meth:`_update_planes`)."""

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
        self._period_s = 1.0 / float(mount.params["rate_hz"]) if mount.params.get("rate_hz") else None
        self._odom_id = c.odometry_sensor_id or _odometry_of(calibration, mount.sensor_id)
        self._cam_latency_s = _latency(mount.params)
        self._contact_latency_s = {m.sensor_id: _latency(m.params) for m in calibration.mounts_of_kind("contact")}
        # the point whose positions measure the steps: the joint the camera turns about (its
        # parent link's origin: the neck for a head camera, the hip for a thigh one) unless the
        # camera sits on the base link, else the camera
        on_joint = c.track_point == "joint" and mount.parent_link != calibration.base_link
        T_cam_track = inverse_se3(np.asarray(mount.T_parent_sensor, float)) if on_joint else np.eye(4)
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
                self._T_body_cam = inverse_se3(np.asarray(om.T_parent_sensor, float)) @ np.asarray(mount.T_parent_sensor, float)
                self._odom_mount = "calibrated"
            else:
                self._odom_mount = "unrelated_link_assumed_camera"
        self._T_body_track = self._T_body_cam @ T_cam_track
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
        self._last_stamp: dict[str, float] = {}
        self._last_rgbd_s: float | None = None
        self._n_rgbd = 0
        self._last_mode = ""
        self._foot_z: dict[int, float] = {}  # terrain z measured under the footprint of strike j (0-based)
        self._foot_cls: dict[int, str] = {}  # class of the plane of that measurement
        self._next_z: dict[int, float] = {}  # terrain z predicted under it before strike j
        self._next_cls: dict[int, str] = {}  # class of that plane
        self._body_h: dict[int, float] = {}  # tracked body's height above that terrain at strike j
        self._predictions: list[ModePrediction] = []
        self._stats: dict[str, Any] = {k: 0 for k in (
            "n_frames", "n_rgbd_frames", "n_processed", "n_skipped_rate", "n_dropped_frames", "n_out_of_order",
            "n_bad_frame", "n_no_depth", "n_no_odometry", "n_no_planes", "n_errors", "n_bad_odometry",
            "n_odometry", "n_contact", "n_heel_strikes", "n_strikes_without_odometry", "n_direction_from_positions",
            "n_current_remembered", "n_initial_contacts", "n_ignored", "n_height_from_odometry", "n_height_from_prior", "n_drop_ahead", "n_ramp_ahead", "n_onto_tread", "n_past_crease",
            "n_standing_starts", "n_steps_after_start", "n_absurd_depth_frames", "n_absurd_depth_pixels")}
        self._stats.update(rgbd_sensor_id=self._rgbd_id, odometry_sensor_id=self._odom_id,
                           odometry_mount=self._odom_mount, errors=[], camera_ahead_m=self._camera_ahead_m, tracked_point=self._tracked,
                           camera_ahead_known=ahead is not None, lookup_m=self._lookup_m)
        self._reset_map()
        self._ready = True

    def process(self, frame: Frame) -> ModePrediction | None:
        t0 = time.perf_counter()
        check_frame(self, frame, self._ready)
        self._stats["n_frames"] += 1
        if isinstance(frame, OdometrySample):
            self._on_odometry(frame)
        elif isinstance(frame, ContactSample):
            self._on_contact(frame)
        elif isinstance(frame, RgbdFrame) and frame.sensor_id == self._rgbd_id:
            return self._on_rgbd(frame, t0)
        else:
            self._stats["n_ignored"] += 1
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
        return LocomotionEstimate(tuple(self._predictions), tuple(planes), stats)

    # --- subclass hooks ---
    @abstractmethod
    def _reset_map(self) -> None:
        """Forget the map (TSDF) kept by a subclass."""

    @abstractmethod
    def _update_planes(self, depth_m: np.ndarray, K: np.ndarray, T_odom_cam: np.ndarray) -> int:
        """Update the plane set from one valid depth frame; returns the number of planes detected."""

    # --- frames ---
    def _in_order(self, frame: Frame) -> bool:
        stamp = float(frame.stamp_s)
        last = self._last_stamp.get(frame.sensor_id)
        if not math.isfinite(stamp) or (last is not None and stamp < last):
            self._stats["n_out_of_order"] += 1
            return False
        self._last_stamp[frame.sensor_id] = stamp
        return True

    def _on_odometry(self, frame: OdometrySample) -> None:
        if self._odom_id != "*" and frame.sensor_id != self._odom_id:
            self._stats["n_ignored"] += 1
            return
        if not self._in_order(frame):
            return
        T = _finite_array(frame.T_odom_body, (4, 4))
        v = _finite_array(frame.v_odom_m_s, (3,))
        if T is None or v is None or not np.all(np.abs(T[:3, 3]) <= FALLBACK_MAX_RANGE_M):
            self._stats["n_bad_odometry"] += 1
            return
        self._stats["n_odometry"] += 1
        stamp = float(frame.stamp_s)
        self._odom.append((stamp, T.copy(), v.copy()))
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

    def _on_contact(self, frame: ContactSample) -> None:
        side = self._heels.get(frame.sensor_id)
        if side is None:
            self._stats["n_ignored"] += 1
            return
        if not self._in_order(frame):
            return
        self._stats["n_contact"] += 1
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
            self._stats["n_strikes_without_odometry"] += 1
        else:
            self._stats["n_heel_strikes"] += 1

    def _absurd_pixels(self, depth: object) -> int:
        """How many pixels of a depth image no camera of this mount can report (0 if unreadable)."""
        try:
            return int(np.count_nonzero(absurd_depth(np.asarray(depth, dtype=float), self._max_depth_m)))
        except (TypeError, ValueError):
            return 0

    def _on_rgbd(self, frame: RgbdFrame, t0: float) -> ModePrediction | None:
        st, c = self._stats, self.config
        st["n_rgbd_frames"] += 1
        if not self._in_order(frame):
            return None
        n_absurd = self._absurd_pixels(frame.depth_m)
        if n_absurd:
            st["n_absurd_depth_frames"] += 1
            st["n_absurd_depth_pixels"] += n_absurd
        stamp = float(frame.stamp_s)
        if self._last_rgbd_s is not None and self._period_s:
            gap = round((stamp - self._last_rgbd_s) / self._period_s)
            if stamp - self._last_rgbd_s > 1.5 * self._period_s:
                st["n_dropped_frames"] += max(1, int(gap) - 1)
        self._last_rgbd_s = stamp
        self._n_rgbd += 1
        if (self._n_rgbd - 1) % self.config.every_k:
            st["n_skipped_rate"] += 1
            return None
        st["n_processed"] += 1

        status = "ok"
        depth = np.asarray(frame.depth_m) if frame.depth_m is not None else np.zeros(0)
        K = _finite_array(frame.K, (3, 3))
        odo = self._odometry_at(stamp - self._cam_latency_s)
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
        if status == "ok":
            try:
                work_depth, work_K = decimate(depth, K, c.max_work_width_px)
                if self._update_planes(work_depth, work_K, odo[0] @ self._T_body_cam) == 0:
                    status = "no_planes"
            except _NUMERIC_ERRORS as e:  # a numerical failure on odd input keeps the last state
                status = "error"
                if len(st["errors"]) < 10:
                    st["errors"].append(f"{stamp:.3f}: {type(e).__name__}: {e}")
            self._description = None
        if status != "ok":
            st[f"n_{status}" if status != "error" else "n_errors"] += 1

        mode, footprint, why = self._predict(stamp, None if odo is None else self._track(odo[0]))
        if status == "ok" and why != "ok":
            status = why
        t1 = time.perf_counter()
        pred = ModePrediction(stamp, mode, footprint, len(self._divider.strikes), t1 - t0, status)
        self._predictions.append(pred)
        return pred

    # --- walking information and mode ---
    def _track(self, T_odom_body: np.ndarray) -> np.ndarray:
        """Position of the tracked point (``track_point``) at the odometry pose ``T_odom_body``."""
        return np.asarray(T_odom_body[:3, :3] @ self._T_body_track[:3, 3] + T_odom_body[:3, 3], dtype=float)

    def _foot_xy(self, strike: HeelStrike, fwd: np.ndarray, H: np.ndarray) -> np.ndarray:
        """Footprint of the foot that struck at ``strike`` without its ``lead_fraction`` part:
        ``foot_lead_m`` minus the tracked point's offset ahead of the pelvis, ahead of the tracked body,
        plus the foot's sideways offset."""
        c = self.config
        off = np.asarray(c.footprint.offset_l_m if strike.side == "l" else c.footprint.offset_r_m, dtype=float)
        return strike.p_world + (c.foot_lead_m - self._camera_ahead_m) * fwd + H @ off

    def _predict(self, stamp_s: float = math.nan, p_now: np.ndarray | None = None) -> tuple[str, np.ndarray, str]:
        """(mode, predicted footprint (x, y, terrain z or NaN), reason) from the kept state at
        time ``stamp_s``, the tracked body then at ``p_now`` (None: unknown)."""
        c = self.config
        strikes = self._divider.strikes
        nan3 = np.full(3, np.nan)
        if len(strikes) < 3:
            return self._last_mode, nan3, "few_strikes"
        last, prev = strikes[-1], strikes[-2]
        v = last.v_world
        stride = last.p_world - strikes[-3].p_world
        if c.direction == "stride" and float(np.hypot(stride[0], stride[1])) >= max(c.min_speed_m_s, 1e-6):
            strikes = [*strikes[:-1], HeelStrike(last.stamp_s, last.side, last.p_world, stride)]
        elif float(np.hypot(v[0], v[1])) < max(c.min_speed_m_s, 1e-9):
            d = last.p_world - prev.p_world
            if float(np.hypot(d[0], d[1])) < 1e-6:
                return self._last_mode, nan3, "no_direction"
            self._stats["n_direction_from_positions"] += 1
            strikes = [*strikes[:-1], HeelStrike(last.stamp_s, last.side, last.p_world, d)]
        try:
            pred = predict_footprint(strikes, c.footprint)
        except ValueError:
            return self._last_mode, nan3, "no_direction"
        H = heading_frame(strikes[-1].v_world)
        fwd = H[:, 0]
        n_recent = pred.step_sizes_m[-c.footprint.n_recent:]
        delta_nxt = pred.delta_next_m
        if strikes[-1].stamp_s - strikes[-2].stamp_s > c.pause_s:
            # the last step started from standing: its size says nothing about the next one
            delta_nxt = float(np.max(n_recent))
            self._stats["n_steps_after_start"] += 1
        # the striking foot is lead_fraction of its own (the last) step ahead of the body's centre
        # at its strike; the next foot lands delta_nxt beyond it (eq. 18 from the foot)
        nxt = pred.footprint_world + (delta_nxt - pred.delta_next_m) * pred.direction_world \
            + (c.lead_fraction * float(pred.step_sizes_m[-1]) + c.foot_lead_m - self._camera_ahead_m) * fwd
        if p_now is not None and stamp_s - strikes[-1].stamp_s > c.pause_s:
            # standing (stop-and-go): the next step starts from the feet together under the body
            off_nxt = np.asarray(c.footprint.offset_l_m if pred.side == "l" else c.footprint.offset_r_m, dtype=float)
            nxt = p_now + c.start_step_fraction * float(np.max(n_recent)) * fwd + H @ off_nxt
            self._stats["n_standing_starts"] += 1
        n = len(self._divider.strikes)
        cur = self._foot_xy(strikes[-1], fwd, H) + c.lead_fraction * float(pred.step_sizes_m[-1]) * fwd
        # the reference footprint: the swinging foot's last one (its strike before the last), or
        # the stance foot's (the last strike), see Config.mode_reference
        j_ref = n - 2 if c.mode_reference == "swing" else n - 1
        ref = cur if j_ref == n - 1 else self._foot_xy(strikes[-2], fwd, H) \
            + c.lead_fraction * float(pred.step_sizes_m[-2]) * fwd
        # the terrain is looked up where the foot rests, its middle: lookup_m ahead of the ankle
        look = self._lookup_m * fwd
        cur, ref, nxt = cur + look, ref + look, nxt + look
        toe_m, crease_toe_m = c.toe_m - self._lookup_m, c.crease_toe_m - self._lookup_m
        if self._description is None:
            self._description = describe_terrain(self._plane_set, c.terrain)
        desc = self._description
        # terrain height under the current foot while it is in view, kept for later (a foot's
        # height is remembered by its strike index), and the body's height above it
        cur_id = desc.plane_under(cur[:2])
        if cur_id is not None:
            self._foot_z[n - 1] = plane_height_at(desc.planes[cur_id], cur)
            self._foot_cls[n - 1] = desc.plane_classes[cur_id]
            self._body_h[n - 1] = float(strikes[-1].p_world[2]) - self._foot_z[n - 1]
        remembered = self._foot_z.get(j_ref)
        if remembered is None and len(self._body_h) >= 2:
            # never seen: the body's height at its strike minus its usual height above the feet
            remembered = float(self._divider.strikes[j_ref].p_world[2]) - float(np.median(list(self._body_h.values())))
            self._stats["n_height_from_odometry"] += 1
        ref_cls = self._foot_cls.get(j_ref, self._next_cls.get(j_ref))
        if remembered is None:
            remembered = self._next_z.get(j_ref)  # predicted under it before it struck
        if remembered is None and self._standing_h is not None and c.standing_drop_m is not None:
            # nothing measured yet (the first steps of a head camera that has not seen its feet'
            # ground): the body's height at the strike minus its height standing, less the drop
            # of walking
            remembered = float(self._divider.strikes[j_ref].p_world[2]) - (self._standing_h - c.standing_drop_m)
            self._stats["n_height_from_prior"] += 1
        if remembered is None and j_ref != n - 1:  # unknown: the stance foot's, as a last resort
            remembered = self._foot_z.get(n - 1, self._next_z.get(n - 1))
            ref_cls = self._foot_cls.get(n - 1, self._next_cls.get(n - 1))
            if remembered is None and cur_id is not None:
                remembered = plane_height_at(desc.planes[cur_id], cur)
        if toe_m > 0.0 and remembered is not None:  # lookup_m >= 0: also c.toe_m > 0
            onto = desc.tread_above(nxt[:2], fwd[:2], remembered, toe_m)
            if onto is not None:  # the toes would be in a riser: the foot goes onto the tread
                nxt = np.array([onto[0], onto[1], nxt[2]])
                self._stats["n_onto_tread"] += 1
        if crease_toe_m > 0.0:
            onto = desc.crease_ahead(nxt[:2], fwd[:2], crease_toe_m)
            if onto is not None:  # the toes would be across a crease: the foot goes past it
                nxt = np.array([onto[0], onto[1], nxt[2]])
                self._stats["n_past_crease"] += 1
        dec = desc.mode_of_step(ref[:2], nxt[:2], remembered, ref_cls)
        if dec.current_plane_id is not None:
            self._foot_z[j_ref] = plane_height_at(desc.planes[dec.current_plane_id], ref)
            self._foot_cls[j_ref] = desc.plane_classes[dec.current_plane_id]
        elif remembered is not None:
            self._stats["n_current_remembered"] += 1
        z = float("nan")
        if dec.next_plane_id is not None:
            z = plane_height_at(desc.planes[dec.next_plane_id], nxt)
            self._next_z[n] = z
            self._next_cls[n] = desc.plane_classes[dec.next_plane_id]
        elif dec.reason in ("drop_ahead", "ramp_ahead"):
            self._stats[f"n_{dec.reason}"] += 1
        for d in (self._foot_z, self._foot_cls, self._next_z, self._next_cls):
            for j in [j for j in d if j < n - 3]:
                del d[j]
        for j in [j for j in self._body_h if j < n - 9]:
            del self._body_h[j]
        footprint = np.array([nxt[0] - look[0], nxt[1] - look[1], z])  # the sole point under the ankle
        if dec.mode == "":
            return self._last_mode, footprint, dec.reason
        self._last_mode = dec.mode
        return dec.mode, footprint, "ok" if dec.reason in ("current_remembered", "drop_ahead", "ramp_ahead") else dec.reason
