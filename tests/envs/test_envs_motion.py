"""envs.motion: leg IK against MuJoCo kinematics, smooth consistent derivatives, the
paper's climbing step against the true staircase geometry, and walking a course."""

import mujoco
import numpy as np
import pytest

from exobench.core import ConfigError
from exobench.core.transforms import rot_y, rot_z
from exobench.envs.motion import (
    LEVEL_LEAN_RAD,
    GaitError,
    Route,
    climb_step,
    leg_fk,
    leg_ik,
    plan_walk,
    sole_grid_f,
)
from exobench.envs.sim import PAPER_CASES, StairScenario
from exobench.envs.sim.scenarios.stairs import compiled_staircase
from exobench.envs.terrain import Terrain
from exobench.models.exo_spec import JOINT_RANGES_RAD, LEG_JOINTS, ExoSpec
from exobench.models.world_params import CourseParams
from exobench.models.worlds import build_course, build_level, compose


def _case(case: str):
    sc = StairScenario.paper_case(case)
    exo = sc.exo_spec()
    scene = compiled_staircase(sc.staircase_params(exo), exo)
    motion = climb_step(exo, scene.truth, distance_m=sc.distance_m, yaw_deg=sc.yaw_deg, duration_s=sc.duration_s)
    return sc, exo, scene, motion


def _plate_corners_w(model, data, side: str) -> np.ndarray:
    """Bottom corners of the MuJoCo foot plate geom, world (the model's own foot, not the planner's)."""
    g = data.geom(f"exo_footplate_{side}")
    h = model.geom(f"exo_footplate_{side}").size
    R = g.xmat.reshape(3, 3)
    c = [np.array([sx * h[0], sy * h[1], -h[2]]) for sx in (-1, 1) for sy in (-1, 1)]
    return np.array([g.xpos + R @ v for v in c])


def test_leg_ik_inverts_forward_kinematics():
    exo = ExoSpec(user_height_m=1.62)
    rng = np.random.default_rng(3)
    dx, dz = rng.uniform(-0.3, 0.3, 200), -rng.uniform(0.45, 0.8, 200)
    fp, pp = rng.uniform(-0.3, 0.3, 200), rng.uniform(-0.1, 0.1, 200)
    n_ok = 0
    for i in range(200):
        try:
            q = leg_ik(exo, dx[i : i + 1], dz[i : i + 1], fp[i : i + 1], pp[i : i + 1])
        except GaitError:  # out of reach or a joint outside its range
            continue
        n_ok += 1
        x, z, f = leg_fk(exo, *q, pp[i : i + 1])
        np.testing.assert_allclose([x[0], z[0], f[0]], [dx[i], dz[i], fp[i]], atol=1e-12)
        assert q[1][0] > 0  # the knee always flexes forward
    assert n_ok > 50


def test_leg_ik_refuses_out_of_reach():
    exo = ExoSpec()
    with pytest.raises(GaitError, match="out of reach"):
        leg_ik(exo, np.array([0.0]), np.array([-1.2]), np.array([0.0]), np.array([0.0]))


@pytest.mark.parametrize("case", ["A", "C"])
def test_motion_through_mujoco_kinematics_reaches_the_planned_feet(case):
    _, exo, scene, motion = _case(case)
    model, data = scene.model, mujoco.MjData(scene.model)
    t = np.linspace(0.0, motion.duration_s, 37)
    st, smp = motion.state(t), motion.sample(model, t)
    for k in range(len(t)):
        data.qpos[:] = smp.qpos[k]
        mujoco.mj_kinematics(model, data)
        np.testing.assert_allclose(data.body("pelvis").xpos, st.pelvis_w[k], atol=1e-12)
        R_pelvis = rot_z(st.yaw[k]) @ rot_y(st.pitch[k])
        np.testing.assert_allclose(data.body("pelvis").xmat.reshape(3, 3), R_pelvis, atol=1e-12)
        for side in ("l", "r"):
            np.testing.assert_allclose(data.body(f"foot_{side}").xpos, st.ankle_w[side][k], atol=1e-9)
            # the sole keeps its planned pitch: flat on the ground and the tread
            R_foot = rot_z(st.yaw[k]) @ rot_y(-st.foot_pitch[side][k])
            np.testing.assert_allclose(data.body(f"foot_{side}").xmat.reshape(3, 3), R_foot, atol=1e-9)
        for j, name in enumerate(LEG_JOINTS):
            assert data.joint(name).qpos[0] == pytest.approx(st.joints[k, j], abs=1e-15)


