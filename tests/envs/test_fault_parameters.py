"""Every fault and noise parameter of every scenario table changes the frames it names, in the
way it says, and no other stream: each is set to an active value on a tiny episode of its world
and compared with the fault-free episode of the same seed (simulated once per world). A new
parameter of that family without a case here fails :func:`test_every_fault_parameter_has_a_case`.
"""

from __future__ import annotations

import dataclasses
import re
from collections.abc import Callable

import numpy as np
import pytest

from exobench.benchmarks.tracks import get_track
from exobench.core.kinds import frame_kind
from exobench.envs.sim.scenarios import course, office, stairs

pytestmark = pytest.mark.long(seconds=15)  # the workers take it first (tests/conftest.py); 15: the file at -n 0 in one run at load 12-15, scaled to that run's CPU

TABLES = {"stairs": stairs.PARAMS, "office": office.PARAMS, "course": course.PARAMS}
TRACKS = {"stairs": "stairs", "office": "odometry", "course": "locomotion"}  # a track that simulates the world
TINY = {"stairs": {}, "office": {"max_distance_m": 1.0}, "course": {"duration_cap_s": 2.5}}
FAULT_FAMILY = re.compile(r"dropout|nan|duplicate|out_of_order|time_jump|latency|noise|drift|orientation_deg")
SEED = 2


def _simulate(world: str, values: dict) -> tuple:
    trk = get_track(TRACKS[world])
    return trk.simulate(trk.validate_scenario({**trk.smoke_scenario, **TINY[world], **values}), SEED).frames


_BASE: dict[str, tuple] = {}


def _base(world: str) -> tuple:
    if world not in _BASE:
        _BASE[world] = _simulate(world, {})
    return _BASE[world]


def _of(frames, kind: str) -> list:
    return [f for f in frames if frame_kind(f) == kind]


def _same(a, b) -> bool:
    """Two frames equal field by field, arrays bit for bit (NaN equal to NaN)."""
    if type(a) is not type(b):
        return False
    for f in dataclasses.fields(a):
        x, y = getattr(a, f.name), getattr(b, f.name)
        if isinstance(x, np.ndarray):
            if x.shape != y.shape or x.dtype != y.dtype or not np.array_equal(x, y, equal_nan=x.dtype.kind == "f"):
                return False
        elif x != y and not (isinstance(x, float) and np.isnan(x) and np.isnan(y)):
            return False
    return True


def _keys(frames) -> list[tuple[str, float]]:
    return [(f.sensor_id, f.stamp_s) for f in frames]


# --- what each parameter does to the frames it names -----------------------------------------


def dropped(kind: str) -> Callable:
    def check(base, got):
        b, g = _keys(_of(base, kind)), _keys(_of(got, kind))
        assert len(g) < len(b) and set(g) <= set(b), (len(g), len(b))
    return check


def delayed(kind: str, dt: float) -> Callable:
    def check(base, got):
        b, g = _of(base, kind), _of(got, kind)
        assert len(g) == len(b) and len(b) > 0
        assert np.allclose([f.stamp_s for f in g], [f.stamp_s + dt for f in b], atol=1e-9)
    return check


def values_differ(kind: str, field: str) -> Callable:
    """The same frames at the same stamps, the field's values changed in most of them."""
    def check(base, got):
        b, g = _of(base, kind), _of(got, kind)
        assert _keys(g) == _keys(b) and len(b) > 0
        changed = sum(not np.array_equal(np.asarray(getattr(x, field)), np.asarray(getattr(y, field)), equal_nan=True)
                      for x, y in zip(b, g, strict=True))  # fmt: skip
        assert changed > len(b) // 2, (changed, len(b))
    return check


def fewer_points(base, got):
    b, g = _of(base, "lidar"), _of(got, "lidar")
    assert _keys(g) == _keys(b)
    assert sum(len(s.points_xyz) for s in g) < 0.8 * sum(len(s.points_xyz) for s in b)


def nan_points(base, got):
    b, g = _of(base, "lidar"), _of(got, "lidar")
    assert _keys(g) == _keys(b) and [len(s.points_xyz) for s in g] == [len(s.points_xyz) for s in b]
    assert sum(np.isnan(s.points_xyz).any(axis=1).sum() for s in b) == 0
    assert sum(np.isnan(s.points_xyz).any(axis=1).sum() for s in g) > 0.1 * sum(len(s.points_xyz) for s in g)


def duplicated(base, got):
    b, g = _of(base, "lidar"), _of(got, "lidar")
    stamps = [s.stamp_s for s in g]
    assert len(g) > len(b) and len(set(stamps)) == len(b) and sorted(set(stamps)) == [s.stamp_s for s in b]


