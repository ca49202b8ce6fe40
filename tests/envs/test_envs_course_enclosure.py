"""The stairwell around a course (``enclosure="stairwell"``): where its walls and ceiling are, what
the camera sees of them, and that the walk and its terrain truth are the open course's."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from exobench.core import ConfigError, ContactSample, ImuSample, RgbdFrame
from exobench.envs.sim.scenarios.course import LocomotionScenario, enclosure_of, simulate_locomotion
from exobench.envs.sim.scenarios.course_enclosure import enclose_stairwell
from exobench.envs.sim.scenarios.course_world import build_locomotion_world

pytestmark = pytest.mark.long(seconds=2)  # the workers take it first (tests/conftest.py); 2: the file at -n 0 in one run at load 12-15, scaled to that run's CPU

# a head camera that looks up more than the paper's (mean pitch 0.1 rad above the horizon), so a
# 6 s walk sees the ceiling; 212 px wide so plane extraction finds it (at 64 px it finds none)
WALK = {"width_px": 212, "height_px": 120, "rate_hz": 5.0, "duration_cap_s": 6.0, "surfaces": "textured", "mount": "head",
        "head_pitch_mean_rad": -0.1, "odom_drift_pct": 0.0, "odom_yaw_drift_deg_per_m": 0.0}


@pytest.fixture(scope="module")
def walks():
    """The same walk, same seed, on the open course and in its stairwell."""
    return {enc: simulate_locomotion(LocomotionScenario(**WALK, enclosure=enc), 0) for enc in ("open", "stairwell")}


def _ray(model: mujoco.MjModel, data: mujoco.MjData, p: list[float], d: list[float]) -> tuple[float, str]:
    """Distance to the first world geom along a ray (direction ``d``), and its name (-1 and '' when none)."""
    gid = np.array([-1], dtype=np.int32)
    u = np.array(d, float) / np.linalg.norm(d)
    dist = mujoco.mj_ray(model, data, np.array(p, float), u, None, 1, -1, gid)
    return float(dist), (mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, int(gid[0])) or "") if gid[0] >= 0 else ""


@pytest.mark.parametrize("values", [
    {"terrain": "stairs", "riser_m": 0.20, "n_steps": 4, "width_m": 1.2},
    {"terrain": "ramp", "slope_deg": 15.8, "ramp_length_m": 2.5, "width_m": 1.6},
])  # fmt: skip
def test_the_stairwell_closes_the_course_where_stated(values):
    """End walls 1 m beyond the ends of the course's floor, side walls continued to them, a ceiling
    2.4 m over the highest walking surface, spots under it: measured by rays from inside
    against the course's own dimensions (profile ends, rise, width); the open course has none."""
    sc = LocomotionScenario(**values, approach_m=2.2, enclosure="stairwell")
    world = build_locomotion_world(sc)[0]
    prof = world.truth.params["profile"]
    xs, xe, W = prof[0]["x0"], prof[-1]["x1"], 0.5 * values["width_m"]
    rise = (values["n_steps"] * values["riser_m"] if values["terrain"] == "stairs"
            else values["ramp_length_m"] * np.tan(np.radians(values["slope_deg"])))  # fmt: skip
    assert xs == pytest.approx(-2.2) and world.truth.params["top_z_m"] == pytest.approx(rise)
    zc = rise + 2.4
    enclosed = enclose_stairwell(world, values["width_m"])
    for w, closed in ((world, False), (enclosed, True)):
        model = w.spec.copy().compile()
        data = mujoco.MjData(model)
        mujoco.mj_forward(model, data)
        hits = {
            "end": _ray(model, data, [xe, 0.0, 1.0], [1, 0, 0]),
            "start": _ray(model, data, [xs, 0.0, 1.0], [-1, 0, 0]),
            "up_floor": _ray(model, data, [xs + 0.5, 0.0, 1.0], [0, 0, 1]),
            "up_top": _ray(model, data, [0.5 * (xs + xe), 0.0, rise + 1.0], [0, 0, 1]),
            "side_beyond_end": _ray(model, data, [xe + 0.5, 0.0, 1.0], [0, 1, 0]),
            "side_before_start": _ray(model, data, [xs - 0.5, 0.0, 1.0], [0, -1, 0]),
        }
        if not closed:
            assert all(d == -1 for d, _ in hits.values()), hits
            continue
        assert hits["end"][0] == pytest.approx(1.0, abs=1e-6)
        assert hits["start"][0] == pytest.approx(1.0, abs=1e-6)
        assert hits["up_floor"][0] == pytest.approx(zc - 1.0, abs=1e-6)
        assert hits["up_top"][0] == pytest.approx(1.4, abs=1e-6)
        assert hits["side_beyond_end"][0] == pytest.approx(W, abs=1e-6)
        assert hits["side_before_start"][0] == pytest.approx(W, abs=1e-6)
        # the corners are closed: a ray into the corner of an end wall and a side wall hits
        assert _ray(model, data, [xe, 0.0, 1.0], [1.0, W, 0.0])[0] == pytest.approx(np.hypot(1.0, W), abs=1e-6)
        spots = [model.light_pos[i] for i in range(model.nlight) if model.light(i).name.startswith("world_spot")]
        assert len(spots) == 2 and all(p[2] == pytest.approx(zc - 0.1) for p in spots)
        # the truth: the ceiling's underside faces down at zc, the end walls face inwards at xs - 1, xe + 1
        new = enclosed.truth.surfaces[len(world.truth.surfaces):]
        ceiling = [s for s in new if s.kind == "ceiling"]
        assert len(ceiling) == 1 and ceiling[0].normal_w[2] == pytest.approx(-1.0)
        assert ceiling[0].polygon_w[:, 2] == pytest.approx(np.full(4, zc))
        end_x = sorted(float(s.point_w[0]) for s in new if s.kind == "wall" and abs(s.normal_w[0]) > 0.9)
        assert end_x == pytest.approx([xs - 1.0, xe + 1.0])


