"""Walking routes that revisit places and turn sharply: loops, out-and-back spurs, the office loop."""

import numpy as np
import pytest

from exobench.core import ConfigError
from exobench.envs.motion import Route, plan_walk
from exobench.envs.sim.scenarios.office import OfficeScenario, plan_office_walk, route_waypoints
from exobench.models.exo_spec import ExoSpec
from exobench.models.office import office_route
from exobench.models.worlds import build_level

# a closed loop with an out-and-back spur (180 deg turn), 90 deg corners and revisited points
LOOP = ((0.0, 0.0), (2.0, 0.0), (2.0, 1.5), (2.0, 0.0), (3.0, 0.0), (3.0, -1.5), (0.0, -1.5), (0.0, 0.0))


def _mid_track(motion, dt: float = 0.05) -> tuple[np.ndarray, np.ndarray]:
    t = np.arange(0.0, motion.duration_s + 1e-9, dt)
    st = motion.state(t, solve_legs=False)
    return t, st.pelvis_w[:, :2]


def _visit_times(t: np.ndarray, xy: np.ndarray, waypoints, tol_m: float) -> list[float]:
    """Time of the first pass within ``tol_m`` of each waypoint after the previous one's (in order)."""
    out, k0 = [], 0
    for w in waypoints:
        d = np.linalg.norm(xy[k0:] - np.asarray(w), axis=1)
        near = np.flatnonzero(d < tol_m)
        assert len(near), f"waypoint {w} never reached after t={t[k0]:.1f} s (closest {d.min():.3f} m)"
        k0 += int(near[0])
        out.append(float(t[k0]))
    return out


def _on_segments_in_order(t, xy, waypoints, visits, tol_m: float) -> None:
    """Between the visits of waypoints i and i+1 the walker stays near segment i."""
    for i, (a, b) in enumerate(zip(waypoints, waypoints[1:])):
        a, b = np.asarray(a), np.asarray(b)
        m = (t >= visits[i]) & (t <= visits[i + 1])
        ab = b - a
        u = np.clip((xy[m] - a) @ ab / (ab @ ab), 0.0, 1.0)
        dist = np.linalg.norm(a + u[:, None] * ab - xy[m], axis=1)
        assert dist.max() < tol_m, (i, float(dist.max()))


@pytest.fixture(scope="module")
def level_loop():
    exo = ExoSpec()
    route = Route(LOOP, step_length_m=0.35, swing_s=0.6, double_support_s=0.1, max_turn_deg=25.0, end_yaw_deg=0.0)
    return exo, route, plan_walk(exo, build_level().truth, route)


def test_loop_with_a_spur_is_walked_in_order_and_closes(level_loop):
    exo, route, motion = level_loop
    t, xy = _mid_track(motion)
    visits = _visit_times(t, xy, LOOP, tol_m=0.2)
    _on_segments_in_order(t, xy, LOOP, visits, tol_m=0.3)
    # the spur is walked out and back: (2, 0) is passed twice, and the start at both ends
    assert len(set(LOOP)) < len(LOOP)
    end = motion.state(motion.duration_s)
    mid = 0.5 * (end.ankle_w["l"][0] + end.ankle_w["r"][0])
    assert np.linalg.norm(mid[:2]) < 0.1
    assert abs(np.angle(np.exp(1j * end.yaw[0]))) < np.radians(0.5)  # turned back to the start heading
    # no heading change per step beyond max_turn_deg, also in the 180 deg turn
    yaws = np.array([0.0] + [f.yaw_rad for f in motion.footsteps])
    assert np.max(np.abs(np.diff(yaws))) <= np.radians(route.max_turn_deg) + 1e-9
    # feet flat on the floor, never crossing: the left foot stays left of the right one
    st = motion.state(np.array([f.touchdown_s for f in motion.footsteps]))
    lateral = np.einsum("ij,ij->i", st.ankle_w["l"][:, :2] - st.ankle_w["r"][:, :2],
                        np.column_stack([-np.sin(st.yaw), np.cos(st.yaw)]))  # fmt: skip
    assert np.all(lateral > 0.5 * exo.hip_width_m)


