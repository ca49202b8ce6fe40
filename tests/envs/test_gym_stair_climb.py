"""exobench/StairClimb-v0: registration, gymnasium's checker, determinism, touch-down safety, points, rendering.

The oracle policy and the geometric checks compute footholds and surfaces from the true staircase
parameters (riser, tread, the staircase frame) and the user's dimensions, independently of the
environment's own planning and judging code.
"""

import dataclasses
import subprocess
import sys
import warnings

import gymnasium
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import exobench.envs  # noqa: F401  (registers the environment)
from exobench.core import ConfigError, ExobenchError, UnknownNameError
from exobench.envs.gym.stair_climb import StairClimbEnv
from exobench.models.exo_spec import ExoSpec

pytestmark = pytest.mark.long(seconds=5)  # the workers take it first (tests/conftest.py); 5: the file at -n 0 in one run at load 12-15, scaled to that run's CPU

ENV_ID = "exobench/StairClimb-v0"
FRONTAL = {"riser_m": 0.16, "tread_m": 0.30, "yaw_deg": 0.0, "distance_m": 0.30, "user_height_m": 1.75}


def _frames(info):
    T = np.asarray(info["T_world_stairs"])
    yaw = info["heading_rad"]
    x = np.array([np.cos(yaw), np.sin(yaw), 0.0])
    y = np.array([-np.sin(yaw), np.cos(yaw), 0.0])
    return T[:3, :3], T[:3, 3], x, y


def oracle_target(info, approach_above_m=0.55):
    """(forward, up) centring the ankle-to-toe part of the foot on the next tread, from the truth.

    When that step would be longer than ``approach_above_m`` (far from the first riser), an
    approach step on the ground brings the toe 3 cm short of the first riser first.
    """
    exo = ExoSpec(user_height_m=info["user_height_m"])
    R, o, x, y = _frames(info)
    P = np.asarray(info["stance_sole_w"])
    sg = 1.0 if info["stance_side"] == "l" else -1.0
    lateral = -sg * exo.hip_width_m * y  # the swing foot's line is one hip width beside the stance foot
    toe = exo.foot_m - exo.heel_to_ankle_m
    riser, tread = info["riser_m"], info["tread_m"]
    k = int(round(P[2] / riser)) + 1  # the next tread above the stance foot
    along = float(x @ R[:, 0])  # forward motion per metre along the flight's axis
    centre_now = float((P + lateral + 0.5 * toe * x - o) @ R[:, 0])
    forward = ((k - 0.5) * tread - centre_now) / along
    up = k * riser - P[2]
    if forward > approach_above_m:
        half_width = 0.5 * 0.055 * info["user_height_m"]
        toe_now = float((P + lateral + toe * x - o) @ R[:, 0])
        forward = (-0.03 - half_width * abs(np.sin(np.radians(info["yaw_deg"]))) - toe_now) / along
        up = 0.0
    return forward, up