def reordered(all_pairs: bool) -> Callable:
    """Late sweeps: the same sweeps (by start), delivered with a later sweep first; at probability
    1 every pair swaps."""
    def check(base, got):
        b, g = [s.sweep_start_s for s in _of(base, "lidar")], [s.sweep_start_s for s in _of(got, "lidar")]
        assert sorted(g) == b
        assert np.any(np.diff(g) < 0)
        if all_pairs:
            swapped = [b[i ^ 1] if (i ^ 1) < len(b) else b[i] for i in range(len(b))]
            assert g == swapped
    return check


def clock_steps(step_s: float) -> Callable:
    """The same sweeps (told apart by their noisy points), stamps shifted by whole clock steps
    that only add up over time."""
    def check(base, got):
        b, g = _of(base, "lidar"), _of(got, "lidar")
        assert len(g) == len(b)
        true = {s.points_xyz.tobytes(): s.stamp_s for s in b}
        t_true = np.array([true[s.points_xyz.tobytes()] for s in g])
        steps = (np.array([s.stamp_s for s in g]) - t_true) / step_s
        assert np.allclose(steps, np.round(steps), atol=1e-6)
        steps = np.round(steps)[np.argsort(t_true)]
        assert steps.max() >= 1 and np.all(np.diff(steps) >= 0)
    return check


# world, values, the stream they change, how
CASES: list[tuple[str, dict, str, Callable]] = [
    ("stairs", {"tof_dropout": 0.5}, "tof", dropped("tof")),
    ("stairs", {"tof_latency_s": 0.05}, "tof", delayed("tof", 0.05)),
    ("stairs", {"tof_noise_m": 0.02}, "tof", values_differ("tof", "range_m")),
    ("stairs", {"imu_noise_scale": 5.0}, "imu", values_differ("imu", "gyro_rad_s")),
    ("stairs", {"imu_orientation_deg": 5.0}, "imu", values_differ("imu", "quat_wxyz")),
    ("stairs", {"encoder_noise_rad": 0.01}, "joints", values_differ("joints", "position_rad")),
    ("office", {"lidar_scan_dropout": 0.5}, "lidar", dropped("lidar")),
    ("office", {"lidar_point_dropout": 0.5}, "lidar", fewer_points),
    ("office", {"lidar_nan_points": 0.5}, "lidar", nan_points),
    ("office", {"lidar_duplicate_scans": 0.5}, "lidar", duplicated),
    ("office", {"lidar_out_of_order": 1.0}, "lidar", reordered(all_pairs=True)),
    ("office", {"lidar_out_of_order": 0.3}, "lidar", reordered(all_pairs=False)),
    ("office", {"lidar_time_jump_prob": 0.5}, "lidar", clock_steps(1.0)),
    ("office", {"lidar_time_jump_prob": 0.5, "lidar_time_jump_s": 0.35}, "lidar", clock_steps(0.35)),
    ("office", {"lidar_noise_m": 0.05}, "lidar", values_differ("lidar", "points_xyz")),
    ("office", {"imu_noise_scale": 5.0}, "imu", values_differ("imu", "gyro_rad_s")),
    ("office", {"encoder_noise_rad": 0.01}, "joints", values_differ("joints", "position_rad")),
    ("course", {"frame_dropout": 0.5}, "rgbd", dropped("rgbd")),
    ("course", {"latency_s": 0.1}, "rgbd", delayed("rgbd", 0.1)),
    ("course", {"depth_noise_scale": 5.0}, "rgbd", values_differ("rgbd", "depth_m")),
    ("course", {"imu_noise_scale": 5.0}, "imu", values_differ("imu", "gyro_rad_s")),
    ("course", {"odom_drift_pct": 10.0}, "odometry", values_differ("odometry", "T_odom_body")),
    ("course", {"odom_yaw_drift_deg_per_m": 10.0}, "odometry", values_differ("odometry", "T_odom_body")),
]


def test_every_fault_parameter_has_a_case():
    covered = {(w, k) for w, values, _, _ in CASES for k in values}
    family = {(w, k) for w, table in TABLES.items() for k in table if FAULT_FAMILY.search(k)}
    assert family - covered == set()


@pytest.mark.parametrize("world,values,kind,check", CASES, ids=[f"{w}-{','.join(f'{k}={v}' for k, v in vals.items())}" for w, vals, _, _ in CASES])
def test_a_fault_changes_the_frames_it_names_and_no_others(world, values, kind, check):
    for k, v in values.items():
        assert v != TABLES[world][k].default, f"{k}={v} is the fault-free default"
    base, got = _base(world), _simulate(world, values)
    check(base, got)
    for other in {frame_kind(f) for f in base} - {kind}:
        b, g = _of(base, other), _of(got, other)
        assert len(b) == len(g) and all(_same(x, y) for x, y in zip(b, g, strict=True)), f"{other} frames changed"
