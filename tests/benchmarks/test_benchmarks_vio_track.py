"""The vio track: its scorer against computations done here by hand, its suites, its streamed
truth, its refusals and a run of its quick suite from the command line.

The scorer is checked on a constructed episode (a camera walking a 3 x 2 m rectangle at 30 Hz,
back to where it started, facing as it started) so that every expected value has a closed form:
the ATE of a noisy estimate by an SVD (Kabsch) alignment written here, the loop drift of a known
end offset, the share of frames without a pose, the time to the first pose.
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest

from exobench.benchmarks.tracks import get_track
from exobench.benchmarks.tracks.vio import paper
from exobench.benchmarks.tracks.vio.general import general_cases
from exobench.core import Calibration, Episode, EpisodeTruth, SceneTruth
from exobench.core.calibration import SensorMount
from exobench.core.counters import FrameCounts
from exobench.core.errors import ConfigError
from exobench.core.estimates import TrajectoryEstimate
from exobench.core.frames import ImuSample, RgbdFrame
from exobench.core.transforms import make_T, matrix_to_quat_wxyz, quat_wxyz_to_matrix, rot_z

pytestmark = pytest.mark.long(seconds=20)  # the workers take it first (tests/conftest.py); 20: the file at -n 0 in one run at load 12-15, scaled to that run's CPU

RATE_HZ = 30.0
TRACK = get_track("vio")


def _rectangle_walk() -> np.ndarray:
    """(N, 4, 4) camera poses: 3 x 2 m rectangle at 0.5 m/s, yaw following the path, a 3 cm
    vertical bob, ending exactly at the first pose."""
    corners = np.array([[0, 0], [3, 0], [3, 2], [0, 2], [0, 0]], dtype=float)
    seg = np.linalg.norm(np.diff(corners, axis=0), axis=1)
    n = int(round(seg.sum() / 0.5 * RATE_HZ))
    s = np.linspace(0.0, seg.sum(), n + 1)
    cum = np.concatenate([[0.0], np.cumsum(seg)])
    xy = np.column_stack([np.interp(s, cum, corners[:, k]) for k in range(2)])
    yaw = 0.4 * np.sin(2 * np.pi * s / seg.sum())  # back to 0 at the end
    z = 1.5 + 0.03 * np.sin(2 * np.pi * s / 0.7)
    z[-1] = z[0]
    return np.stack([make_T(rot_z(a), [x, y, h]) for (x, y), a, h in zip(xy, yaw, z, strict=True)])


def _episode(T: np.ndarray, latency_s: float = 0.0) -> Episode:
    t = np.arange(len(T)) / RATE_HZ
    rows = np.column_stack([t, T[:, :3, 3], np.stack([matrix_to_quat_wxyz(R) for R in T[:, :3, :3]])])
    cal = Calibration("", "pelvis", (), (SensorMount("rgbd_head", "rgbd", "head", np.eye(4), {"latency_s": latency_s}),
                                          SensorMount("imu_head", "imu", "head", np.eye(4))), 0.1, 0.26, 0.05)  # fmt: skip
    truth = EpisodeTruth(scene=SceneTruth((), {}), T_world_estimator=np.eye(4),
                         body_tracks={"rgbd_head": rows, "imu_head": rows})  # fmt: skip
    cal = dataclasses.replace(cal, extra={"camera": "rgbd_head", "camera_imu": "imu_head"})
    return Episode({"world": "office"}, 0, cal, (), truth)


def _estimate(stamps, T, status=None, times=None, used=None) -> TrajectoryEstimate:
    n = len(stamps)
    counts = {"rgbd": FrameCounts(used=used)} if used is not None else {}
    return TrajectoryEstimate(np.asarray(stamps, dtype=float), np.asarray(T), np.full(n, 0.02) if times is None else times,
                              status=tuple(status or ("ok",) * n), counts=counts)  # fmt: skip


def _kabsch_rmse(p: np.ndarray, q: np.ndarray) -> float:
    """RMSE of |R p + t - q| at the best rotation and translation (Kabsch, written out here)."""
    pc, qc = p - p.mean(0), q - q.mean(0)
    u, _, vt = np.linalg.svd(qc.T @ pc)
    d = np.sign(np.linalg.det(u @ vt))
    R = u @ np.diag([1.0, 1.0, d]) @ vt
    return float(np.sqrt(np.mean(np.sum((pc @ R.T - qc) ** 2, axis=1))))


def _in_frame(G: np.ndarray, T: np.ndarray) -> np.ndarray:
    return np.einsum("ij,njk->nik", G, T)


G_EST = make_T(rot_z(1.1), [5.0, -2.0, 0.3])  # the estimator's own world


def test_a_perfect_estimate_in_its_own_frame_scores_zero_and_a_closed_loop_is_found():
    T = _rectangle_walk()
    ep = _episode(T)
    m = TRACK.score(ep, _estimate(np.arange(len(T)) / RATE_HZ, _in_frame(G_EST, T)))
    assert not m["failed"]
    assert m["ate_m"] < 1e-9 and m["te_m"] < 1e-9 and m["lost_frac"] == 0.0 and m["init_s"] == 0.0
    assert m["path_m"] == pytest.approx(np.sum(np.linalg.norm(np.diff(T[:, :3, 3], axis=0), axis=1)))


def test_ate_of_a_known_perturbation_is_the_kabsch_rmse_computed_here():
    T = _rectangle_walk()
    rng = np.random.default_rng(3)
    noisy = T.copy()
    noisy[:, :3, 3] += rng.normal(0.0, 0.05, (len(T), 3))
    m = TRACK.score(_episode(T), _estimate(np.arange(len(T)) / RATE_HZ, _in_frame(G_EST, noisy)))
    assert m["ate_m"] == pytest.approx(_kabsch_rmse(noisy[:, :3, 3], T[:, :3, 3]), rel=1e-9)
    assert 0.07 < m["ate_m"] < 0.1  # sqrt(3) * 0.05, less what the alignment absorbs


def test_loop_drift_of_a_known_end_offset():
    T = _rectangle_walk()
    est = T.copy()
    delta = np.array([-0.216, 0.023, 0.136])  # Table V's D-VIO drift; the first pose is upright, so its axes are G's
    k = len(T) - 30  # the last second drifts linearly to it
    est[k:, :3, 3] += np.linspace(0.0, 1.0, len(T) - k)[:, None] * delta
    m = TRACK.score(_episode(T), _estimate(np.arange(len(T)) / RATE_HZ, _in_frame(G_EST, est)))
    assert [m["tve_x_m"], m["tve_y_m"], m["tve_z_m"]] == pytest.approx(delta, abs=1e-9)
    assert m["te_m"] == pytest.approx(np.linalg.norm(delta), abs=1e-9)  # 0.256, Table V
    assert m["oe_rad"] == pytest.approx(0.0, abs=1e-9)


def test_loop_drift_of_an_optical_frame_camera_is_given_in_gravity_axes_as_table_v():
    """A real camera's pose is its optical frame (x right, y down, z forward), looking 10 deg down:
    Table V's drift z is vertical (D-VIO's frame G is gravity-aligned), so a drift of 0.136 m up
    must come out as ``tve_z_m``, not along the first camera's down or forward axis."""
    pitch = np.radians(10.0)
    c, s = np.cos(pitch), np.sin(pitch)
    body_to_optical = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]]) @ np.array(
        [[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])  # optical axes in the walker's (x ahead, z up), pitched down
    T = _rectangle_walk()
    T[:, :3, :3] = T[:, :3, :3] @ body_to_optical
    right, ahead, up = np.array([0.0, -1.0, 0.0]), np.array([1.0, 0.0, 0.0]), np.array([0.0, 0.0, 1.0])  # at the start
    drift_g = np.array([-0.216, 0.023, 0.136])  # Table V's x / y / z
    est = T.copy()
    k = len(T) - 30
    est[k:, :3, 3] += np.linspace(0.0, 1.0, len(T) - k)[:, None] * (drift_g @ np.stack([right, ahead, up]))
    m = TRACK.score(_episode(T), _estimate(np.arange(len(T)) / RATE_HZ, _in_frame(G_EST, est)))
    assert [m["tve_x_m"], m["tve_y_m"], m["tve_z_m"]] == pytest.approx(drift_g, abs=1e-9)
    assert m["te_m"] == pytest.approx(0.256, abs=1e-3)


def test_lost_frames_are_counted_and_never_scored():
    T = _rectangle_walk()
    n = len(T)
    stamps = np.arange(n) / RATE_HZ
    status = ["lost" if i < 15 or i % 2 else "ok" for i in range(n)]
    P = _in_frame(G_EST, T)
    P[1::2] = np.nan  # a lost frame's pose may be anything; NaN must not leak into the scores
    times = np.linspace(0.01, 0.05, n)
    used = n + 20  # 20 frames the pipeline used but left out of its estimate: lost too
    m = TRACK.score(_episode(T), _estimate(stamps, P, status, times, used))
    scored = sum(s == "ok" for s in status)
    assert m["n_poses"] == scored and m["n_frames"] == used
    assert m["lost_frac"] == pytest.approx(1.0 - scored / used)
    assert m["init_s"] == pytest.approx(16 / RATE_HZ)  # frame 16: the first even frame after 15 lost
    assert m["ate_m"] < 1e-9 and not m["failed"]
    assert m["time_per_frame_ms"] == pytest.approx(1e3 * np.median(times))
    assert m["time_per_frame_ms_p95"] == pytest.approx(1e3 * np.percentile(times, 95))


def test_an_estimate_without_a_pose_fails_and_is_never_scored_good():
    T = _rectangle_walk()
    n = len(T)
    for est in (_estimate(np.arange(n) / RATE_HZ, T, ["lost"] * n),
                _estimate(np.zeros(0), np.zeros((0, 4, 4))),
                _estimate(np.arange(n) / RATE_HZ, np.full((n, 4, 4), np.nan))):  # fmt: skip
        m = TRACK.score(_episode(T), est)
        assert m["failed"] and math.isnan(m["ate_m"]) and math.isnan(m["te_m"])
        assert m["lost_frac"] == 1.0 or math.isnan(m["lost_frac"])


def test_a_camera_that_never_moves_scores_the_spread_of_the_true_path():
    T = _rectangle_walk()
    m = TRACK.score(_episode(T), _estimate(np.arange(len(T)) / RATE_HZ, np.tile(np.eye(4), (len(T), 1, 1))))
    p = T[:, :3, 3]
    assert m["ate_m"] == pytest.approx(np.sqrt(np.mean(np.sum((p - p.mean(0)) ** 2, axis=1))))
    assert m["ate_m"] > 0.9


def test_a_straight_walk_is_scored_though_evo_refuses_to_align_a_line():
    """Every position on one line (a straight corridor): Umeyama's rotation about the line is free
    and evo refuses it; the ATE is the minimum all those rotations share (Kabsch here), and the
    record keeps its counts. It used to fail whole, with lost_frac NaN."""
    n = 90
    T = np.stack([make_T(np.eye(3), [0.5 * k / RATE_HZ, 0.0, 1.5]) for k in range(n)])
    est = T.copy()
    est[:, 0, 3] += np.random.default_rng(4).normal(0.0, 0.02, n)  # errors along the line only
    status = ["lost"] * 10 + ["ok"] * (n - 10)
    m = TRACK.score(_episode(T), _estimate(np.arange(n) / RATE_HZ, _in_frame(G_EST, est), status=status))
    assert not m["failed"], m["failed_reason"]
    assert m["ate_m"] == pytest.approx(_kabsch_rmse(est[10:, :3, 3], T[10:, :3, 3]), rel=1e-6)
    assert m["ate_m"] > 0.01 and m["lost_frac"] == pytest.approx(10 / n) and m["n_poses"] == n - 10


def test_the_truth_is_read_at_the_measurement_time_of_a_late_frame():
    T = _rectangle_walk()
    latency = 5 / RATE_HZ
    stamps = np.arange(len(T)) / RATE_HZ + latency  # delivered 5 frames after measurement
    m = TRACK.score(_episode(T, latency), _estimate(stamps, T))
    assert m["ate_m"] < 1e-9 and m["n_poses"] == len(T)


# ---------------------------------------------------------------- suites and refusals


def test_quick_suite_has_one_walk_per_mount_and_a_short_closed_loop():
    cases = TRACK.cases("quick")
    walks = [c for c in cases if not c.scenario.get("out_and_back")]
    assert sorted(c.scenario["mount"] for c in walks) == ["chest", "head", "thigh"]
    loops = [c for c in cases if c.scenario.get("out_and_back")]
    assert len(loops) == 1 and loops[0].scenario["max_distance_m"] <= 2.0
    assert all(c.scenario["max_distance_m"] <= 2.0 for c in cases)


def test_paper_suite_is_shaped_like_tables_iv_and_v():
    cases = TRACK.cases("paper")
    euroc = [c for c in cases if c.group in paper.EUROC]
    assert [c.group for c in euroc] == list(paper.EUROC)
    for c in euroc:
        length, speed = paper.EUROC_LENGTH_SPEED[c.group]
        assert 35.0 <= c.scenario["max_distance_m"] <= 90.0
        assert c.scenario["max_distance_m"] == pytest.approx(min(max(length, 35.0), 90.0))
        step, swing = paper.PACES[paper.pace_of(speed)]
        assert (c.scenario["step_length_m"], c.scenario["swing_s"]) == (step, swing)
    assert {paper.pace_of(paper.EUROC_LENGTH_SPEED[c.group][1]) for c in euroc} == {"wander", "walk", "jog"}
    assert {c.scenario["mount"] for c in cases} == {"head", "chest", "thigh"}
    assert all(1.65 <= c.scenario["user_height_m"] <= 1.88 for c in cases)
    loops = [c for c in cases if c.group == "loop"]
    # closed: a whole ring (the planner ends it where it started) or there and back
    assert loops and all(c.scenario.get("out_and_back") or (c.scenario["route"] == "ring" and c.scenario["max_distance_m"] >= 500) for c in loops)
    assert {c.scenario["world"] for c in cases} == {"office", "course"}


def test_general_suite_is_drawn_from_the_run_seed():
    a, b = general_cases(0), general_cases(1)
    assert len(a) >= 8 and a == general_cases(0) and [c.scenario for c in a] != [c.scenario for c in b]
    drawn = [c.scenario for s in range(4) for c in general_cases(s)]
    assert {d["world"] for d in drawn} == {"office", "course"}
    assert {d["mount"] for d in drawn} == {"head", "chest", "thigh"}
    assert len({d.get("surfaces", "default") for d in drawn}) == 3
    for c in a:
        TRACK.validate_scenario(c.scenario)


@pytest.mark.parametrize(
    ("values", "field"),
    [
        ({"terrain": "ramp"}, "terrain"),  # a course's row on an office walk
        ({"world": "course", "route": "ring"}, "route"),  # an office's row on a course
        ({"imu_time_offset_s": 0.5}, "imu_time_offset_s"),
        ({"width_px": 8}, "width_px"),
        ({"imu_rate_hz": 50.0}, "imu_rate_hz"),
        ({"frame_dropout": 0.95}, "frame_dropout"),
        ({"world": "moon"}, "world"),
    ],
)
def test_bad_camera_imu_and_world_values_are_refused_naming_the_field(values, field):
    with pytest.raises(ConfigError) as err:
        TRACK.validate_scenario(values)
    assert err.value.field == field and str(err.value).startswith(f"{field}=")


# ---------------------------------------------------------------- a streamed walk


def test_a_streamed_walk_keeps_a_camera_pose_per_frame_and_an_imu_pose_per_sample():
    """With the D455's extrinsics the IMU's true pose is the camera's times T_camera_imu at the
    instants both sample (every 0.1 s): an independent check of both truths."""
    scenario = TRACK.validate_scenario({**TRACK.smoke_scenario, "mount": "chest", "imu_extrinsics": "d455",
                                        "width_px": 64, "height_px": 48})  # fmt: skip
    stream = TRACK.stream(scenario, 0)
    n_rgbd = n_imu = 0
    for f in stream.frames:
        n_rgbd += isinstance(f, RgbdFrame)
        n_imu += isinstance(f, ImuSample)
    ep = stream.finish()
    assert not ep.frames
    cam, imu = ep.truth.body_tracks["rgbd_chest"], ep.truth.body_tracks["imu_chest"]
    assert len(cam) == n_rgbd > 50 and len(imu) == n_imu > 300
    T_ci = np.asarray(ep.calibration.extra["T_camera_imu"], dtype=float)
    shared = [(i, j) for i, t in enumerate(cam[:, 0]) for j in np.flatnonzero(np.abs(imu[:, 0] - t) < 1e-9)]
    assert len(shared) >= 5
    for i, j in shared:
        T_wc = make_T(quat_wxyz_to_matrix(cam[i, 4:8]), cam[i, 1:4])
        T_wi = make_T(quat_wxyz_to_matrix(imu[j, 4:8]), imu[j, 1:4])
        assert np.allclose(T_wc @ T_ci, T_wi, atol=1e-6)
    # the chest camera turns on its rig (the view process), unlike a camera fixed to the pelvis
    assert {"chest_yaw", "chest_pitch"} <= set(TRACK_VIEW_JOINTS(scenario))


def TRACK_VIEW_JOINTS(scenario) -> list[str]:  # noqa: N802
    from exobench.benchmarks.tracks.vio.scenario import _scenario
    from exobench.envs.sim.scenarios.office import plan_office_walk

    sc = _scenario(scenario)
    _, motion = plan_office_walk(sc, sc.rig())
    return [j for h in sc.recording_hooks(sc.exo_spec(), motion, 0) for j in h.view.joints]


# ---------------------------------------------------------------- the command line


def test_quick_suite_runs_from_the_command_line_with_a_test_pipeline(tmp_path, still_camera_installed):
    import json

    from click.testing import CliRunner

    from exobench.benchmarks.cli import cli

    out = tmp_path / "run"
    args = ["run", "--track", "vio", "--pipeline", "vio-still", "--out", str(out), "--set", "max_distance_m=0.6",
            "--set", "rate_hz=10", "--set", "width_px=64", "--set", "height_px=48", "--set", "vio-still.lost_every=2",
            "--set", "repeated_frames=0.2", "--set", "late_frames=0.1", "--set", "imu_dropout=0.1"]
    result = CliRunner().invoke(cli, args)
    assert result.exit_code == 0, result.output
    records = [json.loads(line) for line in (out / "results.jsonl").read_text().splitlines()]
    assert sorted(r["case"] for r in records) == sorted(c.name for c in TRACK.cases("quick"))
    for r in records:
        m = r["metrics"]
        assert m["lost_frac"] == pytest.approx(np.floor(m["n_frames"] / 2) / m["n_frames"])
        assert m["ate_m"] > 0.0
        # the delivery faults reached the streams and were counted, not fatal
        assert m["frames.imu.repeated"] > 0 and m["frames.imu.out_of_order"] > 0 and m["frames.imu.dropped"] > 0
        assert m["frames.rgbd.used"] == m["n_frames"]
    report = (out / "report.md").read_text()
    assert "Table IV" in report and "Table V" in report
    assert any(Path(out, "trajectories").glob("*__vio-still.tum"))


@pytest.fixture
def still_camera_installed(monkeypatch):
    """The test pipeline installed through the ``exobench.pipelines`` entry-point group (as a
    package would install one), in fresh default registries."""
    import importlib.metadata

    from exobench.benchmarks import registry as pipeline_registry

    real = importlib.metadata.entry_points
    ep = importlib.metadata.EntryPoint("vio-still", "vio_pipeline:StillCamera", "exobench.pipelines")

    def fake(**params):
        if params.get("group") == "exobench.pipelines":
            return importlib.metadata.EntryPoints([ep])
        return real(**params)

    monkeypatch.setattr(importlib.metadata, "entry_points", fake)
    pipeline_registry.default_registry.cache_clear()
    yield
    monkeypatch.undo()
    pipeline_registry.default_registry.cache_clear()


# ---------------------------------------------------------------- delivery faults


def _imu(t: float) -> ImuSample:
    return ImuSample(t, "imu_head", np.array([1.0, 0, 0, 0]), np.zeros(3), np.array([0, 0, 9.81]))


def _rgbd(t: float) -> RgbdFrame:
    return RgbdFrame(t, "rgbd_head", np.zeros((4, 4, 3), np.uint8), np.ones((4, 4)), np.eye(3))


def test_delivery_faults_at_probability_one_do_exactly_what_they_say():
    from exobench.benchmarks.tracks.vio.faults import DeliveryFaults

    frames = [_imu(k / 200) for k in range(6)]
    late = list(DeliveryFaults({"depth_missing": 0, "repeated_frames": 0, "late_frames": 1.0}, 0).apply(frames))
    assert [f.stamp_s * 200 for f in late] == pytest.approx([1, 0, 3, 2, 5, 4])  # each pair swapped
    twice = list(DeliveryFaults({"depth_missing": 0, "repeated_frames": 1.0, "late_frames": 0}, 0).apply(frames))
    assert [f.stamp_s * 200 for f in twice] == pytest.approx([k for k in range(6) for _ in (0, 1)])
    cams = [_rgbd(k / 30) for k in range(3)]
    dark = list(DeliveryFaults({"depth_missing": 1.0, "repeated_frames": 0, "late_frames": 0}, 0).apply(cams + frames))
    assert all(not np.any(np.asarray(f.depth_m)) for f in dark[:3]) and dark[3:] == frames
    none = DeliveryFaults({"depth_missing": 0, "repeated_frames": 0, "late_frames": 0}, 0)
    assert list(none.apply(cams + frames)) == cams + frames


def test_delivery_fault_rates_and_independent_draws():
    from exobench.benchmarks.tracks.vio.faults import DeliveryFaults

    frames = [_imu(k / 200) for k in range(4000)]
    rep = list(DeliveryFaults({"depth_missing": 0, "repeated_frames": 0.1, "late_frames": 0}, 3).apply(frames))
    assert 0.08 < (len(rep) - len(frames)) / len(frames) < 0.12
    both = list(DeliveryFaults({"depth_missing": 0, "repeated_frames": 0.1, "late_frames": 0.1}, 3).apply(frames))
    stamps = np.array([f.stamp_s for f in both])
    assert len(both) == len(rep)  # turning on late frames moves no repeat draw
    assert 0.07 < np.mean(np.diff(stamps) < 0) < 0.11


def test_a_run_of_every_track_runs_the_vio_track_with_its_pipelines(tmp_path, monkeypatch):
    """Planned, not run: the runner's loop is replaced by one that keeps the plans it is given.
    (Before dvio, dvio-no-depth and orb-slam3 were registered, such a run skipped vio.)"""
    from click.testing import CliRunner

    from exobench.benchmarks import cli as cli_module
    from exobench.benchmarks.registry import default_registry

    reg = default_registry()
    want = [n for n in reg.names(track="vio") if not reg.unavailable(n)]
    assert {"dvio", "dvio-no-depth"} <= set(want)
    planned = {}
    monkeypatch.setattr(cli_module, "_run_all",
                        lambda plans, *a, **k: planned.update({p.track.name: [r.name for r in p.pipelines] for p in plans}) or [])
    result = CliRunner().invoke(cli_module.cli, ["run", "--out", str(tmp_path / "all")])
    assert result.exit_code == 0, result.output
    assert {"vio", "stairs", "odometry", "locomotion"} <= set(planned)
    assert planned["vio"] == want
    assert "skipping track vio" not in result.stderr


def test_the_recording_holds_the_images_and_the_estimate_against_the_truth(tmp_path):
    import rerun  # noqa: F401  (the recording's dependency)
    from vio_pipeline import StillCamera

    scenario = TRACK.validate_scenario({**TRACK.smoke_scenario, "width_px": 64, "height_px": 48, "rate_hz": 10})
    ep = TRACK.simulate(scenario, 0)
    pipe = StillCamera()
    pipe.reset(ep.calibration)
    for f in ep.frames:
        pipe.process(f)
    path = TRACK.write_recording(ep, {"vio-still": pipe.finalize()}, tmp_path / "vio.rrd")
    data = path.read_bytes()
    assert len(data) > 10_000
    for entity in (b"world/camera/rgb", b"world/camera/depth", b"world/truth", b"world/estimates/vio-still"):
        assert entity in data, entity


def test_an_office_walk_the_asked_step_cannot_walk_is_planned_with_a_shorter_one(monkeypatch):
    """The office loop's first doorway leaves a 1.65 m user jogging with 0.45 m steps no foothold
    (found planning the paper suite's V102-like walk): the vio office walk retries as the courses
    do; the LiDAR tracks' office walks keep the one step they ask for."""
    from exobench.benchmarks.tracks.vio.scenario import _scenario
    from exobench.envs.motion import GaitError
    from exobench.envs.sim.scenarios.office import plan_office_walk
    from exobench.envs.sim.scenarios.office_camera import CameraOfficeScenario

    values = {"route": "loop", "max_distance_m": 4.0, "step_length_m": 0.45, "swing_s": 0.3, "user_height_m": 1.65}
    sc = _scenario(TRACK.validate_scenario(values))
    _, motion = plan_office_walk(sc, sc.rig())
    steps = [np.linalg.norm((b.sole_w - a.sole_w)[:2]) for a, b in zip(motion.footsteps, motion.footsteps[2:], strict=False)]
    assert max(steps) < 0.45 * 2 * 0.95  # walked with a shorter step than asked
    monkeypatch.setattr(CameraOfficeScenario, "step_factors", lambda self: (1.0,))
    with pytest.raises(GaitError):
        plan_office_walk(sc, sc.rig())
