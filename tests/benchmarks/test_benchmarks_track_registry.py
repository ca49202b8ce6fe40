"""Track registry: built-ins by string, the ``exobench.tracks`` entry-point group, duplicates,
unknown names, and a toy track defined in this file run end to end through the command line.

The toy track and its pipeline live only here: the runner, the report writer and the command
line find them through the entry-point groups, so they know nothing about particular tracks.
"""

from __future__ import annotations

import importlib.metadata
import json
import sys
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar

import numpy as np
import pytest
from click.testing import CliRunner

from exobench.benchmarks import registry as pipeline_registry
from exobench.benchmarks.cli import cli
from exobench.benchmarks.tracks import get_track, track_names
from exobench.benchmarks.tracks import registry as track_registry
from exobench.benchmarks.tracks.spec import Case, ParamInfo, Reference, SummaryRow, Track, param_infos
from exobench.core import ConfigError, UnknownNameError, check_range

MODULE = __name__


# ------------------------------------------------------------------ a toy track and its pipeline


@dataclass(frozen=True)
class ToyFrame:
    """A noisy reading of a level, m."""

    stamp_s: float
    sensor_id: str
    value_m: float


@dataclass(frozen=True)
class ToyEpisode:
    """What the harness needs of an episode: scenario, seed, calibration, frames, truth."""

    scenario: dict[str, Any]
    seed: int
    calibration: Any
    frames: tuple[ToyFrame, ...]
    truth: float


@dataclass(frozen=True)
class ToyParam:
    default: float
    low: float
    high: float
    unit: str
    doc: str


TOY_PARAMS = {
    "level_m": ToyParam(0.3, 0.0, 1.0, "m", "the level to estimate"),
    "noise_m": ToyParam(0.01, 0.0, 0.1, "m", "reading noise, standard deviation"),
}


class ToyTrack:
    """Estimate a constant level from ten noisy readings."""

    name: ClassVar[str] = "toy"
    suites: ClassVar[tuple[str, ...]] = ("quick",)
    default_suite: ClassVar[str] = "quick"
    streams: ClassVar[tuple[str, ...]] = ("toy",)
    estimate_type: ClassVar[type] = float
    smoke_scenario: ClassVar[Mapping[str, Any]] = {"noise_m": 0.0}
    timing_metrics: ClassVar[frozenset[str]] = frozenset()
    scoring_keys: ClassVar[frozenset[str]] = frozenset()
    report_intro: ClassVar[str] = "Toy figures, invented for the test."

    def params(self) -> list[ParamInfo]:
        return param_infos(TOY_PARAMS)

    def validate_scenario(self, values: dict[str, Any]) -> dict[str, Any]:
        out = {k: p.default for k, p in TOY_PARAMS.items()}
        for k, v in values.items():
            if k not in TOY_PARAMS:
                raise UnknownNameError("toy scenario parameter", k, TOY_PARAMS)
            out[k] = check_range(k, v, TOY_PARAMS[k].low, TOY_PARAMS[k].high)
        return out

    def group_label(self, case: Case, scenario: Mapping[str, Any]) -> str:
        return case.group

    def cases(self, suite: str, run_seed: int = 0) -> list[Case]:
        return [Case("one", "level", {}, figure=True)]

    def simulate(self, scenario: dict[str, Any], seed: int) -> ToyEpisode:
        rng = np.random.default_rng(seed)
        values = scenario["level_m"] + scenario["noise_m"] * rng.standard_normal(10)
        frames = tuple(ToyFrame(0.1 * k, "toy", float(v)) for k, v in enumerate(values))
        return ToyEpisode(dict(scenario), seed, None, frames, float(scenario["level_m"]))

    def score(self, episode: ToyEpisode, estimate: float, scoring: Mapping[str, Any] | None = None) -> dict[str, Any]:
        return {"failed": False, "level_error_m": estimate - episode.truth}

    def failed_metrics(self, episode: ToyEpisode | None, reason: str) -> dict[str, Any]:
        return {"failed": True, "failed_reason": reason, "level_error_m": float("nan")}

    def references(self) -> list[Reference]:
        return [Reference("level_error_m", "< 5", "Toy Tab. 1", value=5.0, bound="<")]

    def summary_rows(self) -> list[SummaryRow]:
        return [SummaryRow("level_error_m", "level error (mm)", scale=1000, absolute=True)]

    def figure_data(self, episode: ToyEpisode, estimates: dict[str, Any], scoring: Mapping[str, Any] | None = None) -> dict[str, Any]:
        return {"readings": np.array([f.value_m for f in episode.frames])}

    def report_sections(self, records: list[dict[str, Any]], pipelines: list[str], out: Path) -> list[str]:
        figures = sorted((out / "figures").glob("*.npz"))
        return ["## Toy levels", "", f"{len(records)} records, {len(figures)} figure files", ""]

    def write_recording(self, episode: ToyEpisode, estimates_by_pipeline: dict[str, Any], path: Path,
                        scoring: Mapping[str, Any] | None = None) -> Path:
        Path(path).write_text(json.dumps(sorted(estimates_by_pipeline)))
        return Path(path)


