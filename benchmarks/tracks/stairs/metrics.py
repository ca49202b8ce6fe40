"""Scoring a staircase estimate against the exact ground truth of an episode.

Definitions follow the staircase paper (seeds/004, Sec. V and Fig. 5):

- ``alpha_deg_S{i}``: angle between the true and the estimated normal of surface S_i, taken as
  lines (a normal and its opposite describe the same plane), deg, in [0, 90].
- ``d_m_S{i}``: signed distance of the estimated centroid, mapped to the world with
  ``truth.T_world_estimator``, from the true plane; positive on the side the true normal points
  to (above a tread, in front of a riser), m.
- ``touchdown_error_m`` (the paper's e): elevation of the estimated S2 plane at the true
  touch-down point's (x, y) minus the elevation of the true S2 there, m (negative: estimated
  tread too low).
- ``riser_error_pct`` / ``tread_error_pct``: |estimate - true| / true * 100 against the
  built staircase's riser_m / tread_m (``truth.scene.params``, not the scenario record).
- ``s2_reliable_s``: time S2 became reliable after lift-off, s; ``s2_remaining_travel_m``: length
  of the foot path still to go then, up to touch-down, m.
- ``assignment_accuracy``: among the readings the estimator used (``surface_index != -2``), the
  fraction whose final surface index equals the true surface id of the ray (a discarded reading,
  -1, counts as correct only when its ray hit no listed surface). ``assigned_accuracy`` is the
  same over the readings kept in a surface only.
- ``time_per_point_us``: median of ``compute_time_s``, microseconds.
- ``failed`` / ``failed_reason``: S2 never became reliable, or the pipeline raised.

Missing values are NaN here; the result store writes them as JSON null.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from exobench.core.episode import Episode
from exobench.core.estimates import StaircaseEstimate
from exobench.core.transforms import angle_between_deg, transform_points
from exobench.core.truth import PlanarSurface

N_SURFACES = 5  # S0..S4, as in the paper's tables
NAN = float("nan")


def surface_metric_keys() -> list[str]:
    keys = []
    for i in range(N_SURFACES):
        keys += [f"alpha_deg_S{i}", f"d_m_S{i}", f"reliable_S{i}"]
    return keys


def plane_elevation(normal: np.ndarray, point: np.ndarray, x: float, y: float) -> float:
    """Height z of the plane (normal, point) above (x, y); NaN for a near-vertical plane."""
    n = np.asarray(normal, dtype=float)
    if abs(n[2]) < 0.5:
        return NAN
    return float(point[2] - (n[0] * (x - point[0]) + n[1] * (y - point[1])) / n[2])


def path_length(track: np.ndarray, t0: float, t1: float) -> float:
    """Length of the path ``track`` (rows t, x, y, z) between times t0 and t1, m."""
    track = np.asarray(track, dtype=float)
    if len(track) < 2 or not t1 > t0:
        return 0.0 if len(track) else NAN
    t = track[:, 0]
    inner = track[(t > t0) & (t < t1), 1:4]
    ends = [np.array([np.interp(tt, t, track[:, k]) for k in (1, 2, 3)]) for tt in (t0, t1)]
    pts = np.vstack([ends[0], inner, ends[1]])
    return float(np.linalg.norm(np.diff(pts, axis=0), axis=1).sum())


def _surface(episode: Episode, sid: int) -> PlanarSurface | None:
    try:
        return episode.truth.scene.surface(sid)
    except KeyError:
        return None


def _plane_world(episode: Episode, normal: np.ndarray, centroid: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    T = np.asarray(episode.truth.T_world_estimator, dtype=float)
    return T[:3, :3] @ np.asarray(normal, dtype=float), transform_points(T, np.asarray(centroid, dtype=float))


def _finite(*arrays: Any) -> bool:
    return all(np.all(np.isfinite(np.asarray(a, dtype=float))) for a in arrays)


def _true_surface_ids(episode: Episode) -> dict[tuple[float, str], int]:
    return {(round(float(t.stamp_s), 9), t.sensor_id): int(t.surface_id) for t in episode.truth.stairs.tof}


def _stats(stats: dict[str, Any]) -> dict[str, float]:
    out: dict[str, float] = {}
    for k, v in stats.items():
        if k == "config":  # the pipeline config is recorded apart
            continue
        if isinstance(v, dict):
            out.update({f"stat_{k}_{kk}": vv for kk, vv in v.items() if isinstance(vv, (int, float))})
        elif isinstance(v, (bool, int, float)):
            out[f"stat_{k}"] = v
    return out


def _pct_error(est: float, true: float) -> float:
    if not (math.isfinite(est) and math.isfinite(true) and true != 0):
        return NAN
    return abs(est - true) / abs(true) * 100.0


def empty_metrics(episode: Episode | None) -> dict[str, Any]:
    """The metric schema with every value missing (``episode`` None: the simulation failed)."""
    m: dict[str, Any] = {k: NAN for k in surface_metric_keys()}
    m.update({f"reliable_S{i}": False for i in range(N_SURFACES)})
    for k in (
        "riser_est_m", "tread_est_m", "riser_error_pct", "tread_error_pct", "touchdown_error_m",
        "s2_reliable_s", "s2_remaining_travel_m", "assignment_accuracy", "assigned_accuracy",
        "discarded_fraction", "time_per_point_us",
    ):
        m[k] = NAN
    m.update(n_points=0, n_assigned=0, n_tof=0 if episode is None or episode.truth.stairs is None else len(episode.truth.stairs.tof), failed=True, failed_reason="")
    return m


def score_staircase(episode: Episode, est: StaircaseEstimate) -> dict[str, Any]:
    """Every metric of the module docstring for one estimate (never raises on bad values)."""
    m = empty_metrics(episode)
    truth, climb = episode.truth, episode.truth.stairs
    if climb is None:
        m["failed_reason"] = "the episode has no climbing-step truth (truth.stairs)"
        return m
    for i in range(N_SURFACES):
        s, p = _surface(episode, i), est.plane(i)
        if s is None or p is None or not _finite(p.normal, p.centroid) or not np.linalg.norm(p.normal) > 0:
            continue
        n_w, c_w = _plane_world(episode, p.normal, p.centroid)
        m[f"alpha_deg_S{i}"] = angle_between_deg(s.normal_w, n_w)
        m[f"d_m_S{i}"] = float(s.signed_distance(c_w))
        m[f"reliable_S{i}"] = bool(p.reliable)

    # the geometry that was built (truth), never the scenario record, which a session may misstate
    riser_true = float(truth.scene.params.get("riser_m", NAN))
    tread_true = float(truth.scene.params.get("tread_m", NAN))
    m["riser_est_m"], m["tread_est_m"] = float(est.riser_height_m), float(est.tread_depth_m)
    m["riser_error_pct"] = _pct_error(m["riser_est_m"], riser_true)
    m["tread_error_pct"] = _pct_error(m["tread_est_m"], tread_true)

    s2_true, s2 = _surface(episode, 2), est.plane(2)
    if s2_true is not None and s2 is not None and _finite(s2.normal, s2.centroid):
        x, y = float(climb.touchdown_w[0]), float(climb.touchdown_w[1])
        n_w, c_w = _plane_world(episode, s2.normal, s2.centroid)
        m["touchdown_error_m"] = plane_elevation(n_w, c_w, x, y) - plane_elevation(s2_true.normal_w, s2_true.point_w, x, y)

    track = np.asarray(climb.foot_track_w, dtype=float).reshape(-1, 4)
    liftoff = float(truth.events.get("liftoff_s", track[0, 0] if len(track) else 0.0))
    touchdown = float(truth.events.get("touchdown_s", track[-1, 0] if len(track) else NAN))
    if s2 is None:
        m["failed_reason"] = "no S2 estimate"
    elif not s2.reliable or s2.reliable_stamp_s is None:
        m["failed_reason"] = "S2 never became reliable"
    else:
        t_rel = float(s2.reliable_stamp_s)
        m["failed"] = False
        m["s2_reliable_s"] = t_rel - liftoff
        m["s2_remaining_travel_m"] = path_length(track, t_rel, touchdown) if t_rel < touchdown else 0.0

    true_ids = _true_surface_ids(episode)
    used = [a for a in est.assignments if a.surface_index != -2]
    correct = [true_ids.get((round(float(a.stamp_s), 9), a.sensor_id)) == a.surface_index for a in used]
    kept = [c for a, c in zip(used, correct, strict=True) if a.surface_index >= 0]
    m["n_points"], m["n_assigned"] = len(used), len(kept)
    if used:
        m["assignment_accuracy"] = float(np.mean(correct))
        m["discarded_fraction"] = float(np.mean([a.surface_index == -1 for a in used]))
    if kept:
        m["assigned_accuracy"] = float(np.mean(kept))
    times = np.asarray(est.compute_time_s, dtype=float)
    if times.size:
        m["time_per_point_us"] = float(np.median(times) * 1e6)
    m.update(_stats(est.stats))
    return m


def failure_metrics(episode: Episode | None, reason: str) -> dict[str, Any]:
    """Metrics of a pipeline that raised or returned something that is not an estimate."""
    m = empty_metrics(episode)
    m["failed_reason"] = reason
    return m
