"""The stairs scenario (envs.sim.scenarios.stairs): validation, the paper-case placement, episodes end to end."""

import math

import numpy as np
import pytest

from exobench.core import ConfigError, Episode, ImuSample, JointState, ToFReading, UnknownNameError
from exobench.envs.sim import simulate_stairs
from exobench.envs.sim.scenarios.stairs import PAPER_CASES, PARAMS, StairScenario, staircase_params_for_case
from exobench.models.exo_spec import ExoSpec
from exobench.models.worlds import build_staircase


def test_params_table_matches_the_dataclass_defaults():
    sc = StairScenario()
    for name, spec in PARAMS.items():
        assert getattr(sc, name) == spec.default
        assert spec.unit is not None and spec.doc
    assert set(PARAMS) == set(sc.as_dict()) | {"extra_sensors"}  # left out of records while empty
    assert StairScenario(extra_sensors="lidar_trunk").as_dict()["extra_sensors"] == "lidar_trunk"


def test_from_dict_converts_strings_and_names_bad_fields():
    sc = StairScenario.from_dict({"riser_m": "0.17", "n_steps": "3", "yaw_deg": -10})
    assert sc.riser_m == 0.17 and sc.n_steps == 3 and isinstance(sc.n_steps, int) and sc.yaw_deg == -10.0
    for values, field in [
        ({"riser_m": 0.0}, "riser_m"),
        ({"riser_m": 0.31}, "riser_m"),
        ({"tread_m": 0.1}, "tread_m"),
        ({"yaw_deg": 50}, "yaw_deg"),
        ({"distance_m": float("nan")}, "distance_m"),
        ({"distance_m": "far"}, "distance_m"),
        ({"n_steps": 2.5}, "n_steps"),
        ({"tof_cone_rays": "1.5"}, "tof_cone_rays"),
        ({"user_height_m": 2.1}, "user_height_m"),
    ]:
        with pytest.raises(ConfigError) as e:
            StairScenario.from_dict(values)
        assert e.value.field == field
        assert field in str(e.value) and e.value.allowed
    with pytest.raises(UnknownNameError) as e:
        StairScenario.from_dict({"rizer_m": 0.1})
    assert "riser_m" in str(e.value)


@pytest.mark.parametrize("case", sorted(PAPER_CASES))
def test_case_staircase_is_at_distance_L_from_the_toe_and_yawed(case):
    exo = ExoSpec()
    L, yaw = PAPER_CASES[case]["distance_m"], PAPER_CASES[case]["yaw_deg"]
    params = staircase_params_for_case(0.162, 0.28, L, yaw, exo)
    truth = build_staircase(params).truth
    riser, tread = truth.surface(1), truth.surface(2)
    toe = np.array([exo.foot_m - exo.heel_to_ankle_m, -0.5 * exo.hip_width_m, 0.0])
    assert float((riser.point_w - toe) @ -riser.normal_w) == pytest.approx(L, abs=1e-12)
    # the exoskeleton (facing +x) is turned by yaw counter-clockwise relative to the stairs
    up = -riser.normal_w
    assert math.degrees(math.atan2(up[1], up[0])) == pytest.approx(-yaw, abs=1e-9)
    assert tread.point_w[2] == pytest.approx(0.162)


@pytest.fixture(scope="module")
def episode_a() -> Episode:
    return simulate_stairs(StairScenario.paper_case("A"), seed=3)


def test_episode_frames_truth_and_calibration(episode_a):
    ep = episode_a
    stamps = [f.stamp_s for f in ep.frames]
    assert stamps == sorted(stamps)
    rank = {s.sensor_id: i for i, s in enumerate(StairScenario().rig())}
    for a, b in zip(ep.frames, ep.frames[1:]):  # ties broken by the fixed sensor order
        if a.stamp_s == b.stamp_s:
            assert rank[a.sensor_id] < rank[b.sensor_id]
    tofs = [f for f in ep.frames if isinstance(f, ToFReading)]
    assert len(tofs) == len(ep.truth.stairs.tof)
    assert all((f.stamp_s, f.sensor_id) == (t.stamp_s, t.sensor_id) for f, t in zip(tofs, ep.truth.stairs.tof))
    dur = float(ep.scenario["duration_s"])
    assert sum(isinstance(f, ImuSample) for f in ep.frames) == round(dur * 200) + 1  # 200 Hz, both ends
    assert sum(isinstance(f, JointState) for f in ep.frames) == round(dur * 200) + 1
    tr = ep.truth
    assert tr.stairs.stance_side == "l" and tr.max_penetration_m == 0.0
    assert tr.events["liftoff_s"] == pytest.approx(0.3) and tr.events["touchdown_s"] == pytest.approx(dur - 0.3)
    # estimator frame: world axes, origin on the ground below the left ankle
    exo = ExoSpec()
    np.testing.assert_allclose(tr.T_world_estimator[:3, :3], np.eye(3))
    np.testing.assert_allclose(tr.T_world_estimator[:3, 3], [0.0, 0.5 * exo.hip_width_m, 0.0], atol=1e-12)
    # the foot track starts at the right sole and ends at the touch-down point on the tread
    climb = tr.stairs
    np.testing.assert_allclose(climb.foot_track_w[0, 1:], [0.0, -0.5 * exo.hip_width_m, 0.0], atol=1e-12)
    np.testing.assert_allclose(climb.foot_track_w[-1, 1:], climb.touchdown_w, atol=1e-12)
    assert tr.scene.surface(2).contains(climb.touchdown_w)
    assert set(tr.body_tracks) >= {"pelvis", "foot_r", "shank_r"} and tr.body_tracks["pelvis"].shape == (round(dur * 50) + 1, 8)
    cal = ep.calibration
    assert cal.base_link == "pelvis" and cal.mount("tof_r_lat").params["rate_hz"] == 50.0
    assert cal.mount("tof_r_lat").params["noise_sigma_m"] == 1.5e-3
    assert ep.scenario["distance_m"] == 0.305 and ep.seed == 3


def test_simulation_is_deterministic_bit_for_bit(episode_a):
    again = simulate_stairs(StairScenario.paper_case("A"), seed=3)
    assert len(again.frames) == len(episode_a.frames)
    for a, b in zip(episode_a.frames, again.frames):
        assert type(a) is type(b) and a.stamp_s == b.stamp_s and a.sensor_id == b.sensor_id
        for name in ("range_m", "quat_wxyz", "gyro_rad_s", "accel_m_s2", "position_rad", "force_n"):
            if hasattr(a, name):
                assert np.asarray(getattr(a, name)).tobytes() == np.asarray(getattr(b, name)).tobytes()
    other = simulate_stairs(StairScenario.paper_case("A"), seed=4)
    ra = [f.range_m for f in episode_a.frames if isinstance(f, ToFReading)]
    rb = [f.range_m for f in other.frames if isinstance(f, ToFReading)]
    assert ra != rb


def test_unreachable_scenario_is_a_config_error():
    with pytest.raises(ConfigError) as e:
        simulate_stairs(StairScenario(distance_m=0.8, yaw_deg=-45.0), seed=0)
    assert e.value.field == "distance_m"
