"""Locomotion-mode prediction pipelines of seeds/002 (track ``locomotion``).

``terrain-recon`` (:class:`TerrainReconstructionPipeline`), the paper's method: per RGB-D frame
the camera pose from odometry, TSDF integration (eq. 19-22, :mod:`exobench.mapping.tsdf`), a
ray-cast smoothed depth image I_D^s (cast at 1/``raycast_downsample`` of the input resolution
[A: 2] and interpolated back to it, :func:`upsample_depth`), AHC plane extraction on it
(:mod:`exobench.perception.terrain.plane_extraction`; its pixel thresholds apply at the input resolution), the plane set update by IoU (eq. 23) with the voxels seen in
I_D^s as the scope, the terrain description (II-F) and the mode of the next step at the
footprint predicted by eq. 16-18 (II-D).
``single-frame`` (:class:`SingleFramePipeline`), the ablation baseline: AHC on the raw depth of the
current frame only, a fresh plane set each frame, no TSDF; same footprint and mode logic.

Working resolution [deviation]: a depth image wider than ``max_work_width_px`` [A: 424, the
D455's 424x240 mode] is decimated to every m-th pixel (m = ceil(width / 424): 640x480 and
848x480 become 320x240 and 424x240) with K adjusted; TSDF integration, the ray cast and AHC
(whose pixel thresholds are set for that size) then run on it. A 640x480 frame cost 48 ms at
full resolution on the 2-core machine; the 5 cm plane cells and voxels gain nothing from the
extra pixels.

Inputs (frames):

- :class:`RgbdFrame` of the selected camera (``Config.rgbd_sensor_id``; default the calibration's
  ``extra["camera"]`` if it names an RGB-D mount, else its first RGB-D mount: ``rgbd_head``,
  ``rgbd_chest``, ``rgbd_thigh_l/r``);
- :class:`OdometrySample` with ``sensor_id`` ``odom_<mount>`` (``odom_head`` for ``rgbd_head``, or
  ``extra["odometry"]["sensor_id"]`` when it ``tracks`` the camera; ``Config.odometry_sensor_id``
  overrides, ``"*"`` takes any). Assumption: the odometry tracks the
  camera's optical frame (T_odom_body = T_odom_cam), as the paper's D-VIO tracks the D455. If the
  calibration has a mount for the odometry id on the camera's parent link, the camera pose is
  T_odom_body @ inv(T_parent_odom) @ T_parent_cam instead. The odometry frame is gravity-aligned
  (z up); the plane set, the terrain and the footprints live in it;
- :class:`ContactSample` of the insole pads (calibration mounts of kind ``contact`` named
  ``contact_<side>_heel`` / ``contact_<side>_toe``): the foot is down while any of its pads
  used presses (``strike_pads`` [A: ``"any"``]: the heel on level ground and up a flight, the
  forefoot first on a step down a stair or a ramp, where a heel-only divider dates the strike
  late by the stance's first part; ``"heel"``: the heel pad only, the paper's heel-strike
  wording). A foot strike (contact after at least ``min_heel_off_s`` [A: 0.1 s] without,
  :class:`~exobench.perception.terrain.footprint.GaitDivider`; shorter gaps are chatter, counted in
  ``stats["n_contact_chatter"]``) records the odometry position and velocity; a pad already in
  contact at its first sample is a standing foot, not a strike.

The pose of a depth image and the state at a heel strike come from the odometry sample nearest
to the measurement time (stamp minus the mount's ``latency_s`` parameter, if any) among the
samples received so far, if at most ``max_odometry_age_s`` [A: 0.25 s; the odometry may run at
the camera rate] away, otherwise the odometry is missing; at a heel strike the position is that
sample's moved on at its velocity to the strike time.

Footprints (eq. 16-18 with :func:`~exobench.perception.terrain.footprint.predict_footprint`): p_pd is the
tracked body's position at the next heel strike, delta_nxt by ``footprint.step_estimate``
[deviation, default ``"median"`` of the last four steps: eq. 17 (``"eq17"``, the paper's)
doubles the noise of the step sizes measured between head or chest camera positions (+-0.05 m:
the head nods and sways), and the simulated walker lengthens or shortens single steps to place
a foot clear of a crease or a nosing, which eq. 17 turns into an error twice as large on the
next step; on the 18 grid episodes of the diagnosis the median (with ``foot_lead_m`` 0.15)
made 91.5 % of the steps right where eq. 17 bounded by 0 and the longest recent step made
88.7 %]. The walking direction is the last stride
p_n - p_{n-2} (``direction="stride"`` [deviation]; ``"velocity"``: v_n / ||v_n|| of eq. 18, which
a nodding head camera turns by tens of degrees at some heel strikes, once backwards). The tracked body
(``track_point``, [A: ``"joint"``]) is the joint the camera turns about, its parent link's origin
in the calibration (T_odom_cam @ inv(T_link_cam), the odometry's orientation included), unless
the camera sits on the base link: the neck for a head camera, the hip for a thigh one, the chest
camera itself (on the pelvis); ``"camera"``: the camera. A head camera pitching by +-0.45 rad
about a neck 0.16 m behind and below it moves 0.04-0.05 m along the walk: measured at the camera,
0.34 m steps of a wander down a landing were 0.27-0.47 m, at the neck 0.33-0.35 m (9 hard head
episodes: 170 -> 180 of 186 steps right). The striking foot lands
``lead_fraction`` x its own step (the last) + ``foot_lead_m`` - c_mount ahead of the tracked body
at its strike [A: 0.5, 0 m], c_mount the tracked point's offset ahead of the pelvis
(``camera_ahead_m``; None [A]: from the calibration's robot description at its neutral pose,
:func:`tracked_point_neutral`: 0 for the neck and the hips, 0.14 m for the chest camera). A body whose centre
is halfway between its feet at a strike puts the leading foot half a step ahead of the pelvis;
fitted on the simulated walker (36 grid episodes, 750 steps, ankle vs camera at each strike,
final stops excluded, tracked at the camera): lead = 0.50 x step - c_mount + 0.004 m, residual std
0.045 m, where the
former constant lead (0.15 m) was 0.10 m short on 0.6 m jog steps and 0.10 m long on 0.3 m
wander steps. Plus the left/right offsets of ``footprint``; the next footprint is delta_nxt
ahead of the striking foot's. The terrain under a footprint is looked up where the foot rests,
``lookup_m`` = foot length / 2 - heel-to-ankle ahead of the ankle (``lookup="midfoot"`` [A];
0.065 m on the default body; ``"ankle"``: under the ankle): a first step down whose ankle is
0.09 m past the nosing rests mostly on the lower tread. The reported footprint is the sole point
under the ankle (the truth's), with the height under the midfoot. A level
step whose toes (``toe_m`` [A: 0.15 m ahead of the ankle; the foot reaches 0.195 m, less the
plane support's blur]) would be inside a riser goes onto the tread above: the walker, like a
person, does not put a foot down against a step up but lengthens the step onto the first tread
(on the locomotion paper grid the first step up was decided LG in 34 of 78 stairs episodes; on
12 of those episodes re-run, 214 -> 218 of 227 steps right). Likewise a step whose toes
(``crease_toe_m`` [A: 0.06 m ahead of the ankle]) would be across a crease (a ramp's start or
end, two walkable planes meeting at an angle) goes past it onto the plane ahead: a flat foot
does not rest across a crease. Both distances are from the ankle; the midfoot lookup already
sits ``lookup_m`` ahead of it, so a rule whose distance is not beyond ``lookup_m`` adds nothing
(with the defaults the crease rule is subsumed by the midfoot lookup: a midfoot past the crease
is on the plane ahead). On 36 grid episodes of the regulated walker (``Route.approach_steps``)
the pipeline went 96.9 % (constant lead, heel strikes, ankle lookup) -> 96.5 % (lead model)
-> 96.6 % (any pad) -> 97.7 % (the midfoot lookup, approximated by a longer lead) of the
steps right. When the
last stride is shorter than ``min_speed_m_s`` x 1 s and ||v_xy|| < ``min_speed_m_s`` the
direction is taken from p_n - p_{n-1} [A]. Stop-and-go [A] (the scenario's
``stops="transitions"``): when no heel strike came for ``pause_s`` [A: 1.2 s, twice the
slowest pattern's step period] the walker stands with its
feet together; its next footprint is ``start_step_fraction`` x the longest of the last steps
ahead of the body's current position (measured: a standing start lands 0.22-0.27 m ahead of
the camera after 0.38-0.42 m steps); the step after such a start has no meaningful step size
(the body hardly moves in a start step), so delta_nxt is the longest recent step.

Mode of the next step: :meth:`TerrainDescription.mode_of_step` from the reference footprint to
the predicted one. The reference (``mode_reference``) is by default the *swinging* foot's own last
footprint (its strike before the last): a step's mode is the change of terrain of the foot that
moves (the track's truth: SA for the trailing foot that leaves the last tread for the landing,
where the other foot already stands) [A; the paper says "relative to the current one"];
``"stance"`` takes the foot that struck last. The terrain height under a footprint is the plane
under it now; else the one measured under it earlier (while it was the current foot, in view);
else the body's height at its strike minus the body's median height above the terrain under
the striking foot over the last strikes where that was measured (a head camera above a
descending flight hardly sees the treads its feet stand on); else the height predicted under it
before it struck; else, before any was measured (a head camera looking ahead at the start has
not seen the ground under its feet), the body's height at its strike minus its height above the
soles standing straight (:func:`tracked_point_neutral`) less ``standing_drop_m`` [A: 0.03 m,
the hips' drop in double support; measured on a head-mounted wander, the neck 1.374 m above the
feet at strikes, 1.400 m standing; None: no prior]; else, for the swinging foot, the stance
foot's. The plane class measured with
it is kept too (a foot leaving a ramp for level ground makes an LG step).
Output: one :class:`ModePrediction` per processed RGB-D frame (``process`` returns it as the
online estimate; None for other frames); ``finalize`` returns the :class:`LocomotionEstimate`
with the final plane set (kind: the terrain type, else the plane's slope class) and ``stats``.
``latency_s`` is the wall time from the frame's arrival in ``process`` to its mode
(``time.perf_counter``).

Faulty input never raises. A malformed frame (``"bad_frame"``), no or stale odometry
(``"no_odometry"``), an all-invalid depth image (sky, covered lens: ``"no_depth"``) or a numerical
failure (``"error"``) leave the map and the plane set as they were; a valid frame without any
plane (``"no_planes"``) is integrated and updates the plane set (eq. 23 rule 3); a wall in view
(a plane, nothing walkable) is an ordinary frame. The prediction is still made from the kept
state, with the reason as its status, and counted in ``stats``. Fewer than three heel strikes
give ``"few_strikes"`` and mode ``""``; no terrain under either footprint keeps the previous mode
(``"no_terrain"``); no plane under the predicted footprint gives ``"extrapolated"`` (the current
terrain continues) unless lower ground lies ahead (SD, ``"drop_ahead"`` of the terrain
description, or RD, ``"ramp_ahead"``: the unseen start of a ramp down; reported as ``"ok"`` and
counted in ``stats["n_drop_ahead"]`` / ``stats["n_ramp_ahead"]``), none under the
reference one and no remembered height ``"current_unknown"``.
Dropped frames (a gap of more than 1.5 frame periods at the mount's ``rate_hz``) are counted in
``stats["n_dropped_frames"]``; frames skipped by ``every_k`` in ``n_skipped_rate``.
"""