def test_qvel_and_qacc_are_the_derivatives_of_qpos():
    _, _, scene, motion = _case("B")
    model = scene.model
    d = 1e-3
    for t in (0.5, 0.9, 1.31, 1.6):
        s = motion.sample(model, np.array([t - d, t, t + d]))
        v_fd = np.zeros(model.nv)
        mujoco.mj_differentiatePos(model, v_fd, 2 * d, s.qpos[0], s.qpos[2])
        np.testing.assert_allclose(s.qvel[1], v_fd, atol=2e-5 * max(1.0, np.abs(s.qvel[1]).max()))
        a_fd = (s.qvel[2] - s.qvel[0]) / (2 * d)
        np.testing.assert_allclose(s.qacc[1], a_fd, atol=5e-4 * max(1.0, np.abs(s.qacc[1]).max()))
    # at rest before lift-off and after touch-down
    s = motion.sample(model, np.array([0.1, motion.duration_s - 0.05]))
    assert np.abs(s.qvel).max() < 1e-9 and np.abs(s.qacc).max() < 1e-6


@pytest.mark.parametrize("case", sorted(PAPER_CASES))
def test_climb_step_clears_the_nosing_and_lands_fully_on_the_first_tread(case):
    sc, exo, scene, motion = _case(case)
    model, data, truth = scene.model, mujoco.MjData(scene.model), scene.truth
    terrain = Terrain(truth)
    tread = truth.surface(2)
    t = np.arange(0.0, motion.duration_s + 1e-9, 0.005)
    smp = motion.sample(model, t)
    lowest_gap = np.inf
    lift, td = motion.events["liftoff_s"], motion.events["touchdown_s"]
    for k in range(len(t)):
        data.qpos[:] = smp.qpos[k]
        mujoco.mj_kinematics(model, data)
        for side in ("l", "r"):
            c = _plate_corners_w(model, data, side)
            gap = c[:, 2] - terrain.height(c[:, :2])
            assert np.all(gap > -1e-9), f"foot_{side} penetrates at t={t[k]:.3f}"
            if side == "r" and lift + 0.35 * (td - lift) < t[k] < lift + 0.65 * (td - lift):
                lowest_gap = min(lowest_gap, gap.min())
    assert lowest_gap > 0.03  # the 4 cm clearance in mid-swing, over the nosing too
    # at touch-down the whole plate rests on the first tread
    data.qpos[:] = motion.sample(model, motion.events["touchdown_s"]).qpos[0]
    mujoco.mj_kinematics(model, data)
    c = _plate_corners_w(model, data, "r")
    z, ids = terrain.query(c[:, :2])
    assert np.all(ids == 2)
    np.testing.assert_allclose(c[:, 2], tread.point_w[2], atol=1e-9)
    np.testing.assert_allclose(z, tread.point_w[2], atol=1e-12)
    # the stance foot never moved; the recorded touch-down sole point is below the right ankle
    fs = motion.footsteps[0]
    np.testing.assert_allclose(fs.sole_w, data.site("sole_r").xpos, atol=1e-9)
    assert motion.max_penetration_m(truth, t) == pytest.approx(0.0, abs=1e-12)


def test_climb_step_checks_the_staircase_matches_the_case():
    sc, exo, scene, _ = _case("A")
    with pytest.raises(ConfigError) as e:
        climb_step(exo, scene.truth, distance_m=0.40, yaw_deg=0.0)
    assert e.value.field == "distance_m"
    with pytest.raises(ConfigError) as e:
        climb_step(exo, scene.truth, distance_m=sc.distance_m, yaw_deg=10.0)
    assert e.value.field == "yaw_deg"


def test_far_first_riser_is_refused_as_out_of_reach():
    sc = StairScenario(distance_m=0.8, yaw_deg=45.0)
    exo = sc.exo_spec()
    scene = compiled_staircase(sc.staircase_params(exo), exo)
    with pytest.raises(ConfigError) as e:
        climb_step(exo, scene.truth, distance_m=0.8, yaw_deg=45.0)
    assert e.value.field == "distance_m"


