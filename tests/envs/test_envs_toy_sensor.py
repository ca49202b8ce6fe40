"""A toy sensor kind, defined in this file only, mounted anywhere on the exoskeleton in any world.

A barometer on the left shank. Its frame module (the ``PressureSample`` frame and its core
record: fault forms, NaN-value counter, absurd-value rule) and its sensor folder (config,
adapter, codec) live here, and it is registered through the public API for this module, one
call per table (:func:`exobench.core.kinds.register_kind`,
:func:`exobench.envs.sensors.kinds.register_sensor_kind`); no other file of exobench knows it.
It records on an office walk beside the default rig, its readings follow the true height of its
mount, the calibration carries its mount, a session keeps it bit for bit, a shipped pipeline
accepts and counts its frames, and it passes the same kind conformance checks as the shipped
kinds (``tests/kind_conformance.py``), whose checker is also shown to name what a
half-registered kind lacks. This is the worked example of ``docs/adding-a-sensor.md``.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, replace
from typing import Any, ClassVar

import numpy as np
import pytest
from kind_conformance import kind_problems

from exobench.core import Calibration
from exobench.core.errors import FrameTypeError
from exobench.core.kinds import FrameKind, nan_form, nan_in, record_problems, register_kind, unregister_kind
from exobench.core.pipeline import check_frame
from exobench.core.transforms import make_T, quat_wxyz_to_matrix
from exobench.envs.sensors.adapter import BaseAdapter, Mount, MountedSensor, RecordContext, SensorOutput
from exobench.envs.sensors.common import sample_times, sensor_rngs
from exobench.envs.sensors.kinds import register_sensor_kind, registration_problems, unregister_sensor_kind
from exobench.envs.session import read_session, write_session
from exobench.envs.session.codecs import FLOAT, line_codec
from exobench.envs.sim import OfficeScenario, simulate_office

P0_PA = 101_325.0
DP_DZ_PA_M = -12.0  # near sea level, about -12 Pa per metre of height


@dataclass(frozen=True, eq=False)
class PressureSample:
    """One barometer reading: ``pressure_pa`` at ``stamp_s`` (delivery time)."""

    stamp_s: float
    sensor_id: str
    pressure_pa: float


# --- the frame module: the frame type and its core record ----------------------------------------
MIN_PA, MAX_PA = 30_000.0, 120_000.0  # from the summit of Everest (~33 kPa) to a deep mine (~110 kPa)
ABSURD_PA = (1e308, -1.0, 0.0)


def baro_absurd_values(calibration: Calibration | None):
    """A finite pressure outside what air on Earth has (the limits need nothing of the calibration)."""
    return lambda f: int(np.isfinite(f.pressure_pa) and not MIN_PA <= f.pressure_pa <= MAX_PA)


BARO_KIND = FrameKind(
    "barometer", PressureSample, nan=nan_form("pressure_pa"), nan_values=nan_in("pressure_pa"),
    absurd=lambda f, variant: replace(f, pressure_pa=ABSURD_PA[variant % len(ABSURD_PA)]),
    absurd_values=baro_absurd_values,
)  # fmt: skip


# --- the sensor folder: config, adapter, codec -----------------------------------------------------
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


BARO_CODEC = line_codec(
    "barometer", PressureSample, lambda rng: PressureSample(0.5, "baro", float("nan")), pressure_pa=FLOAT
)
BARO = MountedSensor("baro_shank_l", "barometer", BarometerConfig(), mount=Mount("shank_l", (0.03, 0.0, -0.12)))


@pytest.fixture(scope="module")
def toy_kind():
    """The barometer registered in the two tables for this module: one call each."""
    register_kind(BARO_KIND)
    register_sensor_kind("barometer", BarometerAdapter, BARO_CODEC)
    yield
    unregister_sensor_kind("barometer")
    unregister_kind("barometer")


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


def test_toy_kind_passes_the_conformance_of_every_kind(walk, tmp_path):
    assert not registration_problems()
    assert kind_problems("barometer", list(walk.frames), walk.calibration, tmp_path / "s") == []


def test_a_shipped_pipeline_accepts_and_counts_the_toy_frames(walk):
    """check_frame accepts a registered kind: a LiDAR filter fed the walk with the barometer
    counts every pressure sample as seen and ignored, and filters as it does without them."""
    from exobench.benchmarks.registry import default_registry

    registry = default_registry()
    n_baro = sum(isinstance(f, PressureSample) for f in walk.frames)
    estimates = []
    for frames in (walk.frames, tuple(f for f in walk.frames if not isinstance(f, PressureSample))):
        pipe = registry.make(registry.names(track="lidar-filter")[0])
        pipe.reset(walk.calibration)
        for f in frames:
            pipe.process(f)
        estimates.append(pipe.finalize())
    c = estimates[0].counts["barometer"]
    assert (c.seen, c.ignored, c.used) == (n_baro, n_baro, 0)
    assert "barometer" not in estimates[1].counts
    assert estimates[0].counts["lidar"].as_dict() == estimates[1].counts["lidar"].as_dict()


@dataclass(frozen=True, eq=False)
class ThermoSample:
    stamp_s: float
    sensor_id: str
    temperature_k: float


THERMO_KIND = FrameKind(
    "thermo", ThermoSample, nan=nan_form("temperature_k"), nan_values=nan_in("temperature_k"),
    absurd=lambda f, variant: replace(f, temperature_k=-1.0), absurd_values=lambda c: lambda f: int(f.temperature_k < 0),
)  # fmt: skip
THERMO_CODEC = line_codec("thermo", ThermoSample, lambda rng: ThermoSample(0.5, "t", float("nan")), temperature_k=FLOAT)


def test_the_checker_names_what_a_half_registered_kind_lacks(walk, tmp_path):
    """The kind checks can fail: each half of a registration, a record without a rule and a rule
    that does not see its own absurd form are named."""
    register_sensor_kind("thermo", BarometerAdapter, THERMO_CODEC)  # no core record
    try:
        problems = registration_problems()
        assert any("'thermo' has no core record" in p and "no absurd-value rule" in p for p in problems), problems
        with pytest.raises(FrameTypeError, match="ThermoSample"):
            check_frame(None, ThermoSample(0.0, "t", 300.0), True)
    finally:
        unregister_sensor_kind("thermo")
    register_kind(THERMO_KIND)  # no adapter, no codec
    try:
        assert any("frame kind 'thermo': no adapter and no session codec" in p for p in registration_problems())
    finally:
        unregister_kind("thermo")
    assert not registration_problems()

    no_rule = dataclasses.replace(THERMO_KIND, absurd_values=None)
    assert record_problems(no_rule) == ["no absurd-value rule (absurd_values)"]
    with pytest.raises(ValueError, match="'thermo': no absurd-value rule"):
        register_kind(no_rule)

    unregister_kind("barometer")  # the barometer with a rule that never finds its absurd form
    register_kind(dataclasses.replace(BARO_KIND, absurd_values=lambda calibration: lambda f: 0))
    try:
        problems = kind_problems("barometer", list(walk.frames), walk.calibration, tmp_path / "s")
    finally:
        unregister_kind("barometer")
        register_kind(BARO_KIND)
    assert any("absurd form 0 is not counted by its absurd-value rule" in p for p in problems), problems
    assert any("faults injected" in p and "'absurd': 1" in p for p in problems), problems
