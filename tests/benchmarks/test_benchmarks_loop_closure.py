"""Loop-closure track: PR metrics on hand-computed cases; a short office walk through the runner.

The hand case (revisit 5 m, recent = younger than 25 s), keyframes every 10 s:

    k  pos       match  dist  eligible  match within 5 m  true loop (cond. 3)
    0  (0, 0)    -      -     -         -                 no (nothing eligible)
    1  (10, 0)   0      0.5   no (10 s) -                 no
    2  (20, 0)   -      -     -         -                 no
    3  (20, 10)  0      0.2   yes       no (22.4 m)       no (k0 22.4 m)
    4  (1, 0)    0      0.1   yes       yes (1 m)         yes (k0)
    5  (10, 3)   2      0.3   yes       no (10.4 m)       yes (k1, 3 m)

tau 0.1: TP 1, FP 0, FN 1 (k5) -> P 1, R 0.5; tau 0.2: TP 1, FP 1, FN 1 -> P 0.5, R 0.5;
tau 0.3: TP 1, FP 2, FN 0 (k5 detected, wrongly) -> P 1/3, R 1. Max recall at P = 1: 0.5;
AUC = 0.5 * 1 + 0 * 0.5 + 0.5 * 1/3 = 2/3; best F1 = 2/3 at tau 0.1.
"""

import math

import numpy as np
import pytest

from exobench.benchmarks.tracks.loop_closure.metrics import (
    best_f1,
    eligible_pairs,
    keyframe_poses,
    max_recall_at_full_precision,
    pr_auc,
    pr_curve,
    true_loops,
    yaw_errors,
)

pytestmark = pytest.mark.long(seconds=10)  # the workers take it first (tests/conftest.py); 10: the file at -n 0 in one run at load 12-15, scaled to that run's CPU

T = np.array([0.0, 10.0, 20.0, 30.0, 40.0, 50.0])
POS = np.array([[0, 0, 0], [10, 0, 0], [20, 0, 0], [20, 10, 0], [1, 0, 0], [10, 3, 0]], dtype=float)
MATCH = np.array([-1, 0, -1, 0, 0, 2])
DIST = np.array([np.inf, 0.5, np.inf, 0.2, 0.1, 0.3])


def _curve():
    return pr_curve(POS, T, MATCH, DIST, revisit_m=5.0, exclude_recent_s=25.0)


def test_eligibility_and_true_loops_by_hand():
    E = eligible_pairs(T, 25.0)
    assert E[3].tolist() == [True, False, False, False, False, False]
    assert E[5].tolist() == [True, True, True, False, False, False]
    assert not E[:3].any()
    assert true_loops(POS, T, 5.0, 25.0).tolist() == [False, False, False, False, True, True]


def test_pr_curve_by_hand():
    c = _curve()
    np.testing.assert_allclose(c.tau, [0.1, 0.2, 0.3])
    assert c.tp.tolist() == [1, 1, 1]
    assert c.fp.tolist() == [0, 1, 2]
    assert c.fn.tolist() == [1, 1, 0]
    np.testing.assert_allclose(c.precision, [1.0, 0.5, 1 / 3])
    np.testing.assert_allclose(c.recall, [0.5, 0.5, 1.0])
    assert (c.n_keyframes, c.n_loops, c.n_detectable) == (6, 2, 3)
    assert c.correct.tolist() == [False, False, False, False, True, False]


def test_summary_metrics_by_hand():
    c = _curve()
    assert max_recall_at_full_precision(c) == pytest.approx(0.5)
    assert pr_auc(c) == pytest.approx(2 / 3)
    f1, tau = best_f1(c)
    assert f1 == pytest.approx(2 / 3)
    assert tau == pytest.approx(0.1)


def test_perfect_and_empty_detectors():
    # a perfect detector: both loop keyframes matched correctly, nothing else detected
    match = np.array([-1, -1, -1, -1, 0, 1])
    dist = np.array([np.inf, np.inf, np.inf, np.inf, 0.2, 0.3])
    c = pr_curve(POS, T, match, dist, revisit_m=5.0, exclude_recent_s=25.0)
    assert max_recall_at_full_precision(c) == 1.0
    assert pr_auc(c) == pytest.approx(1.0)
    # no detection at all: recall 0, AUC 0, no best threshold
    none = pr_curve(POS, T, np.full(6, -1), np.full(6, np.inf), revisit_m=5.0, exclude_recent_s=25.0)
    assert max_recall_at_full_precision(none) == 0.0
    assert pr_auc(none) == 0.0
    assert best_f1(none)[0] == 0.0
    # no true loop anywhere: AUC undefined
    far = POS * 100.0
    c = pr_curve(far, T, MATCH, DIST, revisit_m=5.0, exclude_recent_s=25.0)
    assert c.n_loops == 0 and math.isnan(pr_auc(c))
    assert max_recall_at_full_precision(c) == 0.0