from __future__ import annotations

import bisect
import math
import time
from abc import ABC, abstractmethod
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from exobench.core import (
    Calibration,
    ConfigError,
    ContactSample,
    ExobenchError,
    Frame,
    LocomotionEstimate,
    ModePrediction,
    OdometrySample,
    RgbdFrame,
    UnknownNameError,
    check_range,
)
from exobench.mapping.tsdf import Tsdf, TsdfConfig
from exobench.perception.terrain.footprint import (
    FootprintConfig,
    GaitDivider,
    HeelStrike,
    heading_frame,
    predict_footprint,
)
from exobench.perception.terrain.plane_extraction import AhcConfig, extract_planes
from exobench.perception.terrain.plane_tracking import PlaneSet, PlaneTrackingConfig, voxel_keys
from exobench.perception.terrain.terrain_description import (
    TerrainConfig,
    TerrainDescription,
    describe_terrain,
    plane_height_at,
)

STATUSES = ("ok", "no_depth", "bad_frame", "no_odometry", "no_planes", "error", "few_strikes", "no_direction",
            "no_terrain", "extrapolated", "current_unknown")
_NUMERIC_ERRORS = (ValueError, ArithmeticError, np.linalg.LinAlgError)
ODOM_HISTORY_S = 2.0
MODE_REFERENCES = ("swing", "stance")
DIRECTIONS = ("stride", "velocity")
STRIKE_PADS = ("any", "heel")
LOOKUPS = ("midfoot", "ankle")
TRACK_POINTS = ("joint", "camera")


