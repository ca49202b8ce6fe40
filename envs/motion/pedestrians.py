"""Pedestrians of the locomotion track: people walking past the walker on straight lines at
constant speed, passing it at a seeded time and drifting across the lane (so they cross the
camera view); their height is the terrain height under them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class PedestrianPath:
    """A straight walk: position (x, y) at time t = p0 + v t; height from the terrain."""

    p0_xy: np.ndarray
    v_xy: np.ndarray
    height_m: float

    def xy(self, t: np.ndarray) -> np.ndarray:
        return self.p0_xy[None, :] + np.asarray(t, dtype=float)[:, None] * self.v_xy[None, :]

    @property
    def yaw(self) -> float:
        return float(np.arctan2(self.v_xy[1], self.v_xy[0]))


def pedestrian_paths(n: int, walker_xy: object, heading: object, duration_s: float,
                     rng: np.random.Generator) -> list[PedestrianPath]:  # fmt: skip
    """``n`` people passing the walker: at a seeded time t_c a person is 1.2-2.5 m ahead of the
    walker, walking towards it or away from it at 0.8-1.4 m/s along its heading and drifting
    across the lane (lateral speed 0.15-0.35 m/s), so that it crosses the camera view."""
    out = []
    for _ in range(n):
        tc = float(rng.uniform(0.2, 0.8) * duration_s)
        ahead = float(rng.uniform(1.2, 2.5))
        speed = float(rng.uniform(0.8, 1.4)) * (1.0 if rng.random() < 0.5 else -1.0)
        lateral = float(rng.uniform(0.15, 0.35)) * (1.0 if rng.random() < 0.5 else -1.0)
        height = float(rng.uniform(1.6, 1.9))
        c = np.asarray(walker_xy(tc), dtype=float)  # type: ignore[operator]
        psi = float(heading(tc))  # type: ignore[operator]
        x, y = np.array([np.cos(psi), np.sin(psi)]), np.array([-np.sin(psi), np.cos(psi)])
        v = speed * x + lateral * y
        pc = c + ahead * x
        out.append(PedestrianPath(pc - tc * v, v, height))
    return out
