"""The recorder stepped while its motion grows (envs.sim.recorder.Recorder.advance_to).

The oracle is :func:`record` over the final motion: a recording stepped through growing
prefixes of the same motion must deliver its frames and truth bit for bit.
"""

import dataclasses

import numpy as np
import pytest

from exobench.core import ConfigError, ExobenchError
from exobench.envs.motion import Motion
from exobench.envs.sensors import ImuConfig, ToFConfig
from exobench.envs.sensors.adapter import MountedSensor
from exobench.envs.sim import StairScenario, plan_climb
from exobench.envs.sim.recorder import Recorder, record
from exobench.models.exo_spec import TOF_IDS

SEED = 3


@pytest.fixture(scope="module")
def climb():
    scenario = StairScenario(duration_s=1.5)
    scene, motion = plan_climb(scenario)
    return scene, scenario.exo_spec(), motion


def _fields(frame):
    """Every field of a frame or truth as comparable bytes (bit-for-bit equality)."""
    return tuple((k, np.asarray(v).tobytes()) for k, v in dataclasses.asdict(frame).items())


def _tof_rig(**config):
    return tuple(MountedSensor(sid, "tof", ToFConfig(**config)) for sid in TOF_IDS)


@pytest.mark.parametrize("latency", [0.0, 0.03])
def test_stepping_through_growing_motions_gives_the_frames_of_one_recording(climb, latency):
    scene, exo, motion = climb
    rig = _tof_rig(latency_s=latency, dropout_prob=0.2)
    whole = record(scene.model, scene.truth, exo, motion, rig, SEED)
    truth = whole.frame_truth(list(TOF_IDS))

    def measured(frame):
        """The measurement instant k / rate_hz of a frame, exactly as the sensors compute it."""
        return round((frame.stamp_s - latency) * 50.0) / 50.0

    def by(t):
        """record()'s frames measured before t (a step observes [t_prev, t)) and stamped by t."""
        return [(f, tr) for f, tr in zip(whole.frames, truth) if measured(f) < t and f.stamp_s <= t + 1e-12]

    def due(t0, t1):
        """What a step from t0 to t1 delivers: by(t1) less by(t0)."""
        old = {id(f) for f, _ in by(t0)}
        return [(f, tr) for f, tr in by(t1) if id(f) not in old]

    segs = motion.segments
    assert len(segs) == 3  # still, swing, still
    # decision times: inside the first segment, at both segment boundaries (instants of the
    # 50 Hz sensors), at the end
    stops = [(0.15, 1), (segs[0].t1, 1), (segs[1].t1, 2), (motion.duration_s, 3)]
    assert segs[0].t1 * 50.0 == round(segs[0].t1 * 50.0) and segs[1].t1 * 50.0 == round(segs[1].t1 * 50.0)
    got, t_prev = [], -1.0
    with Recorder(scene.model, scene.truth, exo, Motion(exo, list(segs[:1])), rig, SEED) as rec:
        for t, n in stops:
            step = rec.advance_to(t, Motion(exo, list(segs[:n])))
            assert [_fields(f) for f, _ in step] == [_fields(f) for f, _ in due(t_prev, t)]
            got += step
            t_prev = t
    want = by(motion.duration_s)
    assert len(want) > 200 and len(want) < 4 * 75  # dropout at work
    assert any(measured(f) == motion.duration_s for f in whole.frames)  # record() measures at the end...
    assert not any(measured(f) == motion.duration_s for f, _ in got)  # ...a step observes [t_prev, t)
    assert [_fields(f) for f, _ in got] == [_fields(f) for f, _ in want]
    assert [_fields(tr) for _, tr in got] == [_fields(tr) for _, tr in want]


def test_stepping_refuses_kinds_that_cannot_stream_time_going_back_and_other_motions(climb):
    scene, exo, motion = climb
    first = Motion(exo, list(motion.segments[:1]))
    imu = (MountedSensor("imu_trunk", "imu", ImuConfig()),)
    with Recorder(scene.model, scene.truth, exo, first, imu, SEED) as rec, pytest.raises(ConfigError) as e:
        rec.advance_to(0.1)
    assert e.value.field == "rig" and "imu" in str(e.value) and "tof" in str(e.value)
    with Recorder(scene.model, scene.truth, exo, first, _tof_rig(), SEED) as rec:
        rec.advance_to(0.2)
        with pytest.raises(ConfigError) as e:
            rec.advance_to(0.1)
        assert e.value.field == "t_s"
        with pytest.raises(ConfigError) as e:
            rec.advance_to(first.duration_s + 0.1)  # beyond the motion
        assert e.value.field == "t_s"
        other = Motion(exo, [dataclasses.replace(motion.segments[0], h=(0.9, 0.9)), *motion.segments[1:]])
        with pytest.raises(ConfigError) as e:
            rec.advance_to(0.5, other)
        assert e.value.field == "motion"
        with pytest.raises(ExobenchError, match="step by step"):
            rec.finish()  # the frames went out with advance_to; finish() would give only the rest