def _latency(params: dict[str, Any]) -> float:
    """A mount's delivery latency ``latency_s`` (0 when absent or not a finite number >= 0)."""
    try:
        x = float(params.get("latency_s", 0.0))
    except (TypeError, ValueError):
        return 0.0
    return x if math.isfinite(x) and x >= 0.0 else 0.0


def _check_config(cfg: Any) -> None:
    if isinstance(cfg.every_k, bool) or not isinstance(cfg.every_k, (int, np.integer)) or cfg.every_k < 1:
        raise ConfigError("every_k", cfg.every_k, "an integer >= 1")
    check_range("max_odometry_age_s", cfg.max_odometry_age_s, 0.0)
    check_range("lead_fraction", cfg.lead_fraction, 0.0, 1.0)
    check_range("foot_lead_m", cfg.foot_lead_m, -1.0, 1.0)
    if cfg.camera_ahead_m is not None:
        check_range("camera_ahead_m", cfg.camera_ahead_m, -1.0, 1.0)
    check_range("pause_s", cfg.pause_s, 0.0, low_open=True)
    check_range("start_step_fraction", cfg.start_step_fraction, 0.0, 2.0)
    if cfg.mode_reference not in MODE_REFERENCES:
        raise ConfigError("mode_reference", cfg.mode_reference, list(MODE_REFERENCES))
    check_range("min_speed_m_s", cfg.min_speed_m_s, 0.0)
    check_range("min_heel_off_s", cfg.min_heel_off_s, 0.0, 1.0)
    if isinstance(cfg.max_work_width_px, bool) or not isinstance(cfg.max_work_width_px, (int, np.integer)) \
            or cfg.max_work_width_px < 16:
        raise ConfigError("max_work_width_px", cfg.max_work_width_px, "an integer >= 16")
    if cfg.standing_drop_m is not None:
        check_range("standing_drop_m", cfg.standing_drop_m, -0.5, 0.5)
    if cfg.track_point not in TRACK_POINTS:
        raise ConfigError("track_point", cfg.track_point, list(TRACK_POINTS))
    if cfg.lookup not in LOOKUPS:
        raise ConfigError("lookup", cfg.lookup, list(LOOKUPS))
    if cfg.strike_pads not in STRIKE_PADS:
        raise ConfigError("strike_pads", cfg.strike_pads, list(STRIKE_PADS))
    if cfg.direction not in DIRECTIONS:
        raise ConfigError("direction", cfg.direction, list(DIRECTIONS))


