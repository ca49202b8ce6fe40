"""envs sensors: ToF against ray-plane geometry, IMU against the motion's derivatives, encoders,
contacts, latency/dropout, and seeded reproducibility."""

import dataclasses

import mujoco
import numpy as np
import pytest

from exobench.core import ConfigError, ImuSample, JointState, SceneTruth, ToFReading, TofStatus
from exobench.envs.motion import climb_step
from exobench.envs.sensors import (
    ContactConfig,
    EncoderConfig,
    ImuConfig,
    ImuSensor,
    SensorsConfig,
    ToFConfig,
    ToFSensor,
    cone_directions,
    imu_dynamics,
    sensor_rngs,
    stable_int_key,
)
from exobench.envs.sim import StairScenario, scalar_rig
from exobench.envs.sim.scenarios.stairs import compiled_staircase, record_climb
from exobench.models.exo import add_exo
from exobench.models.exo_spec import LEG_JOINTS, TOF_IDS, ExoSpec

NOISELESS = SensorsConfig(
    tof=ToFConfig(noise_m=0.0, resolution_m=0.0),
    imu=ImuConfig(noise_scale=0.0, orientation_rms_deg=0.0),
    encoders=EncoderConfig(noise_rad=0.0, resolution_bits=0),
    contact=ContactConfig(noise_n=0.0),
)


def _setup(case: str = "A"):
    sc = StairScenario.paper_case(case)
    exo = sc.exo_spec()
    scene = compiled_staircase(sc.staircase_params(exo), exo)
    motion = climb_step(exo, scene.truth, distance_m=sc.distance_m, yaw_deg=sc.yaw_deg)
    return exo, scene, motion


def _by(frames, cls, sid=None):
    return [f for f in frames if isinstance(f, cls) and (sid is None or f.sensor_id == sid)]


@pytest.mark.parametrize("case", ["A", "C"])
def test_noiseless_tof_range_is_the_distance_to_the_true_plane(case):
    exo, scene, motion = _setup(case)
    rec = record_climb(scene, exo, motion, scalar_rig(NOISELESS), 0)
    tofs = _by(rec.frames, ToFReading)
    assert len(tofs) == len(rec.frame_truth(TOF_IDS)) == 4 * 101
    data = mujoco.MjData(scene.model)
    seen = set()
    for fr, tt in zip(tofs, rec.frame_truth(TOF_IDS)):
        assert (fr.stamp_s, fr.sensor_id) == (tt.stamp_s, tt.sensor_id)
        # the sensor pose, independently from MuJoCo's kinematics at that instant
        data.qpos[:] = motion.sample(scene.model, fr.stamp_s).qpos[0]
        mujoco.mj_kinematics(scene.model, data)
        p, R = data.site(fr.sensor_id).xpos, data.site(fr.sensor_id).xmat.reshape(3, 3)
        np.testing.assert_allclose(tt.T_world_sensor[:3, 3], p, atol=1e-12)
        if tt.surface_id < 0:
            continue
        s = scene.truth.surface(tt.surface_id)
        expected = float((s.point_w - p) @ s.normal_w / (R[:, 2] @ s.normal_w))
        assert fr.status == TofStatus.VALID
        assert fr.range_m == pytest.approx(expected, abs=1e-9)
        assert tt.true_range_m == pytest.approx(expected, abs=1e-9)
        assert s.contains(tt.hit_w, tol_m=1e-6)
        seen.add((fr.sensor_id, tt.surface_id))
    # the climbing calf's two beams sweep the ground, the first riser, the first tread and beyond
    for sid in ("tof_r_med", "tof_r_lat"):
        assert {0, 1, 2, 3, 4} <= {k for s_, k in seen if s_ == sid}


def _bare_model(exo: ExoSpec) -> mujoco.MjModel:
    spec = mujoco.MjSpec()
    add_exo(spec, exo)  # no floor, no stairs: nothing to hit below
    return spec.compile()


