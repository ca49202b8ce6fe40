"""`exobench run --case PATTERN`: one case (or a few) of a suite, for every seed, on the fake
stairs track (no MuJoCo). The expected episodes are worked out here from the suite's own case
list with plain string tests, not with the runner's matcher."""

from __future__ import annotations

import json

import pytest
from test_benchmarks_support import FakeTrack
from test_run_folders import (
    _comparable,
    _interrupt_after,
    _lines,
    _one_error_line,
    _printed_command,
    _run,
    _serve,
)

from exobench.benchmarks.results import RESULTS_FILE, RUN_CONFIG_FILE

QUICK = [c.name for c in FakeTrack().cases("quick")]  # A, B, C, 0.162-0.280/pose00..02


@pytest.fixture
def tracks(monkeypatch):
    _serve(monkeypatch)


@pytest.fixture
def whole(tmp_path_factory, monkeypatch):
    """The quick suite of the fake stairs track, every case, seeds 0 and 1."""
    _serve(monkeypatch)
    out = tmp_path_factory.mktemp("whole") / "run"
    assert _run(["run", "--track", "stairs", "--seeds", "2", "--out", out, "--no-report"]).exit_code == 0
    return out


@pytest.mark.parametrize("patterns, expected", [
    (["B"], ["B"]),
    (["0.162-0.280/*"], [n for n in QUICK if n.startswith("0.162-0.280/")]),
    (["C", "A"], ["A", "C"]),  # the suite's order, not the patterns'
    (["?"], [n for n in QUICK if len(n) == 1]),
    (["*pose0[02]", "B"], [n for n in QUICK if n == "B" or n.endswith(("pose00", "pose02"))]),
])  # fmt: skip
def test_case_keeps_the_matching_cases_in_the_suites_order_for_every_seed(tmp_path, whole, patterns, expected):
    assert 0 < len(expected) < len(QUICK)
    out = tmp_path / "part"
    args = ["run", "--track", "stairs", "--seeds", "2", "--out", out, "--no-report"]
    result = _run([*args, *[a for p in patterns for a in ("--case", p)]])
    assert result.exit_code == 0, result.stderr
    config = json.loads((out / RUN_CONFIG_FILE).read_text())
    assert config["episodes"] == [f"{n}/s{s}" for n in expected for s in (0, 1)]
    assert config["cases"] == patterns
    # the same episodes as in the run of the whole suite, with the same figures
    assert _comparable(out) == [r for r in _comparable(whole) if r[1].rsplit("/s", 1)[0] in expected]
    assert f"--case {', '.join(patterns)}: {2 * len(expected)} episodes" in result.stdout


def test_a_run_of_the_whole_suite_stores_no_case_patterns(whole):
    assert json.loads((whole / RUN_CONFIG_FILE).read_text())["cases"] == []
    assert len({r["episode"] for r in _lines(whole / RESULTS_FILE)}) == 2 * len(QUICK)


@pytest.mark.parametrize("args, named", [
    (["--track", "stairs", "--case", "D"], ["'D'", "A", "B", "C"]),
    (["--track", "stairs", "--case", "A", "--case", "pose*"], ["'pose*'"]),  # a glob is of the whole name
    (["--track", "stairs", "paper", "--case", "0.170-*"], ["'0.170-*'", "'paper'", "(63 in all)"]),
    (["--track", "stairs", "--case", "A", "--case", "A"], ["A,A", "each pattern once"]),
    (["--track", "all", "--case", "A"], ["one track"]),
    (["--case", "A"], ["one track"]),  # --track all is the default
])  # fmt: skip
def test_a_case_that_cannot_be_run_is_one_line_exit_2_and_nothing_written(tmp_path, tracks, monkeypatch, args, named):
    monkeypatch.setattr(FakeTrack, "simulate", lambda *a: pytest.fail("simulated a refused run"))
    out = tmp_path / "run"
    result = _run(["run", *args, "--out", out])
    assert result.exit_code == 2, result.output
    line = _one_error_line(result)
    assert "--case" in line and all(n in line for n in named), line
    assert not out.exists()


def test_a_case_run_resumed_as_printed_continues_the_same_cases(tmp_path, tracks, monkeypatch):
    args = ["run", "--track", "stairs", "--seeds", "2", "--case", "A", "--case", "0.162-0.280/pose01", "--no-report"]
    assert _run([*args, "--out", tmp_path / "whole"]).exit_code == 0
    with monkeypatch.context() as m:
        _interrupt_after(m, 2)
        stopped = _run([*args, "--out", tmp_path / "part"])
    assert stopped.exit_code == 130
    command = _printed_command(stopped.stderr)
    assert "--case" not in command  # the patterns are read back from the folder
    resumed = _run(command)
    assert resumed.exit_code == 0 and "2 finished episodes kept" in resumed.stderr, resumed.stderr
    assert _comparable(tmp_path / "part") == _comparable(tmp_path / "whole")
    assert sorted({r[1] for r in _comparable(tmp_path / "part")}) == ["0.162-0.280/pose01/s0", "0.162-0.280/pose01/s1", "A/s0", "A/s1"]


def test_resume_takes_the_same_cases_and_refuses_others(tmp_path, tracks):
    out = tmp_path / "run"
    assert _run(["run", "--track", "stairs", "--case", "B", "--out", out, "--no-report"]).exit_code == 0
    again = _run(["run", "--resume", "--out", out, "--case", "B"])
    assert again.exit_code == 0 and "1 finished episodes kept" in again.stderr, again.stderr
    for other in (["--case", "C"], ["--case", "B", "--case", "C"]):
        result = _run(["run", "--resume", "--out", out, *other])
        assert result.exit_code == 2 and "--resume cases" in _one_error_line(result)
    whole = tmp_path / "whole"
    assert _run(["run", "--track", "stairs", "--out", whole, "--no-report"]).exit_code == 0
    result = _run(["run", "--resume", "--out", whole, "--case", "B"])  # a run of every case is not continued as a part
    assert result.exit_code == 2 and "--resume cases" in _one_error_line(result)
    assert [r["episode"] for r in _lines(out / RESULTS_FILE)] == ["B/s0"]
    assert len(_lines(whole / RESULTS_FILE)) == len(QUICK)


def test_the_report_says_which_cases_ran(tmp_path, tracks):
    out = tmp_path / "run"
    assert _run(["run", "--track", "stairs", "--case", "A", "--case", "0.162*", "--out", out]).exit_code == 0
    text = (out / "report.md").read_text()
    assert "4 of 4 episodes finished" in text and "only the cases matching --case A, 0.162*" in text