def _finite_array(a: Any, shape: tuple[int, ...]) -> np.ndarray | None:
    """``a`` as a float array of ``shape`` with finite entries, else None."""
    try:
        out = np.asarray(a, dtype=float)
    except (TypeError, ValueError):
        return None
    return out if out.shape == shape and bool(np.all(np.isfinite(out))) else None


def _inv(T: np.ndarray) -> np.ndarray:
    out = np.eye(4)
    out[:3, :3] = T[:3, :3].T
    out[:3, 3] = -T[:3, :3].T @ T[:3, 3]
    return out


def backproject(depth_m: np.ndarray, K: np.ndarray, T_world_cam: np.ndarray, stride: int = 1) -> np.ndarray:
    """World points (N, 3) of the valid (> 0, finite) pixels of a z-depth image, every ``stride``-th
    row and column."""
    d = np.asarray(depth_m, dtype=float)[::stride, ::stride]
    v, u = np.nonzero(np.isfinite(d) & (d > 0))
    z = d[v, u]
    u = u * stride
    v = v * stride
    x = (u - K[0, 2]) * z / K[0, 0]
    y = (v - K[1, 2]) * z / K[1, 1]
    p = np.column_stack([x, y, z])
    return p @ T_world_cam[:3, :3].T + T_world_cam[:3, 3]


