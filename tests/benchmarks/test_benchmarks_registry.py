"""Pipeline registry: built-ins by string, the entry-point group, duplicates, unknown names."""

from __future__ import annotations

import importlib.metadata
import sys
import textwrap

import pytest
from test_benchmarks_support import FakeStairs, FakeTrack

from exobench.benchmarks import registry as registry_mod
from exobench.benchmarks.registry import PipelineRegistry, build_registry
from exobench.benchmarks.runner import execute, plan_run
from exobench.core import ConfigError, UnknownNameError

PLUGIN = textwrap.dedent(
    '''
    """A third-party pipeline that exobench only knows through its entry point."""
    from dataclasses import dataclass
    import numpy as np
    from exobench.core import PlaneEstimate, StaircaseEstimate

    class PluginStairs:
        name = "plugin-stairs"
        track = "stairs"

        @dataclass
        class Config:
            height_m: float = 0.162

        def __init__(self, config=None):
            self.config = config or self.Config()

        def reset(self, calibration):
            self.n = 0

        def process(self, frame):
            self.n += 1

        def finalize(self):
            s2 = PlaneEstimate(2, np.array([0, 0, 1.0]), np.array([0.45, -0.05, self.config.height_m]), {}, 0.0, True, 1.0)
            return StaircaseEstimate((s2,), self.config.height_m, 0.28)
    '''
)


@pytest.fixture
def plugin(tmp_path, monkeypatch):
    """A module on sys.path and an entry point in the exobench.pipelines group naming it."""
    (tmp_path / "exobench_plugin_for_tests.py").write_text(PLUGIN)
    monkeypatch.syspath_prepend(str(tmp_path))
    real = importlib.metadata.entry_points
    eps = [importlib.metadata.EntryPoint("plugin-stairs", "exobench_plugin_for_tests:PluginStairs", "exobench.pipelines")]

    def fake_entry_points(**params):
        if params.get("group") == "exobench.pipelines":
            return importlib.metadata.EntryPoints(eps)
        return real(**params)

    monkeypatch.setattr(importlib.metadata, "entry_points", fake_entry_points)
    yield eps
    sys.modules.pop("exobench_plugin_for_tests", None)


def test_builtins_are_registered_without_importing_them():
    before = "exobench.perception.stairs.rtls_pipeline" in sys.modules
    reg = build_registry(entry_points=False)
    assert {"rtls", "rtls-htvr", "batch-ransac"} <= set(reg.names())
    assert reg.spec("rtls").entry_point == "exobench.perception.stairs.rtls_pipeline:RtlsStairs"
    assert ("exobench.perception.stairs.rtls_pipeline" in sys.modules) == before


def test_entry_point_pipeline_is_found_and_run(plugin, tmp_path):
    reg = build_registry()
    assert "plugin-stairs" in reg.names()
    assert reg.spec("plugin-stairs").source == "entry-point"
    assert "exobench_plugin_for_tests" not in sys.modules  # lazy until used
    plan = plan_run(FakeTrack(), "quick", ["plugin-stairs"], [0], {"plugin-stairs.height_m": "0.165"}, registry=reg)
    assert plan.pipelines[0].config.height_m == 0.165
    out = execute(plan, tmp_path / "run")
    assert len(out.records) == 6
    for r in out.records:
        assert r["pipeline"] == "plugin-stairs" and r["config"] == {"height_m": 0.165}
        assert r["metrics"]["failed"] is False
        assert r["metrics"]["d_m_S2"] == pytest.approx(0.165 - r["scenario"]["riser_m"])


def test_duplicate_names_are_refused(monkeypatch):
    reg = PipelineRegistry()
    reg.register("fake", FakeStairs)
    with pytest.raises(ConfigError, match="fake"):
        reg.register("fake", "somewhere:Else")
    eps = [importlib.metadata.EntryPoint("rtls", "elsewhere:Rtls", "exobench.pipelines")]
    monkeypatch.setattr(importlib.metadata, "entry_points", lambda **kw: importlib.metadata.EntryPoints(eps))
    with pytest.raises(ConfigError, match="rtls"):
        build_registry()


def test_unknown_name_lists_the_valid_ones():
    reg = build_registry(entry_points=False)
    with pytest.raises(UnknownNameError) as err:
        reg.load("rtsl")
    assert "rtls" in str(err.value) and "batch-ransac" in str(err.value)


def test_bad_entries_are_config_errors():
    reg = PipelineRegistry()
    reg.register("missing", "no_such_module_xyz:Cls")
    with pytest.raises(ConfigError, match="importable"):
        reg.load("missing")
    reg.register("not-a-pipeline", "math:pi")
    with pytest.raises(ConfigError):
        reg.load("not-a-pipeline")
    reg.register("fake", FakeStairs)
    with pytest.raises(UnknownNameError, match="offset_m"):
        reg.make_config("fake", {"offest_m": "1"})
    with pytest.raises(ConfigError, match="fake.offset_m"):
        reg.make_config("fake", {"offset_m": "abc"})


def test_default_registry_is_cached_and_rebuildable(plugin):
    registry_mod.default_registry.cache_clear()
    try:
        assert "plugin-stairs" in registry_mod.default_registry().names()
        assert registry_mod.default_registry() is registry_mod.default_registry()
    finally:
        registry_mod.default_registry.cache_clear()