def test_the_stairwell_changes_what_the_camera_sees_and_no_terrain_truth(walks):
    """Same seed, open and enclosed: the steps (footprints, modes, times), the events, the camera
    trajectory, the IMU and the insoles are the same bit for bit, the open course's surfaces are
    the enclosed one's first ones unchanged; the depth images see more (the end wall ahead, the
    ceiling, where the open course has sky)."""
    eps = walks
    a, b = eps["open"].truth, eps["stairwell"].truth
    assert len(a.steps) >= 5 and len(a.steps) == len(b.steps)
    for sa, sb in zip(a.steps, b.steps):
        assert np.array_equal(sa.footprint_w, sb.footprint_w)
        assert (sa.mode, sa.terrain, sa.liftoff_s, sa.heel_strike_s) == (sb.mode, sb.terrain, sb.liftoff_s, sb.heel_strike_s)
    assert a.events == b.events and np.array_equal(a.trajectory_w, b.trajectory_w)
    n = len(a.scene.surfaces)
    assert len(b.scene.surfaces) > n
    for s, t in zip(a.scene.surfaces, b.scene.surfaces[:n]):
        assert (s.surface_id, s.kind, s.geom_names) == (t.surface_id, t.kind, t.geom_names)
        assert np.array_equal(s.polygon_w, t.polygon_w)

    def motion_frames(ep):
        return [(f.sensor_id, f.stamp_s, getattr(f, "accel_m_s2", None), getattr(f, "in_contact", None))
                for f in ep.frames if isinstance(f, (ImuSample, ContactSample))]

    fa, fb = motion_frames(eps["open"]), motion_frames(eps["stairwell"])
    assert len(fa) == len(fb) and all(x[:2] == y[:2] and np.array_equal(x[2], y[2]) and x[3] == y[3] for x, y in zip(fa, fb))
    valid = {k: np.array([np.mean(f.depth_m > 0) for f in ep.frames if isinstance(f, RgbdFrame)]) for k, ep in eps.items()}
    assert np.all(valid["stairwell"] >= valid["open"] - 0.01)
    assert float(np.max(valid["stairwell"] - valid["open"])) > 0.1


def test_a_stairwell_needs_walls_and_is_not_for_the_parallel_course():
    assert LocomotionScenario().enclosure == "open"
    # auto: a stairwell where one can stand, else open
    assert enclosure_of(LocomotionScenario(enclosure="auto")) == "stairwell"
    assert enclosure_of(LocomotionScenario(terrain="ramp", enclosure="auto")) == "stairwell"
    assert enclosure_of(LocomotionScenario(terrain="parallel", enclosure="auto")) == "open"
    assert enclosure_of(LocomotionScenario(walls=False, enclosure="auto")) == "open"
    for bad in ({"terrain": "parallel"}, {"walls": False}):
        with pytest.raises(ConfigError, match="enclosure"):
            LocomotionScenario(**bad, enclosure="stairwell")
    with pytest.raises(ConfigError, match="enclosure"):
        LocomotionScenario(enclosure="roof")


def test_terrain_recon_ignores_the_ceiling(walks):
    """terrain-recon (given odometry, exact here) in the stairwell: the ceiling is mapped as
    planes seen from below (``overhead``) at its height, none of them is terrain, and every
    prediction is the open course's (the same mode and footprint on every frame)."""
    from exobench.mapping.locomotion import TerrainReconstructionPipeline

    est = {}
    for enc, ep in walks.items():
        p = TerrainReconstructionPipeline()
        p.reset(ep.calibration)
        for f in ep.frames:
            p.process(f)
        est[enc] = p.finalize()
    a, b = est["open"].predictions, est["stairwell"].predictions
    assert len(a) == len(b) and sum(bool(x.mode) for x in a) >= 10
    for x, y in zip(a, b):
        assert x.mode == y.mode and np.allclose(x.footprint_odom, y.footprint_odom, equal_nan=True, atol=1e-9)
    ep = walks["stairwell"]
    # the odometry frame: gravity-aligned, its origin the camera at t = 0
    zc = ep.truth.scene.params["ceiling_z_m"] - float(ep.truth.trajectory_w[0, 3])
    overhead = [pl for pl in est["stairwell"].planes if pl["kind"] == "overhead"]
    assert overhead and all(abs(pl["centroid"][2] - zc) < 0.05 for pl in overhead)
    assert all(pl["kind"] == "steep" or pl["centroid"][2] < 0.0 for pl in est["stairwell"].planes if pl["kind"] != "overhead")
    assert not any(pl["kind"] == "overhead" for pl in est["open"].planes)