def upsample_depth(depth_m: np.ndarray, n: int, shape: tuple[int, int], jump_m: float = 0.05) -> np.ndarray:
    """A z-depth image ray cast at 1/n resolution (K scaled by :func:`scale_intrinsics`) brought
    back to ``shape``: bilinear interpolation of the inverse depth, which is exact on planes
    (1/z is affine in the pixel coordinates of a plane); where a neighbour is invalid or the
    four neighbours' depths span more than ``jump_m`` (an edge), the nearest sample instead."""
    d = np.asarray(depth_m, dtype=np.float32)
    h, w = shape
    hs, ws = d.shape
    # pixel u of the full image is at (u + 0.5) / n - 0.5 in the small one
    y = np.clip((np.arange(h) + 0.5) / n - 0.5, 0.0, hs - 1.0)
    x = np.clip((np.arange(w) + 0.5) / n - 0.5, 0.0, ws - 1.0)
    y0 = np.minimum(np.floor(y).astype(int), hs - 1)
    x0 = np.minimum(np.floor(x).astype(int), ws - 1)
    y1, x1 = np.minimum(y0 + 1, hs - 1), np.minimum(x0 + 1, ws - 1)
    fy, fx = (y - y0).astype(np.float32)[:, None], (x - x0).astype(np.float32)[None, :]
    inv_small = np.zeros_like(d)
    np.divide(1.0, d, out=inv_small, where=d > 0)
    rows0, rows1 = d[y0], d[y1]
    c = (rows0[:, x0], rows0[:, x1], rows1[:, x0], rows1[:, x1])  # 00, 01, 10, 11
    cmax = np.maximum(np.maximum(c[0], c[1]), np.maximum(c[2], c[3]))
    cmin = np.minimum(np.minimum(c[0], c[1]), np.minimum(c[2], c[3]))
    smooth = (cmin > 0) & (cmax - cmin <= jump_m)
    i0, i1 = inv_small[y0], inv_small[y1]
    iv = (i0[:, x0] * (1 - fx) + i0[:, x1] * fx) * (1 - fy) + (i1[:, x0] * (1 - fx) + i1[:, x1] * fx) * fy
    near = d[np.clip(np.rint(y).astype(int), 0, hs - 1)][:, np.clip(np.rint(x).astype(int), 0, ws - 1)]
    out = near.copy()
    np.divide(1.0, iv, out=out, where=smooth)
    return out


