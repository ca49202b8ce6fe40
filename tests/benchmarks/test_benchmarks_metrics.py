"""The stairs scorer against hand-computed values on constructed episodes and estimates."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from test_benchmarks_support import make_episode

from exobench.benchmarks.tracks.stairs import StairsTrack
from exobench.benchmarks.tracks.stairs.metrics import path_length, score_staircase
from exobench.core import (
    Episode,
    PlaneEstimate,
    PointAssignment,
    StaircaseEstimate,
    ToFReading,
    ToFTruth,
)
from exobench.core.transforms import invert_T, make_T, rot_z, transform_points

DEG = math.pi / 180


def _with(ep: Episode, **truth_changes) -> Episode:
    """The episode with some truth replaced; ``tof``/``foot_track_w`` go to its stairs part."""
    stairs_changes = {k: truth_changes.pop(k) for k in ("tof", "foot_track_w") if k in truth_changes}
    truth = dataclasses.replace(ep.truth, **truth_changes)
    if stairs_changes:
        truth = dataclasses.replace(truth, stairs=dataclasses.replace(truth.stairs, **stairs_changes))
    return Episode(ep.scenario, ep.seed, ep.calibration, ep.frames, truth)


def _plane_in_estimator(T_world_est, index, n_w, c_w, reliable=True, stamp=1.0) -> PlaneEstimate:
    T_est_world = invert_T(T_world_est)
    return PlaneEstimate(index, T_est_world[:3, :3] @ n_w, transform_points(T_est_world, c_w), {"tof_r_lat": 9}, 0.001, reliable, stamp)


@pytest.fixture
def rotated_episode() -> Episode:
    # estimator frame yawed by 30 deg and shifted: the scorer must map estimates to the world
    T = make_T(rot_z(30 * DEG), np.array([-0.3, 0.1, 0.02]))
    return _with(make_episode(), T_world_estimator=T)


def test_tilted_tread_gives_known_alpha_d_and_touchdown_error(rotated_episode):
    ep = rotated_episode
    T = ep.truth.T_world_estimator
    n_w = np.array([math.sin(5 * DEG), 0.0, math.cos(5 * DEG)])  # 5 deg tilt about y
    c_w = np.array([0.1, 0.0, 0.165])  # 3 mm above the true tread at z = 0.162
    est = StaircaseEstimate((_plane_in_estimator(T, 2, n_w, c_w),), 0.170, 0.27)
    m = score_staircase(ep, est)
    assert m["alpha_deg_S2"] == pytest.approx(5.0, abs=1e-9)
    assert m["d_m_S2"] == pytest.approx(0.003, abs=1e-12)
    # touch-down at x = 0.14: the plane drops tan(5 deg) * 0.04 m from its centroid
    assert m["touchdown_error_m"] == pytest.approx(0.003 - math.tan(5 * DEG) * 0.04, abs=1e-12)
    assert m["riser_error_pct"] == pytest.approx(0.008 / 0.162 * 100)
    assert m["tread_error_pct"] == pytest.approx(0.01 / 0.28 * 100)
    assert m["riser_est_m"] == 0.170 and m["tread_est_m"] == 0.27
    assert math.isnan(m["alpha_deg_S3"]) and math.isnan(m["d_m_S0"])


def test_normals_are_compared_as_lines_and_d_is_signed(rotated_episode):
    ep = rotated_episode
    T = ep.truth.T_world_estimator
    n_w = np.array([-math.cos(10 * DEG), math.sin(10 * DEG), 0.0])  # riser normal yawed by 10 deg
    behind = _plane_in_estimator(T, 1, -n_w, np.array([0.004, 0.0, 0.08]))  # flipped, 4 mm into the step
    m = score_staircase(ep, StaircaseEstimate((behind,), float("nan"), float("nan")))
    assert m["alpha_deg_S1"] == pytest.approx(10.0, abs=1e-9)
    assert m["d_m_S1"] == pytest.approx(-0.004, abs=1e-12)  # the true riser normal points to -x
    assert math.isnan(m["riser_error_pct"])


def test_reliability_time_and_remaining_travel():
    track = np.array([[0.5, 0, 0, 0], [1.0, 0.3, 0, 0.4], [1.5, 0.3, 0, 0.6]])
    ep = _with(make_episode(), foot_track_w=track, events={"liftoff_s": 0.5, "touchdown_s": 1.5})
    s2 = PlaneEstimate(2, np.array([0, 0, 1.0]), np.array([0.4, -0.05, 0.162]), {}, 0.001, True, 0.75)
    m = score_staircase(ep, StaircaseEstimate((s2,), 0.16, 0.28))
    assert m["s2_reliable_s"] == pytest.approx(0.25)
    # from the middle of the first segment (0.5 * 0.5 m) plus the second segment (0.2 m)
    assert m["s2_remaining_travel_m"] == pytest.approx(0.25 + 0.2)
    assert m["failed"] is False
    assert path_length(track, 0.5, 1.5) == pytest.approx(0.7)


def test_unreliable_s2_is_a_scored_failure():
    ep = make_episode()
    s2 = PlaneEstimate(2, np.array([0, 0, 1.0]), np.array([0.4, -0.05, 0.162]), {}, 0.001, False, None)
    m = score_staircase(ep, StaircaseEstimate((s2,), 0.16, 0.28))
    assert m["failed"] is True and "never" in m["failed_reason"]
    assert math.isnan(m["s2_reliable_s"])
    assert m["d_m_S2"] == pytest.approx(0.0, abs=1e-12)  # the plane is still scored
    m = score_staircase(ep, StaircaseEstimate((), 0.16, 0.28))
    assert m["failed"] is True and "no S2" in m["failed_reason"]


def test_assignment_accuracy_matches_rays_by_stamp_and_sensor():
    base = make_episode()
    true_ids = [0, 1, 2, 2, -1]
    frames = tuple(ToFReading(0.1 * k, "tof_r_med" if k % 2 else "tof_r_lat", 0.4) for k in range(5))
    tof = tuple(ToFTruth(f.stamp_s, f.sensor_id, 0.4, np.zeros(3), i, np.eye(4)) for f, i in zip(frames, true_ids, strict=True))
    ep = Episode(base.scenario, 0, base.calibration, frames, _with(base, tof=tof).truth)
    given = [0, 2, 2, -1, -2]  # right, wrong, right, discarded a tread point, unused
    # assignments listed out of order: matching must use (stamp_s, sensor_id), not position
    assignments = tuple(PointAssignment(f.stamp_s, f.sensor_id, np.zeros(3), g) for f, g in reversed(list(zip(frames, given, strict=True))))
    est = StaircaseEstimate((), 0.16, 0.28, assignments, {"n_nan": 3, "extra": {"n_bad": 2}}, np.array([1e-4, 3e-4, 2e-4]))
    m = score_staircase(ep, est)
    assert m["assignment_accuracy"] == pytest.approx(2 / 4)
    assert m["assigned_accuracy"] == pytest.approx(2 / 3)
    assert m["discarded_fraction"] == pytest.approx(1 / 4)
    assert m["n_points"] == 4 and m["n_assigned"] == 3 and m["n_tof"] == 5
    assert m["time_per_point_us"] == pytest.approx(200.0)
    assert m["stat_n_nan"] == 3 and m["stat_extra_n_bad"] == 2


def test_suites_are_deterministic_and_follow_the_paper():
    track = StairsTrack()
    paper = track.cases("paper")
    assert [c.name for c in paper[:3]] == ["A", "B", "C"]
    assert paper[1].scenario == {"riser_m": 0.162, "tread_m": 0.28, "yaw_deg": 23.0, "distance_m": 0.27}
    assert len(paper) == 3 + 3 * 20
    assert [c.scenario for c in track.cases("paper")] == [c.scenario for c in paper]
    poses = [c.scenario for c in paper[3:]]
    assert all(-25 <= p["yaw_deg"] <= 25 and 0.25 <= p["distance_m"] <= 0.5 for p in poses)
    assert {(p["riser_m"], p["tread_m"]) for p in poses} == {(0.153, 0.294), (0.162, 0.28), (0.175, 0.27)}
    quick = track.cases("quick")
    assert len(quick) == 6 and {c.name for c in quick} <= {c.name for c in paper}


def test_an_episode_without_climbing_truth_is_scored_failed_not_perfect():
    ep = _with(make_episode(), stairs=None)
    m = score_staircase(ep, StaircaseEstimate((), 0.162, 0.28))
    assert m["failed"] is True and "truth.stairs" in m["failed_reason"] and m["n_tof"] == 0
    assert math.isnan(m["riser_error_pct"]) and math.isnan(m["touchdown_error_m"])


def test_true_geometry_comes_from_the_truth_not_the_scenario_record(rotated_episode):
    # a session's meta.scenario may misstate the staircase: the built one (truth) is scored
    ep = rotated_episode
    lying = Episode({**ep.scenario, "riser_m": 0.30, "tread_m": 0.40}, ep.seed, ep.calibration, ep.frames, ep.truth)
    T = ep.truth.T_world_estimator
    est = StaircaseEstimate((_plane_in_estimator(T, 2, np.array([0.0, 0.0, 1.0]), np.array([0.1, 0.0, 0.162])),), 0.170, 0.27)
    m = score_staircase(lying, est)
    assert m["riser_error_pct"] == pytest.approx(0.008 / 0.162 * 100)
    assert m["tread_error_pct"] == pytest.approx(0.01 / 0.28 * 100)
