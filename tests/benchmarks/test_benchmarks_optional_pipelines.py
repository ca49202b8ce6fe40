"""A pipeline behind an optional extra (ORB-SLAM3: `pip install 'exobench[orbslam3]'`): listed as
unavailable with the line that installs it, refused at plan time when named (exit 2, nothing
written), left out of a run of all the track's pipelines with a note; its setup runs before the
episodes. The module is made unimportable here (``sys.modules[name] = None``, what ``import``
refuses), the registration is done here on the fake stairs track (no MuJoCo)."""

from __future__ import annotations

import sys

import pytest
from click.testing import CliRunner
from test_benchmarks_support import FakeStairs, FakeTrack, serve_tracks

from exobench.benchmarks import registry as registry_mod
from exobench.benchmarks.cli import cli
from exobench.benchmarks.registry import (
    ORB_SLAM3_ENTRY_POINT,
    ORB_SLAM3_NEEDS,
    PipelineRegistry,
    module_available,
)
from exobench.benchmarks.runner import plan_run
from exobench.core.errors import ConfigError

INSTALL = "pip install 'exobench[orbslam3]'"


@pytest.fixture
def served(monkeypatch):
    """The fake stairs track with the fake pipeline and ORB-SLAM3's entry registered for it."""
    serve_tracks(monkeypatch, stairs=FakeTrack)
    reg = PipelineRegistry()
    reg.register("fake", FakeStairs)
    reg.register("orb-slam3", ORB_SLAM3_ENTRY_POINT, track="stairs", **ORB_SLAM3_NEEDS)
    monkeypatch.setattr(registry_mod, "default_registry", lambda: reg)
    monkeypatch.setattr("exobench.benchmarks.runner.default_registry", lambda: reg)
    return reg


@pytest.fixture
def no_pyorbslam3(monkeypatch):
    monkeypatch.setitem(sys.modules, "pyorbslam3", None)


def _run(args):
    return CliRunner().invoke(cli, args, catch_exceptions=False)


def test_module_available_finds_without_importing(monkeypatch):
    assert module_available("json") and not module_available("no_such_module_xyz")
    monkeypatch.setitem(sys.modules, "json", None)
    assert not module_available("json")


def test_installed_it_is_available_and_planned(served):
    # the test command installs the extra (Makefile), so here it is there
    was = "pyorbslam3" in sys.modules
    assert module_available("pyorbslam3")
    assert ("pyorbslam3" in sys.modules) == was  # found, not imported
    assert served.unavailable("orb-slam3") is None
    assert served.spec("orb-slam3").extra == "orbslam3"


def test_list_shows_it_unavailable_with_the_install_line(served, no_pyorbslam3):
    result = _run(["list"])
    assert result.exit_code == 0, result.output
    line = next(ln for ln in result.output.splitlines() if ln.strip().startswith("orb-slam3"))
    assert "UNAVAILABLE" in line and INSTALL in line
    fake = next(ln for ln in result.output.splitlines() if ln.strip().startswith("fake"))
    assert "UNAVAILABLE" not in fake


