"""Session format version 2: LiDAR scans, RGB-D frames and LiDAR truth in binary files; version 1 still reads."""

import json
import os
from dataclasses import replace

import numpy as np
import pytest

from exobench.core import (
    Calibration,
    Episode,
    EpisodeTruth,
    ImuSample,
    LidarScan,
    LidarTruth,
    PlanarSurface,
    RgbdFrame,
    SceneTruth,
    SessionError,
    ToFReading,
    TofStatus,
)
from exobench.envs.session import iter_frames, read_meta, read_session, write_session
from exobench.envs.sim.scenarios.office import OfficeScenario, simulate_office

pytestmark = pytest.mark.long(seconds=6)  # the workers take it first (tests/conftest.py); 6: the file at -n 0 in one run at load 12-15, scaled to that run's CPU


def _same(a, b) -> bool:
    """Equal value and type; arrays must also have the same dtype and shape (NaN == NaN)."""
    if isinstance(a, np.ndarray):
        if not isinstance(b, np.ndarray) or a.dtype != b.dtype or a.shape != b.shape:
            return False
        return bool(np.array_equal(a, b, equal_nan=a.dtype.kind in "fc"))
    if isinstance(a, float):
        return isinstance(b, float) and ((np.isnan(a) and np.isnan(b)) or a == b)
    return type(a) is type(b) and a == b


def _assert_same_objects(xs, ys, what: str) -> None:
    assert len(xs) == len(ys), what
    for i, (a, b) in enumerate(zip(xs, ys)):
        assert type(a) is type(b), (what, i)
        for k, v in vars(a).items():
            assert _same(v, getattr(b, k)), (what, i, type(a).__name__, k)


def _calibration() -> Calibration:
    return Calibration(
        robot_urdf="<robot name='x'/>", base_link="pelvis", joint_names=("hip_l",), mounts=(),
        sole_height_m=0.068, foot_length_m=0.26, heel_to_ankle_m=0.065,
    )  # fmt: skip


def _scan(rng, t: float, sid: str = "lidar_a", n: int = 40) -> LidarScan:
    pts = rng.normal(size=(n, 3))
    if n > 3:
        pts[3] = np.nan  # a NaN point must survive too
    return LidarScan(
        t, sid, pts, rng.integers(0, 256, n).astype(np.uint8), rng.integers(0, 16, n).astype(np.uint16),
        np.sort(rng.uniform(0, 0.1, n)), t - 0.1,
    )  # fmt: skip


def _lidar_truth(rng, scan: LidarScan) -> LidarTruth:
    n = len(scan.points_xyz)
    return LidarTruth(
        scan.stamp_s, scan.sensor_id, rng.uniform(0, 10, n), rng.normal(size=(n, 3)),
        rng.integers(-1, 30, n), rng.integers(-1, 9, n), rng.choice(np.array(["wood", "glass", "ceiling_tile"]), n),
        rng.integers(0, 4, n).astype(np.int8), rng.integers(-1, 3, n), rng.uniform(0, 300, n),
        rng.normal(size=(n, 3)), rng.normal(size=(n, 3)),
    )  # fmt: skip


def _synthetic(rng) -> Episode:
    """Two LiDARs, two RGB-D cameras and an IMU, interleaved in time."""
    frames, truths = [], []
    for i in range(6):
        t = 0.1 * (i + 1)
        frames.append(ImuSample(t, "imu_trunk", rng.normal(size=4), rng.normal(size=3), rng.normal(size=3)))
        for sid in ("lidar_a", "lidar_b"):
            frames.append(_scan(rng, t, sid, n=0 if i == 2 else 40))
            truths.append(_lidar_truth(rng, frames[-1]))
        for cam in ("rgbd_head", "rgbd_chest"):
            depth = rng.uniform(0.2, 5.0, (6, 8)).astype(np.float32)
            depth[0, :3] = 0.0
            K = np.array([[300.0, 0, 3.9], [0, 301.5, 2.7], [0, 0, 1]])
            frames.append(RgbdFrame(t, cam, rng.integers(0, 256, (6, 8, 3)).astype(np.uint8), depth, K))
    surf = PlanarSurface(0, "ground", np.array([0, 0, 1.0]), np.zeros(3), rng.normal(size=(4, 3)), ("floor",))
    truth = EpisodeTruth(
        scene=SceneTruth((surf,), {"floor": (0,)}, {}, "office"),
        T_world_estimator=np.eye(4), lidar=tuple(truths), trajectory_w=rng.normal(size=(len(truths), 8)),
    )  # fmt: skip
    return Episode({"case": "synthetic"}, 11, _calibration(), tuple(frames), truth)