def test_walk_turns_on_level_ground_with_sagittal_legs():
    exo = ExoSpec()
    world = build_level()
    route = Route(((0.0, 0.0), (1.5, 0.0), (1.5, 1.5)), step_length_m=0.3, swing_s=0.6, double_support_s=0.1)
    motion = plan_walk(exo, world.truth, route)
    end = motion.state(motion.duration_s)
    mid = 0.5 * (end.ankle_w["l"][0] + end.ankle_w["r"][0])
    assert np.linalg.norm(mid[:2] - [1.5, 1.5]) < 0.2
    assert abs(end.yaw[0] - np.pi / 2) < np.radians(20)  # pure pursuit: back on the route after the corner
    # the model follows the plan: feet flat on the floor at every footstep, no penetration
    scene = compose(world, exo)
    data = mujoco.MjData(scene.model)
    t = np.arange(0.0, motion.duration_s, 0.01)
    smp = motion.sample(scene.model, t)
    for k in range(0, len(t), 3):
        data.qpos[:] = smp.qpos[k]
        mujoco.mj_kinematics(scene.model, data)
        for side in ("l", "r"):
            assert _plate_corners_w(scene.model, data, side)[:, 2].min() > -1e-9


@pytest.mark.parametrize("mode", ["step-over", "step-to"])
def test_walk_up_and_down_stairs_lands_every_step_on_a_tread(mode):
    exo = ExoSpec()
    course = CourseParams(
        segments=(
            ("level", {"length_m": 0.6}),
            ("stairs", {"direction": "up", "n_steps": 2, "riser_m": 0.15, "tread_m": 0.30}),
            ("level", {"length_m": 1.2}),
            ("stairs", {"direction": "down", "n_steps": 2, "riser_m": 0.15, "tread_m": 0.30}),
            ("level", {"length_m": 0.6}),
        ),
        approach_m=1.0,
        exit_m=1.0,
    )
    truth = build_course(course).truth
    motion = plan_walk(exo, truth, Route(((-0.5, 0.0), (4.2, 0.0)), stairs=mode))
    treads = [s.surface_id for s in truth.surfaces if s.kind == "tread"]
    landed = [f.surface_id for f in motion.footsteps]
    per_tread = 1 if mode == "step-over" else 2  # step-to: both feet on every tread
    assert treads and all(landed.count(i) == per_tread for i in treads)
    terrain = Terrain(truth)
    for f in motion.footsteps:  # every landing sole point lies on the surface it was planned on
        z, sid = terrain.query(f.sole_w[None, :2])
        assert sid[0] == f.surface_id and f.sole_w[2] == pytest.approx(z[0], abs=1e-9)
    t = np.arange(0.0, motion.duration_s, 0.002)
    assert motion.max_penetration_m(truth, t) < 1e-9


