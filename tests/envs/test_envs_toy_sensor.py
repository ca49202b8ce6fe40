"""A toy sensor kind, defined in this file only, mounted anywhere on the exoskeleton in any world.

A barometer on the left shank: its frame type, config, adapter and session codec live here and
are registered for the test (``envs/sensors/kinds.ADAPTERS``, ``envs/session.register_codec``);
no other file of exobench knows it. It records on an office walk beside the default rig, its
readings follow the true height of its mount, the calibration carries its mount, and a session
keeps it bit for bit. This is the worked example of ``docs/adding-a-sensor.md``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np
import pytest

from exobench.core.transforms import make_T, quat_wxyz_to_matrix
from exobench.envs.sensors import kinds
from exobench.envs.sensors.adapter import BaseAdapter, Mount, MountedSensor, RecordContext, SensorOutput
from exobench.envs.sensors.common import sample_times, sensor_rngs
from exobench.envs.session import CODECS, FrameCodec, read_session, register_codec, write_session
from exobench.envs.sim import OfficeScenario, simulate_office

P0_PA = 101_325.0
DP_DZ_PA_M = -12.0  # near sea level, about -12 Pa per metre of height


@dataclass(frozen=True, eq=False)
class PressureSample:
    """One barometer reading: ``pressure_pa`` at ``stamp_s`` (delivery time)."""

    stamp_s: float
    sensor_id: str
    pressure_pa: float


@dataclass(frozen=True)
class BarometerConfig:
    rate_hz: float = 25.0
    noise_pa: float = 0.0


class BarometerAdapter(BaseAdapter):
    """Reads the height of its site at every sample; pressure from the standard gradient."""

    needs_dynamics: ClassVar[bool] = False

    def __init__(self, sensor: MountedSensor, ctx: RecordContext) -> None:
        super().__init__(sensor, ctx)
        import mujoco

        self.site = mujoco.mj_name2id(ctx.model, mujoco.mjtObj.mjOBJ_SITE, sensor.sensor_id)
        self.noise, _ = sensor_rngs(ctx.seed, sensor.sensor_id)
        self.frames: list[PressureSample] = []

    def instants(self) -> np.ndarray:
        return sample_times(self.config.rate_hz, self.ctx.duration_s)

    def observe(self, model: Any, data: Any, t: float) -> None:
        z = float(data.site_xpos[self.site][2])
        p = P0_PA + DP_DZ_PA_M * z + self.config.noise_pa * float(self.noise.standard_normal())
        self.frames.append(PressureSample(t, self.sensor_id, p))

    def finish(self) -> SensorOutput:
        return SensorOutput(list(self.frames))

    @staticmethod
    def calibration_params(sensor: MountedSensor) -> dict[str, Any]:
        return {"rate_hz": sensor.config.rate_hz, "noise_pa": sensor.config.noise_pa}


BARO = MountedSensor("baro_shank_l", "barometer", BarometerConfig(), mount=Mount("shank_l", (0.03, 0.0, -0.12)))


@pytest.fixture(scope="module")
def toy_kind():
    """The barometer registered as a sensor kind and a session frame kind, for this module."""
    kinds.ADAPTERS["barometer"] = BarometerAdapter
    register_codec(FrameCodec(
        "barometer", PressureSample,
        encode=lambda f, store: {"pressure_pa": f.pressure_pa},
        decode=lambda d, stamp, sid, root: PressureSample(stamp, sid, d["pressure_pa"]),
        example=lambda rng: PressureSample(0.5, "baro", float(rng.normal(P0_PA, 10.0))),
    ))  # fmt: skip
    yield
    del kinds.ADAPTERS["barometer"]
    del CODECS["barometer"]


@pytest.fixture(scope="module")
def walk(toy_kind):
    scenario = OfficeScenario.from_dict({"max_distance_m": 0.6, "lidar_rate_hz": 5.0, "lidar": "vlp16"})
    return simulate_office(scenario, seed=3, rig=(*scenario.rig(), BARO))


def test_toy_sensor_records_at_its_rate_beside_the_default_rig(walk):
    baro = [f for f in walk.frames if isinstance(f, PressureSample)]
    duration = max(f.stamp_s for f in walk.frames)
    assert len(baro) == int(np.floor(duration * 25.0 + 1e-9)) + 1
    assert [f.stamp_s for f in baro] == sorted(f.stamp_s for f in baro)
    assert {f.sensor_id for f in walk.frames} >= {"imu_trunk", "lidar_trunk", "baro_shank_l"}


def test_toy_readings_follow_the_true_height_of_its_mount(walk):
    """Pressure from the shank's true pose (link tracks at 50 Hz) composed with the mount."""
    track = walk.truth.body_tracks["shank_l"]
    T_mount = make_T(np.eye(3), np.array([0.03, 0.0, -0.12]))
    checked = 0
    for f in (f for f in walk.frames if isinstance(f, PressureSample)):
        k = np.flatnonzero(np.isclose(track[:, 0], f.stamp_s, atol=1e-12, rtol=0))
        if not len(k):
            continue
        row = track[k[0]]
        T_world_shank = make_T(quat_wxyz_to_matrix(row[4:8]), row[1:4])
        z = (T_world_shank @ T_mount)[2, 3]
        assert f.pressure_pa == pytest.approx(P0_PA + DP_DZ_PA_M * z, abs=1e-6)
        checked += 1
    assert checked >= 10
    heights = [(P0_PA - f.pressure_pa) / -DP_DZ_PA_M for f in walk.frames if isinstance(f, PressureSample)]
    assert 0.05 < max(heights) < 0.6 and np.ptp(heights) > 0.01  # a swinging shank, above the floor


def test_calibration_carries_the_toy_mount(walk):
    m = walk.calibration.mount("baro_shank_l")
    assert m.kind == "barometer" and m.parent_link == "shank_l"
    np.testing.assert_allclose(m.T_parent_sensor[:3, 3], [0.03, 0.0, -0.12])
    assert m.params == {"rate_hz": 25.0, "noise_pa": 0.0}


def test_toy_frames_survive_a_session_bit_for_bit(walk, tmp_path):
    back = read_session(write_session(walk, tmp_path / "s"))
    a = [f for f in walk.frames if isinstance(f, PressureSample)]
    b = [f for f in back.frames if isinstance(f, PressureSample)]
    assert [(f.stamp_s, f.sensor_id, f.pressure_pa) for f in a] == [(f.stamp_s, f.sensor_id, f.pressure_pa) for f in b]
