"""Data of the side view of one stairs episode, like Fig. 4 of the staircase paper.

The view plane is vertical and runs up the staircase: ``s`` is the horizontal distance along
the staircase's ascending direction (from the first riser's plane), ``z`` the world height.
The report draws these arrays; keeping them apart lets it be regenerated from the run folder.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from exobench.core.episode import Episode
from exobench.core.estimates import StaircaseEstimate
from exobench.core.transforms import transform_points

S_RANGE_M = (-0.8, 1.0)  # side-view extent along the staircase around the first riser
WALKABLE_OR_RISER = ("ground", "tread", "riser", "landing")


def _view_axes(episode: Episode) -> tuple[np.ndarray, np.ndarray]:
    """Origin and ascending horizontal unit direction of the side view."""
    scene = episode.truth.scene
    risers = [s for s in scene.surfaces if s.kind == "riser"]
    if not risers:
        return np.zeros(3), np.array([1.0, 0.0, 0.0])
    first = min(risers, key=lambda s: s.surface_id)
    u = -np.array([first.normal_w[0], first.normal_w[1], 0.0])  # risers face the walker
    return np.asarray(first.point_w, dtype=float), u / np.linalg.norm(u)


def _sz(points_w: np.ndarray, o: np.ndarray, u: np.ndarray) -> np.ndarray:
    p = np.asarray(points_w, dtype=float).reshape(-1, 3)
    return np.column_stack([(p - o) @ u, p[:, 2]])


def _clip_s(seg: np.ndarray) -> np.ndarray | None:
    """Clip a segment ((s0, z0), (s1, z1)) to S_RANGE_M; None when nothing is left."""
    (s0, z0), (s1, z1) = seg
    lo, hi = S_RANGE_M
    if abs(s1 - s0) < 1e-12:
        return seg if lo <= s0 <= hi else None
    t = sorted(((lo - s0) / (s1 - s0), (hi - s0) / (s1 - s0)))
    t0, t1 = max(0.0, t[0]), min(1.0, t[1])
    if t0 >= t1:
        return None
    a, b = np.array([s0, z0]), np.array([s1, z1])
    return np.array([a + t0 * (b - a), a + t1 * (b - a)])


def _extreme_pair(pts: np.ndarray) -> np.ndarray:
    d = np.linalg.norm(pts[:, None, :] - pts[None, :, :], axis=2)
    i, j = np.unravel_index(int(np.argmax(d)), d.shape)
    return np.array([pts[i], pts[j]])


def true_profile(episode: Episode, o: np.ndarray, u: np.ndarray) -> np.ndarray:
    """Segments (K, 2, 2) of the true staircase profile in (s, z)."""
    segs = []
    for s in episode.truth.scene.surfaces:
        if s.kind not in WALKABLE_OR_RISER or len(s.polygon_w) < 2:
            continue
        seg = _clip_s(_extreme_pair(_sz(s.polygon_w, o, u)))
        if seg is not None:
            segs.append(seg)
    return np.array(segs).reshape(-1, 2, 2)


def estimated_profile(
    episode: Episode, est: StaircaseEstimate, o: np.ndarray, u: np.ndarray, points_sz: np.ndarray, labels: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Segments (M, 2, 2) of the estimated planes cut by the view plane through their centroids."""
    T = np.asarray(episode.truth.T_world_estimator, dtype=float)
    segs, idx = [], []
    for p in est.planes:
        if not (np.all(np.isfinite(p.normal)) and np.all(np.isfinite(p.centroid))):
            continue
        n_w = T[:3, :3] @ np.asarray(p.normal, dtype=float)
        c_sz = _sz(transform_points(T, p.centroid), o, u)[0]
        n2 = np.array([n_w @ u, n_w[2]])
        if np.linalg.norm(n2) < 0.3:  # plane nearly parallel to the view plane: no clean cut
            continue
        d2 = np.array([-n2[1], n2[0]]) / np.linalg.norm(n2)
        mine = points_sz[labels == p.index]
        proj = (mine - c_sz) @ d2 if len(mine) else np.array([-0.1, 0.1])
        lo, hi = min(float(proj.min()), -0.02), max(float(proj.max()), 0.02)
        segs.append(np.array([c_sz + lo * d2, c_sz + hi * d2]))
        idx.append(p.index)
    return np.array(segs).reshape(-1, 2, 2), np.array(idx, dtype=int)


def side_view_data(episode: Episode, estimates: dict[str, Any]) -> dict[str, np.ndarray]:
    """Arrays for the report's side view (see module docstring); one block per pipeline."""
    o, u = _view_axes(episode)
    track = np.asarray(episode.truth.foot_track_w, dtype=float).reshape(-1, 4)
    T = np.asarray(episode.truth.T_world_estimator, dtype=float)
    out: dict[str, np.ndarray] = {
        "true_segments": true_profile(episode, o, u),
        "foot_sz": _sz(track[:, 1:4], o, u),
        "pipelines": np.array(sorted(estimates), dtype=str),
    }
    for name, est in sorted(estimates.items()):
        if not isinstance(est, StaircaseEstimate):
            continue
        used = [a for a in est.assignments if a.surface_index != -2 and np.all(np.isfinite(a.point))]
        pts_w = transform_points(T, np.array([a.point for a in used]).reshape(-1, 3))
        pts_sz = _sz(pts_w, o, u)
        labels = np.array([a.surface_index for a in used], dtype=int)
        segs, idx = estimated_profile(episode, est, o, u, pts_sz, labels)
        rel = np.full(2, np.nan)
        s2 = est.plane(2)
        if s2 is not None and s2.reliable_stamp_s is not None and len(track):
            t = float(s2.reliable_stamp_s)
            rel = _sz(np.array([np.interp(t, track[:, 0], track[:, k]) for k in (1, 2, 3)]), o, u)[0]
        out[f"{name}__points_sz"] = pts_sz
        out[f"{name}__labels"] = labels
        out[f"{name}__plane_segments"] = segs
        out[f"{name}__plane_index"] = idx
        out[f"{name}__s2_reliable_sz"] = rel
    return out