def test_registration_imports_nothing_heavy():
    code = (
        "import sys, gymnasium, exobench.envs; assert 'exobench/StairClimb-v0' in gymnasium.registry; "
        "print(sorted(m for m in ('mujoco', 'exobench.envs.gym', 'exobench.envs.gym.stair_climb', 'exobench.envs.motion') if m in sys.modules))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


def test_make_gives_the_documented_spaces_and_limits():
    env = gymnasium.make(ENV_ID)
    assert env.spec.max_episode_steps == 12
    assert env.action_space == gymnasium.spaces.Box(-1.0, 1.0, (2,), np.float32)
    assert env.observation_space.shape == (4 * 16 * 4 + 6,) and env.observation_space.dtype == np.float32
    obs, info = env.reset(seed=3)
    assert obs in env.observation_space
    assert 0.13 <= info["riser_m"] <= 0.19 and 0.26 <= info["tread_m"] <= 0.34
    assert -10.0 <= info["yaw_deg"] <= 10.0 and 0.25 <= info["distance_m"] <= 0.5
    assert StairClimbEnv.target_from_action(np.array([-1.0, -1.0])) == pytest.approx((0.10, -0.05))
    assert StairClimbEnv.target_from_action(np.array([1.0, 1.0])) == pytest.approx((0.70, 0.30))
    assert StairClimbEnv.target_from_action(StairClimbEnv.action_from_target(0.33, 0.17)) == pytest.approx((0.33, 0.17), abs=1e-6)
    env.close()


def test_check_env_passes_without_warnings():
    env = gymnasium.make(ENV_ID)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check_env(env.unwrapped)
    env.close()


def _rollout(seed, actions=None):
    """Observations and rewards as bytes; the oracle's actions when ``actions`` is None."""
    env = gymnasium.make(ENV_ID)
    obs, info = env.reset(seed=seed)
    out, used = [obs.tobytes()], []
    for i in range(env.spec.max_episode_steps):
        a = StairClimbEnv.action_from_target(*oracle_target(info)) if actions is None else actions[i]
        used.append(a)
        obs, r, term, trunc, info = env.step(a)
        out += [obs.tobytes(), np.float64(r).tobytes()]
        if term or trunc:
            break
    env.close()
    return out, used


def test_same_seed_and_actions_give_identical_episodes():
    first, actions = _rollout(11)
    assert len(actions) >= 4
    again, _ = _rollout(11, actions)
    assert again == first  # bit for bit, sensor noise included
    other, _ = _rollout(12, actions)
    assert other[0] != first[0]


@pytest.mark.parametrize("seed", [0, 1, 5])
def test_oracle_climbs_to_the_landing_safely(seed):
    env = gymnasium.make(ENV_ID)
    _, info = env.reset(seed=seed)
    n, riser = info["n_steps"], info["riser_m"]
    total, touched = 0.0, []
    for _ in range(env.spec.max_episode_steps):
        forward, up = oracle_target(info)
        _, reward, terminated, truncated, info = env.step(StairClimbEnv.action_from_target(forward, up))
        assert info["safe"], info["failure"]
        assert info["penetration_m"] <= 1e-3 and info["nosing_clearance_m"] >= 0.01
        total += reward
        touched.append(info["touched_surface_id"])
        # the foot now stands on the true surface it was aimed at
        k = int(round(info["stance_sole_w"][2] / riser))
        assert info["stance_sole_w"][2] == pytest.approx(k * riser, abs=1e-9)
        if info["touched_surface_id"] > 0:
            assert abs(info["placement_error_m"]) < 1e-6  # the oracle centres the foot on the tread
            assert reward == pytest.approx(1.0, abs=1e-6)
        if terminated or truncated:
            break
    assert terminated and info["is_success"]
    assert [t for t in touched if t > 0] == [2 * k for k in range(1, n + 1)]  # step-over: one tread per step
    assert info["climbed"] == n and total == pytest.approx(n, abs=1e-5)
    env.close()


def test_stepping_flat_into_the_first_riser_is_unsafe():
    env = gymnasium.make(ENV_ID)
    _, info = env.reset(seed=0, options=FRONTAL)
    forward, _ = oracle_target(info)
    _, reward, terminated, _, info = env.step(StairClimbEnv.action_from_target(forward, 0.0))
    assert terminated and reward == -1.0 and not info["safe"]
    assert info["failure"] == "collision"
    # the sole lands at ground level under the first tread: riser_m deep in the step
    assert info["penetration_m"] == pytest.approx(FRONTAL["riser_m"], abs=1e-6)
    assert info["touched_surface_id"] == 2
    with pytest.raises(ExobenchError, match="reset"):
        env.step(env.action_space.sample())
    env.close()


@pytest.mark.parametrize(
    "d_forward, d_up, failure",
    [
        (0.0, 0.08, "drop"),  # lands 8 cm above the tread
        (-0.12, 0.0, "no_foothold"),  # the ankle short of the nosing: the sole spans ground and tread
        (0.15, 0.0, "collision"),  # the toe runs into the second riser
    ],
)
def test_misplaced_feet_are_unsafe(d_forward, d_up, failure):
    env = gymnasium.make(ENV_ID)
    _, info = env.reset(seed=0, options=FRONTAL)
    forward, up = oracle_target(info)
    _, reward, terminated, _, info = env.step(StairClimbEnv.action_from_target(forward + d_forward, up + d_up))
    assert terminated and reward == -1.0 and info["failure"] == failure
    env.close()


def test_a_small_drop_settles_on_the_tread():
    env = gymnasium.make(ENV_ID)
    _, info = env.reset(seed=0, options=FRONTAL)
    forward, up = oracle_target(info)
    _, reward, terminated, _, info = env.step(StairClimbEnv.action_from_target(forward, up + 0.01))
    assert info["safe"] and not terminated and reward > 0.99
    assert info["drop_m"] == pytest.approx(0.01, abs=1e-6)
    assert info["stance_sole_w"][2] == pytest.approx(FRONTAL["riser_m"], abs=1e-9)
    env.close()


def _on_staircase(points_w, info, tol_m):
    """Whether world points lie on the true ground, treads or risers (staircase frame)."""
    R, o, _, _ = _frames(info)
    loc = (points_w - o) @ R
    riser, tread, n = info["riser_m"], info["tread_m"], info["n_steps"]
    x, z = loc[:, 0], loc[:, 2]
    level = np.where(x < 0.0, 0.0, np.clip(np.floor(x / tread) + 1, 0, n) * riser)
    k = np.round(x / tread)
    on_riser = (np.abs(x - k * tread) < tol_m) & (k >= 0) & (k < n) & (z > k * riser - tol_m) & (z < (k + 1) * riser + tol_m)
    return (np.abs(z - level) < tol_m) | on_riser


def test_observed_points_lie_on_the_true_staircase():
    env = gymnasium.make(ENV_ID)
    obs, info = env.reset(seed=2)
    n_valid = 0
    while True:
        pts = obs[:256].reshape(-1, 4)
        assert set(np.unique(pts[:, 3])) <= {0.0, 1.0}
        assert np.all(pts[pts[:, 3] == 0.0, :3] == 0.0)
        _, _, x, y = _frames(info)
        local = pts[pts[:, 3] == 1.0, :3].astype(np.float64)
        world = info["stance_sole_w"] + local @ np.array([x, y, [0.0, 0.0, 1.0]])
        assert np.all(_on_staircase(world, info, 8e-3))  # 1.5 mm range noise, 1 mm quantisation
        n_valid += len(local)
        forward, up = oracle_target(info)
        obs, _, terminated, truncated, info = env.step(StairClimbEnv.action_from_target(forward, up))
        if terminated or truncated:
            break
    assert n_valid > 200
    env.close()


def test_render_rgb_array_and_no_human_mode():
    env = gymnasium.make(ENV_ID, render_mode="rgb_array")
    env.reset(seed=1)
    img = env.render()
    assert img.shape == (480, 640, 3) and img.dtype == np.uint8
    assert img.reshape(-1, 3).std(axis=0).max() > 10.0
    env.close()
    with pytest.raises(ConfigError, match="human"):
        StairClimbEnv(render_mode="human")


def test_reset_options_are_validated():
    env = gymnasium.make(ENV_ID)
    _, info = env.reset(seed=0, options={"riser_m": 0.17})
    assert info["riser_m"] == 0.17
    with pytest.raises(UnknownNameError):
        env.reset(options={"risers": 0.17})
    with pytest.raises(ConfigError):
        env.reset(options={"riser_m": 0.5})
    env.close()


def test_actions_outside_the_box_are_clipped_as_the_error_text_says():
    # gymnasium's convention for continuous Box actions: clip, do not refuse
    infos = []
    for action in ([5.0, 5.0], [1.0, 1.0]):
        env = StairClimbEnv()
        env.reset(seed=3)
        infos.append(env.step(np.array(action, dtype=np.float32))[4])
        env.close()
    assert (infos[0]["forward_m"], infos[0]["up_m"]) == (infos[1]["forward_m"], infos[1]["up_m"]) == pytest.approx((0.70, 0.30))
    env = StairClimbEnv()
    env.reset(seed=3)
    for bad in ([np.nan, 0.0], [0.0], [0.0, 0.0, 0.0]):
        with pytest.raises(ConfigError) as err:
            env.step(np.array(bad, dtype=np.float32))
        assert "two finite numbers" in str(err.value) and "clipped" in str(err.value)
    env.close()


@pytest.mark.parametrize("latency", [0.0, 0.03])
def test_observations_are_the_frames_the_recorder_produces(latency):
    # the oracle: envs.sim's record() over the episode's motion with the episode's rig and seed
    from exobench.envs.sensors import ToFConfig
    from exobench.envs.sim import record

    env = StairClimbEnv(tof=ToFConfig(latency_s=latency, dropout_prob=0.2))
    steps = [env.reset(seed=4)]
    for _ in range(6):
        obs, _, terminated, truncated, info = env.step(StairClimbEnv.action_from_target(*oracle_target(steps[-1][1])))
        steps.append((obs, info))
        if terminated or truncated:
            break
    assert len(steps) >= 4
    scene = env.scene
    rec = record(scene.model, scene.truth, scene.exo, env.motion, env.rig, env.sensor_seed)
    truth = rec.frame_truth([s.sensor_id for s in env.rig])
    t_end = steps[-1][1]["time_s"]
    assert env.motion.duration_s == t_end

    def measured(frame):
        """The measurement instant k / rate_hz of a frame, exactly as the sensors compute it."""
        return round((frame.stamp_s - latency) * 50.0) / 50.0

    def by(t):
        """The frames (and truth) measured before t (a step observes [t_prev, t)) and stamped by t."""
        return [(f, tr) for f, tr in zip(rec.frames, truth) if measured(f) < t and f.stamp_s <= t + 1e-12]

    def fields(frames):
        """Every field of every frame as bytes: equality bit for bit (NaN ranges included)."""
        return [tuple((k, np.asarray(v).tobytes()) for k, v in dataclasses.asdict(f).items()) for f in frames]

    delivered = [f for _, info in steps for f in info["frames"]]
    assert len(delivered) > 200
    assert fields(delivered) == fields(f for f, _ in by(t_end))
    names = [s.sensor_id for s in env.rig]
    n_before = 0
    for obs, info in steps:
        t = info["time_s"]
        now = by(t)
        assert fields(info["frames"]) == fields(f for f, _ in now[n_before:])  # what arrived during the step
        n_before = len(now)
        # each observation shows, per sensor, the last 16 readings delivered by its time, as
        # points along the beam from the recorder's true sensor pose, in the stance ground frame
        _, _, x, y = _frames(info)
        axes = np.column_stack([x, y, [0.0, 0.0, 1.0]])
        expected = np.zeros((4, 16, 4))
        for i, sid in enumerate(names):
            last = [(f, tr) for f, tr in now if f.sensor_id == sid][-16:]
            for k, (f, tr) in enumerate(last, start=16 - len(last)):
                if f.valid:
                    T = tr.T_world_sensor
                    expected[i, k, :3] = (T[:3, 3] + f.range_m * T[:3, 2] - info["stance_sole_w"]) @ axes
                    expected[i, k, 3] = 1.0
        np.testing.assert_array_equal(obs[:256], expected.reshape(-1).astype(np.float32))
    env.close()
