"""Every frame kind registered in the sensor kind table round-trips through a session on disk, bit for bit."""

import dataclasses

import numpy as np
import pytest

from exobench.core import FRAME_TYPES, Calibration, Episode, EpisodeTruth, SceneTruth, SessionError
from exobench.envs.sensors.kinds import EPISODE_KINDS
from exobench.envs.session import (
    CODECS,
    FrameCodec,
    codec_table,
    frame_from_dict,
    frame_to_dict,
    iter_frames,
    read_session,
    register_codec,
    write_session,
)


def _assert_bit_exact(a, b, where: str) -> None:
    assert type(a) is type(b), where
    if isinstance(a, np.ndarray):
        assert a.dtype == b.dtype and a.shape == b.shape, where
        assert a.tobytes() == b.tobytes(), where  # NaN payloads and signed zeros included
    elif isinstance(a, float):
        assert np.float64(a).tobytes() == np.float64(b).tobytes(), where
    elif isinstance(a, tuple):
        assert len(a) == len(b), where
        for i, (x, y) in enumerate(zip(a, b)):
            _assert_bit_exact(x, y, f"{where}[{i}]")
    else:
        assert a == b, where


def _episode(frames) -> Episode:
    calib = Calibration(
        robot_urdf="<robot name='x'/>", base_link="pelvis", joint_names=(), mounts=(),
        sole_height_m=0.068, foot_length_m=0.26, heel_to_ankle_m=0.065,
    )  # fmt: skip
    truth = EpisodeTruth(
        scene=SceneTruth((), {}), T_world_estimator=np.eye(4),
    )  # fmt: skip
    return Episode({}, 0, calib, tuple(frames), truth)


@pytest.mark.parametrize("kind", sorted(codec_table()))
def test_every_registered_kind_round_trips_bit_exact(kind, tmp_path):
    codec = codec_table()[kind]
    rng = np.random.default_rng(3)
    frames = [codec.example(rng), codec.example(rng)]  # two frames of one sensor: two binary files
    for f in frames:
        assert isinstance(f, codec.frame_type)
        values = [getattr(f, fl.name) for fl in dataclasses.fields(f)]
        if kind in EPISODE_KINDS:  # session marks and place labels hold no measured float
            continue
        assert any(isinstance(v, float) and np.isnan(v) for v in values) or any(
            isinstance(v, np.ndarray) and v.dtype.kind == "f" and np.isnan(v).any() for v in values
        ), f"the example {kind} frame should carry a NaN"
    write_session(_episode(frames), tmp_path / "s")
    back = tuple(iter_frames(tmp_path / "s"))  # frames only: these scans have no truth to be scored with
    assert len(back) == len(frames)
    for i, (a, b) in enumerate(zip(frames, back)):
        for fl in dataclasses.fields(a):
            _assert_bit_exact(getattr(a, fl.name), getattr(b, fl.name), f"{kind} frame {i}: {fl.name}")


def test_the_table_covers_every_core_frame_type():
    assert {k: c.frame_type for k, c in codec_table().items()} == FRAME_TYPES


def test_a_kind_or_type_registered_twice_is_refused():
    with pytest.raises(ValueError, match="codec already"):
        register_codec(codec_table()["tof"])
    twin = FrameCodec(
        "tof2", CODECS["tof"].frame_type, CODECS["tof"].encode, CODECS["tof"].decode, CODECS["tof"].example
    )
    with pytest.raises(ValueError, match="codec already"):
        register_codec(twin)


def test_binary_kinds_need_the_store_and_the_root():
    rng = np.random.default_rng(0)
    for codec in codec_table().values():
        if not codec.binary:
            assert frame_from_dict(frame_to_dict(codec.example(rng))) is not None
            continue
        with pytest.raises(SessionError, match="binary files"):
            frame_to_dict(codec.example(rng))
        with pytest.raises(SessionError, match="session root"):
            frame_from_dict({"kind": codec.kind, "stamp_s": 0.0, "sensor_id": "x", "file": "f.npz"})


def test_a_new_kind_is_one_codec_entry(tmp_path):
    """A toy sensor: its frame type and one codec; sessions write and read it with no other change."""

    @dataclasses.dataclass(frozen=True, eq=False)
    class ThermoSample:
        stamp_s: float
        sensor_id: str
        temperature_k: float

    from exobench.envs.session.codecs import FLOAT, line_codec

    codec = line_codec(
        "thermo",
        ThermoSample,
        lambda rng: ThermoSample(0.5, "thermo_shank", float("nan")),
        temperature_k=FLOAT,
    )
    register_codec(codec)
    try:
        frame = ThermoSample(0.25, "thermo_shank", 305.125)
        write_session(_episode([frame, codec.example(None)]), tmp_path / "s")
        back = read_session(tmp_path / "s").frames
        assert (
            type(back[0]) is ThermoSample
            and back[0].temperature_k == 305.125
            and np.isnan(back[1].temperature_k)
        )
    finally:
        del CODECS["thermo"]
