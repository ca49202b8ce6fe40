"""Settings from the command line: every scenario parameter of every registered track, set to each
of its allowed values as ``--set KEY=VALUE`` gives it (a string), is accepted at plan time and
gives the typed value; what can be checked without simulating (the rig) is refused at plan time;
seed counts are bounded before anything is built. Plan only: nothing here simulates."""

from __future__ import annotations

import math
import time

import pytest
from click.testing import CliRunner
from vio_pipeline import StillCamera

from exobench.benchmarks.cli import cli
from exobench.benchmarks.registry import build_registry
from exobench.benchmarks.runner import MAX_SEEDS, plan_run
from exobench.benchmarks.tracks import get_track, track_names
from exobench.core.errors import ConfigError
from exobench.envs.sim.rig import PRESETS
from exobench.envs.sim.scenario import OMIT_AT_DEFAULT

TRUE_SPELLINGS = ("true", "True", "TRUE", "1", "yes", "on", " true ")
FALSE_SPELLINGS = ("false", "False", "0", "no", "off", "OFF")

# A value allowed only together with another parameter: (track, name) -> the other values under
# which the whole of its range is valid (the office's rooms must fit its corridor; a segmentation
# truth needs a camera, which the office rig has only when one is added).
CONTEXT = {
    **{
        (t, "segmentation_truth"): {"extra_sensors": "rgbd_head"}
        for t in ("odometry", "lidar-filter", "loop-closure")
    },
    ("loop-closure", "n_offices"): {"corridor_length_m": "80"},
    ("loop-closure", "corridor_length_m"): {"n_offices": "1", "meeting_room_m": "1.5"},
    ("loop-closure", "meeting_room_m"): {"corridor_length_m": "80"},
    **{(t, "change_seed"): {"day": "1"} for t in ("odometry", "lidar-filter", "loop-closure", "vio")},  # it draws `day` days
    # multisession: the quick case's small office and written script (a script is written or drawn)
    ("multisession", "n_offices"): {"corridor_length_m": "80", "changes": ""},
    ("multisession", "corridor_length_m"): {"n_offices": "1", "meeting_room_m": "1.5"},
    ("multisession", "meeting_room_m"): {"corridor_length_m": "80", "changes": ""},
    ("multisession", "change_seed"): {"changes": ""},
    ("multisession", "room_depth_m"): {"changes": ""},
    # repeated_rooms needs as many offices (up to 3); the small offices of these quick cases have 1
    ("multisession", "repeated_rooms"): {"n_offices": "3", "corridor_length_m": "80", "changes": ""},
    ("loop-closure", "repeated_rooms"): {"n_offices": "3", "corridor_length_m": "80"},
    # a moved start stands on the north corridor (the row's high: the default office's east end)
    # and walks through regions
    **{(t, "start_x_m"): {"route_regions": "corridor_n"} for t in ("odometry", "lidar-filter", "vio")},
    ("loop-closure", "start_x_m"): {"route_regions": "corridor_n", "corridor_length_m": "24"},
    ("multisession", "start_x_m"): {"corridor_length_m": "24", "changes": ""},
}


# free-string parameters and values of them to try (the presets of extra_sensors: see below)
FREE_STRINGS = {"extra_sensors": ("",), "changes": ("", "1 remove chair0; 2 move chair1 1.0 1.0 0; 1 remove bin0"),
                "route_regions": ("", "corridor_s,office0"), "sessions": ("0:corridor_s;1:corridor_s", "0:office0;0:meeting;2:office0")}


def _vio_context() -> dict[tuple[str, str], dict[str, str]]:
    """The vio track's rows of one world act with that world only: a course's row is set on
    course walks (the quick suite's office rows back at their defaults), and so is ``world``."""
    from exobench.benchmarks.tracks.vio.scenario import scenario_classes

    office, course = (set(c.PARAMS) for c in scenario_classes().values())
    track = get_track("vio")
    set_by_quick = {k for c in track.cases("quick") for k in c.scenario if k in office - course}
    at_default = {k: str(office_row.default) for k, office_row in scenario_classes()["office"].PARAMS.items() if k in set_by_quick}
    out = {("vio", k): {**at_default, "world": "course"} for k in course - office}
    out[("vio", "world")] = at_default
    out[("vio", "exposure_s")] = {"rate_hz": "10"}  # at most one frame period
    out[("vio", "change_seed")] = {**at_default, "day": "1"}  # it draws `day` days
    return out


CONTEXT.update(_vio_context())
# the vio track's plans here are made with a test pipeline (cheap; the registered ones are in conformance)
REGISTRY = build_registry()
REGISTRY.register("vio-still", StillCamera)


def _number_text(x: float | int) -> str:
    return str(x) if isinstance(x, int) else repr(float(x))