def test_sharp_turns_need_no_large_max_turn():
    exo = ExoSpec()
    truth = build_level().truth
    spur = ((0.0, 0.0), (1.5, 0.0), (0.0, 0.0))  # straight out and back: a 180 deg turn
    for max_turn in (10.0, 60.0):
        motion = plan_walk(exo, truth, Route(spur, swing_s=0.5, double_support_s=0.0, max_turn_deg=max_turn))
        t, xy = _mid_track(motion)
        visits = _visit_times(t, xy, spur, tol_m=0.2)
        assert visits[1] < visits[2]
        end = motion.state(motion.duration_s)
        assert abs(abs(np.angle(np.exp(1j * end.yaw[0]))) - np.pi) < np.radians(1.0)  # facing back
        assert np.max(xy[:, 0]) < 1.5 + 0.3  # did not overshoot the turning point


def test_route_validation_of_the_new_fields():
    with pytest.raises(ConfigError) as e:
        Route(LOOP, turn_in_place_deg=0.0)
    assert e.value.field == "route.turn_in_place_deg"
    with pytest.raises(ConfigError) as e:
        Route(LOOP, end_yaw_deg=720.0)
    assert e.value.field == "route.end_yaw_deg"


@pytest.mark.parametrize("office_seed", [3])
def test_office_loop_is_planned_closes_and_revisits(office_seed):
    sc = OfficeScenario.from_dict({"route": "loop", "max_distance_m": 500.0, "office_seed": office_seed})
    scene, motion = plan_office_walk(sc)
    truth = scene.truth
    wps = route_waypoints(office_route(truth, "loop"), sc.max_distance_m)
    assert wps[0] == wps[-1]
    t, xy = _mid_track(motion, dt=0.1)
    visits = _visit_times(t, xy, wps, tol_m=0.25)
    _on_segments_in_order(t, xy, wps, visits, tol_m=0.35)
    # revisits: the start is passed at least three times (the loop closes twice) and the north
    # corridor east of the start is walked twice in the same direction
    start = np.asarray(wps[0])
    near = np.linalg.norm(xy - start, axis=1) < 0.3
    assert np.count_nonzero(np.diff(near.astype(int)) == 1) >= 2
    # ends in its start pose: same place, same heading (TE / OE protocol of seeds/003 5.2.2)
    st = motion.state(np.array([0.0, motion.duration_s]), solve_legs=False)
    assert np.linalg.norm(st.pelvis_w[1, :2] - st.pelvis_w[0, :2]) < 0.1
    assert abs(np.angle(np.exp(1j * (st.yaw[1] - st.yaw[0])))) < np.radians(0.5)
    # every footstep on the floor, no penetration, the body clear of walls and furniture
    assert {truth.surface(f.surface_id).kind for f in motion.footsteps} == {"ground"}
    from exobench.models.office_truth import points_inside_solids

    st = motion.state(t, solve_legs=False)
    side = np.column_stack([-np.sin(st.yaw), np.cos(st.yaw), np.zeros_like(st.yaw)])
    for off in (-0.2, 0.0, 0.2):
        for z in (0.3, 1.0):
            p = st.pelvis_w + off * side
            p[:, 2] = z
            assert not points_inside_solids(truth, p).any()


def test_office_loop_plan_is_deterministic():
    sc = OfficeScenario.from_dict({"route": "loop", "max_distance_m": 12.0})
    _, a = plan_office_walk(sc)
    _, b = plan_office_walk(sc)
    assert len(a.footsteps) == len(b.footsteps)
    for fa, fb in zip(a.footsteps, b.footsteps):
        assert np.array_equal(fa.sole_w, fb.sole_w) and fa.yaw_rad == fb.yaw_rad and fa.touchdown_s == fb.touchdown_s


def test_office_walk_stands_with_the_scenario_start_lean():
    """The scenario's start_lean_deg reaches the walk: the trunk leans by it while standing at the start."""
    for lean in (0.0, 2.5):
        _, motion = plan_office_walk(OfficeScenario(route="corridor", max_distance_m=1.0, start_lean_deg=lean))
        assert motion.state(np.array([0.0])).pitch[0] == pytest.approx(np.radians(lean))
