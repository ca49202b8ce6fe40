"""``terrain-recon`` on its own odometry (issue 27): the ``odometry`` option (``given`` | ``dvio``),
the ``terrain-recon-dvio`` variant, predictions placed with D-VIO's poses, missing poses."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from click.testing import CliRunner

from exobench.benchmarks.cli import cli
from exobench.benchmarks.registry import build_registry
from exobench.benchmarks.tracks import get_track
from exobench.core import ConfigError, ImuSample, OdometrySample, RgbdFrame
from exobench.mapping.locomotion import TerrainReconConfig, TerrainReconDvioConfig
from exobench.mapping.odometry.dvio.pipeline import DvioConfig

pytestmark = pytest.mark.long(seconds=21)  # the workers take it first (tests/conftest.py); 21: the file's CPU-s alone at -n 0 (23.7 with the bridging run, before the batched footholds)

PIPELINE_REGISTRY = build_registry(entry_points=False)


@pytest.fixture(scope="module")
def track():
    return get_track("locomotion")


@pytest.fixture(scope="module")
def smoke(track):
    """The track's smoke episode (96x72: too small for D-VIO to initialise)."""
    return track.simulate(track.validate_scenario(track.smoke_scenario), 0)


def _run(name, episode, frames=None, **values):
    pipe = PIPELINE_REGISTRY.make(name, PIPELINE_REGISTRY.make_config(name, values))
    pipe.reset(episode.calibration)
    for f in episode.frames if frames is None else frames:
        pipe.process(f)
    return pipe, pipe.finalize()


# ------------------------------------------------------------------ the option


def test_odometry_option_refuses_a_bad_value_naming_field_value_and_choices():
    with pytest.raises(ConfigError) as err:
        TerrainReconConfig(odometry="vins")
    assert (err.value.field, err.value.value) == ("odometry", "vins")
    assert "given" in str(err.value.allowed) and "dvio" in str(err.value.allowed)
    assert TerrainReconConfig().odometry == "given" and TerrainReconDvioConfig().odometry == "dvio"


def test_dvio_parameters_are_a_nested_config_of_terrain_recon():
    cfg = PIPELINE_REGISTRY.make_config("terrain-recon", {"odometry": "dvio", "dvio.window": "7", "dvio.init_keyframes": "5"})
    assert cfg.odometry == "dvio" and isinstance(cfg.dvio, DvioConfig)
    assert (cfg.dvio.window, cfg.dvio.init_keyframes) == (7, 5)
    assert dataclasses.replace(cfg.dvio, window=10, init_keyframes=10) == DvioConfig()  # the rest as D-VIO's defaults
    variant = PIPELINE_REGISTRY.make_config("terrain-recon-dvio", {"dvio.window": "6", "dvio.init_keyframes": "6"})
    assert variant.odometry == "dvio" and variant.dvio.window == 6
    assert PIPELINE_REGISTRY.load("terrain-recon-dvio").track == "locomotion"