class ToyMean:
    """The mean of the last ``window`` readings."""

    name: ClassVar[str] = "toy-mean"
    track: ClassVar[str] = "toy"

    @dataclass
    class Config:
        window: int = 10

    def __init__(self, config: Config | None = None) -> None:
        self.config = config or self.Config()

    def reset(self, calibration: Any) -> None:
        self._values: list[float] = []

    def process(self, frame: Any) -> float | None:
        self._values.append(frame.value_m)
        return None

    def finalize(self) -> float:
        return float(np.mean(self._values[-self.config.window :]))


# ------------------------------------------------------------------ fixtures


def _entry_points(monkeypatch: pytest.MonkeyPatch, groups: dict[str, list[tuple[str, str]]]) -> None:
    """Serve ``groups`` (group -> [(name, "module:attr")]) as installed entry points."""
    real = importlib.metadata.entry_points

    def fake(**params: Any) -> Any:
        if params.get("group") in groups:
            g = params["group"]
            return importlib.metadata.EntryPoints(importlib.metadata.EntryPoint(n, v, g) for n, v in groups[g])
        return real(**params)

    monkeypatch.setattr(importlib.metadata, "entry_points", fake)


@pytest.fixture
def toy_installed(monkeypatch):
    """The toy track and pipeline installed through the entry-point groups; fresh default registries."""
    _entry_points(monkeypatch, {
        "exobench.tracks": [("toy", f"{MODULE}:ToyTrack")],
        "exobench.pipelines": [("toy-mean", f"{MODULE}:ToyMean")],
    })  # fmt: skip
    track_registry.default_track_registry.cache_clear()
    pipeline_registry.default_registry.cache_clear()
    yield
    track_registry.default_track_registry.cache_clear()
    pipeline_registry.default_registry.cache_clear()


# ------------------------------------------------------------------ tests


def test_builtin_tracks_are_registered_without_importing_them():
    before = "exobench.benchmarks.tracks.loop_closure.track" in sys.modules
    reg = track_registry.build_track_registry(entry_points=False)
    assert reg.names() == ["stairs", "lidar-filter", "odometry", "locomotion", "loop-closure", "vio", "multisession"]
    assert reg.entry("stairs").entry_point == "exobench.benchmarks.tracks.stairs:StairsTrack"
    assert reg.names("lidar") == ["lidar-filter", "odometry", "loop-closure"]
    assert reg.names("session") == ["multisession"]
    assert ("exobench.benchmarks.tracks.loop_closure.track" in sys.modules) == before


def test_every_builtin_track_satisfies_the_protocol_and_declares_its_streams_and_timings():
    reg = track_registry.build_track_registry(entry_points=False)
    for name in reg.names():
        track = reg.get(name)
        assert isinstance(track, Track) and track.name == name
        assert set(reg.entry(name).tags) == set(track.streams)
        assert isinstance(track.timing_metrics, frozenset) and all(isinstance(m, str) for m in track.timing_metrics)
        assert isinstance(track.estimate_type, type) and track.estimate_type.__module__ == "exobench.core.estimates"
        assert isinstance(track.smoke_scenario, Mapping)
        track.validate_scenario(track.smoke_scenario)
        assert reg.get(name) is track  # one instance per track


