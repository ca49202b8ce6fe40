"""The next step's footprint and locomotion mode, from the heel strikes and the terrain now.

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
:class:`StepPredictor` keeps these heights per strike between frames.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np

from exobench.perception.terrain.footprint import HeelStrike, heading_frame, predict_footprint
from exobench.perception.terrain.terrain_description import TerrainDescription
from exobench.perception.terrain.terrain_types import plane_height_at

from .config import LocomotionConfig

__all__ = ["StepPredictor"]


class StepPredictor:
    """Footprint and mode of the next step (module docstring), with the terrain heights seen
    under recent footprints kept by strike index.

    Args:
        config: the pipeline's config (footprint, direction, lookup, mode reference, ...).
        stats: the pipeline's stats; the ``n_*`` counters of the prediction are incremented here.
        camera_ahead_m: the tracked point's offset ahead of the pelvis, m.
        lookup_m: how far ahead of the ankle the terrain is looked up, m.
        standing_h: the tracked point's height above the soles standing straight, m (None: unknown).
    """

    def __init__(self, config: LocomotionConfig, stats: dict[str, Any], camera_ahead_m: float, lookup_m: float,
                 standing_h: float | None) -> None:
        self.config = config
        self._stats = stats
        self._camera_ahead_m = camera_ahead_m
        self._lookup_m = lookup_m
        self._standing_h = standing_h
        self._last_mode = ""
        self._foot_z: dict[int, float] = {}  # terrain z measured under the footprint of strike j (0-based)
        self._foot_cls: dict[int, str] = {}  # class of the plane of that measurement
        self._next_z: dict[int, float] = {}  # terrain z predicted under it before strike j
        self._next_cls: dict[int, str] = {}  # class of that plane
        self._body_h: dict[int, float] = {}  # tracked body's height above that terrain at strike j

    def predict(self, strikes: list[HeelStrike], terrain: Callable[[], TerrainDescription], stamp_s: float = math.nan,
                p_now: np.ndarray | None = None) -> tuple[str, np.ndarray, str]:
        """(mode, predicted footprint (x, y, terrain z or NaN), reason) from the heel strikes so
        far (``strikes``, oldest first), the terrain now (``terrain()``, called only when needed) at
        time ``stamp_s``, the tracked body then at ``p_now`` (None: unknown)."""
        c = self.config
        all_strikes = strikes
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
        n = len(all_strikes)
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
        desc = terrain()
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
            remembered = float(all_strikes[j_ref].p_world[2]) - float(np.median(list(self._body_h.values())))
            self._stats["n_height_from_odometry"] += 1
        ref_cls = self._foot_cls.get(j_ref, self._next_cls.get(j_ref))
        if remembered is None:
            remembered = self._next_z.get(j_ref)  # predicted under it before it struck
        if remembered is None and self._standing_h is not None and c.standing_drop_m is not None:
            # nothing measured yet (the first steps of a head camera that has not seen its feet'
            # ground): the body's height at the strike minus its height standing, less the drop
            # of walking
            remembered = float(all_strikes[j_ref].p_world[2]) - (self._standing_h - c.standing_drop_m)
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

    def _foot_xy(self, strike: HeelStrike, fwd: np.ndarray, H: np.ndarray) -> np.ndarray:
        """Footprint of the foot that struck at ``strike`` without its ``lead_fraction`` part:
        ``foot_lead_m`` minus the tracked point's offset ahead of the pelvis, ahead of the tracked body,
        plus the foot's sideways offset."""
        c = self.config
        off = np.asarray(c.footprint.offset_l_m if strike.side == "l" else c.footprint.offset_r_m, dtype=float)
        return strike.p_world + (c.foot_lead_m - self._camera_ahead_m) * fwd + H @ off