def _quat_yaw(yaw):
    return [math.cos(yaw / 2), 0.0, 0.0, math.sin(yaw / 2)]


def test_keyframe_poses_and_yaw_errors():
    tr = np.array([[t, t, 2 * t, 1.0, *_quat_yaw(y)] for t, y in ((0.0, 0.0), (0.1, math.pi / 2), (0.2, math.pi))])
    pos, yaw, found = keyframe_poses(tr, np.array([0.1, 0.2, 0.5, 0.01]))
    assert found.tolist() == [True, True, False, True]
    np.testing.assert_allclose(pos[0], [0.1, 0.2, 1.0])
    np.testing.assert_allclose(yaw[[0, 1, 3]], [math.pi / 2, math.pi, 0.0], atol=1e-12)
    # keyframe 1 (yaw 90 deg) matches keyframe 0 (yaw 0): the query is the match rotated by 0 - 90 deg
    y = np.array([0.0, math.pi / 2])
    err = yaw_errors(y, np.array([-1, 0]), np.array([np.nan, -math.pi / 2 + 0.1]), np.array([False, True]))
    np.testing.assert_allclose(err, [0.1])


# ------------------------------------------------------------------ a short office walk

# the quick office, cut after walking into the office at the end of the north corridor and out
# again (the way out revisits the way in, turned by 180 deg); revisits within 1.5 m and 5 s
SHORT = {"max_distance_m": 12.0, "revisit_m": 1.5, "exclude_recent_s": 5.0, "lidar_azimuth_step_deg": 1.0}
PIPES = ["sc++", "gsc-height", "gsc-huber", "gsc-intensity"]
PIPE_SET = {f"{p}.exclude_recent": 8 for p in PIPES}  # 8 keyframes of 0.5 s: 4 s


@pytest.fixture(scope="module")
def short_run(tmp_path_factory):
    from exobench.benchmarks.runner import execute, plan_run

    plan = plan_run("loop-closure", "quick", PIPES, seeds=[3], overrides={**SHORT, **PIPE_SET})
    out = tmp_path_factory.mktemp("lc")
    outcome = execute(plan, out / "run")
    return plan, outcome


TIMING = {"time_per_keyframe_ms"}


def test_office_walk_through_runner_detects_a_true_loop(short_run):
    plan, outcome = short_run
    records = outcome.records
    assert {r["pipeline"] for r in records} == set(PIPES)
    for r in records:
        m = r["metrics"]
        assert not m["failed"], m.get("failed_reason")
        assert m["n_keyframes"] > 10
        assert m["n_revisits"] > 0
        assert len(m["pr_tau"]) == len(m["pr_precision"]) == len(m["pr_recall"])
    assert max(r["metrics"]["max_recall_at_full_precision"] for r in records) > 0.0


def test_office_walk_is_deterministic_and_reports(short_run, tmp_path):
    from exobench.benchmarks.report import write_report
    from exobench.benchmarks.runner import run_pipelines
    from exobench.benchmarks.tracks.spec import scoring_of

    plan, outcome = short_run
    episode = plan.track.simulate(plan.episodes[0].scenario, plan.episodes[0].seed)
    # the scoring settings (revisit_m 1.5, exclude_recent_s 5) are the plan's, not the episode's
    assert not {"revisit_m", "exclude_recent_s"} & set(episode.scenario)
    scoring = scoring_of(plan.track, plan.episodes[0].scenario)
    assert scoring == {"exclude_recent_s": 5.0, "revisit_m": 1.5}
    est1, met1, _, _ = run_pipelines(plan.track, episode, plan.pipelines, scoring=scoring)
    est2, _, _, _ = run_pipelines(plan.track, episode, plan.pipelines)
    for name in PIPES:
        a, b = est1[name], est2[name]
        for field in ("stamps_s", "match_index", "distance", "yaw_rad"):
            np.testing.assert_array_equal(getattr(a, field), getattr(b, field))
    # the runner's own simulation of the same seed gives the same scores
    by_pipe = {r["pipeline"]: r["metrics"] for r in outcome.records}
    from exobench.benchmarks.results import json_safe

    for name in PIPES:
        live = {k: v for k, v in json_safe(met1[name]).items() if k not in TIMING}
        stored = {k: v for k, v in by_pipe[name].items() if k not in TIMING}
        assert live == stored
    report = write_report(outcome.out_dir).read_text()
    assert "Precision-recall curves" in report and "Loop matches" in report
    assert list(outcome.out_dir.glob("pr_*.png")) and list((outcome.out_dir / "figures").glob("*.png"))
    rrd = plan.track.write_recording(episode, est1, tmp_path / "lc.rrd")
    assert rrd.exists() and rrd.stat().st_size > 0
