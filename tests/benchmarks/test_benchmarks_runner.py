"""Runner: validation before any file, determinism across --jobs, atomic results and resume."""

from __future__ import annotations

import json
from typing import Any, ClassVar

import pytest
from test_benchmarks_support import FakeStairs, FakeTrack, RaisingStairs

from exobench.benchmarks.overrides import split_overrides
from exobench.benchmarks.registry import PipelineRegistry
from exobench.benchmarks.results import RESULTS_FILE, RUN_CONFIG_FILE, read_records, repair_results
from exobench.benchmarks.runner import episode_seed, execute, plan_run, untimed_metrics
from exobench.core import ConfigError, StaircaseEstimate, UnknownNameError


@pytest.fixture
def reg() -> PipelineRegistry:
    r = PipelineRegistry()
    r.register("fake", FakeStairs)
    r.register("fake-raise", RaisingStairs)
    return r


def _plan(reg, **kw):
    args = {"track": FakeTrack(), "suite": "quick", "pipelines": ["fake", "fake-raise"], "seeds": [0], "overrides": None}
    args.update(kw)
    return plan_run(args.pop("track"), args.pop("suite"), args.pop("pipelines"), args.pop("seeds"), args.pop("overrides"), registry=reg)


def _comparable(records):
    out = []
    for r in records:
        metrics = untimed_metrics(FakeTrack(), r["metrics"])
        out.append((r["episode"], r["pipeline"], r["seed"], r["scenario"], r["config"], metrics))
    return sorted(out, key=lambda x: (x[0], x[1]))


def test_plan_validates_everything_before_anything_is_written(reg, tmp_path):
    with pytest.raises(ConfigError, match="riser_m"):
        _plan(reg, overrides={"riser_m": "0.31"})
    with pytest.raises(ConfigError, match="riser_m"):
        _plan(reg, overrides={"riser_m": "nan"})
    with pytest.raises(UnknownNameError, match="riser_m"):  # the valid names are listed
        _plan(reg, overrides={"risr_m": "0.1"})
    with pytest.raises(UnknownNameError, match="quick"):
        _plan(reg, suite="fast")
    with pytest.raises(UnknownNameError, match="fake"):
        _plan(reg, pipelines=["nope"])
    with pytest.raises(ConfigError, match="seeds"):
        _plan(reg, seeds=[-1])
    with pytest.raises(ConfigError, match="fake.offset_m"):
        _plan(reg, overrides={"fake.offset_m": "x"})
    assert list(tmp_path.iterdir()) == []


def test_plan_applies_overrides_and_derives_seeds(reg):
    plan = _plan(reg, seeds=[0, 1], overrides={"tof_noise_m": "0", "fake.offset_m": "0.002"})
    assert len(plan.episodes) == 12
    assert all(e.scenario["tof_noise_m"] == 0.0 for e in plan.episodes)
    assert plan.pipelines[0].config.offset_m == 0.002
    e = plan.episodes[0]
    assert e.seed == episode_seed(e.run_seed, e.case.name)
    assert len({x.seed for x in plan.episodes}) == 12


def test_failing_pipeline_is_recorded_and_run_goes_on(reg, tmp_path):
    out = execute(_plan(reg), tmp_path / "run")
    by = {}
    for r in out.records:
        by.setdefault(r["pipeline"], []).append(r)
    assert len(by["fake"]) == len(by["fake-raise"]) == 6
    assert all(r["metrics"]["failed"] and "boom" in r["metrics"]["failed_reason"] for r in by["fake-raise"])
    assert not any(r["metrics"]["failed"] for r in by["fake"])
    rec = by["fake"][0]
    for key in ("track", "suite", "episode", "scenario", "seed", "pipeline", "config", "metrics", "versions", "wall_s"):
        assert key in rec
    assert {"exobench", "mujoco", "numpy", "pinocchio", "open3d", "python", "platform"} <= set(rec["versions"])
    config = json.loads((tmp_path / "run" / RUN_CONFIG_FILE).read_text())
    assert config["suite"] == "quick" and [p["name"] for p in config["pipelines"]] == ["fake", "fake-raise"]
    # figures are kept for cases A, B, C only
    assert sorted(p.name for p in (tmp_path / "run" / "figures").glob("*.npz")) == ["A__s0.npz", "B__s0.npz", "C__s0.npz"]


class NoEstimateStairs(FakeStairs):
    name: ClassVar[str] = "fake-none"

    def finalize(self) -> Any:
        return None


class TrustingTrack(FakeTrack):
    """A track whose scorer trusts the protocol: it is only ever given a StaircaseEstimate."""

    scored: ClassVar[list[str]] = []

    def score(self, episode: Any, estimate: Any, scoring: Any = None) -> dict[str, Any]:
        TrustingTrack.scored.append(type(estimate).__name__)
        return super().score(episode, estimate, scoring) if isinstance(estimate, StaircaseEstimate) else {"failed": False}


