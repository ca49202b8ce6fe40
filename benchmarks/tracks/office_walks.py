"""Office walks as the LiDAR tracks (lidar-filter, odometry, loop-closure) share them.

- Scenario parameters: :func:`office_params` (the :data:`exobench.envs.sim.scenarios.office.PARAMS` table
  as :class:`ParamInfo` rows, plus a track's own extra rows), :func:`validate_office_scenario`
  (typed values; the track's extra keys validated by the same ``ParamSpec`` rules),
  :func:`simulate_office_episode` (drops the extra keys, runs ``simulate_office``).
- Ground truth per LiDAR point: :func:`lidar_pairs` (scans with their ``LidarTruth``),
  :func:`point_classes` (genuine / glass / ghost codes and whether the true surface is ground),
  :func:`points_world` (each measured point in the world: the true ray origin and direction of
  its firing, at the measured range, so motion distortion is shown as the sensor saw it),
  :func:`sweep_start_poses`.

Their rerun views are in :mod:`.office_recording`, the scoring of a LiDAR trajectory in
:mod:`.lidar_trajectory`.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from exobench.core.episode import Episode, EpisodeStream
from exobench.core.errors import UnknownNameError
from exobench.core.frames import LidarScan

from .spec import ParamInfo, param_infos

GROUND_KINDS = ("ground", "tread", "landing", "ramp")  # surfaces a walker stands on (SceneTruth kinds)
# class of a point: ReturnKind GENUINE/THROUGH_GLASS, GLASS, GHOST, NAN
GENUINE, GLASS, GHOST, NAN_POINT = 0, 1, 2, 3


def office_params(extra: Mapping[str, Any] | None = None) -> list[ParamInfo]:
    """Rows of the office scenario table, then ``extra`` (name -> ``ParamSpec``) of a track."""
    from exobench.envs.sim.scenarios.office import PARAMS

    return param_infos({**PARAMS, **dict(extra or {})})


def validate_office_scenario(values: Mapping[str, Any], extra: Mapping[str, Any] | None = None) -> dict[str, Any]:
    """Typed office scenario values plus the track's ``extra`` keys (defaults filled in).

    Unknown names raise :class:`UnknownNameError`; bad values ``ConfigError``.
    """
    from exobench.envs.sim.scenarios.office import PARAMS, OfficeScenario
    from exobench.models.world_params import ParamSpec

    extra = dict(extra or {})
    own = {k: v for k, v in values.items() if k in extra}
    rest = {k: v for k, v in values.items() if k not in extra}
    for k in rest:
        if k not in PARAMS:
            raise UnknownNameError("office scenario parameter", k, [*PARAMS, *extra])
    out = OfficeScenario.from_dict(rest).as_dict()
    for name, spec in extra.items():
        out[name] = _check_extra(name, own.get(name, spec.default), spec) if isinstance(spec, ParamSpec) else own.get(name)
    return out


def _check_extra(name: str, raw: Any, spec: Any) -> Any:
    from exobench.core.errors import ConfigError, check_range
    from exobench.core.pipeline import coerce_like

    value = coerce_like(name, raw, spec.default)
    if spec.choices and value not in spec.choices:
        raise ConfigError(name, raw, " or ".join(repr(c) for c in spec.choices))
    if spec.low is not None and spec.high is not None and not isinstance(value, (str, bool)):
        check_range(name, value, spec.low, spec.high, low_open=spec.low_open)
    return value


def simulate_office_episode(scenario: Mapping[str, Any], seed: int, extra: Mapping[str, Any] | None = None) -> Episode:
    """``simulate_office`` on the office part of a validated scenario (``extra`` keys dropped)."""
    from exobench.envs.sim.scenarios.office import OfficeScenario, simulate_office

    office = {k: v for k, v in scenario.items() if k not in dict(extra or {})}
    return simulate_office(OfficeScenario.from_dict(office), seed)


def stream_office_episode(
    scenario: Mapping[str, Any], seed: int, extra: Mapping[str, Any] | None = None, *, lidar_truth: bool = True
) -> EpisodeStream:
    """:func:`simulate_office_episode` as a stream (``stream_office``), without the per-point
    LiDAR truth unless ``lidar_truth``."""
    from exobench.envs.sim.scenarios.office import OfficeScenario, stream_office

    office = {k: v for k, v in scenario.items() if k not in dict(extra or {})}
    return stream_office(OfficeScenario.from_dict(office), seed, lidar_truth=lidar_truth)


# ------------------------------------------------------------------------- truth per point


def lidar_pairs(episode: Episode, sensor_id: str | None = None) -> list[tuple[LidarScan, Any]]:
    """(scan, LidarTruth) in time order, matched by sensor and stamp (truth is per scan; scans of
    one stamp, a duplicated scan, take that stamp's truths in order)."""
    scans = [f for f in episode.frames if isinstance(f, LidarScan) and (sensor_id is None or f.sensor_id == sensor_id)]
    truths: dict[tuple[str, float], list[Any]] = {}
    for t in episode.truth.lidar:
        truths.setdefault((t.sensor_id, round(float(t.stamp_s), 9)), []).append(t)
    out = []
    for s in scans:
        same = truths.get((s.sensor_id, round(float(s.stamp_s), 9)))
        t = same.pop(0) if same else None
        if t is not None and len(t.kind) == len(s.points_xyz):
            out.append((s, t))
    return out


def point_classes(episode: Episode, truth: Any) -> tuple[np.ndarray, np.ndarray]:
    """(class per point: :data:`GENUINE`/:data:`GLASS`/:data:`GHOST`/:data:`NAN_POINT`, on a ground surface per point).

    ``THROUGH_GLASS`` counts as genuine (a real surface on the straight ray); a point the sensor
    reported as NaN (``ReturnKind.NAN``) is :data:`NAN_POINT`, neither genuine nor spurious. A
    point is ground when it is genuine and its true surface's kind is in :data:`GROUND_KINDS`.
    """
    from exobench.core import ReturnKind

    kind = np.asarray(truth.kind)
    cls = np.full(len(kind), GENUINE, dtype=np.int8)
    cls[kind == ReturnKind.GLASS] = GLASS
    cls[kind == ReturnKind.GHOST] = GHOST
    cls[kind == ReturnKind.NAN] = NAN_POINT
    ground_ids = np.array([s.surface_id for s in episode.truth.scene.surfaces if s.kind in GROUND_KINDS], dtype=int)
    ground = (cls == GENUINE) & np.isin(np.asarray(truth.surface_id, dtype=int), ground_ids)
    return cls, ground


def points_world(scan: LidarScan, truth: Any, T_world_sensor: np.ndarray | None = None) -> np.ndarray:
    """Measured points in the world frame: ``origin_w + |p| dir_w`` of each point's firing, (N, 3).

    A compact truth (``lidar_truth="labels"``) has no rays; then the points are moved by
    ``T_world_sensor`` (the pose at the sweep start; the motion within the sweep is ignored).
    """
    if len(truth.origin_w) != len(scan.points_xyz):
        if T_world_sensor is None:
            raise ValueError("a compact LiDAR truth has no rays: pass the scan's T_world_sensor")
        T = np.asarray(T_world_sensor, dtype=float)
        return np.asarray(scan.points_xyz, dtype=float) @ T[:3, :3].T + T[:3, 3]
    r = np.linalg.norm(np.asarray(scan.points_xyz, dtype=float), axis=1)
    return np.asarray(truth.origin_w, dtype=float) + r[:, None] * np.asarray(truth.dir_w, dtype=float)


def sweep_start_poses(episode: Episode) -> dict[float, np.ndarray]:
    """True ``T_world_sensor`` at each scan start, keyed by the start time rounded to 1 ns."""
    from exobench.core.transforms import make_T, quat_wxyz_to_matrix

    return {
        round(float(r[0]), 9): make_T(quat_wxyz_to_matrix(r[4:8]), r[1:4]) for r in np.asarray(episode.truth.trajectory_w)
    }