def _cases(track_name: str) -> list[tuple[str, str, object]]:
    """(name, value as the command line gives it, the typed value expected) of every allowed
    value of every scenario parameter of a track (the presets of extra_sensors: see below)."""
    out: list[tuple[str, str, object]] = []
    for p in get_track(track_name).params():
        if isinstance(p.default, bool):
            assert p.choices == (False, True), p
            out += [(p.name, s, True) for s in TRUE_SPELLINGS] + [(p.name, s, False) for s in FALSE_SPELLINGS]
        elif p.choices:
            out += [(p.name, str(c), c) for c in p.choices]
        elif p.name in FREE_STRINGS:
            out += [(p.name, v, v) for v in FREE_STRINGS[p.name]]
        else:
            assert p.low is not None and p.high is not None, p
            is_int = isinstance(p.default, int) or (
                p.default is None and isinstance(p.low, int) and isinstance(p.high, int)
            )
            values = [v for v in (p.low, p.default, p.high) if v is not None and math.isfinite(v)]
            if p.low_open:
                values = [v for v in values if v != p.low]
            if p.default is None:
                out.append((p.name, "none", None))
            for v in values:
                out.append((p.name, _number_text(v), int(v) if is_int else float(v)))
    return out


def _typed(track_name: str, name: str, text: str) -> tuple[object, list[dict]]:
    ctx = CONTEXT.get((track_name, name), {})
    plan = plan_run(track_name, "quick", None, [0], {**ctx, name: text}, registry=REGISTRY)
    return plan.scenario_overrides[name], [e.scenario for e in plan.episodes]


@pytest.mark.parametrize("track_name", track_names())
def test_every_parameter_takes_each_allowed_value_from_the_command_line(track_name):
    cases = _cases(track_name)
    assert cases
    for name, text, expected in cases:
        try:
            typed, scenarios = _typed(track_name, name, text)
        except ConfigError as e:
            pytest.fail(f"{track_name}: --set {name}={text!r} refused: {e}")
        assert typed == expected and type(typed) is type(expected), (track_name, name, text, typed)
        for sc in scenarios:  # the typed value reaches every episode (or is left out at its neutral default)
            left_out = name in OMIT_AT_DEFAULT and expected == OMIT_AT_DEFAULT[name]
            assert sc.get(name, expected) == expected if left_out else sc[name] == expected, (name, text, sc)


def test_boolean_parameters_refuse_other_words():
    for track_name, name in (("locomotion", "walls"), ("odometry", "segmentation_truth")):
        with pytest.raises(ConfigError, match=name):
            plan_run(track_name, "quick", None, [0], {name: "maybe"})
        with pytest.raises(ConfigError, match=name):
            plan_run(track_name, "quick", None, [0], {name: "2"})


@pytest.mark.parametrize("track_name", [t for t in track_names() if "extra_sensors" in {p.name for p in get_track(t).params()}])
def test_each_sensor_preset_is_accepted_unless_its_sensors_are_on_the_rig(track_name):
    """A preset whose sensor ids the track's rig already has is refused at plan time naming
    extra_sensors; every other preset is accepted. The rig's ids: the default scenario's rig."""
    from exobench.envs.sim.scenarios.course import LocomotionScenario
    from exobench.envs.sim.scenarios.office import OfficeScenario
    from exobench.envs.sim.scenarios.stairs import StairScenario

    cls = {"stairs": StairScenario, "locomotion": LocomotionScenario}.get(track_name, OfficeScenario)
    on_rig = {s.sensor_id for s in cls().rig()}
    track = get_track(track_name)
    for preset, make in PRESETS.items():
        clash = on_rig & {s.sensor_id for s in make()}
        if clash:
            with pytest.raises(ConfigError, match="extra_sensors"):
                track.validate_scenario({"extra_sensors": preset})
        else:
            assert track.validate_scenario({"extra_sensors": preset})["extra_sensors"] == preset