@pytest.fixture(scope="module")
def office(tmp_path_factory):
    ep = simulate_office(OfficeScenario.from_dict({"max_distance_m": 0.5}), 5)
    path = write_session(ep, tmp_path_factory.mktemp("office") / "s")
    return ep, path


def test_office_episode_roundtrip_is_bit_exact(office):
    ep, path = office
    assert any(isinstance(f, LidarScan) for f in ep.frames) and len(ep.truth.lidar) > 0
    back = read_session(path)
    _assert_same_objects(ep.frames, back.frames, "frames")
    _assert_same_objects(ep.truth.lidar, back.truth.lidar, "lidar truth")
    assert _same(ep.truth.trajectory_w, back.truth.trajectory_w)
    assert ep.truth.body_tracks.keys() == back.truth.body_tracks.keys()
    for k, v in ep.truth.body_tracks.items():
        assert _same(v, back.truth.body_tracks[k]), k
    assert ep.truth.stairs is None and back.truth.stairs is None  # an office walk has no climbing step
    assert back.scenario == ep.scenario and back.seed == ep.seed
    assert read_meta(path)["version"] == 5


def test_lidar_lines_reference_per_scan_files(office, tmp_path):
    """Format 4 (still written with compact=False, and read): one file per scan and per truth."""
    ep = office[0]
    path = write_session(ep, tmp_path / "s4", compact=False)
    assert read_meta(path)["version"] == 4
    _assert_same_objects(ep.frames, read_session(path).frames, "frames")
    lines = [json.loads(s) for s in (path / "frames.jsonl").read_text().splitlines()]
    assert len(lines) == len(ep.frames)
    stamps = [d["stamp_s"] for d in lines]
    assert stamps == sorted(stamps)
    scans = [f for f in ep.frames if isinstance(f, LidarScan)]
    refs = [d for d in lines if d["kind"] == "lidar"]
    assert len(refs) == len(scans)
    for k, (d, scan) in enumerate(zip(refs, scans)):
        assert d["index"] == k and d["n"] == len(scan.points_xyz) and d["sweep_start_s"] == scan.sweep_start_s
        assert d["file"] == f"lidar/{scan.sensor_id}/{k:06d}.npz" and (path / d["file"]).is_file()
    assert sorted(os.listdir(path / "truth" / "lidar")) == [f"{k:06d}.npz" for k in range(len(ep.truth.lidar))]


def test_synthetic_rgbd_and_multi_lidar_roundtrip(tmp_path):
    ep = _synthetic(np.random.default_rng(1))
    write_session(ep, tmp_path / "s")
    back = read_session(tmp_path / "s")
    _assert_same_objects(ep.frames, back.frames, "frames")
    _assert_same_objects(ep.truth.lidar, back.truth.lidar, "lidar truth")
    assert _same(ep.truth.trajectory_w, back.truth.trajectory_w)
    assert sorted(os.listdir(tmp_path / "s" / "rgbd")) == ["rgbd_chest", "rgbd_head"]
    assert len(os.listdir(tmp_path / "s" / "rgbd" / "rgbd_head")) == 6
    assert sorted(os.listdir(tmp_path / "s" / "lidar")) == ["lidar_a.npz", "lidar_b.npz"]  # one stream per sensor
    assert sorted(os.listdir(tmp_path / "s" / "truth")) == ["episode.json", "lidar.npz", "tof.jsonl"]
    write_session(ep, tmp_path / "s4", compact=False)
    assert len(os.listdir(tmp_path / "s4" / "lidar" / "lidar_b")) == 6
    _assert_same_objects(ep.truth.lidar, read_session(tmp_path / "s4").truth.lidar, "lidar truth")
    # without truth the frames still replay
    write_session(ep, tmp_path / "bare", include_truth=False)
    assert not (tmp_path / "bare" / "truth").exists()
    _assert_same_objects(ep.frames, list(iter_frames(tmp_path / "bare")), "frames")


