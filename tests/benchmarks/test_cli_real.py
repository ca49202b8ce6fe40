"""Small real runs: MuJoCo simulation, the perception pipelines, sessions, benches."""

from __future__ import annotations

import json

import pytest
from click.testing import CliRunner

from exobench.benchmarks.cli import cli
from exobench.benchmarks.registry import default_registry
from exobench.benchmarks.results import json_safe, read_records
from exobench.benchmarks.runner import execute, plan_run, run_pipelines, untimed_metrics
from exobench.benchmarks.tracks.stairs import StairsTrack
from exobench.benchmarks.tracks.stairs.track import CASES

pytestmark = pytest.mark.long(seconds=10)  # the workers take it first (tests/conftest.py); 10: the file at -n 0 in one run at load 12-15, scaled to that run's CPU


def _invoke(args):
    result = CliRunner().invoke(cli, args, catch_exceptions=False)
    assert result.exit_code == 0, result.output + result.stderr
    return result


def _metrics(records):
    return sorted(
        ((r["episode"], r["pipeline"], untimed_metrics(StairsTrack, r["metrics"])) for r in records),
        key=lambda x: (x[0], x[1]),
    )


def test_real_quick_cases_are_identical_with_one_or_two_jobs(tmp_path):
    plan = plan_run("stairs", "quick", ["rtls-htvr", "batch-ransac"], [0])
    plan.episodes = plan.episodes[:3]  # cases A, B, C
    one = execute(plan, tmp_path / "one", jobs=1)
    two = execute(plan, tmp_path / "two", jobs=2)
    assert len(one.records) == 6
    assert _metrics(one.records) == _metrics(two.records)
    assert all(r["versions"]["mujoco"] != "not installed" for r in one.records)
    # the scorer saw real truth: the HTVR tread is horizontal by construction
    assert all(r["metrics"]["alpha_deg_S2"] in (None, 0.0) for r in one.records if r["pipeline"] == "rtls-htvr")


def test_record_then_replay_scores_like_the_live_run(tmp_path):
    session = tmp_path / "session"
    _invoke(["record", "--case", "B", "--seed", "3", str(session)])
    assert (session / "meta.json").exists()
    replay = _invoke(["replay", str(session), "--pipeline", "rtls", "--json"])
    replayed = json.loads(replay.output.strip().splitlines()[0])
    assert replayed["scenario"]["yaw_deg"] == 23.0 and replayed["seed"] == 3

    # the same episode (case B, episode seed 3) scored live must give the same metrics
    plan = plan_run("stairs", "quick", ["rtls"], [0])
    track = StairsTrack()
    episode = track.simulate(track.validate_scenario(CASES["B"]), 3)
    _, live, _, _ = run_pipelines(track, episode, plan.pipelines)
    expected = untimed_metrics(track, json_safe(live["rtls"]))
    got = untimed_metrics(track, replayed["metrics"])
    assert got == expected

    again = CliRunner().invoke(cli, ["record", str(session)])
    assert again.exit_code == 2 and "does not exist" in again.stderr


def test_bench_commands_report_json():
    rtls = json.loads(_invoke(["bench", "rtls", "--json"]).output)
    assert rtls["points"] > 0 and rtls["rtls_update_median_us"] > 0 and rtls["batch_over_rtls"] > 0
    sim = json.loads(_invoke(["bench", "sim", "--json", "--track", "stairs"]).output)
    assert sim["simulated_s"] > 0 and sim["real_time_factor"] > 0 and sim["frames"]["tof"] > 0
    ep = sim["episodes"]["stairs"]  # the paper suite's first case, in a process of its own
    assert set(ep["pipelines_wall_s"]) == set(default_registry().names(track="stairs")) and not ep["failed"]
    stages = ep["stages_s"]
    assert stages["casting"] > 0 and stages["pipelines"] > 0 and stages["motion"] > 0  # ToF cones, RTLS, the walk
    assert 0.5 * ep["cpu_s"] < sum(stages.values()) < 1.1 * ep["cpu_s"]  # every stage of the episode's CPU time
    assert 0 < ep["cpu_s"] < 3 * ep["wall_s"]  # the profile counts CPU time, whatever else the machine runs
    assert 0.1 < ep["peak_rss_gb"] < 8
    bad = CliRunner().invoke(cli, ["bench", "sim", "--track", "nope"])
    assert bad.exit_code == 2 and "nope" in bad.stderr
    bad = CliRunner().invoke(cli, ["bench", "lidar", "--track", "stairs"])
    assert bad.exit_code == 2 and "bench sim (any number) or bench executor (one)" in bad.stderr


