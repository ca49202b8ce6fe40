"""Scans of a room with solid boxes, cast by hand (slab ray-box intersection): change
detection tests know which points lie on which box.

Sensors look horizontally (a pinhole fan of ``n_u x n_v`` rays, 90 x 70 degrees) in the
directions given; every ray hits the room's inside or the nearest box first.
"""

from __future__ import annotations

import math

import numpy as np

ROOM = np.array([4.0, 4.0, 2.5])


def _box_entry(o, d, lo, hi):
    with np.errstate(divide="ignore", invalid="ignore"):
        t1 = (lo - o) / d
        t2 = (hi - o) / d
    tmin = np.nanmax(np.minimum(t1, t2), axis=1)
    tmax = np.nanmin(np.maximum(t1, t2), axis=1)
    return np.where((tmax >= tmin) & (tmin > 0), tmin, np.inf)


def cast(origin, boxes, yaw_rad, pitch_rad=-0.35, n_u=80, n_v=60):
    """Points (n, 3) seen from ``origin`` looking at ``yaw_rad`` (pitched down ``pitch_rad``)."""
    u = np.tan(np.radians(45)) * np.linspace(-1, 1, n_u)
    v = np.tan(np.radians(35)) * np.linspace(-1, 1, n_v)
    uu, vv = np.meshgrid(u, v)
    # camera frame: x forward, y left, z up
    rays = np.stack([np.ones_like(uu), -uu, -vv], -1).reshape(-1, 3)
    cp, sp = math.cos(pitch_rad), math.sin(pitch_rad)
    rays = rays @ np.array([[cp, 0, -sp], [0, 1, 0], [sp, 0, cp]]).T
    cy, sy = math.cos(yaw_rad), math.sin(yaw_rad)
    d = rays @ np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]]).T
    o = np.asarray(origin, float)
    with np.errstate(divide="ignore", invalid="ignore"):
        t_room = np.min(np.where(d > 0, (ROOM - o) / d, np.where(d < 0, -o / d, np.inf)), axis=1)
    t = t_room
    for lo, hi in boxes:
        t = np.minimum(t, _box_entry(o, d, np.asarray(lo, float), np.asarray(hi, float)))
    return o + t[:, None] * d


def on_box(points, box, tol=0.01):
    """Whether points lie on the surface of ``box`` (within ``tol``)."""
    lo, hi = (np.asarray(b, float) for b in box)
    inside = np.all((points >= lo - tol) & (points <= hi + tol), axis=1)
    return inside