@pytest.mark.parametrize("compact", [False, True])
def test_iter_frames_streams_scan_files(tmp_path, compact):
    ep = _synthetic(np.random.default_rng(2))
    path = write_session(ep, tmp_path / "s", compact=compact)
    it = iter_frames(path)
    first = next(it)  # the IMU sample at 0.1 s; the scan files are not read yet
    assert isinstance(first, ImuSample)
    victim = path / "lidar" / ("lidar_b.npz" if compact else "lidar_b/000003.npz")
    victim.unlink()
    got = [first]
    with pytest.raises(SessionError, match=victim.name):
        for f in it:
            got.append(f)
    # everything before the missing scan's line was delivered (format 5: the sensor's first scan reads the stream)
    i_missing = [k for k, f in enumerate(ep.frames) if isinstance(f, LidarScan) and f.sensor_id == "lidar_b"][
        0 if compact else 3
    ]
    assert len(got) == i_missing


@pytest.mark.parametrize(
    "rel", ["lidar/lidar_a/000001.npz", "rgbd/rgbd_chest/000004.npz", "truth/lidar/000002.npz", "lidar/lidar_a.npz",
            "truth/lidar.npz"],
)  # fmt: skip
def test_corrupt_or_missing_binary_files_name_the_file(tmp_path, rel):
    compact = rel in ("lidar/lidar_a.npz", "truth/lidar.npz")
    path = write_session(_synthetic(np.random.default_rng(3)), tmp_path / "s", compact=compact)
    target = path / rel
    data = target.read_bytes()
    target.write_bytes(data[: len(data) // 2])  # truncated
    with pytest.raises(SessionError, match=rel.rsplit("/", 1)[-1]):
        read_session(path)
    # flipped bytes in the middle of the compressed data
    mangled = bytearray(data)
    for k in range(60, 90):
        mangled[k] ^= 0xFF
    target.write_bytes(bytes(mangled))
    with pytest.raises(SessionError, match=rel.rsplit("/", 1)[-1]):
        read_session(path)
    target.unlink()
    with pytest.raises(SessionError, match=rel.rsplit("/", 1)[-1]):
        read_session(path)


def test_scan_file_not_matching_its_line_is_refused(tmp_path):
    ep = _synthetic(np.random.default_rng(4))
    path = write_session(ep, tmp_path / "s", compact=False)
    other = path / "lidar" / "lidar_a" / "000002.npz"  # the empty scan
    os.replace(other, path / "lidar" / "lidar_a" / "000000.npz")
    with pytest.raises(SessionError, match="000000.npz"):
        read_session(path)


def test_failed_writes_leave_nothing(tmp_path):
    ep = _synthetic(np.random.default_rng(5))
    late_failure = Episode(ep.scenario, ep.seed, ep.calibration, (*ep.frames, object()), ep.truth)
    with pytest.raises(TypeError):
        write_session(late_failure, tmp_path / "s")  # scan files were already written
    bad = ep.frames[1]
    pickled = replace(bad, intensity=bad.intensity.astype(object))
    with pytest.raises(SessionError, match="object"):
        write_session(Episode(ep.scenario, ep.seed, ep.calibration, (pickled,), ep.truth), tmp_path / "s")
    escaping = replace(bad, sensor_id="../outside")
    with pytest.raises(SessionError, match="sensor id"):
        write_session(Episode(ep.scenario, ep.seed, ep.calibration, (escaping,), ep.truth), tmp_path / "s")
    bad_truth = replace(ep.truth, lidar=(*ep.truth.lidar, object()))
    with pytest.raises(AttributeError):
        write_session(Episode(ep.scenario, ep.seed, ep.calibration, ep.frames, bad_truth), tmp_path / "s")
    assert list(tmp_path.iterdir()) == []


def test_version_1_session_still_reads(tmp_path):
    """A session laid out by hand as format version 1 wrote it (no binary files, no LiDAR truth)."""
    p = tmp_path / "v1"
    (p / "truth").mkdir(parents=True)
    meta = {
        "format": "exobench-session", "version": 1, "exobench_version": "0.1.0", "scenario": {"riser_m": 0.17},
        "seed": 3, "frame_counts": {"tof": 2, "imu": 1}, "has_truth": True,
    }  # fmt: skip
    (p / "meta.json").write_text(json.dumps(meta))
    calib = {
        "robot_urdf": "<robot name='x'/>", "base_link": "pelvis", "joint_names": ["hip_l"], "sole_height_m": 0.068,
        "foot_length_m": 0.26, "heel_to_ankle_m": 0.065, "extra": {},
        "mounts": [{"sensor_id": "tof_r_med", "kind": "tof", "parent_link": "shank_r",
                    "T_parent_sensor": np.eye(4).tolist(), "params": {"rate_hz": 50.0}}],
    }  # fmt: skip
    (p / "calibration.json").write_text(json.dumps(calib))
    lines = [
        {"kind": "tof", "stamp_s": 0.02, "sensor_id": "tof_r_med", "range_m": 0.4123456789012345, "status": 0},
        {"kind": "imu", "stamp_s": 0.025, "sensor_id": "imu_trunk", "quat_wxyz": [1.0, 0.0, 0.0, 0.0],
         "gyro_rad_s": [0.1, -0.2, 0.3], "accel_m_s2": [0.0, 0.0, 9.81]},
        {"kind": "tof", "stamp_s": 0.04, "sensor_id": "tof_r_med", "range_m": None, "status": 255},
    ]  # fmt: skip
    (p / "frames.jsonl").write_text("".join(json.dumps(d) + "\n" for d in lines))
    truth = {
        "scene": {"kind": "staircase", "params": {"riser_m": 0.17}, "geom_surfaces": {"floor": [0]},
                  "surfaces": [{"surface_id": 0, "kind": "ground", "normal_w": [0, 0, 1.0], "point_w": [0, 0, 0.0],
                                "polygon_w": [[0, 0, 0.0], [1, 0, 0.0], [1, 1, 0.0]], "geom_names": ["floor"]}]},
        "T_world_estimator": np.eye(4).tolist(), "stance_side": "l", "touchdown_w": [0.3, 0.0, 0.17],
        "foot_track_w": [[0.0, 0.1, 0.0, 0.0], [0.1, 0.2, 0.0, 0.05]], "body_tracks": {},
        "max_penetration_m": 0.0, "events": {"touchdown_s": 0.9},
    }  # fmt: skip
    (p / "truth" / "episode.json").write_text(json.dumps(truth))
    tof = {"stamp_s": 0.02, "sensor_id": "tof_r_med", "true_range_m": 0.41, "hit_w": [0.1, 0.2, 0.0],
           "surface_id": 0, "T_world_sensor": np.eye(4).tolist()}  # fmt: skip
    no_target = {**tof, "stamp_s": 0.04, "true_range_m": None, "hit_w": [None, None, None], "surface_id": -1}
    (p / "truth" / "tof.jsonl").write_text(json.dumps(tof) + "\n" + json.dumps(no_target) + "\n")  # one per reading

    ep = read_session(p)
    assert [type(f) for f in ep.frames] == [ToFReading, ImuSample, ToFReading]
    assert ep.frames[0].range_m == 0.4123456789012345 and ep.frames[0].status == TofStatus.VALID
    assert np.isnan(ep.frames[2].range_m) and ep.frames[2].status == TofStatus.NO_TARGET
    assert np.array_equal(ep.frames[1].accel_m_s2, [0.0, 0.0, 9.81])
    assert ep.truth.lidar == () and ep.truth.trajectory_w.shape == (0, 8)
    assert np.array_equal(ep.truth.stairs.foot_track_w, [[0.0, 0.1, 0.0, 0.0], [0.1, 0.2, 0.0, 0.05]])
    assert ep.truth.stairs.tof[0].true_range_m == 0.41 and ep.truth.events == {"touchdown_s": 0.9}
    assert ep.scenario == {"riser_m": 0.17} and ep.seed == 3
    # and re-writing it gives a version-5 session with the same content
    back = read_session(write_session(ep, tmp_path / "v5"))
    assert read_meta(tmp_path / "v5")["version"] == 5
    assert np.array_equal(back.truth.stairs.foot_track_w, ep.truth.stairs.foot_track_w)
    _assert_same_objects(ep.frames, back.frames, "frames")


def test_version_2_truth_gives_a_stairs_part_only_to_staircase_episodes(tmp_path):
    """Version 2 wrote the climbing step's fields flat for every episode; read back, an office
    walk has no stairs part, and the same fields under a staircase scene make one."""
    ep = _synthetic(np.random.default_rng(5))
    path = write_session(ep, tmp_path / "s")
    td = json.loads((path / "truth" / "episode.json").read_text())
    assert td.pop("stairs") is None
    td.update(stance_side="r", touchdown_w=[0.1, 0.2, 0.3], foot_track_w=[[0.0, 0.1, 0.2, 0.3]])
    (path / "truth" / "episode.json").write_text(json.dumps(td))
    meta = json.loads((path / "meta.json").read_text())
    for key in ("files", "truth_counts", "track"):  # version 2 had none of them
        meta.pop(key)
    (path / "meta.json").write_text(json.dumps({**meta, "version": 2}))
    assert read_session(path).truth.stairs is None
    td["scene"]["kind"] = "staircase"
    (path / "truth" / "episode.json").write_text(json.dumps(td))
    stairs = read_session(path).truth.stairs
    assert stairs.stance_side == "r" and np.array_equal(stairs.touchdown_w, [0.1, 0.2, 0.3]) and stairs.tof == ()


def test_lidar_truth_materials_are_stored_as_indices_into_a_name_table(tmp_path):
    ep = _synthetic(np.random.default_rng(4))
    path = write_session(ep, tmp_path / "s", compact=False)
    for k, lt in enumerate(ep.truth.lidar):
        with np.load(path / "truth" / "lidar" / f"{k:06d}.npz") as z:
            assert "material" not in z.files
            idx, names = z["material_index"], z["material_names"]
            assert idx.dtype == np.uint8 and idx.shape == lt.material.shape
            assert len(names) == len(set(lt.material.tolist())) and list(names) == sorted(set(lt.material.tolist()))
            np.testing.assert_array_equal(names[idx], lt.material)
    back = read_session(path)
    _assert_same_objects(ep.truth.lidar, back.truth.lidar, "lidar truth")
    # more than 256 distinct names need 16-bit indices
    rng = np.random.default_rng(5)
    scan = _scan(rng, 0.7, "lidar_a", n=300)
    lt = replace(_lidar_truth(rng, scan), material=np.array([f"m{i:03d}" for i in range(300)]))
    ep2 = replace(ep, frames=ep.frames + (scan,), truth=replace(ep.truth, lidar=ep.truth.lidar + (lt,)))
    path2 = write_session(ep2, tmp_path / "s2", compact=False)
    with np.load(path2 / "truth" / "lidar" / f"{len(ep2.truth.lidar) - 1:06d}.npz") as z:
        assert z["material_index"].dtype == np.uint16
    _assert_same_objects(ep2.truth.lidar, read_session(path2).truth.lidar, "lidar truth")


def test_lidar_truth_files_with_material_strings_still_read(tmp_path):
    """Sessions written before the name table stored ``material`` as a unicode array (version 3:
    no file hashes, so the files rewritten here are read as they are)."""
    ep = _synthetic(np.random.default_rng(6))
    path = write_session(ep, tmp_path / "s", compact=False)
    meta = json.loads((path / "meta.json").read_text())
    for key in ("files", "truth_counts", "track"):  # version 3 had none of them
        meta.pop(key)
    (path / "meta.json").write_text(json.dumps({**meta, "version": 3}))
    old_fields = ("stamp_s", "sensor_id", "true_range_m", "hit_w", "geom_id", "surface_id", "material", "kind",
                  "via_geom_id", "signal", "origin_w", "dir_w")  # fmt: skip
    for k, lt in enumerate(ep.truth.lidar):
        arrays = {n: np.asarray(getattr(lt, n)) for n in old_fields}
        with open(path / "truth" / "lidar" / f"{k:06d}.npz", "wb") as fh:
            np.savez_compressed(fh, **arrays)
    _assert_same_objects(ep.truth.lidar, read_session(path).truth.lidar, "lidar truth")
    # an index beyond its name table is refused, naming the file
    bad = path / "truth" / "lidar" / "000000.npz"
    lt = ep.truth.lidar[0]
    arrays = {n: np.asarray(getattr(lt, n)) for n in old_fields if n != "material"}
    arrays["material_names"] = np.array(["wood"])
    arrays["material_index"] = np.full(len(lt.kind), 3, dtype=np.uint8)
    with open(bad, "wb") as fh:
        np.savez_compressed(fh, **arrays)
    with pytest.raises(SessionError, match="000000.npz"):
        read_session(path)