def test_tof_without_target_or_out_of_range_gives_nan_and_a_status():
    exo = ExoSpec()
    model = _bare_model(exo)
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    empty = SceneTruth((), {})
    s = ToFSensor("tof_r_med", ToFConfig(), model, seed=1)
    s.observe(model, data, 0.0)
    (fr, tt), = s.frames(model, empty)
    assert np.isnan(fr.range_m) and fr.status == TofStatus.NO_TARGET and not fr.valid
    assert np.isnan(tt.true_range_m) and tt.surface_id == -1 and np.all(np.isnan(tt.hit_w))
    # a target beyond the maximum range
    exo2, scene, motion = _setup("A")
    data = mujoco.MjData(scene.model)
    data.qpos[:] = motion.sample(scene.model, 0.0).qpos[0]
    mujoco.mj_kinematics(scene.model, data)
    s = ToFSensor("tof_r_med", ToFConfig(max_range_m=0.1), scene.model, seed=1)
    s.observe(scene.model, data, 0.0)
    (fr, tt), = s.frames(scene.model, scene.truth)
    assert np.isnan(fr.range_m) and fr.status == TofStatus.OUT_OF_BOUNDS
    assert tt.true_range_m > 0.1 and tt.surface_id >= 0


def test_tof_cone_mixes_sub_rays_within_the_field_of_view():
    d = cone_directions(16, 27.0)
    np.testing.assert_allclose(np.linalg.norm(d, axis=1), 1.0)
    assert np.allclose(d[0], [0, 0, 1]) and np.degrees(np.arccos(d[:, 2].min())) <= 13.5 + 1e-9
    exo, scene, motion = _setup("A")
    cfg = dataclasses.replace(NOISELESS, tof=ToFConfig(noise_m=0.0, resolution_m=0.0, n_cone_rays=16))
    rec = record_climb(scene, exo, motion, scalar_rig(cfg), 0)
    diffs = [abs(f.range_m - t.true_range_m) for f, t in zip(_by(rec.frames, ToFReading), rec.frame_truth(TOF_IDS)) if f.valid]
    # a flat target seen at an angle: the mixture stays near the central range, edges differ more
    assert np.median(diffs) < 0.03 and max(diffs) > np.median(diffs)


def test_imu_reads_gravity_at_rest_and_the_motion_while_moving():
    exo, scene, motion = _setup("B")
    rec = record_climb(scene, exo, motion, scalar_rig(NOISELESS), 0)
    imu = _by(rec.frames, ImuSample)
    assert len(imu) == 401
    g = -scene.model.opt.gravity[2]
    for f in imu:
        if f.stamp_s < motion.events["liftoff_s"]:  # standing still, upright
            np.testing.assert_allclose(f.accel_m_s2, [0.0, 0.0, g], atol=1e-6)
            np.testing.assert_allclose(f.gyro_rad_s, 0.0, atol=1e-9)
            np.testing.assert_allclose(f.quat_wxyz, [1.0, 0.0, 0.0, 0.0], atol=1e-9)
    # while moving: specific force and angular rate from finite differences of the site's pose
    data = mujoco.MjData(scene.model)
    h = 1e-3

    def site_pose(t):
        data.qpos[:] = motion.sample(scene.model, t).qpos[0]
        mujoco.mj_kinematics(scene.model, data)
        return data.site("imu_trunk").xpos.copy(), data.site("imu_trunk").xmat.reshape(3, 3).copy()

    for f in imu[100:300:20]:
        (pm, Rm), (p0, R0), (pp, Rp) = site_pose(f.stamp_s - h), site_pose(f.stamp_s), site_pose(f.stamp_s + h)
        acc_w = (pp - 2 * p0 + pm) / h**2
        np.testing.assert_allclose(f.accel_m_s2, R0.T @ (acc_w + [0, 0, g]), atol=2e-3)
        W = R0.T @ (Rp - Rm) / (2 * h)
        np.testing.assert_allclose(f.gyro_rad_s, [W[2, 1], W[0, 2], W[1, 0]], atol=2e-4)