def test_the_runner_fails_an_estimate_of_the_wrong_type_before_any_scorer_sees_it(reg, tmp_path):
    reg.register("fake-none", NoEstimateStairs)
    TrustingTrack.scored.clear()
    out = execute(_plan(reg, track=TrustingTrack(), pipelines=["fake", "fake-none"]), tmp_path / "run")
    none = [r["metrics"] for r in out.records if r["pipeline"] == "fake-none"]
    assert len(none) == 6 and all(m["failed"] for m in none)
    assert {m["failed_reason"] for m in none} == {"finalize() returned NoneType, not StaircaseEstimate"}
    assert set(none[0]) == set(FakeTrack().failed_metrics(None, "x"))  # the track's failure record
    assert TrustingTrack.scored == ["StaircaseEstimate"] * 6  # only the real estimates were scored


def test_jobs_two_gives_the_same_results_as_jobs_one(reg, tmp_path):
    plan = _plan(reg, seeds=[0, 1], pipelines=["fake"])
    one = execute(plan, tmp_path / "one", jobs=1)
    two = execute(plan, tmp_path / "two", jobs=2)
    assert _comparable(one.records) == _comparable(two.records)
    assert len(one.records) == 12


def test_resume_after_interrupt_neither_repeats_nor_loses(reg, tmp_path, monkeypatch):
    plan = _plan(reg, pipelines=["fake"])
    calls = {"n": 0}
    real = FakeStairs.finalize

    def interrupting(self):
        calls["n"] += 1
        if calls["n"] == 3:
            raise KeyboardInterrupt
        return real(self)

    monkeypatch.setattr(FakeStairs, "finalize", interrupting)
    with pytest.raises(KeyboardInterrupt):
        execute(plan, tmp_path / "run")
    kept = read_records(tmp_path / "run" / RESULTS_FILE)
    assert len(kept) == 2

    monkeypatch.setattr(FakeStairs, "finalize", real)
    out = execute(plan, tmp_path / "run", resume=True)
    assert sorted(out.skipped) == sorted(r["episode"] for r in kept)
    assert len(out.ran) == 4
    keys = [r["episode"] for r in out.records]
    assert sorted(keys) == sorted(e.key for e in plan.episodes)  # each exactly once
    first = {r["episode"]: r["wall_s"] for r in kept}
    assert all(r["wall_s"] == first[r["episode"]] for r in out.records if r["episode"] in first)


