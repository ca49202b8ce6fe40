"""A recording streamed chunk by chunk (envs.sim.recorder.stream_record, envs.sim.scenarios.office.stream_office).

The oracle is :func:`record` (and :func:`simulate_office`) over the same motion and rig: the
stream must hand out the same frames in the same order, bit for bit, and the same truth.
"""

import dataclasses
import pickle

import numpy as np
import pytest

from exobench.envs.sensors import LidarConfig, LidarPattern
from exobench.envs.sensors.rgbd import RgbdConfig
from exobench.envs.sim.recorder import TRACKED_BODIES, record, stream_record
from exobench.envs.sim.scenarios.office import (
    OfficeScenario,
    plan_office_walk,
    simulate_office,
    stream_office,
)

pytestmark = pytest.mark.long(seconds=28)  # the workers take it first (tests/conftest.py); 28: the file at -n 0 in one run at load 12-15, scaled to that run's CPU

SEED = 5


def _bytes(x):
    """Every field of a frame or truth as comparable bytes (bit-for-bit equality)."""
    if x is None:
        return None
    return tuple((k, np.asarray(v).tobytes()) for k, v in dataclasses.asdict(x).items())


def _cheap_rig(scenario, **lidar_faults):
    """The scenario's rig (scalar streams, trunk LiDAR, head camera) with a sparse LiDAR and a
    small image, so that a walk of a few seconds records in seconds."""
    out = []
    for s in scenario.rig():
        if s.kind == "lidar":
            cfg = LidarConfig(pattern=LidarPattern.grid([-10.0, 0.0, 10.0], 6.0, rate_hz=10.0), **lidar_faults)
            s = dataclasses.replace(s, config=cfg)
        elif s.kind == "rgbd":
            s = dataclasses.replace(s, config=RgbdConfig(width_px=32, height_px=24, fx_px=20.0, fy_px=20.0, cx_px=16.0,
                                                         cy_px=12.0, segmentation_truth=True))  # fmt: skip
        out.append(s)
    return tuple(out)


@pytest.fixture(scope="module")
def walk():
    scenario = OfficeScenario.from_dict({"route": "corridor", "max_distance_m": 0.5, "extra_sensors": "rgbd_head"})
    return scenario, plan_office_walk(scenario, scenario.rig())


@pytest.mark.parametrize("chunk_s", [0.3])
def test_a_streamed_recording_gives_the_frames_and_truth_of_one_recording(walk, chunk_s):
    scenario, (scene, motion) = walk
    # duplicated and late sweeps: the stream must hold a late sweep back across chunks
    rig = _cheap_rig(scenario, duplicate_prob=0.3, out_of_order_prob=0.3, dropout_prob=0.1)
    exo = scenario.exo_spec()
    whole = record(scene.model, scene.truth, exo, motion, rig, SEED, track_bodies=TRACKED_BODIES)
    streamed = stream_record(scene.model, scene.truth, exo, motion, rig, SEED, track_bodies=TRACKED_BODIES, chunk_s=chunk_s)
    got = list(streamed.items())
    ids = [s.sensor_id for s in rig]
    want_truth = dict(zip(map(id, whole.frames), [None] * len(whole.frames)))
    for sid in ids:
        out = whole.outputs[sid]
        for f, t in zip(out.frames, out.frame_truth or [None] * len(out.frames)):
            want_truth[id(f)] = t
    kinds = {type(f).__name__ for f in whole.frames}
    assert {"LidarScan", "RgbdFrame", "ImuSample", "JointState"} <= kinds
    stamps = [f.stamp_s for f in whole.frames if type(f).__name__ == "LidarScan"]
    assert stamps != sorted(set(stamps))  # the faults are at work: duplicates or late sweeps
    assert len(got) == len(whole.frames)
    assert [(f.sensor_id, _bytes(f)) for f, _ in got] == [(f.sensor_id, _bytes(f)) for f in whole.frames]
    assert [_bytes(t) for _, t in got] == [_bytes(want_truth[id(f)]) for f in whole.frames]
    for sid in ids:  # each sensor's own truth arrays
        a, b = whole.outputs[sid].truth, streamed.outputs[sid].truth
        assert a.keys() == b.keys()
        for k in a:
            x, y = np.asarray(a[k]), np.asarray(b[k])
            if k == "sweep_start_s":  # every delivered frame's start, in delivery order when streamed
                x, y = np.sort(x), np.sort(y)
            assert x.tobytes() == y.tobytes(), (sid, k)
    assert {b: v.tobytes() for b, v in whole.body_tracks.items()} == {b: v.tobytes() for b, v in streamed.body_tracks.items()}


def test_a_streamed_office_walk_is_the_simulated_one_without_its_frames(walk):
    scenario, _ = walk
    rig = _cheap_rig(scenario)
    whole = simulate_office(scenario, SEED, rig)
    stream = stream_office(scenario, SEED, rig)
    assert pickle.dumps(stream.calibration) == pickle.dumps(whole.calibration)
    frames = list(stream.frames)
    assert [_bytes(f) for f in frames] == [_bytes(f) for f in whole.frames]
    ep = stream.finish()
    assert ep.frames == ()
    assert len(ep.truth.lidar) == len(whole.truth.lidar) > 0
    assert [_bytes(t) for t in ep.truth.lidar] == [_bytes(t) for t in whole.truth.lidar]
    assert [_bytes(t) for t in ep.truth.segmentation] == [_bytes(t) for t in whole.truth.segmentation]
    assert ep.truth.trajectory_w.tobytes() == whole.truth.trajectory_w.tobytes()
    assert {k: v.tobytes() for k, v in ep.truth.body_tracks.items()} == {k: v.tobytes() for k, v in whole.truth.body_tracks.items()}
    lean = stream_office(scenario, SEED, rig, lidar_truth=False)
    assert [_bytes(f) for f in lean.frames] == [_bytes(f) for f in whole.frames]
    assert lean.finish().truth.lidar == () and lean.finish().truth.trajectory_w.tobytes() == whole.truth.trajectory_w.tobytes()


def test_a_lidar_clock_stepping_back_is_recorded_whole_first(walk):
    scenario, _ = walk
    rig = _cheap_rig(scenario, time_jump_prob=0.5, time_jump_s=-0.3)
    whole = simulate_office(scenario, SEED, rig)
    stream = stream_office(scenario, SEED, rig)
    assert [_bytes(f) for f in stream.frames] == [_bytes(f) for f in whole.frames]