def test_imu_noise_follows_the_configured_densities():
    exo, scene, motion = _setup("A")
    cfg = ImuConfig(gyro_random_walk=0.0, accel_random_walk=0.0, orientation_rms_deg=0.0)
    s = ImuSensor("imu_trunk", cfg, scene.model, seed=5)
    data = mujoco.MjData(scene.model)
    smp = motion.sample(scene.model, 0.1)
    for k in range(2000):  # standing still
        imu_dynamics(scene.model, data, smp.qpos[0], smp.qvel[0], smp.qacc[0])
        s.observe(scene.model, data, k / cfg.rate_hz)
    gyro = np.array([f.gyro_rad_s for f in s.frames()])
    expected = cfg.gyro_noise_density * np.sqrt(cfg.rate_hz)
    assert np.std(gyro) == pytest.approx(expected, rel=0.05)


def test_encoders_quantise_and_offset():
    exo, scene, motion = _setup("A")
    cfg = dataclasses.replace(NOISELESS, encoders=EncoderConfig(noise_rad=0.0, resolution_bits=14))
    rec = record_climb(scene, exo, motion, scalar_rig(cfg), 0)
    js = _by(rec.frames, JointState)
    assert len(js) == 401 and js[0].names == LEG_JOINTS
    lsb = 2 * np.pi / 2**14
    for f in js[::25]:
        true = motion.state(f.stamp_s).joints[0]
        assert np.all(np.abs(f.position_rad - true) <= lsb / 2 + 1e-12)
        np.testing.assert_allclose(f.position_rad / lsb, np.round(f.position_rad / lsb), atol=1e-9)


def test_contacts_carry_the_weight_and_release_in_swing():
    exo, scene, motion = _setup("A")
    rec = record_climb(scene, exo, motion, scalar_rig(NOISELESS), 0)
    cs = [f for f in rec.frames if f.sensor_id.startswith("contact_")]
    weight = (exo.user_mass_kg + exo.exo_mass_kg) * 9.81
    lift, td = motion.events["liftoff_s"], motion.events["touchdown_s"]
    by_t: dict[float, dict[str, float]] = {}
    for f in cs:
        by_t.setdefault(f.stamp_s, {})[f.sensor_id] = f.force_n
    for t, forces in by_t.items():
        if t < lift or t > td:  # both feet down
            assert sum(forces.values()) == pytest.approx(weight, rel=0.01)
        if lift + 0.2 < t < td - 0.2:  # right foot in the air, the left carries everything
            assert forces["contact_r_heel"] < 2.0 and forces["contact_r_toe"] < 2.0
            assert forces["contact_l_heel"] + forces["contact_l_toe"] > 0.5 * weight


def test_same_seed_same_frames_bit_for_bit_and_different_seed_differs():
    exo, scene, motion = _setup("C")
    cfg = StairScenario(tof_dropout=0.2).sensors_config()
    a = record_climb(scene, exo, motion, scalar_rig(cfg), 11)
    b = record_climb(scene, exo, motion, scalar_rig(cfg), 11)
    c = record_climb(scene, exo, motion, scalar_rig(cfg), 12)

    def flat(rec):
        out = []
        for f in rec.frames:
            d = dataclasses.asdict(f)
            out.append(tuple((k, np.asarray(v).tobytes() if not isinstance(v, str) else v) for k, v in d.items()))
        return out

    assert flat(a) == flat(b)
    assert flat(a) != flat(c)
    n_tof = len(_by(a.frames, ToFReading))
    assert 0.6 * 404 < n_tof < 0.95 * 404  # about 20 % of the ToF frames dropped
    stamps = [f.stamp_s for f in a.frames]
    assert stamps == sorted(stamps)


