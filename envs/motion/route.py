"""Routes of the walker: what to walk (a polyline of waypoints) and how (step length, timing,
stair mode, turns, clearance), validated on construction, and the polyline geometry the walk
planner follows (arc lengths, windowed projection, sharp corners).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from exobench.core import ConfigError, check_int, check_range

STAIR_MODES = ("step-over", "step-to")


@dataclass(frozen=True)
class Route:
    """Where and how to walk.

    Attributes:
        waypoints_xy: polyline (x, y) the body follows, m; it starts at the first point with the
            feet beside it, facing the second (or ``start_yaw_deg``).
        step_length_m: nominal step length on level ground, m (the foot lands this far ahead of
            the other). swing_s / double_support_s: duration of a swing / of the pause after it, s.
        stairs: ``"step-over"`` or ``"step-to"``. max_turn_deg: heading change per step, deg.
        still_s: standing still at the start and at the end, s. clearance_m: toe clearance, m.
        start_yaw_deg: initial heading, deg (default: towards the second waypoint).
        start_lean_deg: forward trunk lean while standing at the start, deg (0: upright; the
            walker takes up its walking lean during the first step).
        end_yaw_deg: heading turned to on the spot at the end, deg (default: none).
        turn_in_place_deg: waypoints where the route turns by more than this are walked to and
            turned at on the spot, deg. max_steps: steps allowed (GaitError beyond).
        approach_steps: over how many steps before a transition (stairs, a ramp's start or end)
            the walker regulates its step length so that the transition step lands where it
            should (see :func:`exobench.envs.motion.footholds.approach_step`); 0 keeps the nominal step up to the transition.
    """

    waypoints_xy: tuple[tuple[float, float], ...]
    step_length_m: float = 0.35
    swing_s: float = 0.8
    double_support_s: float = 0.2
    stairs: str = "step-over"
    max_turn_deg: float = 25.0
    still_s: float = 0.3
    clearance_m: float = 0.04
    start_yaw_deg: float | None = None
    start_lean_deg: float = 0.0
    max_steps: int = 200
    end_yaw_deg: float | None = None
    turn_in_place_deg: float = 45.0
    approach_steps: int = 0

    def __post_init__(self) -> None:
        pts = np.asarray(self.waypoints_xy, dtype=float)
        if pts.ndim != 2 or pts.shape[1] != 2 or len(pts) < 2 or not np.all(np.isfinite(pts)):
            raise ConfigError("route.waypoints_xy", self.waypoints_xy, "at least two finite (x, y) points")
        if np.any(np.linalg.norm(np.diff(pts, axis=0), axis=1) < 1e-6):
            raise ConfigError("route.waypoints_xy", self.waypoints_xy, "distinct consecutive points")
        check_range("route.step_length_m", self.step_length_m, 0.1, 0.8)
        check_range("route.swing_s", self.swing_s, 0.3, 5.0)
        check_range("route.double_support_s", self.double_support_s, 0.0, 5.0)
        if self.stairs not in STAIR_MODES:
            raise ConfigError("route.stairs", self.stairs, " or ".join(STAIR_MODES))
        check_range("route.max_turn_deg", self.max_turn_deg, 0.0, 60.0)
        check_range("route.still_s", self.still_s, 0.0, 10.0)
        check_range("route.clearance_m", self.clearance_m, 0.0, 0.2)
        if self.start_yaw_deg is not None:
            check_range("route.start_yaw_deg", self.start_yaw_deg, -360.0, 360.0)
        check_range("route.start_lean_deg", self.start_lean_deg, -5.0, 10.0)
        object.__setattr__(self, "max_steps", check_int("route.max_steps", self.max_steps, 1, 10000))
        if self.end_yaw_deg is not None:
            check_range("route.end_yaw_deg", self.end_yaw_deg, -360.0, 360.0)
        check_range("route.turn_in_place_deg", self.turn_in_place_deg, 1.0, 180.0)
        object.__setattr__(self, "approach_steps", check_int("route.approach_steps", self.approach_steps, 0, 6))


class Polyline:
    """The route's polyline: arc lengths, projections within a window, points, sharp corners."""

    def __init__(self, pts: np.ndarray) -> None:
        self.p = pts
        self.seg = np.diff(pts, axis=0)
        self.len = np.linalg.norm(self.seg, axis=1)
        self.cum = np.concatenate([[0.0], np.cumsum(self.len)])
        self.total = float(self.cum[-1])

    def project(self, q: np.ndarray, lo: float = 0.0, hi: float = np.inf) -> float:
        """Arc length of the point of the polyline between arc lengths ``lo`` and ``hi`` nearest to ``q``."""
        lo, hi = max(float(lo), 0.0), min(float(hi), self.total)
        hi = max(hi, lo)
        best, best_d = lo, np.inf
        for i in range(len(self.seg)):
            a, b = float(self.cum[i]), float(self.cum[i + 1])
            if b < lo - 1e-12 or a > hi + 1e-12:
                continue
            u0, u1 = (max(lo, a) - a) / self.len[i], (min(hi, b) - a) / self.len[i]
            u = float(np.clip((q - self.p[i]) @ self.seg[i] / self.len[i] ** 2, u0, u1))
            d = float(np.linalg.norm(self.p[i] + u * self.seg[i] - q))
            if d < best_d:
                best, best_d = a + u * float(self.len[i]), d
        return best

    def point(self, s: float, seg: int | None = None) -> np.ndarray:
        """Point at arc length ``s``; beyond the end the last segment is extended. With ``seg``,
        the point on that segment's line (extended beyond its ends)."""
        s = max(float(s), 0.0)
        i = int(np.clip(np.searchsorted(self.cum, s, side="right") - 1, 0, len(self.seg) - 1)) if seg is None else seg
        return self.p[i] + (s - self.cum[i]) / self.len[i] * self.seg[i]

    def stops(self, min_turn_rad: float) -> list[tuple[float, int]]:
        """(arc length, incoming segment) of every vertex turning by more than ``min_turn_rad``, and of the end."""
        out = []
        for j in range(1, len(self.p) - 1):
            a0 = np.arctan2(self.seg[j - 1][1], self.seg[j - 1][0])
            a1 = np.arctan2(self.seg[j][1], self.seg[j][0])
            if abs(wrap_angle(float(a1 - a0))) > min_turn_rad:
                out.append((float(self.cum[j]), j - 1))
        out.append((self.total, len(self.seg) - 1))
        return out


def wrap_angle(a: float) -> float:
    """``a`` wrapped into [-pi, pi), rad."""
    return float((a + np.pi) % (2.0 * np.pi) - np.pi)