@pytest.mark.parametrize("height_m, tread_m", [(1.65, 0.30), (1.88, 0.25)])
def test_walk_down_steep_stairs_lands_on_every_tread_without_penetration(height_m, tread_m):
    """0.25 m risers (seeds/002): every foot flat on its own tread, no penetration; a 1.88 m user's
    foot (0.279 m) is longer than a 0.25 m tread: its toes beyond the ball of the foot overhang."""
    exo = ExoSpec(user_height_m=height_m)
    riser, tread, n = 0.25, tread_m, 3
    course = CourseParams(
        segments=(
            ("stairs", {"direction": "up", "n_steps": n, "riser_m": riser, "tread_m": tread}),
            ("level", {"length_m": 1.2}),
            ("stairs", {"direction": "down", "n_steps": n, "riser_m": riser, "tread_m": tread}),
        ),
        approach_m=1.0,
        exit_m=1.2,
    )
    truth = build_course(course).truth
    edge = (n - 1) * tread + 1.2  # x of the landing's edge (the first riser down)
    toe = exo.foot_m - exo.heel_to_ankle_m
    start_x = edge - toe - 0.08  # standing on the landing, toes 8 cm before its edge
    route = Route(((start_x, 0.0), (edge + n * tread + 0.8, 0.0)), step_length_m=0.35, swing_s=0.42,
                  double_support_s=0.12, max_turn_deg=45.0)  # fmt: skip
    motion = plan_walk(exo, truth, route)
    terrain = Terrain(truth)
    down = [s for s in truth.surfaces if s.kind == "tread" and s.polygon_w[:, 0].min() >= edge - 1e-9]
    assert len(down) == n - 1  # the last tread down is the exit floor
    landed = [f.surface_id for f in motion.footsteps]
    for s in down:  # step-over: one foot on each tread of the flight
        assert landed.count(s.surface_id) == 1
    # each footstep: the sole flat on its surface when the foot is down (from the heel to the ball
    # of the foot at least, 0.73 of the foot from the heel; all of it when it fits), heights
    # falling riser by riser
    grid = sole_grid_f(exo)
    on = grid[:, 0] <= 0.73 * exo.foot_m - exo.heel_to_ankle_m if exo.foot_m > tread else np.ones(len(grid), bool)
    z_prev = riser * n
    for f in motion.footsteps:
        st = motion.state(f.touchdown_s)
        pts = st.sole_points_w(f.side, grid)[0]
        z, ids = terrain.query(pts[:, :2])
        assert np.all(ids[on] == f.surface_id)
        np.testing.assert_allclose(pts[on, 2], z[on], atol=1e-9)
        assert np.all(pts[:, 2] >= np.nan_to_num(z, nan=-np.inf) - 1e-9)
        assert f.sole_w[2] == pytest.approx(z_prev, abs=1e-9) or f.sole_w[2] == pytest.approx(z_prev - riser, abs=1e-9)
        z_prev = min(z_prev, float(f.sole_w[2]))
    assert z_prev == pytest.approx(0.0, abs=1e-9)  # reached the floor
    t = np.arange(0.0, motion.duration_s, 0.002)
    assert motion.max_penetration_m(truth, t) < 1e-9
    # the legs stay inside the model's joint ranges
    q = motion.state(t).joints
    for k, name in enumerate(LEG_JOINTS):
        lo, hi = JOINT_RANGES_RAD[name[:-2]]
        assert lo - 1e-9 <= q[:, k].min() and q[:, k].max() <= hi + 1e-9


def test_walk_starts_with_the_route_start_lean_and_takes_up_the_walking_lean():
    exo = ExoSpec()
    world = build_level()
    wps = ((0.0, 0.0), (1.2, 0.0))
    upright = plan_walk(exo, world.truth, Route(wps))
    leaned = plan_walk(exo, world.truth, Route(wps, start_lean_deg=3.0))
    t_still = np.array([0.0, 0.5 * Route(wps).still_s])
    assert np.allclose(upright.state(t_still).pitch, 0.0)
    assert np.allclose(leaned.state(t_still).pitch, np.radians(3.0))
    # after the first swing both lean as walkers do on level ground
    t_walk = upright.events["liftoff_s"] + Route(wps).swing_s + 0.05
    assert upright.state(t_walk).pitch[0] == pytest.approx(LEVEL_LEAN_RAD)
    assert leaned.state(t_walk).pitch[0] == pytest.approx(LEVEL_LEAN_RAD)
    t = np.arange(0.0, leaned.duration_s, 0.01)
    assert leaned.max_penetration_m(world.truth, t) < 1e-9
    with pytest.raises(ConfigError) as e:
        Route(wps, start_lean_deg=20.0)
    assert e.value.field == "route.start_lean_deg"


def test_max_penetration_in_chunks_is_the_deepest_point_of_every_instant(monkeypatch):
    """Soles lowered 5 mm into a staircase walk: the deepest point over the instants, computed
    10 s of motion at a time (here a few instants at a time), is the one of a direct sweep."""
    from exobench.envs.motion import motion as motion_module
    from exobench.envs.sim import plan_climb

    scenario = StairScenario(duration_s=3.0)
    scene, motion = plan_climb(scenario)
    exo = scenario.exo_spec()
    sole = sole_grid_f(exo) - np.array([0.0, 0.0, 0.005])
    t = np.arange(0.0, motion.duration_s, 0.01)
    terrain = Terrain(scene.truth)
    st = motion.state(t)
    want = max(float(np.max(terrain.penetration(st.sole_points_w(side, sole).reshape(-1, 3)))) for side in ("l", "r"))
    assert want > 0.004
    monkeypatch.setattr(motion_module, "TRUTH_CHUNK", 7)
    assert motion.max_penetration_m(scene.truth, t, sole) == want