def test_latency_shifts_stamps_and_rngs_are_per_sensor():
    exo, scene, motion = _setup("A")
    cfg = dataclasses.replace(NOISELESS, tof=ToFConfig(noise_m=0.0, resolution_m=0.0, latency_s=0.013))
    rec = record_climb(scene, exo, motion, scalar_rig(cfg), 0)
    tofs = _by(rec.frames, ToFReading, "tof_r_lat")
    assert tofs[0].stamp_s == pytest.approx(0.013) and tofs[1].stamp_s == pytest.approx(0.033)
    assert stable_int_key("tof_r_lat") == stable_int_key("tof_r_lat") != stable_int_key("tof_r_med")
    a, _ = sensor_rngs(3, "imu_trunk")
    b, _ = sensor_rngs(3, "imu_trunk")
    c, _ = sensor_rngs(3, "tof_l_med")
    x = a.standard_normal(4)
    assert np.array_equal(x, b.standard_normal(4)) and not np.array_equal(x, c.standard_normal(4))
    with pytest.raises(ConfigError):
        sensor_rngs(-1, "imu_trunk")


@pytest.mark.parametrize(
    "make, field",
    [
        (lambda: ToFConfig(rate_hz=0.0), "tof.rate_hz"),
        (lambda: ToFConfig(n_cone_rays=2.5), "tof.n_cone_rays"),
        (lambda: ToFConfig(dropout_prob=1.0), "tof.dropout_prob"),
        (lambda: ImuConfig(noise_scale=float("nan")), "imu.noise_scale"),
        (lambda: EncoderConfig(resolution_bits=40), "encoders.resolution_bits"),
    ],
)
def test_sensor_configs_validate(make, field):
    with pytest.raises(ConfigError) as e:
        make()
    assert e.value.field == field


def test_every_tof_sensor_and_stream_is_present():
    exo, scene, motion = _setup("B")
    rec = record_climb(scene, exo, motion, scalar_rig(SensorsConfig()), 0)
    ids = {f.sensor_id for f in rec.frames}
    assert set(TOF_IDS) <= ids and {"imu_trunk", "encoders", "contact_l_heel", "contact_r_toe"} <= ids


def test_imu_orientation_error_has_the_configured_rms():
    exo, scene, motion = _setup("A")
    cfg = ImuConfig(noise_scale=0.0, orientation_rms_deg=0.5, orientation_tau_s=0.05)
    s = ImuSensor("imu_trunk", cfg, scene.model, seed=2)
    data = mujoco.MjData(scene.model)
    smp = motion.sample(scene.model, 0.1)
    imu_dynamics(scene.model, data, smp.qpos[0], smp.qvel[0], smp.qacc[0])
    for k in range(4000):
        s.observe(scene.model, data, k / cfg.rate_hz)
    ang = [2 * np.degrees(np.arccos(min(1.0, abs(f.quat_wxyz[0])))) for f in s.frames()]  # true attitude: identity
    assert np.sqrt(np.mean(np.square(ang))) == pytest.approx(0.5, rel=0.1)


def test_vectorised_terrain_and_hit_labels_match_core_truth():
    from exobench.core import height_at
    from exobench.envs.terrain import Terrain, label_hits

    exo, scene, motion = _setup("B")
    truth = scene.truth
    rng = np.random.default_rng(0)
    xy = rng.uniform([-1.0, -1.0], [2.5, 1.0], size=(500, 2))
    z = Terrain(truth).height(xy)
    ref = np.array([height_at(truth, *p) for p in xy])
    np.testing.assert_array_equal(np.isnan(z), np.isnan(ref))
    np.testing.assert_allclose(z[~np.isnan(z)], ref[~np.isnan(ref)], atol=1e-12)
    # points on surfaces (and a little off them), labelled per geom like surface_of_hit
    names, pts = [], []
    for s in truth.surfaces:
        for g in s.geom_names:
            w = rng.uniform(0.0, 1.0, len(s.polygon_w))
            p = (w / w.sum()) @ s.polygon_w + rng.normal(0, 5e-5) * s.normal_w
            names.append(g)
            pts.append(p)
    got = label_hits(truth, names, np.array(pts))
    assert list(got) == [truth.surface_of_hit(n, p) for n, p in zip(names, pts)]