def test_unknown_track_lists_the_valid_ones():
    with pytest.raises(UnknownNameError) as err:
        get_track("stiars")
    assert "stairs" in str(err.value) and "loop-closure" in str(err.value)


def test_duplicate_and_malformed_tracks_are_refused(monkeypatch):
    reg = track_registry.TrackRegistry()
    reg.register("toy", ToyTrack)
    with pytest.raises(ConfigError, match="toy"):
        reg.register("toy", "somewhere:Else")
    reg.register("not-a-track", "math:pi")
    with pytest.raises(ConfigError, match="not-a-track"):
        reg.load("not-a-track")
    no_smoke = type("NoSmoke", (), {k: v for k, v in vars(ToyTrack).items() if k != "smoke_scenario"})
    with pytest.raises(ConfigError, match="no-smoke.*lacks smoke_scenario$"):
        reg.register("no-smoke", no_smoke)
    # each missing member is named, methods included (the docs once forgot group_label)
    partial = type("Partial", (), {k: v for k, v in vars(ToyTrack).items() if k not in ("group_label", "scoring_keys")})
    with pytest.raises(ConfigError, match="lacks scoring_keys, group_label$"):
        reg.register("partial", partial)
    assert set(track_registry.track_members()) == {
        n for n in dir(ToyTrack) if not n.startswith("_")}  # the toy has every member and nothing else
    reg.register("missing", "no_such_module_xyz:Track")
    with pytest.raises(ConfigError, match="importable"):
        reg.load("missing")
    _entry_points(monkeypatch, {"exobench.tracks": [("stairs", f"{MODULE}:ToyTrack")]})
    with pytest.raises(ConfigError, match="stairs"):
        track_registry.build_track_registry()


def test_an_installed_track_is_found_lazily_and_listed(toy_installed):
    assert "toy" in track_names() and "toy" in track_names("toy")
    entry = track_registry.default_track_registry().entry("toy")
    assert entry.source == "entry-point" and entry.tags == ()
    result = CliRunner().invoke(cli, ["list"], catch_exceptions=False)
    assert result.exit_code == 0 and "track toy" in result.output and "level_m" in result.output
    assert "toy-mean" in result.output


def test_a_toy_track_runs_end_to_end_through_the_command_line(toy_installed, tmp_path):
    out = tmp_path / "run"
    args = ["run", "--track", "toy", "--out", str(out), "--seeds", "2", "--set", "level_m=0.5", "--set", "toy-mean.window=4"]
    result = CliRunner().invoke(cli, args, catch_exceptions=False)
    assert result.exit_code == 0, result.output + result.stderr
    assert "level error (mm)" in result.output and "Toy Tab. 1" in result.output
    records = [json.loads(line) for line in (out / "results.jsonl").read_text().splitlines()]
    assert [r["episode"] for r in records] == ["one/s0", "one/s1"]
    for r in records:
        assert r["track"] == "toy" and r["pipeline"] == "toy-mean" and r["config"] == {"window": 4}
        assert r["scenario"]["level_m"] == 0.5 and r["metrics"]["failed"] is False
        assert abs(r["metrics"]["level_error_m"]) < 0.05
    report = (out / "report.md").read_text()
    assert "# exobench run: toy / quick" in report and "Toy figures, invented" in report
    assert "## Toy levels" in report and "2 records, 2 figure files" in report
    assert json.loads((out / "run_config.json").read_text())["track"] == "toy"
    again = CliRunner().invoke(cli, ["report", str(out)], catch_exceptions=False)
    assert again.exit_code == 0 and "level error (mm)" in again.output


def test_the_toy_registration_does_not_outlive_its_tests():
    """The default registries the other tests read (tests/test_conformance.py) hold no toy once
    the toy tests above are done."""
    assert "toy" not in track_names() and "toy-mean" not in pipeline_registry.default_registry().names()