def decimate(depth_m: np.ndarray, K: np.ndarray, max_width_px: int) -> tuple[np.ndarray, np.ndarray]:
    """(depth, K) of the image kept at every m-th pixel, m = ceil(width / ``max_width_px``) (the
    pixel at the centre of each m x m block, (m - 1) // 2 in; K exact for those pixels); the
    image itself when it is no wider than ``max_width_px``."""
    w = depth_m.shape[1]
    m = -(-w // max(1, int(max_width_px)))
    if m <= 1:
        return depth_m, K
    off = (m - 1) // 2
    out = np.array(K, dtype=float)
    out[0, 0] /= m
    out[1, 1] /= m
    out[0, 2] = (out[0, 2] - off) / m
    out[1, 2] = (out[1, 2] - off) / m
    return np.ascontiguousarray(depth_m[off::m, off::m]), out


def tracked_point_neutral(calibration: Calibration, sensor_id: str, *, link_origin: bool = False) -> tuple[float, float] | None:
    """Where the mount ``sensor_id`` (``link_origin``: the origin of its parent link) sits in the
    robot description (URDF, loaded with pinocchio) at its neutral configuration (standing
    straight): (how far ahead of the base link (the pelvis) along its x axis (forward), how high
    above the soles (the feet: the parent links of the ``contact`` mounts, their origins
    ``sole_height_m`` above the sole)), m. None when the description or a link cannot be read."""
    try:
        import pinocchio as pin

        model = pin.buildModelFromXML(calibration.robot_urdf)
        data = model.createData()
        pin.framesForwardKinematics(model, data, pin.neutral(model))
        mount = calibration.mount(sensor_id)

        def placement(link: str) -> np.ndarray:
            return np.asarray(data.oMf[model.getFrameId(link, pin.BODY)].homogeneous, dtype=float)

        T_w_point = placement(mount.parent_link) @ (np.eye(4) if link_origin else np.asarray(mount.T_parent_sensor, dtype=float))
        x = float((_inv(placement(calibration.base_link)) @ T_w_point)[0, 3])
        feet = {m.parent_link for m in calibration.mounts_of_kind("contact")}
        sole = min(float(placement(f)[2, 3]) for f in feet) - float(calibration.sole_height_m)
        h = float(T_w_point[2, 3]) - sole
    except Exception:  # no usable description: the caller falls back
        return None
    return (x, h) if math.isfinite(x) and math.isfinite(h) else None


def scale_intrinsics(K: np.ndarray, s: float) -> np.ndarray:
    """K of the image resized by ``s`` (pixel centres at integer coordinates)."""
    out = np.array(K, dtype=float)
    out[0, 0] *= s
    out[1, 1] *= s
    out[0, 2] = (out[0, 2] + 0.5) * s - 0.5
    out[1, 2] = (out[1, 2] + 0.5) * s - 0.5
    return out


class _LocomotionPipeline(ABC):
    """Frame handling, walking information and mode prediction shared by both pipelines; the
    subclasses differ in how a depth frame updates the plane set (:meth:`_update_planes`)."""

    name = ""
    track = "locomotion"

    @dataclass(frozen=True)
    class Config:
        """``rgbd_sensor_id``: camera used ("" = the calibration's first RGB-D mount).
        ``odometry_sensor_id``: odometry used ("" = ``odom_<mount>``, "*" = any). ``every_k``:
        process every k-th frame of the camera. ``max_odometry_age_s``: the latest odometry
        sample older than this (from a frame or heel strike) counts as missing. ``lead_fraction``,
        ``foot_lead_m``, ``camera_ahead_m`` (None: from the calibration, :func:`tracked_point_neutral`),
        ``track_point`` (``"joint"``, ``"camera"``), ``standing_drop_m``, ``strike_pads``
        (``"any"``, ``"heel"``), ``lookup`` (``"midfoot"``, ``"ankle"``), ``min_speed_m_s``,
        ``pause_s``, ``start_step_fraction``: footprints;
        ``mode_reference``: ``"swing"`` or ``"stance"`` (module docstring). ``observed_stride_px``: pixel stride of
        the points whose voxels make the update's scope. ``max_work_width_px``: wider depth
        images are decimated to every m-th pixel, m = ceil(width / max_work_width_px), before
        anything else. ``min_heel_off_s``: heel-strike debounce. ``toe_m``: a level step whose toes
        (this far ahead of the footprint; 0 = off) would be inside a riser goes onto the tread
        above (:meth:`TerrainDescription.tread_above`). ``crease_toe_m``: likewise, a step whose
        toes (this far ahead; 0 = off) would be across a crease goes past it
        (:meth:`TerrainDescription.crease_ahead`). ``direction``: walking
        direction at a strike, ``"stride"`` or ``"velocity"`` (module docstring). ``ahc``,
        ``planes``, ``terrain``, ``footprint``: configs of plane extraction, eq. 23, the terrain
        description, eq. 16-18."""

        rgbd_sensor_id: str = ""
        odometry_sensor_id: str = ""
        every_k: int = 1
        max_odometry_age_s: float = 0.25
        lead_fraction: float = 0.5
        foot_lead_m: float = 0.0
        camera_ahead_m: float | None = None
        track_point: str = "joint"
        standing_drop_m: float | None = 0.03
        mode_reference: str = "swing"
        pause_s: float = 1.2
        start_step_fraction: float = 0.6
        min_speed_m_s: float = 0.05
        min_heel_off_s: float = 0.1
        strike_pads: str = "any"
        lookup: str = "midfoot"
        direction: str = "stride"
        toe_m: float = 0.15
        crease_toe_m: float = 0.06
        max_work_width_px: int = 424
        observed_stride_px: int = 4
        ahc: AhcConfig = field(default_factory=AhcConfig)
        planes: PlaneTrackingConfig = field(default_factory=PlaneTrackingConfig)
        terrain: TerrainConfig = field(default_factory=TerrainConfig)
        footprint: FootprintConfig = field(default_factory=lambda: FootprintConfig(step_estimate="median", n_recent=4))

        def __post_init__(self) -> None:
            _check_config(self)

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
        self._period_s = 1.0 / float(mount.params["rate_hz"]) if mount.params.get("rate_hz") else None
        suffix = self._rgbd_id[len("rgbd_"):] if self._rgbd_id.startswith("rgbd_") else self._rgbd_id
        odo_info = calibration.extra.get("odometry")
        odo_named = odo_info.get("sensor_id") if isinstance(odo_info, dict) and odo_info.get("tracks") == mount.sensor_id \
            else None
        self._odom_id = c.odometry_sensor_id or (odo_named if isinstance(odo_named, str) else f"odom_{suffix}")
        self._cam_latency_s = _latency(mount.params)
        self._contact_latency_s = {m.sensor_id: _latency(m.params) for m in calibration.mounts_of_kind("contact")}
        # the point whose positions measure the steps: the joint the camera turns about (its
        # parent link's origin: the neck for a head camera, the hip for a thigh one) unless the
        # camera sits on the base link, else the camera
        on_joint = c.track_point == "joint" and mount.parent_link != calibration.base_link
        T_cam_track = _inv(np.asarray(mount.T_parent_sensor, float)) if on_joint else np.eye(4)
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
                self._T_body_cam = _inv(np.asarray(om.T_parent_sensor, float)) @ np.asarray(mount.T_parent_sensor, float)
                self._odom_mount = "calibrated"
            else:
                self._odom_mount = "unrelated_link_assumed_camera"
        self._T_body_track = self._T_body_cam @ T_cam_track
        pads_used = ("heel",) if c.strike_pads == "heel" else ("heel", "toe")
        heels = {}
        for m in calibration.mounts_of_kind("contact"):
            parts = m.sensor_id.split("_")
            if len(parts) == 3 and parts[2] in pads_used and parts[1] in ("l", "r"):
                heels[m.sensor_id] = parts[1]
        self._heels = heels or {f"contact_{side}_{pad}": side for side in ("l", "r") for pad in pads_used}
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
            "n_standing_starts", "n_steps_after_start")}
        self._stats.update(rgbd_sensor_id=self._rgbd_id, odometry_sensor_id=self._odom_id,
                           odometry_mount=self._odom_mount, errors=[], camera_ahead_m=self._camera_ahead_m, tracked_point=self._tracked,
                           camera_ahead_known=ahead is not None, lookup_m=self._lookup_m)
        self._reset_map()
        self._ready = True

    def process(self, frame: Frame) -> ModePrediction | None:
        t0 = time.perf_counter()
        if not self._ready:
            raise ExobenchError("process() called before reset()")
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
            raise ExobenchError("finalize() called before reset()")
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
        if T is None or v is None:
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

    def _on_rgbd(self, frame: RgbdFrame, t0: float) -> ModePrediction | None:
        st, c = self._stats, self.config
        st["n_rgbd_frames"] += 1
        if not self._in_order(frame):
            return None
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
            depth = np.where(np.isfinite(depth) & (depth > 0), depth, 0.0).astype(np.float32)
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