def test_a_run_naming_it_is_refused_at_plan_time_and_writes_nothing(served, no_pyorbslam3, tmp_path, monkeypatch):
    monkeypatch.setattr(FakeTrack, "simulate", lambda *a: pytest.fail("simulated before the plan was refused"))
    with pytest.raises(ConfigError, match=r"pip install 'exobench\[orbslam3\]'"):
        plan_run("stairs", None, ["orb-slam3"], registry=served)
    out = tmp_path / "run"
    result = _run(["run", "--track", "stairs", "--pipeline", "orb-slam3", "--out", str(out)])
    assert result.exit_code == 2
    lines = [ln for ln in result.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("exobench: error: ") and INSTALL in lines[0]
    assert not out.exists()


def test_a_run_of_all_pipelines_skips_it_and_says_so(served, no_pyorbslam3, tmp_path):
    plan = plan_run("stairs", None, None, registry=served)
    assert [p.name for p in plan.pipelines] == ["fake"]
    assert INSTALL in plan.skipped["orb-slam3"]
    out = tmp_path / "run"
    result = _run(["run", "--track", "stairs", "--out", str(out)])
    assert result.exit_code == 0, result.output + result.stderr
    assert "skipping pipeline orb-slam3: needs the optional extra 'orbslam3'" in result.stderr
    assert INSTALL in result.stderr
    import json

    records = [json.loads(ln) for ln in (out / "results.jsonl").read_text().splitlines()]
    assert records and {r["pipeline"] for r in records} == {"fake"}


def test_only_unavailable_pipelines_leave_nothing_to_run_and_say_why(no_pyorbslam3, monkeypatch):
    serve_tracks(monkeypatch, stairs=FakeTrack)
    reg = PipelineRegistry()
    reg.register("orb-slam3", ORB_SLAM3_ENTRY_POINT, track="stairs", **ORB_SLAM3_NEEDS)
    with pytest.raises(ConfigError, match=r"orb-slam3 needs the optional extra 'orbslam3'.*pip install"):
        plan_run("stairs", None, None, registry=reg)


def test_an_entry_needing_a_module_must_name_its_extra():
    with pytest.raises(ConfigError, match="extra"):
        PipelineRegistry().register("x", "m:C", track="stairs", requires="pyorbslam3")


def test_a_pipelines_setup_runs_once_before_the_episodes(monkeypatch, tmp_path):
    serve_tracks(monkeypatch, stairs=FakeTrack)
    calls = []
    monkeypatch.setattr(sys.modules[__name__], "_SETUP_CALLS", calls, raising=False)
    reg = PipelineRegistry()
    reg.register("fake", FakeStairs, setup=f"{__name__}:record_setup")
    from exobench.benchmarks.runner import execute

    plan = plan_run("stairs", None, ["fake"], seeds=[0, 1], registry=reg)
    execute(plan, tmp_path / "run")
    assert calls == [FakeStairs.Config()]
    execute(plan, tmp_path / "run", resume=True)  # nothing left to run: no setup
    assert calls == [FakeStairs.Config()]


def record_setup(config):
    sys.modules[__name__]._SETUP_CALLS.append(config)


def test_orbvoc_builds_the_default_vocabulary_once_into_the_user_cache(monkeypatch, tmp_path):
    import json

    import numpy as np

    from exobench.benchmarks import orbvoc
    from exobench.mapping.odometry.orbslam3.vocabulary import DEFAULT_PARAMS, vocabulary_path

    monkeypatch.setenv("EXOBENCH_CACHE", str(tmp_path))
    rng = np.random.default_rng(0)
    renders = []

    def images():  # instead of minutes of simulation: noise images full of corners
        renders.append(1)
        return [rng.integers(0, 256, (240, 424), dtype=np.uint8) for _ in range(3)]

    monkeypatch.setattr(orbvoc, "training_images", images)
    first = json.loads(_run(["orbvoc", "--json"]).output)
    path = vocabulary_path(DEFAULT_PARAMS)
    assert first["built"] is True and first["path"] == str(path) and path.parent == tmp_path
    assert first["images"] == 3 and first["bytes"] == path.stat().st_size > 0
    again = json.loads(_run(["orbvoc", "--json"]).output)
    assert again == {"path": str(path), "built": False, "bytes": first["bytes"]} and renders == [1]
    # the orb-slam3 entry's setup finds it there, and builds nothing when the config names a file
    from exobench.mapping.odometry.orbslam3 import OrbSlam3Config

    orbvoc.setup_pipeline(OrbSlam3Config())
    orbvoc.setup_pipeline(OrbSlam3Config(vocabulary=str(tmp_path / "mine.txt")))
    assert renders == [1]
    path.unlink()
    orbvoc.setup_pipeline(OrbSlam3Config(vocabulary=str(tmp_path / "mine.txt")))
    assert renders == [1] and not path.exists()
    orbvoc.setup_pipeline(OrbSlam3Config())
    assert renders == [1, 1] and path.is_file()


def test_replay_skips_it_says_so_and_runs_the_setups(monkeypatch, tmp_path, no_pyorbslam3):
    from exobench.benchmarks.registry import BUILTIN_PIPELINES

    session = tmp_path / "session"
    assert _run(["record", "--case", "B", "--seed", "3", str(session)]).exit_code == 0
    calls = []
    monkeypatch.setattr(sys.modules[__name__], "_SETUP_CALLS", calls, raising=False)
    reg = PipelineRegistry()
    reg.register("rtls", BUILTIN_PIPELINES["rtls"][0], track="stairs", setup=f"{__name__}:record_setup")
    reg.register("orb-slam3", ORB_SLAM3_ENTRY_POINT, track="stairs", **ORB_SLAM3_NEEDS)
    monkeypatch.setattr(registry_mod, "default_registry", lambda: reg)
    monkeypatch.setattr("exobench.benchmarks.runner.default_registry", lambda: reg)
    result = _run(["replay", str(session), "--json"])
    assert result.exit_code == 0, result.output + result.stderr
    assert "skipping pipeline orb-slam3" in result.stderr and INSTALL in result.stderr
    assert len(calls) == 1 and type(calls[0]) is reg.load("rtls").Config