def test_bench_sim_case_runs_one_paper_episode_whole_in_its_own_process():
    out = json.loads(_invoke(["bench", "sim", "--json", "--track", "stairs", "--case", "B"]).output)["episode"]
    assert out["case"] == "B" and not out["failed"]
    assert set(out["pipelines_wall_s"]) == set(default_registry().names(track="stairs"))
    assert 0 < out["sim_wall_s"] < out["wall_s"] and 0.1 < out["peak_rss_gb"] < 8
    assert 0 < out["cpu_s"] < 3 * out["wall_s"]
    for args, says in ((["--case", "B"], "exactly one --track"), (["--track", "stairs", "--case", "nope"], "nope"),
                       (["--track", "stairs", "--track", "odometry", "--case", "B"], "exactly one --track")):  # fmt: skip
        bad = CliRunner().invoke(cli, ["bench", "sim", *args])
        assert bad.exit_code == 2 and says in bad.stderr and "Traceback" not in bad.stderr, bad.output
    bad = CliRunner().invoke(cli, ["bench", "lidar", "--track", "stairs", "--case", "B"])
    assert bad.exit_code == 2 and "--case" in bad.stderr


def test_interrupted_run_says_how_to_resume(tmp_path, monkeypatch):
    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr("exobench.benchmarks.runner.execute", interrupted)
    result = CliRunner().invoke(cli, ["run", "--track", "stairs", "--out", str(tmp_path / "run"), "--pipeline", "rtls"])
    assert result.exit_code == 130 and "--resume" in result.stderr
    assert read_records(tmp_path / "run" / "results.jsonl") == []


def test_scoring_settings_are_given_to_replay_not_to_record(tmp_path):
    """revisit_m and exclude_recent_s score a loop-closure session; they are not part of it."""
    refused = CliRunner().invoke(cli, ["record", str(tmp_path / "no"), "--track", "loop-closure", "--set", "revisit_m=2"])
    assert refused.exit_code == 2 and "revisit_m" in refused.stderr and "replay" in refused.stderr
    assert not (tmp_path / "no").exists()
    session = tmp_path / "session"
    _invoke(["record", str(session), "--track", "loop-closure", "--set", "max_distance_m=1.5", "--set", "lidar_azimuth_step_deg=1"])
    meta = json.loads((session / "meta.json").read_text())
    assert not {"revisit_m", "exclude_recent_s"} & set(meta["scenario"])

    def replay(*sets):
        args = ["replay", str(session), "--pipeline", "sc++", "--json", *(x for s in sets for x in ("--set", s))]
        return json.loads(_invoke(args).output.strip().splitlines()[0])["metrics"]

    default = replay()  # a 1.5 m walk lasts less than the 20 s that make an earlier keyframe eligible
    near = replay("exclude_recent_s=0.1", "revisit_m=50")  # every earlier keyframe is a revisit
    assert default["n_keyframes"] == near["n_keyframes"] > 1
    assert default["n_revisits"] == 0 and near["n_revisits"] == near["n_keyframes"] - 1
    wrong = CliRunner().invoke(cli, ["replay", str(session), "--set", "max_distance_m=3"])
    assert wrong.exit_code == 2 and "max_distance_m" in wrong.stderr and "revisit_m" in wrong.stderr


def test_record_of_a_drawn_suite_case_replays_to_the_runs_figures(tmp_path):
    # general/01 under run seed 1: a drawn case (its staircase differs from run seed 0's) whose
    # episode seed is derived from the run seed and the case name, as `run` derives it
    session = tmp_path / "session"
    out = _invoke(["record", "--track", "stairs", "--suite", "general", "--case", "general/01", "--seed", "1", str(session)]).output
    _invoke(["run", "general", "--track", "stairs", "--case", "general/01", "--seed", "1", "--pipeline", "rtls",
             "--out", str(tmp_path / "run"), "--no-report"])  # fmt: skip
    (run,) = read_records(tmp_path / "run" / "results.jsonl")
    replayed = json.loads(_invoke(["replay", str(session), "--pipeline", "rtls", "--json"]).output.strip().splitlines()[0])
    assert replayed["seed"] == run["seed"] != 1 and f"seed {run['seed']} (run seed 1" in out
    scenario = StairsTrack().validate_scenario  # a session leaves out parameters at their neutral defaults
    assert scenario(replayed["scenario"]) == scenario(run["scenario"]) != scenario(StairsTrack().cases("general", 0)[1].scenario)
    assert untimed_metrics(StairsTrack, replayed["metrics"]) == untimed_metrics(StairsTrack, run["metrics"])


def test_record_refuses_an_unknown_suite_or_a_suite_without_a_case(tmp_path):
    bad = CliRunner().invoke(cli, ["record", "--track", "stairs", "--suite", "papr", "--case", "A", str(tmp_path / "s")])
    assert bad.exit_code == 2
    assert "unknown suite of track 'stairs' 'papr'; valid: full, general, paper, quick" in bad.stderr
    no_case = CliRunner().invoke(cli, ["record", "--track", "stairs", "--suite", "general", str(tmp_path / "s")])
    assert no_case.exit_code == 2 and "--case" in no_case.stderr and "general" in no_case.stderr
    unknown = CliRunner().invoke(cli, ["record", "--track", "stairs", "--suite", "general", "--case", "B", str(tmp_path / "s")])
    assert unknown.exit_code == 2 and "unknown case of suite 'general' 'B'; valid: general/00" in unknown.stderr
    assert not (tmp_path / "s").exists()  # nothing written
