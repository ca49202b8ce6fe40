"""The multisession track (issue 28): episode frame kinds on disk, the wrong-label fault, the
scorer's wiring against an independent computation, and a run through ``exobench run``."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest
from click.testing import CliRunner

from exobench.benchmarks.cli import cli
from exobench.benchmarks.tracks.multisession import MultisessionTrack
from exobench.benchmarks.tracks.multisession.episodes import parse_sessions
from exobench.core import Calibration, Episode, EpisodeTruth, SceneTruth
from exobench.core.counters import StreamCounters
from exobench.core.errors import ConfigError
from exobench.core.estimates import MultiSessionEstimate
from exobench.core.faults import swap_place_labels
from exobench.core.frames import ImuSample, PlaceLabel, SessionStart
from exobench.envs.session import iter_frames, write_session

pytestmark = pytest.mark.long(seconds=32)  # the workers take it first (tests/conftest.py); 32: the file at -n 0 in one run at load 12-15, scaled to that run's CPU


def _episode(frames, extra=None, T_we=None) -> Episode:
    calib = Calibration(robot_urdf="<robot name='x'/>", base_link="pelvis", joint_names=(), mounts=(),
                        sole_height_m=0.068, foot_length_m=0.26, heel_to_ankle_m=0.065)  # fmt: skip
    truth = EpisodeTruth(scene=SceneTruth((), {}), T_world_estimator=np.eye(4) if T_we is None else T_we, extra=extra or {})
    return Episode({}, 0, calib, tuple(frames), truth)


def test_session_marks_and_place_labels_round_trip_through_a_recorded_session(tmp_path):
    frames = [
        SessionStart(0.0, "session", 0, 0), PlaceLabel(0.05, "place_label", "corridor"),
        ImuSample(0.1, "imu_thigh_r", np.array([1.0, 0, 0, 0]), np.zeros(3), np.array([0, 0, 9.81])),
        SessionStart(5.0, "session", 1, 2), PlaceLabel(5.05, "place_label", "meeting"),
    ]  # fmt: skip
    write_session(_episode(frames), tmp_path / "s")
    back = list(iter_frames(tmp_path / "s"))
    assert [type(f) for f in back] == [type(f) for f in frames]
    marks = [(f.stamp_s, f.session, f.day) for f in back if isinstance(f, SessionStart)]
    assert marks == [(0.0, 0, 0), (5.0, 1, 2)]
    assert [f.label for f in back if isinstance(f, PlaceLabel)] == ["corridor", "meeting"]


def test_wrong_label_fault_changes_labels_at_the_stated_rate():
    truth = ["corridor", "office", "meeting"] * 40
    frames = [PlaceLabel(0.1 * k, "place_label", lab) for k, lab in enumerate(truth)]
    for fraction in (0.0, 0.1, 0.25, 1.0):
        out = swap_place_labels(frames, fraction, seed=4)
        wrong = [a.label != b for a, b in zip(out, truth)]
        assert sum(wrong) == round(fraction * len(truth))
        assert all(f.label in {"corridor", "office", "meeting"} for f in out)
        assert [f.stamp_s for f in out] == [f.stamp_s for f in frames]
    again = [[f.label for f in swap_place_labels(frames, 0.25, seed=s)] for s in (4, 4, 5)]
    assert again[0] == again[1] != again[2]  # seeded
    # one room only: labels to swap to are given by the building's kinds
    one = [PlaceLabel(0.1 * k, "place_label", "corridor") for k in range(20)]
    out = swap_place_labels(one, 0.5, seed=1, labels=("corridor", "office"))
    assert sum(f.label == "office" for f in out) == 10
    with pytest.raises(ConfigError, match="place_label_error_fraction"):
        swap_place_labels(frames, 1.5, seed=0)


def test_sessions_row_is_parsed_and_refused_when_malformed():
    plans = parse_sessions("0:corridor_s,meeting; 2:office0")
    assert [(p.session, p.day, p.regions) for p in plans] == [(0, 0, ("corridor_s", "meeting")), (1, 2, ("office0",))]
    for bad in ("", "corridor_s", "1:a;0:b", "x:a"):
        with pytest.raises(ConfigError, match="sessions"):
            parse_sessions(bad)


def _plane(z: float, n: int = 41) -> np.ndarray:
    g = np.linspace(0.0, 2.0, n)
    X, Y = np.meshgrid(g, g)
    return np.stack([X.ravel(), Y.ravel(), np.full(X.size, z)], axis=1)


def test_scorer_against_an_independent_computation():
    """Two sessions with known errors: ATE, map error and change counts computed by hand."""
    T_we = np.eye(4)
    T_we[:3, 3] = [10.0, 0.0, 0.0]  # session 0's frame in the world
    t = np.arange(0.0, 3.01, 0.1)
    path = np.stack([t, np.zeros_like(t), np.ones_like(t)], axis=1)  # 1 m/s along x, world - T_we
    rows = lambda off: np.column_stack([t + off, path + T_we[:3, 3], np.tile([1.0, 0, 0, 0], (len(t), 1))])  # noqa: E731
    floor = _plane(0.0)
    box = np.array([[1.0, 1.0, z] for z in np.arange(0.0, 0.5, 0.01)])  # appeared on day 1
    extra = {
        "sessions": ({"session": 0, "day": 0, "camera_w": rows(0.0)}, {"session": 1, "day": 1, "camera_w": rows(10.0)}),
        # the disappeared sample is 2 m above anything mapped: unobserved, scored nowhere
        "changes": {1: {"appeared": box + T_we[:3, 3], "disappeared": np.array([[1.5, 1.5, 2.0]]) + T_we[:3, 3], "objects": []}},
        "surface_last_day": floor + T_we[:3, 3],
        "surfaces_by_day": {0: floor + T_we[:3, 3], 1: np.concatenate([floor, box]) + T_we[:3, 3]},
    }
    ep = _episode((), extra, T_we)
    k = np.arange(0, len(t), 5)
    poses = np.tile(np.eye(4), (len(k), 1, 1))
    poses[:, :3, 3] = path[k]
    poses1 = poses.copy()
    poses1[:, 1, 3] += 0.03  # session 1 merged 3 cm off in y
    map_pts = _plane(0.02, 21)  # 2 cm above the floor
    added = box[::2]  # half of the box's samples found added ...
    every = np.concatenate([map_pts, box[1::2][:5], added])  # ... five of the others left static
    static = np.arange(len(every)) < len(map_pts) + 5
    est = MultiSessionEstimate(
        sessions=(0, 1), days=(0, 1), keyframe_stamps_s=(t[k], t[k] + 10.0), T_map_cam=(poses, poses1),
        map_of_session=(0, 0), change_pairs=((0, 1),), removed_points=(np.zeros((0, 3)),), added_points=(added,),
        static_masks=(static,), merged_map_points=map_pts, map_points_no_change_detection=every,
        map_points_single_session=_plane(0.01, 21), merge_time_s=1.5, peak_memory_mb=12.0,
    )  # fmt: skip
    m = MultisessionTrack().score(ep, est)
    assert not m["failed"], m.get("failed_reason")
    n0, n1 = len(k), len(k)
    assert m["ate_m"] == pytest.approx(np.sqrt(n1 * 0.03**2 / (n0 + n1)))
    assert m["rpe_1m_m"] == pytest.approx(0.0, abs=1e-9)  # the offset is the same for every keyframe of a session
    assert m["map_error_mean_m"] == pytest.approx(0.02)
    assert m["map_error_max_m"] == pytest.approx(0.02)
    # every point straight above the floor's samples: its error is its height
    assert m["map_error_mean_m_no_change_detection"] == pytest.approx(np.mean(every[:, 2]))
    assert m["map_error_mean_m_single_session"] == pytest.approx(0.01)
    # every added point is on the box (TP); the five static box points are FN
    tp, fn = len(added), 5 + 1  # and the map point at (1, 1, 0.02), within 5 cm of the box's foot
    assert m["change_precision"] == pytest.approx(1.0)
    assert m["change_recall"] == pytest.approx(tp / (tp + fn))
    assert m["change_f1"] == pytest.approx(2 * tp / (2 * tp + fn))
    # Chamfer: detected->true 0 (on samples); true->detected: odd samples 1 cm from the nearest even one
    d = np.abs(box[:, 2][:, None] - added[:, 2][None, :]).min(axis=1)
    assert m["change_chamfer_m"] == pytest.approx(0.5 * d.mean())
    assert m["merge_time_s"] == 1.5 and m["peak_memory_mb"] == 12.0
    assert m["n_separate_sessions"] == 0 and m["n_change_runs"] == 1
    # session 1 overlapping nothing: its own map, reported, out of the ATE
    apart = dataclasses.replace(est, map_of_session=(0, 1), separate_sessions=(1,), change_pairs=(), removed_points=(),
                                added_points=(), static_masks=())  # fmt: skip
    m = MultisessionTrack().score(ep, apart)
    assert m["n_separate_sessions"] == 1 and m["separate_sessions"] == [1]
    assert m["ate_m"] == pytest.approx(0.0, abs=1e-12) and m["n_change_runs"] == 0 and np.isnan(m["change_precision"])


def _rot_z(a: float) -> np.ndarray:
    return np.array([[np.cos(a), -np.sin(a), 0.0], [np.sin(a), np.cos(a), 0.0], [0.0, 0.0, 1.0]])


@pytest.mark.parametrize("walk", ["turning", "straight"])
def test_aligned_ate_is_the_error_left_after_the_best_rigid_motion(walk):
    """``ate_aligned_m`` (Table I's aligned trajectories): a merged map that is the truth turned
    and shifted rigidly scores 0 however far it lies (``ate_m`` counts the offset), on a straight
    walk too (where the rotation about the line is free); a map bent inside scores the minimum of
    the RMS over rigid motions, found here by a numerical search."""
    from scipy.optimize import minimize

    t = np.arange(0.0, 6.01, 0.1)
    if walk == "turning":  # 3 m east, then 3 m north, climbing 10 cm
        path = np.where(t[:, None] < 3.0, np.stack([t, 0 * t, 0.01 * t], 1), np.stack([0 * t + 3.0, t - 3.0, 0.01 * t], 1))
    else:
        path = np.stack([t, np.zeros_like(t), np.ones_like(t)], axis=1)
    rows = np.column_stack([t, path, np.tile([1.0, 0, 0, 0], (len(t), 1))])
    ep = _episode((), {"sessions": ({"session": 0, "day": 0, "camera_w": rows},), "surface_last_day": _plane(0.0),
                       "surfaces_by_day": {0: _plane(0.0)}, "changes": {}})  # fmt: skip
    k = np.arange(0, len(t), 3)

    def score(p):
        poses = np.tile(np.eye(4), (len(k), 1, 1))
        poses[:, :3, 3] = p
        est = MultiSessionEstimate(sessions=(0,), days=(0,), keyframe_stamps_s=(t[k],), T_map_cam=(poses,), map_of_session=(0,),
                                   merged_map_points=_plane(0.0), map_points_no_change_detection=_plane(0.0),
                                   map_points_single_session=_plane(0.0))  # fmt: skip
        m = MultisessionTrack().score(ep, est)
        assert not m["failed"], m.get("failed_reason")
        return m

    rigid = path[k] @ _rot_z(0.3).T + [0.5, -0.2, 0.1]
    m = score(rigid)
    assert m["ate_m"] > 0.4 and m["ate_aligned_m"] == pytest.approx(0.0, abs=1e-6)
    bent = path[k] + np.outer(np.arange(len(k)) / len(k), [0.0, 0.2, 0.0])  # drifts 0.2 m sideways
    bent[len(k) // 2:, 2] += 0.05

    def rms(x):  # x: rotation vector, translation
        from scipy.spatial.transform import Rotation

        return np.sqrt(np.mean(np.sum((bent @ Rotation.from_rotvec(x[:3]).as_matrix().T + x[3:] - path[k]) ** 2, 1)))

    best = min((minimize(rms, x0, method="Nelder-Mead", options={"xatol": 1e-10, "fatol": 1e-12, "maxiter": 40000})
                for x0 in (np.zeros(6), np.r_[0.0, 0.0, 0.1, 0, 0, 0])), key=lambda r: r.fun)  # fmt: skip
    m = score(bent)
    assert m["ate_aligned_m"] == pytest.approx(best.fun, abs=1e-5)
    assert m["ate_aligned_m"] < m["ate_m"]


def test_change_truth_flags_the_samples_on_the_changed_object_and_not_the_floor_it_covers():
    """The quick case's stack of boxes (day 1): its faces are on the object; the floor under its
    footprint disappeared (covered) and is flagged off the object."""
    from exobench.benchmarks.tracks.multisession.episodes import on_objects, session_scenario
    from exobench.envs.sim.scenarios.office import _change_script
    from exobench.models.office_change_truth import change_truth

    track = MultisessionTrack()
    scenario = track.validate_scenario(track.cases("quick")[0].scenario)
    office = session_scenario(scenario, parse_sessions(scenario["sessions"])[-1])
    params = office.office_params()
    day = change_truth(params, _change_script(params, office.changes, office.change_seed, 1), 1).days[0]
    (oid, _, kind), = [(o.object_id, o.cls, o.kind) for o in day.objects]
    assert kind == "added"
    app, dis = on_objects(day.appeared_geoms, day.objects), on_objects(day.disappeared_geoms, day.objects)
    assert app.all() and len(app) > 1000  # every appeared sample is on the boxes' faces
    assert len(dis) > 100 and not dis.any()  # every disappeared one is covered floor ...
    assert np.allclose(day.disappeared[:, 2], 0.0)
    lo, hi = day.appeared.min(axis=0), day.appeared.max(axis=0)  # ... inside the boxes' footprint
    assert np.all((day.disappeared[:, :2] >= lo[:2] - 1e-9) & (day.disappeared[:, :2] <= hi[:2] + 1e-9))
    assert on_objects(("floor_corridor_n", f"{oid}_box0", f"{oid}x_box0"), day.objects).tolist() == [False, True, False]


def test_a_covered_floor_is_no_missed_change():
    """A box put down on day 1 covers floor the prior map holds: those prior points are kept
    (nothing can see under the box) and are truly static, not missed changes."""
    floor = _plane(0.0)
    box = np.array([[1.0, 1.0 + y, z] for y in np.arange(-0.1, 0.11, 0.01) for z in np.arange(0.01, 0.3, 0.01)])
    under = floor[(np.abs(floor[:, 0] - 1.0) <= 0.05) & (np.abs(floor[:, 1] - 1.0) <= 0.1)]
    changes = {1: {"appeared": box, "disappeared": under, "appeared_on_object": np.ones(len(box), bool),
                   "disappeared_on_object": np.zeros(len(under), bool), "objects": []}}  # fmt: skip
    t = np.arange(0.0, 1.01, 0.1)
    rows = np.column_stack([t, t, np.zeros_like(t), np.ones_like(t), np.tile([1.0, 0, 0, 0], (len(t), 1))])
    extra = {"sessions": ({"session": 0, "day": 0, "camera_w": rows}, {"session": 1, "day": 1, "camera_w": rows}),
             "changes": changes, "surface_last_day": np.concatenate([floor, box]),
             "surfaces_by_day": {0: floor, 1: np.concatenate([floor, box])}}  # fmt: skip
    poses = np.tile(np.eye(4), (len(t), 1, 1))
    est = MultiSessionEstimate(
        sessions=(0, 1), days=(0, 1), keyframe_stamps_s=(t, t), T_map_cam=(poses, poses), map_of_session=(0, 0),
        change_pairs=((0, 1),), removed_points=(np.zeros((0, 3)),), added_points=(box[::2],),
        static_masks=(np.arange(len(under) + len(box[::2]) + 10) < len(under) + 10,), merged_map_points=floor,
        map_points_no_change_detection=np.concatenate([under, box[1::2][:10], box[::2]]), map_points_single_session=floor,
    )  # fmt: skip
    m = MultisessionTrack().score(_episode((), extra), est)
    # TP: the added half of the box; FN: the ten box points left static, not the floor under it
    tp = len(box[::2])
    assert m["change_recall"] == pytest.approx(tp / (tp + 10))
    assert m["change_precision"] == pytest.approx(1.0)


def test_counters_restart_at_a_session_start_counts_no_drop_over_the_gap():
    c = StreamCounters({"imu_thigh_r": 10.0})
    imu = lambda t: ImuSample(t, "imu_thigh_r", np.array([1.0, 0, 0, 0]), np.zeros(3), np.zeros(3))  # noqa: E731
    for t in (0.0, 0.1, 0.2):
        c.admit(imu(t))
    c.restart()
    for t in (5.0, 5.1):
        c.admit(imu(t))
    assert c.snapshot()["imu"].dropped == 0 and c.snapshot()["imu"].used == 0 and c.snapshot()["imu"].seen == 5
    c.admit(imu(5.5))  # a gap inside a session is still a drop
    assert c.snapshot()["imu"].dropped == 3


def test_scorer_fails_well_formed_on_a_malformed_estimate():
    ep = _episode((), {"sessions": ({"session": 0, "day": 0, "camera_w": np.zeros((3, 8))},)})
    est = MultiSessionEstimate(sessions=(0,), days=(), keyframe_stamps_s=(), T_map_cam=(), map_of_session=())
    m = MultisessionTrack().score(ep, est)
    assert m["failed"] and "days" in m["failed_reason"] and np.isnan(m["ate_m"])


def test_quick_suite_through_exobench_run_on_the_smoke_scenario(tmp_path):
    """`exobench run --track multisession` on the smoke scenario: every pipeline scored, the
    trajectory and map metrics finite, the sessions kept apart reported. (Its recording, whose
    ``--rerun`` simulated the episode and ran both pipelines a second time, is the next test's.)"""
    track = MultisessionTrack()
    sets = [a for k, v in track.smoke_scenario.items() for a in ("--set", f"{k}={v}")]
    out = tmp_path / "run"
    result = CliRunner().invoke(cli, ["run", "--track", "multisession", *sets, "--out", str(out)], catch_exceptions=False)
    assert result.exit_code == 0, result.output
    records = [json.loads(line) for line in (out / "results.jsonl").read_text().splitlines()]
    assert sorted(r["pipeline"] for r in records) == ["lt-exosense", "lt-exosense-dufomap"]
    for r in records:
        m = r["metrics"]
        assert not m["failed"], m.get("failed_reason")
        for key in ("ate_m", "rpe_1m_m", "map_error_mean_m", "map_error_p90_m", "map_error_mean_m_single_session",
                    "merge_time_s", "peak_memory_mb"):
            assert np.isfinite(m[key]), key
        assert m["n_sessions"] == 2 and m["n_separate_sessions"] == len(m["separate_sessions"])
        assert m["ate_m"] < 0.5
    assert "Table II" in (out / "report.md").read_text()


def test_rerun_recording_of_the_first_episode(tmp_path):
    """What ``exobench run --rerun`` writes for the track (``rerun_first_episode``: the episode
    simulated again, a pipeline's online and final estimates): the smoke scenario's two sessions,
    its change, on the shortest walk at 2 Hz and one pipeline: about half the CPU of the smoke
    run's rerun of both pipelines (the true surfaces of the two days, ~5 s, are most of it)."""
    from exobench.benchmarks.runner import plan_run, rerun_first_episode

    small = {**MultisessionTrack.smoke_scenario, "max_distance_m": 0.5, "frame_rate_hz": 2.0}
    plan = plan_run("multisession", pipelines=["lt-exosense"], overrides=small)
    rrd = rerun_first_episode(plan, tmp_path / "ms.rrd")
    assert rrd == tmp_path / "ms.rrd"
    assert rrd.stat().st_size > 10_000  # sessions, pose graph edges, map and changes


def test_invalid_change_script_is_refused_before_anything_runs(tmp_path):
    result = CliRunner().invoke(cli, ["run", "--track", "multisession", "--set", "changes=1 remove nosuchthing",
                                      "--out", str(tmp_path / "run")])  # fmt: skip
    assert result.exit_code == 2
    assert "day 1" in result.output and "nosuchthing" in result.output
    assert not (tmp_path / "run" / "results.jsonl").exists()


def test_bench_multisession_scenario_is_the_quick_office_walked_ten_times():
    from exobench.benchmarks.bench.multisession import bench_scenario

    track = MultisessionTrack()
    quick = track.validate_scenario(track.cases("quick")[0].scenario)
    scenario = track.validate_scenario(bench_scenario(10, 2.0))  # refused if the bench's rows were not the track's
    plans = parse_sessions(scenario["sessions"])
    assert [p.day for p in plans] == [0] + [1] * 9
    assert {p.regions for p in plans} == {parse_sessions(quick["sessions"])[0].regions}
    assert scenario["max_distance_m"] == 2.0
    assert {k: v for k, v in scenario.items() if k not in ("sessions", "max_distance_m")} == {
        k: v for k, v in quick.items() if k not in ("sessions", "max_distance_m")}


@pytest.mark.parametrize("rate", [None, 0.5])
def test_session_odometry_heading_drifts_at_the_sourced_rate(rate):
    """The sessions' odometry turns away from the true heading at 0.02 deg per metre walked (the
    paper's VIO, not the odometry kind's 0.5 deg/m default), or at the row's rate when set; the
    turn is measured against the true camera poses, the distance along the true path."""
    from exobench.benchmarks.tracks.multisession.episodes import stream_sessions
    from exobench.core.frames import OdometrySample

    track = MultisessionTrack()
    rows = {**track.smoke_scenario, "sessions": "0:corridor_s", "max_distance_m": 1.5}
    if rate is not None:
        rows["odom_yaw_drift_deg_per_m"] = rate
    stream = stream_sessions(track.validate_scenario(rows), 0)
    odom = [f for f in stream.frames if isinstance(f, OdometrySample)]
    truth = stream.finish().truth.extra["sessions"][0]
    cam = np.asarray(truth["camera_w"])
    assert len(odom) == len(cam)
    R_odom_cam = np.stack([np.asarray(f.T_odom_body)[:3, :3] for f in odom])
    from exobench.core.transforms import quat_wxyz_to_matrix

    R_true = np.asarray(truth["T_world_odom"])[:3, :3].T @ np.stack([quat_wxyz_to_matrix(q) for q in cam[:, 4:8]])
    err = R_odom_cam[-1] @ R_true[-1].T  # the heading error: a turn about the vertical
    turn_deg = abs(np.degrees(np.arctan2(err[1, 0], err[0, 0])))
    walked = float(np.sum(np.linalg.norm(np.diff(cam[:, 1:3], axis=0), axis=1)))
    assert walked > 1.0
    assert turn_deg == pytest.approx((0.02 if rate is None else rate) * walked, rel=0.05, abs=1e-4)


def _quick_office_and_calibration():
    from exobench.benchmarks.tracks.multisession.episodes import session_rig, session_scenario
    from exobench.envs.sim.calibration import build_calibration

    track = MultisessionTrack()
    scenario = track.validate_scenario(track.cases("quick")[0].scenario)
    plans = parse_sessions(scenario["sessions"])
    calibration = build_calibration(session_scenario(scenario, plans[0]).exo_spec(), session_rig(scenario))
    return scenario, calibration


def test_camera_reach_is_the_largest_depth_along_the_image_corner_ray():
    """The thigh camera, 424 x 240 pixels, fx = fy = 212 px, centred, depth up to 6 m: the corner
    ray (the pixel edges, 212 and 120 px off the centre) is 1 : 1 : 120/212 to the optical axis."""
    from exobench.benchmarks.tracks.multisession.episodes import camera_reach_m

    _, calibration = _quick_office_and_calibration()
    camera = calibration.extra["camera"]
    assert camera_reach_m(calibration, camera) == pytest.approx(6.0 * np.sqrt(1.0 + 1.0 + (120 / 212) ** 2), abs=1e-9)


def test_the_true_surfaces_cover_what_the_camera_can_see():
    """A camera standing at the north corridor's west end sees its east end wall 7.5 m away (and
    up to 9.1 m at its image's corners): that wall's samples are in the truth the map is scored
    against, the same to the bit as the wall's own (the 3 m margin before left it out)."""
    from exobench.benchmarks.tracks.multisession.episodes import camera_reach_m, session_scenario, world_truth
    from exobench.envs.sim.scenarios.office import _change_script
    from exobench.models.office_change_truth import surface_samples

    scenario, calibration = _quick_office_and_calibration()
    plans = parse_sessions(scenario["sessions"])
    office = session_scenario(scenario, plans[-1])
    params = office.office_params()
    cam = np.zeros((2, 8))
    cam[:, 0], cam[:, 1:4], cam[:, 4] = [0.0, 0.1], [0.5, 6.9, 0.5], 1.0
    sessions = ({"session": 0, "day": 0, "camera_w": cam}, {"session": 1, "day": 1, "camera_w": cam})
    truth = world_truth(scenario, sessions, camera_reach_m(calibration, calibration.extra["camera"]))
    wall = np.array([[7.9, 6.5, 0.2], [8.1, 7.5, 1.2]])  # the end wall's face at x = 8, 7.5 m from the camera
    script = _change_script(params, office.changes, office.change_seed, 1)
    want = surface_samples(params, script, 1, 0.01, wall)
    got = truth["surface_last_day"]
    got = got[np.all((got >= wall[0]) & (got <= wall[1]), axis=1)]
    assert len(want) > 5000 and np.allclose(want[:, 0], 8.0)
    assert np.array_equal(got.view(np.uint64), want.view(np.uint64))
