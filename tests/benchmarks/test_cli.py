"""The `exobench` command line: help, listing, bad input (exit 2, one line, no folder), a run."""

from __future__ import annotations

import errno
import json
import os
import subprocess
import sys
from pathlib import Path

import click
import pytest
from click.testing import CliRunner
from test_benchmarks_support import FakeStairs, FakeTrack, serve_tracks

from exobench.benchmarks import registry as registry_mod
from exobench.benchmarks.cli import cli

EXOBENCH = Path(sys.executable).with_name("exobench")


def _run(args: list[str]):
    return CliRunner().invoke(cli, args, catch_exceptions=False)


def _one_error_line(result) -> str:
    lines = [ln for ln in result.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1, result.stderr
    assert lines[0].startswith("exobench: error: ")
    return lines[0]


@pytest.mark.parametrize(
    ("assignment", "expected"),
    [
        ("riser_m=0", "riser_m"),
        ("riser_m=0.31", "riser_m"),
        ("riser_m=nan", "riser_m"),
        ("riser_height=0.2", "riser_m"),  # unknown key: the valid names are listed
        ("riser_m", "KEY=VALUE"),
    ],
)
def test_bad_scenario_values_exit_2_and_write_nothing(tmp_path, assignment, expected):
    out = tmp_path / "run"
    result = _run(["run", "--track", "stairs", "--set", assignment, "--out", str(out)])
    assert result.exit_code == 2
    assert expected in _one_error_line(result)
    assert not out.exists()


@pytest.mark.parametrize(
    ("args", "expected"),
    [
        (["run", "--track", "stairs", "--pipeline", "nope"], "rtls-htvr"),
        (["run", "fast"], "quick"),
        (["run", "--track", "ladders"], "stairs"),
        (["run", "--seed", "1", "--seeds", "2"], "--seed"),
        (["run", "--seeds", "0"], "--seeds"),
        (["run", "--jobs", "0"], "--jobs"),
        (["run", "--track", "stairs", "--set", "rtls.no_such_param=1", "--pipeline", "rtls"], "no_such_param"),
        (["run", "--set", "riser_m=0.2"], "--track"),
        (["run", "--resume"], "--resume"),
    ],
)
def test_bad_names_and_options_exit_2_and_write_nothing(tmp_path, args, expected):
    out = tmp_path / "run"
    result = _run([*args, "--out", str(out)] if "--resume" not in args else args)
    assert result.exit_code == 2
    line = _one_error_line(result)
    assert expected in line, line
    assert not out.exists()


def test_help_answers_and_lists_the_commands():
    result = _run(["--help"])
    assert result.exit_code == 0
    for command in ("run", "list", "bench", "replay", "record"):
        assert command in result.output


def test_a_reader_that_leaves_ends_the_command_quietly(monkeypatch):
    """`exobench list | head`: the write that meets the closed pipe ends the command with the
    shell's status for SIGPIPE and no error line (it was "exobench: error: [Errno 32] Broken pipe")."""

    def closed_pipe(*args, **kwargs):
        raise BrokenPipeError(32, "Broken pipe")

    monkeypatch.setattr(click, "echo", closed_pipe)
    result = CliRunner().invoke(cli, ["list"])
    assert result.exit_code == 141
    assert result.stderr == ""


def test_help_in_a_fresh_process_imports_nothing_heavy():
    code = "import sys; from exobench.benchmarks import cli; print(sorted(m for m in ('numpy', 'mujoco', 'matplotlib', 'rerun', 'open3d') if m in sys.modules))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


@pytest.mark.skipif(not EXOBENCH.exists(), reason="console script not installed")
def test_console_script_refuses_bad_riser_in_a_real_call(tmp_path):
    out = tmp_path / "run"
    env = {**os.environ, "MUJOCO_GL": os.environ.get("MUJOCO_GL", "egl")}
    proc = subprocess.run([str(EXOBENCH), "run", "--track", "stairs", "--set", "riser_m=0.31", "--out", str(out)], capture_output=True, text=True, env=env)
    assert proc.returncode == 2
    assert proc.stderr.startswith("exobench: error: ") and "riser_m" in proc.stderr
    assert len(proc.stderr.strip().splitlines()) == 1
    assert not out.exists()
    help_proc = subprocess.run([str(EXOBENCH), "--help"], capture_output=True, text=True)
    assert help_proc.returncode == 0 and "Commands:" in help_proc.stdout


def test_list_shows_suites_pipelines_and_parameter_ranges():
    result = _run(["list"])
    assert result.exit_code == 0, result.output
    for word in ("quick", "paper", "full", "rtls", "rtls-htvr", "batch-ransac", "riser_m", "yaw_deg"):
        assert word in result.output


@pytest.fixture
def fake_stairs(monkeypatch):
    """Serve the hand-built track under "stairs" and only the fake pipeline (no MuJoCo)."""
    serve_tracks(monkeypatch, stairs=FakeTrack)
    reg = registry_mod.PipelineRegistry()
    reg.register("fake", FakeStairs)
    monkeypatch.setattr(registry_mod, "default_registry", lambda: reg)
    monkeypatch.setattr("exobench.benchmarks.runner.default_registry", lambda: reg)


def test_run_prints_the_table_and_writes_the_run_folder(tmp_path, fake_stairs):
    out = tmp_path / "run"
    result = _run(["run", "--track", "stairs", "--out", str(out), "--seeds", "2", "--set", "tof_noise_m=0"])
    assert result.exit_code == 0, result.output + result.stderr
    assert "alpha S2 (deg)" in result.output and "Tab. III" in result.output
    assert "episode" in result.stderr  # the progress bar
    records = [json.loads(line) for line in (out / "results.jsonl").read_text().splitlines()]
    assert len(records) == 12 and all(r["scenario"]["tof_noise_m"] == 0.0 for r in records)
    assert (out / "report.md").exists() and (out / "run_config.json").exists()
    again = _run(["run", "--track", "stairs", "--out", str(out), "--seeds", "2", "--set", "tof_noise_m=0", "--resume", "--no-report"])
    assert again.exit_code == 0 and "12 finished episodes kept" in again.stderr
    assert len((out / "results.jsonl").read_text().splitlines()) == 12
    report = _run(["report", str(out)])
    assert report.exit_code == 0 and "report.md" in report.output


def test_set_hands_a_dotted_pipeline_path_to_the_registry_whole(tmp_path, fake_stairs, monkeypatch):
    seen: dict[str, dict] = {}
    real = registry_mod.PipelineRegistry.make_config

    def spy(self, name, values=None):
        seen[name] = dict(values or {})
        return real(self, name, {k: v for k, v in (values or {}).items() if "." not in k})

    monkeypatch.setattr(registry_mod.PipelineRegistry, "make_config", spy)
    args = ["run", "--track", "stairs", "--out", str(tmp_path / "run"), "--no-report",
            "--set", "fake.filter.band_m=0.05", "--set", "fake.offset_m=0.001"]  # fmt: skip
    result = _run(args)
    assert result.exit_code == 0, result.output + result.stderr
    assert seen == {"fake": {"filter.band_m": "0.05", "offset_m": "0.001"}}


def test_run_whose_simulation_or_scorer_fails_exits_1_with_the_first_reasons(tmp_path, fake_stairs, monkeypatch):
    real = FakeTrack.simulate

    def sim(self, scenario, seed):
        if scenario["riser_m"] != FakeTrack().validate_scenario({})["riser_m"]:
            raise RuntimeError("sim exploded")
        return real(self, scenario, seed)

    monkeypatch.setattr(FakeTrack, "simulate", sim)
    result = _run(["run", "--track", "stairs", "--out", str(tmp_path / "a"), "--no-report", "--set", "riser_m=0.15"])
    assert result.exit_code == 1, result.output + result.stderr
    assert "failed / episodes" in result.output  # the table is still printed
    last = result.stderr.strip().splitlines()[-1]
    assert "simulation raised RuntimeError: sim exploded" in last and "more" in last and len(last) < 600
    monkeypatch.setattr(FakeTrack, "simulate", real)

    def score(self, episode, estimate, scoring=None):
        raise ValueError("scorer exploded")

    monkeypatch.setattr(FakeTrack, "score", score)
    result = _run(["run", "--track", "stairs", "--out", str(tmp_path / "b"), "--no-report"])
    assert result.exit_code == 1 and "scorer raised ValueError: scorer exploded" in result.stderr
    records = [json.loads(line) for line in (tmp_path / "b" / "results.jsonl").read_text().splitlines()]
    assert all(r["metrics"]["failed"] and "scorer exploded" in r["harness_error"] for r in records)


def test_a_pipelines_own_failures_stay_results_and_exit_0(tmp_path, fake_stairs):
    from test_benchmarks_support import RaisingStairs

    registry_mod.default_registry().register("fake-raise", RaisingStairs)
    result = _run(["run", "--track", "stairs", "--pipeline", "fake-raise", "--out", str(tmp_path / "r"), "--no-report"])
    assert result.exit_code == 0, result.stderr
    assert "6 records (6 failed)" in result.output
    records = [json.loads(line) for line in (tmp_path / "r" / "results.jsonl").read_text().splitlines()]
    assert not any("harness_error" in r for r in records)


def test_stairs_groups_are_labelled_by_the_geometry_that_was_run(tmp_path, fake_stairs):
    args = ["run", "--track", "stairs", "--out", str(tmp_path / "g"), "--no-report", "--set", "riser_m=0.19", "--set", "tread_m=0.26"]
    result = _run(args)
    assert result.exit_code == 0, result.stderr
    groups = {json.loads(line)["group"] for line in (tmp_path / "g" / "results.jsonl").read_text().splitlines()}
    assert groups == {"A 0.190/0.260", "B 0.190/0.260", "C 0.190/0.260", "0.190/0.260"}
    assert "0.162/0.280" not in result.output and "Tab. III" not in result.output  # no paper figure of another staircase
    plain = _run(["run", "--track", "stairs", "--out", str(tmp_path / "p"), "--no-report", "--set", "tof_noise_m=0"])
    assert "0.162/0.280" in plain.output and "Tab. III" in plain.output


@pytest.mark.parametrize(
    ("args", "expected"),
    [
        (["--track", "stairs", "--pipeline", "rtls", "--set", "rtls.queue_q=inf"], "rtls.queue_q"),
        (["--track", "stairs", "--pipeline", "rtls", "--set", "rtls.queue_q=nan"], "rtls.queue_q"),
        (["--track", "locomotion", "--pipeline", "terrain-recon", "--set", "terrain-recon.every_k=inf"], "every_k"),
        (["--track", "locomotion", "--pipeline", "terrain-recon", "--set", "terrain-recon.tsdf=abc"], "tsdf.<field>"),
        (["--track", "locomotion", "--pipeline", "terrain-recon", "--set", "terrain-recon.tsdf.nope=1"], "tsdf.nope"),
        (["--track", "locomotion", "--pipeline", "terrain-recon", "--set", "terrain-recon.tsdf.voxel_size_m.x=1"], "tsdf.voxel_size_m.x"),
        (["--track", "stairs", "--seeds", "20000"], "10000"),  # the seed list was printed whole (129 KB)
        (["--track", "stairs", "--set", "riser_m=" + "9" * 5000], "riser_m"),
        (["--track", "stairs", "--pipeline", "x" * 5000], "rtls-htvr"),
        (["--track", "stairs", "--set", "nosing=1"], "nosing_m"),  # of many names, the closest first
    ],
)
def test_bad_pipeline_and_scenario_values_are_one_short_line_at_plan_time(tmp_path, args, expected):
    out = tmp_path / "run"
    result = _run(["run", *args, "--out", str(out)])
    assert result.exit_code == 2
    line = _one_error_line(result)
    assert expected in line and len(line) < 400, line
    assert not out.exists()


def test_unknown_names_list_the_closest_first_and_a_count():
    from exobench.core import UnknownNameError

    err = str(UnknownNameError("case", "risr_m", [f"case{i:03d}" for i in range(209)] + ["riser_m"]))
    assert len(err) < 300 and "valid: riser_m, case000" in err and "(210 in all)" in err


def refuse_writes_in(monkeypatch, folder: Path, err: int = errno.EACCES) -> None:
    """Make os.open refuse to create or write any file in ``folder`` (and the folder itself), as
    a read-only folder does to a user who is not root (the tests run as root, whom permissions
    do not stop); os.access is left alone, so a check that only asks it is not fooled."""
    real = os.open

    def fake_open(path, flags, *args, **kw):
        p = Path(os.fsdecode(path))
        writes = flags & (os.O_WRONLY | os.O_RDWR | os.O_CREAT | os.O_APPEND)
        if writes and (p.parent == folder or p == folder):
            raise PermissionError(err, os.strerror(err), str(p))
        return real(path, flags, *args, **kw)

    monkeypatch.setattr(os, "open", fake_open)


def _a_file(tmp_path):
    f = tmp_path / "a-file"
    f.write_text("x")
    return f


@pytest.mark.parametrize(
    "args",
    [
        ["run", "--track", "stairs", "--out", "{file}/run"],
        ["run", "--track", "stairs", "--out", "{file}"],
        ["run", "--track", "stairs", "--out", ""],
        ["run", "--track", "stairs", "--out", "{tmp}/run", "--rerun", "{file}/x.rrd"],
        ["run", "--out", "{tmp}/run", "--rerun", "{file}/x.rrd"],  # every track
        ["run", "--track", "stairs", "--out", "{tmp}/run", "--rerun", "{tmp}"],
        ["run", "--track", "stairs", "--out", "{tmp}/run", "--rerun", ""],
        ["record", "{file}/session"],
        ["record", ""],
    ],
)
def test_file_system_problems_are_one_line_and_exit_2_before_anything_runs(tmp_path, args, fake_stairs, monkeypatch):
    f = _a_file(tmp_path)
    monkeypatch.setattr(FakeTrack, "simulate", lambda *a: pytest.fail("simulated before the paths were checked"))
    result = _run([a.format(file=f, tmp=tmp_path) for a in args])
    assert result.exit_code == 2, result.output + result.stderr
    assert len(_one_error_line(result)) < 300
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a-file"]


@pytest.mark.parametrize("args", [["run", "--track", "stairs", "--out", "{ro}/run"], ["record", "{ro}/s"],
                                  ["run", "--track", "stairs", "--out", "{tmp}/run", "--rerun", "{ro}/x.rrd"]])  # fmt: skip
def test_unwritable_folders_are_refused_before_anything_runs(tmp_path, args, fake_stairs, monkeypatch):
    # root can write anywhere, so the kernel's answer is simulated: nothing can be created in "ro"
    ro = tmp_path / "ro"
    ro.mkdir()
    refuse_writes_in(monkeypatch, ro)
    monkeypatch.setattr(FakeTrack, "simulate", lambda *a: pytest.fail("simulated before the paths were checked"))
    result = _run([a.format(ro=ro, tmp=tmp_path) for a in args])
    assert result.exit_code == 2
    assert "not writable" in _one_error_line(result)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["ro"] and not any(ro.iterdir())
