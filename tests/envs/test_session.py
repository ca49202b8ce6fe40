"""Sessions on disk: lossless, atomic, versioned."""

import json

import numpy as np
import pytest

from exobench.core import (
    Calibration,
    ContactSample,
    Episode,
    EpisodeTruth,
    ImuSample,
    JointState,
    OdometrySample,
    PlanarSurface,
    SceneTruth,
    SensorMount,
    SessionError,
    StairTruth,
    ToFReading,
    TofStatus,
    ToFTruth,
)
from exobench.envs.session import iter_frames, read_session, write_session


def _episode(rng) -> Episode:
    frames = []
    tof = []
    for i in range(50):
        t = i * 0.02 + rng.uniform(0, 1e-3)
        frames.append(JointState(t, "encoders", ("hip_l", "knee_l"), rng.normal(size=2)))
        frames.append(ImuSample(t, "imu_trunk", rng.normal(size=4), rng.normal(size=3), rng.normal(size=3)))
        r = float("nan") if i % 7 == 0 else float(rng.uniform(0.1, 2))
        frames.append(ToFReading(t, "tof_r_med", r, TofStatus.NO_TARGET if i % 7 == 0 else TofStatus.VALID))
        frames.append(ContactSample(t, "contact_l_heel", float(rng.uniform(0, 500)), bool(i % 2)))
        frames.append(OdometrySample(t, "odom_head", rng.normal(size=(4, 4)), rng.normal(size=3)))
        tof.append(ToFTruth(t, "tof_r_med", r, rng.normal(size=3), i % 5, np.eye(4) + rng.normal(size=(4, 4))))
    surf = PlanarSurface(0, "ground", np.array([0, 0, 1.0]), np.zeros(3), rng.normal(size=(4, 3)), ("floor",))
    truth = EpisodeTruth(
        scene=SceneTruth((surf,), {"floor": (0,)}, {"riser_m": 0.162}, "staircase"),
        T_world_estimator=np.eye(4),
        stairs=StairTruth(tuple(tof), "l", rng.normal(size=3), rng.normal(size=(20, 4))),
        body_tracks={"pelvis": rng.normal(size=(5, 8))},
        max_penetration_m=0.0,
        events={"liftoff_s": 0.3},
    )
    calib = Calibration(
        robot_urdf="<robot name='x'/>",
        base_link="pelvis",
        joint_names=("hip_l", "knee_l"),
        mounts=(SensorMount("tof_r_med", "tof", "shank_r", rng.normal(size=(4, 4)), {"rate_hz": 50.0}),),
        sole_height_m=0.068,
        foot_length_m=0.26,
        heel_to_ankle_m=0.065,
    )
    return Episode({"riser_m": 0.162, "case": "A"}, 7, calib, tuple(frames), truth)


def _same(a, b):
    if isinstance(a, np.ndarray):
        return a.shape == b.shape and np.array_equal(a, b, equal_nan=True)
    if isinstance(a, float):
        return (np.isnan(a) and np.isnan(b)) or a == b
    return a == b


def test_roundtrip_is_bit_exact(tmp_path):
    ep = _episode(np.random.default_rng(1))
    write_session(ep, tmp_path / "s")
    back = read_session(tmp_path / "s")
    assert len(back.frames) == len(ep.frames)
    for a, b in zip(ep.frames, back.frames):
        assert type(a) is type(b)
        for k, v in vars(a).items():
            assert _same(v, getattr(b, k)), (type(a).__name__, k)
    for a, b in zip(ep.truth.stairs.tof, back.truth.stairs.tof, strict=True):
        for k, v in vars(a).items():
            assert _same(v, getattr(b, k)), k
    assert np.array_equal(back.calibration.mounts[0].T_parent_sensor, ep.calibration.mounts[0].T_parent_sensor)
    assert np.array_equal(back.truth.stairs.foot_track_w, ep.truth.stairs.foot_track_w)
    assert np.array_equal(back.truth.stairs.touchdown_w, ep.truth.stairs.touchdown_w)
    assert back.truth.stairs.stance_side == "l"
    assert np.array_equal(back.truth.body_tracks["pelvis"], ep.truth.body_tracks["pelvis"])
    assert back.scenario == ep.scenario and back.seed == 7
    # streaming gives the same frames as the whole read
    assert [f.stamp_s for f in iter_frames(tmp_path / "s")] == [f.stamp_s for f in back.frames]


def test_files_are_strict_json(tmp_path):
    write_session(_episode(np.random.default_rng(2)), tmp_path / "s")
    constants = []
    lines = (tmp_path / "s" / "frames.jsonl").read_text().splitlines()
    for line in lines:
        json.loads(line, parse_constant=constants.append)
    assert lines and constants == []  # no NaN/Infinity: NaN ranges are written as null
    assert any('"range_m":null' in line for line in lines)


def test_failed_write_leaves_nothing(tmp_path):
    ep = _episode(np.random.default_rng(3))
    bad = Episode(ep.scenario, ep.seed, ep.calibration, (*ep.frames, object()), ep.truth)
    with pytest.raises(TypeError):
        write_session(bad, tmp_path / "s")
    assert list(tmp_path.iterdir()) == []


def test_existing_or_foreign_directories_are_refused(tmp_path):
    ep = _episode(np.random.default_rng(4))
    write_session(ep, tmp_path / "s")
    with pytest.raises(SessionError):
        write_session(ep, tmp_path / "s")
    (tmp_path / "other").mkdir()
    with pytest.raises(SessionError, match="meta.json"):
        read_session(tmp_path / "other")
    meta = json.loads((tmp_path / "s" / "meta.json").read_text())
    meta["version"] = 99
    (tmp_path / "s" / "meta.json").write_text(json.dumps(meta))
    with pytest.raises(SessionError, match="version"):
        read_session(tmp_path / "s")
