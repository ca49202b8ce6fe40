"""Repeated and out-of-order frames through the real pipelines and the runner's records.

A frame measured at the same instant as the last of its stream is counted ``repeated`` and not
used; one measured before it is counted ``out_of_order`` and not used
(:mod:`exobench.core.counters`). So an episode with every right-leg ToF reading doubled scores
exactly as the clean one, and an episode with late readings exactly as the one without them;
the same for LiDAR sweeps through kiss-icp. The records carry the counters as
``frames.<kind>.<counter>``.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from exobench.benchmarks.registry import default_registry
from exobench.benchmarks.runner import PipelineRun, run_pipelines
from exobench.benchmarks.tracks import get_track
from exobench.benchmarks.tracks.stairs.track import CASES
from exobench.core.counters import COUNTERS
from exobench.core.frames import LidarScan, ToFReading

pytestmark = pytest.mark.long(seconds=6)  # the workers take it first (tests/conftest.py); 6: the file at -n 0 in one run at load 12-15, scaled to that run's CPU

STAIRS = ("rtls", "rtls-htvr", "batch-ransac")
RIGHT_LEG = ("tof_r_lat", "tof_r_med")  # the sensors the default config (leg "r") reads


def _runs(names):
    reg = default_registry()
    return [PipelineRun(n, reg.spec(n).entry_point, reg.make_config(n, {})) for n in names]


def _score(track, episode, frames, names):
    _, metrics, _, _ = run_pipelines(track, dataclasses.replace(episode, frames=tuple(frames)), _runs(names))
    return metrics


def _same_but(a: dict, b: dict, skip: set[str]) -> list[str]:
    """Keys whose values differ (NaN equal to NaN), timings and ``skip`` aside."""
    def eq(x, y):
        return x == y or (isinstance(x, float) and isinstance(y, float) and math.isnan(x) and math.isnan(y))

    keys = (a.keys() | b.keys()) - skip - {"time_per_point_us", "time_per_scan_ms"}
    return sorted(k for k in keys if not eq(a.get(k), b.get(k)))


@pytest.fixture(scope="module")
def case_a():
    track = get_track("stairs")
    return track, track.simulate(track.validate_scenario(CASES["A"]), 0)


def test_doubled_tof_readings_are_counted_and_leave_the_scores_unchanged(case_a):
    track, episode = case_a
    doubled = []
    for f in episode.frames:
        doubled.append(f)
        if isinstance(f, ToFReading) and f.sensor_id in RIGHT_LEG:
            doubled.append(dataclasses.replace(f))
    n_doubled = len(doubled) - len(episode.frames)
    assert n_doubled > 200
    clean = _score(track, episode, episode.frames, STAIRS)
    twice = _score(track, episode, doubled, STAIRS)
    for name in STAIRS:
        assert not clean[name]["failed"] and not twice[name]["failed"], name
        assert twice[name]["riser_error_pct"] == clean[name]["riser_error_pct"], name
        assert twice[name]["n_points"] == clean[name]["n_points"] == clean[name]["frames.tof.used"], name
        assert twice[name]["frames.tof.repeated"] == n_doubled and clean[name]["frames.tof.repeated"] == 0
        assert twice[name]["frames.tof.seen"] == clean[name]["frames.tof.seen"] + n_doubled
        assert _same_but(clean[name], twice[name], {"frames.tof.seen", "frames.tof.repeated"}) == [], name


def test_late_tof_readings_are_counted_and_score_as_if_lost(case_a):
    """Every 7th right-leg reading delivered after the next one of its sensor: not used, so the
    scores are those of the episode without these readings (which the gap counts as dropped)."""
    track, episode = case_a
    frames = list(episode.frames)
    late, lost = [], []
    seen: dict[str, int] = {}
    i = 0
    while i < len(frames):
        f = frames[i]
        if isinstance(f, ToFReading) and f.sensor_id in RIGHT_LEG:
            seen[f.sensor_id] = seen.get(f.sensor_id, 0) + 1
            nxt = next((j for j in range(i + 1, len(frames)) if frames[j].sensor_id == f.sensor_id), None)
            if seen[f.sensor_id] % 7 == 0 and nxt is not None:
                frames.insert(nxt, frames.pop(i))  # now right after the next reading of its sensor
                late.append(f)
                continue  # frames[i] is a new frame
        i += 1
    assert len(late) > 20 and len(frames) == len(episode.frames)
    lost = [f for f in episode.frames if not any(f is g for g in late)]
    got = _score(track, episode, frames, STAIRS)
    want = _score(track, episode, lost, STAIRS)
    for name in STAIRS:
        assert got[name]["frames.tof.out_of_order"] == len(late) and want[name]["frames.tof.out_of_order"] == 0
        assert got[name]["frames.tof.dropped"] == want[name]["frames.tof.dropped"] >= len(late)
        assert _same_but(want[name], got[name], {"frames.tof.seen", "frames.tof.out_of_order"}) == [], name


@pytest.fixture(scope="module")
def odometry_smoke():
    track = get_track("odometry")
    return track, track.simulate(track.validate_scenario(track.smoke_scenario), 0)


def _trajectory(track, episode, frames):
    pipe = default_registry().make("kiss-icp")
    pipe.reset(episode.calibration)
    for f in frames:
        pipe.process(f)
    return pipe.finalize()


def test_kiss_icp_counts_repeated_and_late_sweeps_and_uses_neither(odometry_smoke):
    track, episode = odometry_smoke
    scans = [i for i, f in enumerate(episode.frames) if isinstance(f, LidarScan)]
    assert len(scans) >= 10
    clean = _trajectory(track, episode, episode.frames)
    doubled = []
    for f in episode.frames:
        doubled.extend([f, dataclasses.replace(f)] if isinstance(f, LidarScan) else [f])
    twice = _trajectory(track, episode, doubled)
    assert twice.counts["lidar"].repeated == len(scans) and clean.counts["lidar"].repeated == 0
    np.testing.assert_array_equal(twice.stamps_s, clean.stamps_s)
    np.testing.assert_array_equal(twice.T_world_sensor, clean.T_world_sensor)
    # the 5th sweep delivered after the 6th: not registered, as if it were lost
    k, nxt = scans[4], scans[5]
    frames = list(episode.frames)
    frames.insert(nxt, frames.pop(k))
    late = _trajectory(track, episode, frames)
    lost = _trajectory(track, episode, [f for i, f in enumerate(episode.frames) if i != k])
    assert (late.counts["lidar"].out_of_order, late.counts["lidar"].dropped) == (1, 1)
    np.testing.assert_array_equal(late.stamps_s, lost.stamps_s)
    np.testing.assert_array_equal(late.T_world_sensor, lost.T_world_sensor)
    # and the runner's record carries the counters the same way as every track's
    _, metrics, _, _ = run_pipelines(track, dataclasses.replace(episode, frames=tuple(doubled)), _runs(["kiss-icp"]))
    m = metrics["kiss-icp"]
    assert {f"frames.{k}.{c}" for k in track.streams for c in COUNTERS} <= set(m)
    assert m["frames.lidar.repeated"] == len(scans) and m["frames.lidar.seen"] == 2 * len(scans)