class TerrainReconstructionPipeline(_LocomotionPipeline):
    """The paper's pipeline: TSDF, ray-cast smoothed depth, AHC, plane set (eq. 23), terrain,
    footprint (eq. 16-18), mode (module docstring)."""

    name = "terrain-recon"

    @dataclass(frozen=True)
    class Config(_LocomotionPipeline.Config):
        """``raycast_downsample``: I_D^s is ray cast at 1/n of the input resolution (K scaled)
        and brought back to it by :func:`upsample_depth` (``upsample_jump_m``), so plane
        extraction and its pixel thresholds see the input resolution [A: 2: the ray cast and its
        refinement cost about a quarter; the planes stay those of the full-resolution cast on
        the quick suite]."""

        tsdf: TsdfConfig = field(default_factory=TsdfConfig)
        raycast_downsample: int = 2
        upsample_jump_m: float = 0.05

        def __post_init__(self) -> None:
            _check_config(self)
            n = self.raycast_downsample
            if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
                raise ConfigError("raycast_downsample", n, "an integer >= 1")
            check_range("upsample_jump_m", self.upsample_jump_m, 0.0)

    def _reset_map(self) -> None:
        self._tsdf = Tsdf(self.config.tsdf)

    def _update_planes(self, depth_m: np.ndarray, K: np.ndarray, T_odom_cam: np.ndarray) -> int:
        h, w = depth_m.shape
        n = self.config.raycast_downsample
        self._tsdf.integrate(depth_m, K, T_odom_cam)
        Ks = scale_intrinsics(K, 1.0 / n)
        smooth = np.asarray(self._tsdf.raycast_depth(Ks, T_odom_cam, max(1, w // n), max(1, h // n)), dtype=np.float32)
        smooth = np.where(np.isfinite(smooth) & (smooth > 0), smooth, 0.0).astype(np.float32)
        if n > 1:
            smooth = upsample_depth(smooth, n, (h, w), self.config.upsample_jump_m)
        detected = extract_planes(smooth, K, T_odom_cam, self.config.ahc, self.config.planes.cell_m) \
            if np.any(smooth > 0) else []
        stride = max(1, self.config.observed_stride_px)
        observed = voxel_keys(backproject(smooth, K, T_odom_cam, stride), self.config.planes.cell_m)
        self._plane_set.update(list(detected), observed)
        return len(detected)


class SingleFramePipeline(_LocomotionPipeline):
    """Ablation baseline: planes from the current raw depth frame only (AHC, no TSDF), a fresh
    plane set each frame; same footprint and mode logic (module docstring)."""

    name = "single-frame"

    def _reset_map(self) -> None:
        """Nothing to forget: this baseline keeps no map between frames."""

    def _update_planes(self, depth_m: np.ndarray, K: np.ndarray, T_odom_cam: np.ndarray) -> int:
        detected = list(extract_planes(depth_m, K, T_odom_cam, self.config.ahc, self.config.planes.cell_m))
        if detected:  # a frame without planes keeps the last plane set
            self._plane_set = PlaneSet(self.config.planes)
            self._plane_set.update(detected)
        return len(detected)
