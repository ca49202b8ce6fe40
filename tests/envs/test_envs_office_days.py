"""The office scenario on a day of a change script: its rows, validation before anything runs, and
a walk through chosen regions round a corridor obstacle."""

import numpy as np
import pytest
from click.testing import CliRunner

from exobench.core import ChangeScriptError, ConfigError, UnknownNameError
from exobench.envs.sim.scenario import check_scenario
from exobench.envs.sim.scenarios.office import OfficeScenario, plan_office_walk
from exobench.models.furniture_kinds import MAKERS
from exobench.models.office import build_office
from exobench.models.office_routes import WALKER_HALF_WIDTH_M, region_route, standing
from exobench.models.office_truth import solids_from_truth

NEW_ROWS = ("furniture_seed", "furnish", "day", "changes", "change_seed", "route_regions")


def test_records_of_scenarios_without_the_new_rows_are_unchanged():
    d = OfficeScenario().as_dict()
    assert not set(NEW_ROWS) & set(d)
    s = OfficeScenario.from_dict({"day": "2", "change_seed": "4", "furnish": "lab"})
    assert (s.as_dict()["day"], s.as_dict()["change_seed"], s.as_dict()["furnish"]) == (2, 4, "lab")


def test_an_invalid_script_is_refused_before_anything_runs():
    bad = OfficeScenario.from_dict({"changes": "1 remove chair0; 2 move chair0 3.0 3.0 0"})
    with pytest.raises(ChangeScriptError) as e:
        check_scenario(bad)
    assert (e.value.day, e.value.object_id) == (2, "chair0")
    with pytest.raises(UnknownNameError, match="kitchen"):
        check_scenario(OfficeScenario.from_dict({"route_regions": "corridor_s,kitchen"}))
    with pytest.raises(ChangeScriptError):
        plan_office_walk(bad)
    with pytest.raises(ConfigError, match="change_seed"):  # a script of 0 days would draw nothing
        check_scenario(OfficeScenario.from_dict({"change_seed": 3}))
    with pytest.raises(ConfigError, match="change_seed"):  # written or drawn, not both
        check_scenario(OfficeScenario.from_dict({"change_seed": 3, "day": 1, "changes": "1 remove chair0"}))


def test_the_command_line_refuses_an_invalid_script_in_one_line(tmp_path):
    from exobench.benchmarks.cli import cli

    out = tmp_path / "run"
    result = CliRunner().invoke(cli, ["run", "--track", "odometry", "--set", "changes=1 remove chair99", "--out", str(out)])
    assert result.exit_code == 2
    lines = [ln for ln in result.output.splitlines() if ln.strip()]
    assert lines[-1].startswith("exobench: error:") and "day 1" in lines[-1] and "chair99" in lines[-1]
    assert not out.exists() or not any(out.rglob("results.jsonl"))


def test_a_walk_through_regions_goes_round_the_day_s_corridor_obstacle():
    t = MAKERS["trolley"](np.random.default_rng(3))
    w, d = t.size[0], t.size[1]
    x, y = 6.0, 0.85 + d / 2  # across the middle of the south corridor, leaving 0.85 m on its south side
    sc = OfficeScenario.from_dict({"n_offices": 3, "day": 1, "changes": f"1 obstacle trolley/3 cart {x} {y} 0",
                                   "route_regions": "corridor_s,corridor_e", "max_distance_m": 40.0})
    check_scenario(sc)
    scene, motion = plan_office_walk(sc)
    assert {"cart_tray0", "cart_tray1"} <= {scene.model.geom(i).name for i in range(scene.model.ngeom)}
    assert scene.truth.params["day"] == 1
    pelvis = motion.state(np.arange(0.0, motion.duration_s, 0.05), solve_legs=False).pelvis_w[:, :2]
    lo, hi = np.array([x - w / 2, y - d / 2]), np.array([x + w / 2, y + d / 2])
    gap = np.linalg.norm(np.maximum(np.maximum(lo - pelvis, pelvis - hi), 0.0), axis=1)
    assert gap.min() >= WALKER_HALF_WIDTH_M
    # the day before, the same regions' route ran through where the trolley now stands
    day0 = build_office(sc.office_params(), sc.change_script(), 0)
    route = np.asarray(region_route(day0.truth, sc.regions()))
    dense = np.concatenate([a + np.linspace(0, 1, 200)[:, None] * (b - a) for a, b in zip(route[:-1], route[1:])])
    assert np.linalg.norm(np.maximum(np.maximum(lo - dense, dense - hi), 0.0), axis=1).min() < WALKER_HALF_WIDTH_M
    assert np.any(pelvis[:, 0] > x + 1.0)  # and it went on past it
    for s in standing(solids_from_truth(scene.truth)):
        g = np.linalg.norm(np.maximum(np.maximum(s.lo[:2] - pelvis, pelvis - s.hi[:2]), 0.0), axis=1)
        assert g.min() >= WALKER_HALF_WIDTH_M - 0.05, s.name  # the pelvis sways a few cm about the route


@pytest.mark.parametrize("rows", [
    {"n_offices": 3, "day": 1, "changes": "1 obstacle trolley/3 cart 6.0 1.3 0; 1 remove chair0", "surfaces": "textured",
     "route_regions": "corridor_s,corridor_e", "max_distance_m": 40.0},
    {"furniture_seed": 5, "day": 2, "change_seed": 7, "start_x_m": 9.0, "route_regions": "office1,meeting"},
])  # fmt: skip
def test_waypoints_planned_on_the_layout_are_those_of_the_compiled_office(rows):
    """``region_waypoints`` (the walks a draw or a check plans, without compiling the office)
    gives the waypoints planned on the compiled office's truth, as ``plan_office_walk`` plans
    them: the day's furniture, a moved start, a textured look (which changes the model only)."""
    from exobench.envs.sim.scenarios.office import compiled_office, region_waypoints
    from exobench.models.vision_look import WorldLook

    sc = OfficeScenario.from_dict(rows)
    check_scenario(sc)
    look = WorldLook(sc.surfaces, sc.light_level)
    start = sc.start_w()
    scene = compiled_office(sc.office_params(), sc.exo_spec(), (), None if look.is_default else look,
                            changes=sc.change_script(), day=sc.day, start_w=None if start is None else tuple(start))  # fmt: skip
    assert region_waypoints(sc) == sc.route_polyline(region_route(scene.truth, sc.regions()))
    if start is not None:
        assert region_waypoints(sc)[0] == tuple(start[:2])
