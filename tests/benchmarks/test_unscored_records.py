"""A record that scored nothing is failed with its reason, never "0 failed" with every metric
null: an empty estimate on every track, every LiDAR return NaN (``lidar_nan_points=1``) on the
three LiDAR tracks, and the runner's check for any track whose headline metrics are all NaN."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest
from test_benchmarks_support import FakeStairs, FakeTrack, make_episode

from exobench.benchmarks.runner import PipelineRun, plan_run, run_pipelines
from exobench.benchmarks.tracks import get_track, track_names
from exobench.core.estimates import (
    FilterEstimate,
    LocomotionEstimate,
    MultiSessionEstimate,
    PlaceRecognitionEstimate,
    StaircaseEstimate,
    TrajectoryEstimate,
)

pytestmark = pytest.mark.long(seconds=15)  # the workers take it first (tests/conftest.py); 15: the file at -n 0 in one run at load 12-15, scaled to that run's CPU (24), times 18.9/30.0 CPU-s alone after the cheaper vio and multisession walks

E = np.zeros(0)
EMPTY = {
    "stairs": StaircaseEstimate((), math.nan, math.nan),
    "locomotion": LocomotionEstimate(()),
    "lidar-filter": FilterEstimate(E, (), E),
    "odometry": TrajectoryEstimate(E, np.zeros((0, 4, 4)), E),
    "loop-closure": PlaceRecognitionEstimate(E, E.astype(int), E, E, E),
    "vio": TrajectoryEstimate(E, np.zeros((0, 4, 4)), E),
    "multisession": MultiSessionEstimate((), (), (), (), ()),
}


def _nan(v: Any) -> bool:
    return v is None or (isinstance(v, float) and math.isnan(v))


def test_every_track_has_an_empty_estimate_here_and_headline_metrics_it_scores():
    assert set(EMPTY) == set(track_names())
    for name in track_names():
        track = get_track(name)
        rows = {r.metric for r in track.summary_rows()}
        assert track.headline_metrics and set(track.headline_metrics) <= rows, name


# The smoke walk with a smaller or slower camera where its frames took most of the time: the
# estimate is empty, so what the scorer fails on (no pose, no keyframe) is there whatever the
# images (vio 10.3 -> 1.6 CPU-s, multisession 8.9 -> 6.2)
CHEAPER = {"vio": {"width_px": 64, "height_px": 48, "rate_hz": 2.0}, "multisession": {"frame_rate_hz": 2.0}}


@pytest.mark.parametrize("name", sorted(EMPTY))
def test_an_empty_estimate_is_failed_with_a_reason_on_every_track(name):
    track = get_track(name)
    episode = track.simulate(track.validate_scenario({**track.smoke_scenario, **CHEAPER.get(name, {})}), 0)
    m = track.score(episode, EMPTY[name])
    assert m["failed"] is True and m["failed_reason"], m.get("failed_reason")
    assert "raised" not in m["failed_reason"]  # said, not a scorer's crash


@pytest.mark.parametrize("name", ["lidar-filter", "odometry", "loop-closure"])
def test_every_lidar_return_nan_fails_every_pipeline_with_its_reason(name):
    track = get_track(name)
    plan = plan_run(name, None, None, [0], {"lidar_nan_points": 1.0, "max_distance_m": 1.5})
    episode = track.simulate(plan.episodes[0].scenario, 0)
    _, metrics, _, _ = run_pipelines(track, episode, plan.pipelines)
    for pipe, m in metrics.items():
        assert m["failed"] is True and m["failed_reason"], (pipe, m)
        assert all(_nan(m.get(k)) for k in track.headline_metrics), (pipe, {k: m.get(k) for k in track.headline_metrics})


class _NothingScored(FakeTrack):
    def score(self, episode, estimate, scoring=None):
        m = super().score(episode, estimate)
        return {**m, **{k: math.nan for k in self.headline_metrics}, "failed": False, "failed_reason": "a note"}


class _NoHeadline(_NothingScored):
    headline_metrics = ()


def _run(track):
    _, metrics, _, _ = run_pipelines(track, make_episode(), [PipelineRun("fake", f"{FakeStairs.__module__}:FakeStairs", FakeStairs.Config())])
    return metrics["fake"]


def test_the_runner_fails_a_record_whose_headline_metrics_are_all_nan():
    m = _run(_NothingScored())
    assert m["failed"] is True
    assert m["failed_reason"].startswith("no metric could be computed (riser_error_pct") and m["failed_reason"].endswith("; a note")
    ok = _run(FakeTrack())
    assert ok["failed"] is False and math.isfinite(ok["riser_error_pct"])
    assert _run(_NoHeadline())["failed"] is False  # a track that names no headline metric is not second-guessed