def test_partial_trailing_write_is_cut_and_rerun(reg, tmp_path):
    plan = _plan(reg)
    run = tmp_path / "run"
    execute(plan, run)
    results = run / RESULTS_FILE
    lines = results.read_text().splitlines(keepends=True)
    assert len(lines) == 12
    # the last episode's write stopped after its first record and half of the second
    results.write_text("".join(lines[:-1]) + lines[-1][: len(lines[-1]) // 2])
    assert len(read_records(results)) == 10  # the incomplete episode is not counted
    removed = repair_results(results)
    assert removed > 0 and len(results.read_text().splitlines()) == 10
    out = execute(plan, run, resume=True)
    assert len(out.ran) == 1 and len(out.records) == 12


def test_existing_folder_and_changed_resume_are_refused(reg, tmp_path):
    run = tmp_path / "run"
    execute(_plan(reg, pipelines=["fake"]), run)
    with pytest.raises(ConfigError, match="--out"):
        execute(_plan(reg, pipelines=["fake"]), run)
    with pytest.raises(ConfigError, match="resume"):
        execute(_plan(reg, pipelines=["fake"], seeds=[1]), run, resume=True)
    with pytest.raises(ConfigError, match="resume"):
        execute(_plan(reg, pipelines=["fake"]), tmp_path / "never-ran", resume=True)
    assert not (tmp_path / "never-ran").exists()


def test_set_keys_go_to_the_longest_pipeline_name_with_the_rest_kept_whole():
    overrides = {"riser_m": "0.17", "kiss-icp.filter.band_m": "0.05", "fake.offset_m": "1", "fake.v2.stage.x": "2"}
    scenario, pipes = split_overrides(overrides, ["fake", "fake.v2", "kiss-icp"])
    assert scenario == {"riser_m": "0.17"}
    assert pipes == {"kiss-icp": {"filter.band_m": "0.05"}, "fake": {"offset_m": "1"}, "fake.v2": {"stage.x": "2"}}
    with pytest.raises(UnknownNameError, match="kiss"):
        split_overrides({"kiss.x": "1"}, ["fake", "kiss-icp"])


def test_plan_hands_each_pipeline_its_dotted_overrides(monkeypatch):
    seen: dict[str, dict] = {}

    class Spy(PipelineRegistry):
        def make_config(self, name, values=None):
            seen[name] = dict(values or {})
            return super().make_config(name, {k: v for k, v in (values or {}).items() if "." not in k})

    reg = Spy()
    reg.register("fake", FakeStairs)
    reg.register("fake.v2", FakeStairs)
    plan_run(FakeTrack(), "quick", ["fake", "fake.v2"], [0], {"fake.v2.filter.band_m": "0.05", "fake.offset_m": "0.01"}, registry=reg)
    assert seen == {"fake": {"offset_m": "0.01"}, "fake.v2": {"filter.band_m": "0.05"}}


def test_a_corrupt_line_costs_only_its_episode(reg, tmp_path, capsys):
    plan = _plan(reg)
    run = tmp_path / "run"
    execute(plan, run)
    results = run / RESULTS_FILE
    lines = results.read_text().splitlines(keepends=True)
    assert len(lines) == 12
    # the third line (second record of the second episode) is garbled in the middle of the file
    lines[2] = '{"episode": "x", garbled\n'
    results.write_text("".join(lines))
    capsys.readouterr()
    kept = read_records(results)
    assert len(kept) == 10  # every record of the five intact episodes
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "line 3" in err[0] and RESULTS_FILE in err[0]
    assert repair_results(results) == 0  # nothing trailing to cut: later records stay
    out = execute(plan, run, resume=True)
    assert len(out.ran) == 1 and len(out.records) == 12
    assert sorted(r["episode"] for r in out.records) == sorted(r["episode"] for r in read_records(results))


def test_a_line_that_is_not_a_record_between_episodes_is_skipped(reg, tmp_path):
    plan = _plan(reg)
    run = tmp_path / "run"
    execute(plan, run)
    results = run / RESULTS_FILE
    lines = results.read_text().splitlines(keepends=True)
    lines.insert(4, "[1, 2]\n")  # a list instead of a record, between two episodes
    results.write_text("".join(lines))
    assert len(read_records(results)) == 12


@pytest.mark.parametrize("umask", [0o022, 0o077])
def test_run_files_get_ordinary_permissions(reg, tmp_path, umask):
    import os

    old = os.umask(umask)
    try:
        out = execute(_plan(reg, pipelines=["fake"]), tmp_path / "run")
    finally:
        os.umask(old)
    for name in (RUN_CONFIG_FILE, RESULTS_FILE):
        assert (out.out_dir / name).stat().st_mode & 0o777 == 0o666 & ~umask, name
    assert out.out_dir.stat().st_mode & 0o777 == 0o777 & ~umask


class KillingTrack(FakeTrack):
    """Case B kills the process simulating it (as the OOM killer or a user would)."""

    def simulate(self, scenario, seed):
        if scenario.get("yaw_deg") == 23.0:
            import os
            import signal

            os.kill(os.getpid(), signal.SIGKILL)
        return super().simulate(scenario, seed)


def test_a_killed_worker_is_retried_then_recorded_as_failed_and_the_run_finishes(reg, tmp_path):
    plan = _plan(reg, track=KillingTrack(), pipelines=["fake"])
    out = execute(plan, tmp_path / "run", jobs=2)
    assert sorted(r["episode"] for r in out.records) == sorted(e.key for e in plan.episodes)
    b = [r for r in out.records if r["case"] == "B"]
    assert len(b) == 1 and b[0]["metrics"]["failed"] and "killed (SIGKILL) twice, likely out of memory" in b[0]["harness_error"]
    assert not any(r["metrics"]["failed"] for r in out.records if r["case"] != "B")


class LooseStairs(FakeStairs):
    """A fake that declares its results not bit-reproducible (as orb-slam3 does)."""

    name: ClassVar[str] = "fake-loose"
    deterministic: ClassVar[bool] = False


def test_a_pipeline_not_deterministic_is_marked_so_in_config_records_and_report(reg, tmp_path):
    from exobench.benchmarks.report import write_report

    reg.register("fake-loose", LooseStairs)
    out = execute(_plan(reg, pipelines=["fake", "fake-loose"]), tmp_path / "run")
    marks = {(r["pipeline"], r.get("deterministic", True)) for r in out.records}
    assert marks == {("fake", True), ("fake-loose", False)}
    config = json.loads((tmp_path / "run" / RUN_CONFIG_FILE).read_text())
    assert {p["name"]: p.get("deterministic", True) for p in config["pipelines"]} == {"fake": True, "fake-loose": False}
    report = write_report(tmp_path / "run").read_text()
    assert "Not bit-reproducible (a second run of the same episodes may give other figures): fake-loose." in report