@pytest.mark.parametrize(
    ("assignment", "expected"),
    [
        ("terrain-recon.odometry=vins", ("odometry", "vins", "given", "dvio")),
        ("terrain-recon.dvio.kernel=l2", ("kernel", "l2", "cauchy")),
        ("terrain-recon.dvio.nope=1", ("dvio.nope",)),
    ],
)
def test_bad_odometry_values_are_one_line_at_the_command_line(tmp_path, assignment, expected):
    out = tmp_path / "run"
    result = CliRunner().invoke(cli, ["run", "--track", "locomotion", "--pipeline", "terrain-recon", "--set", assignment,
                                      "--out", str(out)], catch_exceptions=False)  # fmt: skip
    assert result.exit_code == 2
    lines = [ln for ln in result.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("exobench: error: "), result.stderr
    assert all(e in lines[0] for e in expected), lines[0]
    assert not out.exists()


# ------------------------------------------------------------------ given: as before


def test_given_odometry_reads_the_stream_and_carries_its_poses(smoke, track):
    """``given`` (the default) ignores the IMU (the same predictions without it), uses the
    odometry sample of each frame (its pose times the camera's mount on the odometry's link,
    from the calibration) and is scored through the stream."""
    _, est = _run("terrain-recon", smoke)
    _, no_imu = _run("terrain-recon", smoke, [f for f in smoke.frames if not isinstance(f, ImuSample)])
    assert est.odometry == "given"
    key = [(p.stamp_s, p.mode, p.strike_index, p.status, np.asarray(p.footprint_odom, float).tobytes()) for p in est.predictions]
    assert key == [(p.stamp_s, p.mode, p.strike_index, p.status, np.asarray(p.footprint_odom, float).tobytes()) for p in no_imu.predictions]
    cal = smoke.calibration
    cam, odo = cal.mount(cal.extra["camera"]), cal.mount(cal.extra["odometry"]["sensor_id"])
    assert cam.parent_link == odo.parent_link
    T_body_cam = np.linalg.inv(np.asarray(odo.T_parent_sensor)) @ np.asarray(cam.T_parent_sensor)
    poses = {f.stamp_s: np.asarray(f.T_odom_body) for f in smoke.frames if isinstance(f, OdometrySample)}
    frames = [f.stamp_s for f in smoke.frames if isinstance(f, RgbdFrame)]
    assert [p.stamp_s for p in est.predictions] == frames and set(frames) <= set(poses)
    for p in est.predictions:
        np.testing.assert_allclose(p.T_odom_camera, poses[p.stamp_s] @ T_body_cam, atol=1e-12)
    assert sum(p.mode != "" for p in est.predictions) > 0


# ------------------------------------------------------------------ missing poses


def test_frames_without_a_dvio_pose_predict_nothing_and_are_never_scored_as_good(smoke, track):
    """On the smoke episode D-VIO never initialises: every prediction is without mode, footprint
    and pose, and every step is undecided (wrong); the given odometry decides steps on the same
    episode, so the missing poses are what leaves them undecided."""
    _, est = _run("terrain-recon-dvio", smoke)
    n = sum(isinstance(f, RgbdFrame) for f in smoke.frames)
    assert est.odometry == "dvio" and len(est.predictions) == n
    assert all(p.mode == "" and p.status == "no_odometry" and p.T_odom_camera is None for p in est.predictions)
    assert all(np.all(np.isnan(p.footprint_odom)) for p in est.predictions)
    assert est.stats["n_frames_without_pose"]["initialising"] == n
    m = track.score(smoke, est)
    assert m["n_steps"] > 0 and m["n_undecided"] == m["n_steps"] and m["accuracy"] == 0.0
    assert math.isnan(m["footprint_error_m"])
    assert est.counts["odometry"].ignored == est.counts["odometry"].seen > 0  # the stream is not read
    assert est.counts["imu"].used > 0
    given = track.score(smoke, _run("terrain-recon", smoke)[1])
    assert given["n_decided"] > 0


# ------------------------------------------------------------------ a course walk on D-VIO

# a short walk on the track's textured course (D-VIO needs texture and the resolution to
# initialise) with a small window so that the test stays short
WALK = {"duration_cap_s": 2.5}
SMALL_DVIO = {"dvio.window": "5", "dvio.init_keyframes": "5", "dvio.max_iterations": "4"}


@pytest.fixture(scope="module")
def walk(track):
    case = track.cases("quick")[0]  # stairs, head camera, 10 Hz, textured
    return track.simulate(track.validate_scenario({**case.scenario, **WALK}), 0)


@pytest.fixture(scope="module")
def dvio_walk(walk):
    pipe, est = _run("terrain-recon-dvio", walk, **SMALL_DVIO)
    return walk, pipe, est


def test_terrain_recon_dvio_starts_from_fewer_keyframes_than_dvio_alone(walk):
    """The walker sets off at the first frame and the predictor needs three heel strikes with a
    pose: terrain-recon-dvio's D-VIO starts from 5 keyframes (its metric SfM needs no long
    baseline), not D-VIO's 10. A frame is at most one keyframe, so 10 keyframes cannot start
    before the tenth 10 Hz frame (0.9 s after the first); the head camera makes a keyframe of
    nearly every frame here, so 5 can from 0.4 s."""
    stamps = sorted(float(f.stamp_s) for f in walk.frames if isinstance(f, RgbdFrame))
    _, est = _run("terrain-recon-dvio", walk)
    init_s = est.stats["dvio_init_s"]
    assert init_s < stamps[9] - stamps[0]
    assert init_s <= 0.5 + 1e-9
    assert est.stats["n_frames_without_pose"]["initialising"] <= 5
    assert any(p.T_odom_camera is not None for p in est.predictions)


def _truth_pose(episode, stamp):
    t, T = episode.truth.extra["camera_stamps_s"], episode.truth.extra["camera_T_world"]
    return np.asarray(T[int(np.argmin(np.abs(np.asarray(t) - stamp)))], dtype=float)


def test_a_course_walk_on_dvio_predicts_with_dvio_poses_that_follow_the_truth(dvio_walk):
    episode, pipe, est = dvio_walk
    results = {s: (T, status) for s, T, status in pipe._own._dvio.frame_results()}  # D-VIO's own output
    posed = [p for p in est.predictions if p.T_odom_camera is not None]
    assert len(posed) >= 10, f"D-VIO gave {len(posed)} poses"
    for p in est.predictions:  # each prediction has D-VIO's pose of its frame, or none when D-VIO had none
        T, status = results[p.stamp_s]
        if status == "ok":
            assert np.array_equal(p.T_odom_camera, T)
        else:
            assert p.T_odom_camera is None and p.mode == ""
    # independently, from the truth: D-VIO's poses brought into the world at the first one
    # follow the true camera (position within 10 cm, gravity within 3 deg)
    T0 = posed[0]
    T_world_G = _truth_pose(episode, T0.stamp_s) @ np.linalg.inv(T0.T_odom_camera)
    for p in posed:
        T_true = _truth_pose(episode, p.stamp_s)
        T_est = T_world_G @ p.T_odom_camera
        assert np.linalg.norm(T_est[:3, 3] - T_true[:3, 3]) < 0.10, p.stamp_s
        # the vertical seen from the camera: G is gravity-aligned
        up_est, up_true = p.T_odom_camera[:3, :3].T @ [0, 0, 1.0], T_true[:3, :3].T @ [0, 0, 1.0]
        assert math.degrees(math.acos(min(1.0, float(up_est @ up_true)))) < 3.0, p.stamp_s


def test_a_course_walk_on_dvio_has_its_footprints_scored_where_it_puts_them(dvio_walk, track):
    """The track scores the walk's footprints through the poses the predictions carry: errors of
    a footprint predictor (tens of cm), not those of D-VIO's frame against the odometry
    stream's (metres)."""
    from exobench.benchmarks.tracks.locomotion.metrics import score_predictions
    from exobench.benchmarks.tracks.locomotion.track import local_odometry_alignment

    episode, _, est = dvio_walk
    m = track.score(episode, est)
    assert m["n_decided"] >= 1 and 0.0 <= m["footprint_error_m"] < 0.4
    steps = sorted(episode.truth.steps, key=lambda s: s.index)
    through_stream = score_predictions(steps, est, T_world_odom=local_odometry_alignment(episode))
    assert through_stream["footprint_error_m"] > 2 * m["footprint_error_m"]


def test_the_recording_of_a_walk_on_dvio_places_its_footprints_as_scored(dvio_walk, track, tmp_path):
    episode, _, est = dvio_walk
    path = track.write_recording(episode, {"terrain-recon-dvio": est}, tmp_path / "walk.rrd")
    assert path.exists() and path.stat().st_size > 1000


# ------------------------------------------------------------------ the start: the window's strikes

# the chest walk with keyframes every 30 px of parallax: D-VIO's five initialisation keyframes
# then span the first strike, so its first pose comes after it
LATE_DVIO = {**SMALL_DVIO, "dvio.keyframe_parallax_px": "30"}


def _tracked_truth(episode, pipe, t_s):
    """The true position of the pipeline's tracked point at ``t_s`` (the camera's pose, linearly
    between the two camera frames around it, times the camera-to-tracked-point offset)."""
    t = np.asarray(episode.truth.extra["camera_stamps_s"], dtype=float)
    Tw = np.asarray(episode.truth.extra["camera_T_world"], dtype=float)
    i = int(np.clip(np.searchsorted(t, t_s), 1, len(t) - 1))
    a = (t_s - t[i - 1]) / (t[i] - t[i - 1])
    p = [T[:3, :3] @ pipe._T_cam_track[:3, 3] + T[:3, 3] for T in (Tw[i - 1], Tw[i])]
    return (1 - a) * p[0] + a * p[1]


def test_the_strikes_before_dvios_first_pose_are_placed_with_its_initialisation_window(track):
    """A strike that comes while D-VIO initialises is held until its first pose, then placed with
    the pose D-VIO gives for that instant (its window's keyframes, optimised at the
    initialisation): no strike is left without a pose, and the strikes before the first pose lie
    where the walker's tracked point truly was (D-VIO's frame brought into the world at its first
    pose)."""
    case = track.cases("quick")[1]  # stairs, chest camera, 10 Hz, textured
    episode = track.simulate(track.validate_scenario({**case.scenario, **WALK}), 0)
    pipe, est = _run("terrain-recon-dvio", episode, **LATE_DVIO)
    first = next(p for p in est.predictions if p.T_odom_camera is not None)
    true_strikes = [s.heel_strike_s for s in episode.truth.steps]
    assert min(true_strikes) < first.stamp_s, "D-VIO started before the first strike: nothing to test"
    strikes = pipe._divider.strikes
    assert est.stats["n_strikes_without_odometry"] == 0
    # every true strike has its strike with a pose (the insoles see it within 0.1 s)
    last = max(float(f.stamp_s) for f in episode.frames)
    for t in true_strikes:
        if t < last - 0.1:
            assert min(abs(s.stamp_s - t) for s in strikes) < 0.1, t
    assert any(s.stamp_s < first.stamp_s for s in strikes)
    T_world_G = _truth_pose(episode, first.stamp_s) @ np.linalg.inv(first.T_odom_camera)
    for s in strikes:
        p_world = T_world_G[:3, :3] @ s.p_world + T_world_G[:3, 3]
        assert np.linalg.norm(p_world - _tracked_truth(episode, pipe, s.stamp_s)) < 0.1, s.stamp_s


# ------------------------------------------------------------------ a re-initialisation: a new frame


class ScriptedOdometry:
    """Stands in for D-VIO inside terrain-recon-dvio: each camera frame is released at once with
    the pose ``pose_of(stamp)`` (None: no pose), as :class:`DvioOdometry` releases D-VIO's."""

    def __init__(self, pose_of, imu_id):
        self._pose_of, self.imu_id = pose_of, imu_id
        self._held = []
        self.n_without_pose = {"initialising": 0, "lost": 0, "unhandled": 0}

    def feed(self, frame):
        pass

    def hold(self, frame, counts, t0):
        self._held.append((frame, counts, t0))

    def idle(self):
        return not self._held

    def released(self):
        while self._held:
            frame, counts, t0 = self._held.pop(0)
            yield frame, counts, t0, self._pose_of(float(frame.stamp_s)) if isinstance(frame, RgbdFrame) else None

    def window_poses(self, before_s):
        return []

    def dead_reckoned(self, stamp_s, max_age_s):
        return None  # a scripted loss has no IMU propagation

    def finish(self):
        return {}


def _yaw_shift(yaw_deg, t):
    M = np.eye(4)
    c, s = math.cos(math.radians(yaw_deg)), math.sin(math.radians(yaw_deg))
    M[:2, :2] = [[c, -s], [s, c]]
    M[:3, 3] = t
    return M


def _scripted_run(walk, pose_of, **values):
    pipe = PIPELINE_REGISTRY.make("terrain-recon-dvio", PIPELINE_REGISTRY.make_config("terrain-recon-dvio", values))
    pipe.reset(walk.calibration)
    pipe._own = ScriptedOdometry(pose_of, pipe._own.imu_id)
    for f in walk.frames:
        pipe.process(f)
    return pipe, pipe.finalize()


def _level_heights_from(est, M):
    """The heights of the map's level planes brought into the world from the frame ``M`` of it."""
    M_inv = np.linalg.inv(M)
    return [float((M_inv[:3, :3] @ np.asarray(p["centroid"]) + M_inv[:3, 3])[2])
            for p in est.planes if abs(float(np.asarray(p["normal"])[2])) > 0.99]


def test_reinit_map_refuses_a_bad_value_naming_field_value_and_choices():
    with pytest.raises(ConfigError) as err:
        TerrainReconDvioConfig(reinit_map="clear")
    assert (err.value.field, err.value.value) == ("reinit_map", "clear")
    assert "keep" in str(err.value.allowed) and "reset" in str(err.value.allowed)


def test_a_reinitialisation_starts_a_new_map_in_its_new_frame(walk):
    """With ``reinit_map="reset"``: D-VIO re-anchors a re-initialised segment on the IMU's dead reckoning through the loss,
    whose error moves the new frame against the old (0.4-5 m measured on the unconventional
    walks). The odometry here is the true camera pose until a loss, none through it, then the
    true pose in a frame shifted by 0.4 m up and turned by 90 deg. The map built before the loss
    is in the old frame: kept, its treads would sit 0.4 m off the new ones. Every level plane of
    the final map, brought into the world from the new frame, lies at a true tread or floor
    height (multiples of the 0.15 m riser), and the map has them again after the loss."""
    stamps = sorted(float(f.stamp_s) for f in walk.frames if isinstance(f, RgbdFrame))
    t_lost, t_back = stamps[0] + 1.3, stamps[0] + 1.6
    M = _yaw_shift(90.0, [0.3, -0.2, 0.4])  # the new frame G2 from the world (= the old frame)

    def pose_of(t):
        T = _truth_pose(walk, t)
        return T if t < t_lost else None if t < t_back else M @ T

    pipe, est = _scripted_run(walk, pose_of, reinit_map="reset")
    heights = _level_heights_from(est, M)
    assert heights, "no level plane in the map"
    for z in heights:
        assert abs(z / 0.15 - round(z / 0.15)) * 0.15 < 0.03, z
    assert est.stats["n_map_resets"] == 1
    assert any(p.T_odom_camera is not None and p.stamp_s > t_back and p.mode for p in est.predictions)
    # the default keeps the old map: a tread of the old frame is then 0.4 m off in the new one
    _, kept = _scripted_run(walk, pose_of)
    assert kept.stats["n_map_resets"] == 0
    assert any(abs(z / 0.15 - round(z / 0.15)) * 0.15 > 0.03 for z in _level_heights_from(kept, M))


# ------------------------------------------------------------------ a loss bridged by the IMU


def test_loss_pose_refuses_a_bad_value_naming_field_value_and_choices():
    with pytest.raises(ConfigError) as err:
        TerrainReconDvioConfig(loss_pose="hold")
    assert (err.value.field, err.value.value) == ("loss_pose", "hold")
    assert "none" in str(err.value.allowed) and "imu" in str(err.value.allowed)
    with pytest.raises(ConfigError) as err:
        TerrainReconDvioConfig(max_dead_reckon_s=-1.0)
    assert err.value.field == "max_dead_reckon_s"


def test_a_short_loss_is_bridged_with_dvios_imu_propagation(walk):
    """The camera sees a blank image for 0.5 s (a lens covered): D-VIO loses its features and is
    lost until it re-initialises. With ``loss_pose="imu"`` the frames of the loss take the pose
    of D-VIO's IMU propagation of its last good state: they predict as a frame with a pose does
    (the predictor's status, not ``no_odometry``), their poses follow the true camera's (the world brought into D-VIO's frame at its last pose before
    the loss) within 0.1 m and a fifth of the way it went, and their depth is not fused (the map is the one of the tracked
    frames). With ``"none"`` they have no pose, no mode and no footprint."""
    stamps = sorted(float(f.stamp_s) for f in walk.frames if isinstance(f, RgbdFrame))
    t_off, t_on = stamps[0] + 1.2, stamps[0] + 1.7

    def blank(f):
        if isinstance(f, RgbdFrame) and t_off <= float(f.stamp_s) < t_on:
            return dataclasses.replace(f, rgb=np.full_like(np.asarray(f.rgb), 128))
        return f

    frames = [blank(f) for f in walk.frames]
    pipe, est = _run("terrain-recon-dvio", walk, frames, **SMALL_DVIO)  # loss_pose="imu", the default
    assert est.stats["dvio_reinitialisations"] >= 1
    lost = [s for s, _, status in pipe._own._dvio.frame_results() if status == "lost"]
    assert lost and min(lost) >= t_off - 1e-9, "D-VIO lost tracking outside the blank frames"
    preds = {round(p.stamp_s, 6): p for p in est.predictions}
    before = max(p.stamp_s for p in est.predictions if p.stamp_s < min(lost) and p.T_odom_camera is not None)
    T_G_world = preds[round(before, 6)].T_odom_camera @ np.linalg.inv(_truth_pose(walk, before))
    bridged = [preds[round(s, 6)] for s in lost if s - min(lost) <= 1.0]
    assert est.stats["n_frames_dead_reckoned"] == len(bridged) > 0
    p0 = _truth_pose(walk, before)[:3, 3]
    for p in bridged:
        assert p.T_odom_camera is not None and p.status != "no_odometry", p
        true = _truth_pose(walk, p.stamp_s)
        err = np.linalg.norm(p.T_odom_camera[:3, 3] - (T_G_world @ true)[:3, 3])
        # within 0.1 m and a fifth of the way the camera went since the last pose (holding that
        # pose would be off by all of it)
        assert err < min(0.1, 0.2 * np.linalg.norm(true[:3, 3] - p0) + 0.02), (p.stamp_s, err)
    # "none" leaves them without a pose; the map (tracked frames only) is the same
    _, none = _run("terrain-recon-dvio", walk, frames, **SMALL_DVIO, loss_pose="none")
    for s in lost:
        p = next(q for q in none.predictions if abs(q.stamp_s - s) < 1e-9)
        assert p.T_odom_camera is None and p.mode == "" and p.status == "no_odometry"
    assert none.stats["n_frames_dead_reckoned"] == 0
    assert sorted(round(p["centroid"][2], 6) for p in est.planes) == sorted(round(p["centroid"][2], 6) for p in none.planes)