def _one_error_line(result) -> str:
    lines = [ln for ln in result.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1, result.stderr
    assert lines[0].startswith("exobench: error: ")
    return lines[0]


@pytest.mark.parametrize(
    ("track_name", "assignment"),
    [
        ("odometry", "extra_sensors=lidar_trunk,lidar_trunk"),
        ("loop-closure", "extra_sensors=lidar_trunk"),
        ("stairs", "extra_sensors=rgbd_head,rgbd_head"),
        ("locomotion", "extra_sensors=rgbd_head"),
    ],
)
def test_an_impossible_rig_is_refused_at_plan_time_as_record_refuses_it(tmp_path, track_name, assignment):
    """What ``record`` refuses (exit 2) ``run`` refuses too, before a folder or an episode."""
    out = tmp_path / "run"
    t0 = time.perf_counter()
    result = CliRunner().invoke(cli, ["run", "--track", track_name, "--set", assignment, "--out", str(out)])
    assert result.exit_code == 2, result.output
    assert "extra_sensors" in _one_error_line(result)
    assert not out.exists()
    assert time.perf_counter() - t0 < 10.0  # nothing simulated


@pytest.mark.parametrize("count", ["30000000", str(10**30), str(MAX_SEEDS + 1), "0", "-5"])
def test_a_seed_count_out_of_bounds_is_refused_before_the_list_is_built(tmp_path, count):
    out = tmp_path / "run"
    t0 = time.perf_counter()
    result = CliRunner().invoke(cli, ["run", "--track", "stairs", "--seeds", count, "--out", str(out)])
    assert result.exit_code == 2, result.output
    line = _one_error_line(result)
    assert "--seeds" in line and str(MAX_SEEDS) in line and len(line) < 200
    assert not out.exists()
    assert time.perf_counter() - t0 < 5.0


def test_plan_run_refuses_a_huge_seed_range_by_its_length():
    t0 = time.perf_counter()
    for seeds in (range(10**30), range(MAX_SEEDS + 1)):
        with pytest.raises(ConfigError, match=f"more than {MAX_SEEDS} seeds"):
            plan_run("stairs", "quick", None, seeds, {})
    assert time.perf_counter() - t0 < 1.0


def test_list_shows_the_allowed_values_of_every_parameter_with_choices():
    result = CliRunner().invoke(cli, ["list"])
    assert result.exit_code == 0, result.output
    sections = result.output.split("\ntrack ")
    n_checked = 0
    for track_name in track_names():
        section = next(
            s for s in sections if s.startswith(f"{track_name}\n") or s.startswith(f"track {track_name}\n")
        )
        rows = {ln.split()[0]: ln for ln in section.splitlines() if ln.startswith("    ") and ln.split()}
        for p in get_track(track_name).params():
            if not p.choices:
                continue
            shown = rows[p.name].split()[2]  # name, default, allowed values, ...
            assert shown.split("|") == [
                str(c).lower() if isinstance(c, bool) else str(c) for c in p.choices
            ], rows[p.name]
            n_checked += 1
    assert n_checked >= 20  # facade, route, lidar, mount, terrain, walls, segmentation_truth, ...


def test_segmentation_truth_without_a_camera_is_refused_not_ignored():
    with pytest.raises(ConfigError, match="segmentation_truth.*RGB-D camera"):
        plan_run("odometry", "quick", None, [0], {"segmentation_truth": "true"})
    plan = plan_run(
        "odometry", "quick", None, [0], {"segmentation_truth": "true", "extra_sensors": "rgbd_chest"}
    )
    assert plan.episodes[0].scenario["segmentation_truth"] is True


def _flat_fields(cfg, prefix=""):
    import dataclasses

    for f in dataclasses.fields(cfg):
        v = getattr(cfg, f.name)
        if dataclasses.is_dataclass(v):
            yield from _flat_fields(v, f"{prefix}{f.name}.")
        else:
            yield f"{prefix}{f.name}", v


def test_tuple_pipeline_parameters_are_parsed_from_the_command_line_or_refused():
    """A pipeline parameter that is a tuple of numbers (a footprint offset) takes ``--set
    NAME.KEY=a,b,c`` as numbers; any other text is refused at plan time (it was kept as the
    string and failed in the run)."""
    from exobench.benchmarks.registry import default_registry

    reg = default_registry()
    n_checked = 0
    for name in reg.names():
        cls = reg.load(name)
        for key, default in _flat_fields(cls.Config()):
            if not (isinstance(default, tuple) and default and all(isinstance(x, float) for x in default)):
                continue
            wanted = tuple(x + 0.5 for x in default)
            plan = plan_run(cls.track, None, [name], [0], {f"{name}.{key}": ", ".join(map(repr, wanted))})
            got = plan.pipelines[0].config
            for part in key.split("."):
                got = getattr(got, part)
            assert got == wanted
            for bad in ("nan", "0,0", ",".join(["inf"] * len(default)), "a,b,c"):
                with pytest.raises(ConfigError, match=key.split(".")[-1]):
                    plan_run(cls.track, None, [name], [0], {f"{name}.{key}": bad})
            n_checked += 1
    assert n_checked >= 2


def test_an_iteration_count_that_would_never_end_is_refused_at_plan_time():
    """batch-ransac draws every hypothesis (no early exit): 1e30 of them ran for ever."""
    with pytest.raises(ConfigError, match="ransac_iterations"):
        plan_run("stairs", "quick", ["batch-ransac"], [0], {"batch-ransac.ransac_iterations": "1e30"})
    plan = plan_run("stairs", "quick", ["batch-ransac"], [0], {"batch-ransac.ransac_iterations": "1000000"})
    assert plan.pipelines[0].config.ransac_iterations == 10**6


@pytest.mark.parametrize("track_name", ["odometry", "loop-closure"])
def test_an_office_that_cannot_be_built_is_refused_at_plan_time(track_name):
    """Ten offices do not fit the default 24 m corridors (2.52 m each): refused before anything
    runs, on the office tracks (n_offices at most 9) and on loop-closure (corridor_length_m)."""
    with pytest.raises(ConfigError, match="n_offices|corridor_length_m"):
        plan_run(
            track_name,
            "quick",
            None,
            [0],
            {"n_offices": "10", "meeting_room_m": "6"}
            if track_name == "loop-closure"
            else {"n_offices": "10"},
        )
