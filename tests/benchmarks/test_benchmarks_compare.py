"""`exobench compare`: known differences give known intervals, a planted regression is flagged
(exit 1), two seeds of the same code are quiet, runs of other tracks or suites are refused."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from scipy import stats
from test_benchmarks_runner import _plan
from test_benchmarks_support import FakeStairs

from exobench.benchmarks.cli import main
from exobench.benchmarks.compare import ALL_GROUPS, RunData, compare_track, t_interval_paired
from exobench.benchmarks.registry import PipelineRegistry
from exobench.benchmarks.results import RESULTS_FILE, RUN_CONFIG_FILE, append_records, write_json_atomic
from exobench.benchmarks.runner import execute
from exobench.benchmarks.tracks import get_track


def _write_run(folder, values, *, track="stairs", suite="quick", seeds=(0,), pipeline="p", metric="riser_error_pct"):
    """A run folder whose records hold ``values`` (case name -> value of ``metric``), group "G"."""
    folder.mkdir()
    config = {"track": track, "suite": suite, "pipelines": [{"name": pipeline, "config": {}}], "seeds": list(seeds),
              "overrides": {}, "pipeline_overrides": {}, "episodes": []}  # fmt: skip
    write_json_atomic(folder / RUN_CONFIG_FILE, config)
    for seed in seeds:
        for case, v in values.items():
            value = v[seed] if isinstance(v, dict) else v
            append_records(folder / RESULTS_FILE, [{"track": track, "suite": suite, "episode": f"{case}/s{seed}", "case": case,
                                                    "group": "G", "run_seed": seed, "pipeline": pipeline,
                                                    "metrics": {metric: value, "failed": False}}])  # fmt: skip
    return folder


def _run(argv, capsys):
    with pytest.raises(SystemExit) as e:
        main(argv)
    out = capsys.readouterr()
    return e.value.code, out.out, out.err


def test_known_paired_differences_give_the_paired_t_interval(tmp_path, capsys):
    a = _write_run(tmp_path / "a", {"c1": 1.0, "c2": 2.0, "c3": 3.0, "c4": 4.0})
    b = _write_run(tmp_path / "b", {"c1": 2.0, "c2": 4.0, "c3": 6.0, "c4": 8.0})  # differences 1, 2, 3, 4
    code, out, err = _run(["compare", str(a), str(b), "--json"], capsys)
    comps = [json.loads(line) for line in out.splitlines()]
    g = next(c for c in comps if c["group"] == "G" and c["metric"] == "riser_error_pct")
    # mean 2.5, sd sqrt(5/3), t(0.975, 3) = 3.182446: 2.5 -+ 3.182446 * 1.290994 / 2
    assert g["diff"] == pytest.approx(2.5) and g["n_pairs"] == 4 and g["better"] == "lower"
    assert g["low"] == pytest.approx(0.445737, abs=1e-5) and g["high"] == pytest.approx(4.554263, abs=1e-5)
    assert g["mean_a"] == pytest.approx(2.5) and g["mean_b"] == pytest.approx(5.0)
    # significant at 95 %, but not at the 97.5 % the two comparisons with a value (G, (all)) ask
    # each (t(0.9875, 3) = 4.176535: 2.5 - 4.176535 * 1.290994 / 2 < 0): quiet, exit 0
    assert code == 0 and err == "" and {c["verdict"] for c in comps} == {""}


def test_a_clearly_worse_error_is_flagged_and_exits_1(tmp_path, capsys):
    a = _write_run(tmp_path / "a", {"c1": 1.0, "c2": 2.0, "c3": 3.0, "c4": 4.0})
    b = _write_run(tmp_path / "b", {"c1": 3.0, "c2": 4.2, "c3": 4.8, "c4": 6.0})  # differences 2, 2.2, 1.8, 2
    code, out, err = _run(["compare", str(a), str(b)], capsys)
    assert code == 1 and "2 headline comparisons worse beyond the threshold 0.05: stairs G p riser_error_pct" in err
    assert [line.split()[-1] for line in out.splitlines() if "riser" in line] == ["WORSE", "WORSE"]
    code, _, _ = _run(["compare", str(a), str(b), "--threshold", "0.9"], capsys)  # 2.0 is less than 90 % of A's 2.5
    assert code == 0


def test_a_higher_better_metric_that_rises_is_better_and_exits_0(tmp_path, capsys):
    a = _write_run(tmp_path / "a", {"c1": 0.5, "c2": 0.6, "c3": 0.7}, metric="assignment_accuracy")
    b = _write_run(tmp_path / "b", {"c1": 0.8, "c2": 0.91, "c3": 0.99}, metric="assignment_accuracy")
    code, out, _ = _run(["compare", str(a), str(b)], capsys)
    assert code == 0
    line = next(x for x in out.splitlines() if x.startswith("stairs") and " G " in x and "assignment" in x)
    assert line.rstrip().endswith("better")


def test_the_intervals_match_scipys_paired_and_welch_t_tests():
    rng = np.random.default_rng(1)
    x, y = rng.normal(1.0, 0.3, 7), rng.normal(1.2, 0.5, 7)
    mean, low, high = t_interval_paired(y - x)
    ci = stats.ttest_rel(y, x).confidence_interval(0.95)
    assert (low, high) == pytest.approx((ci.low, ci.high)) and mean == pytest.approx(float(np.mean(y - x)))
    track = get_track("stairs")
    # other seeds and a drawn suite whose cases differ: nothing pairs, Welch's interval
    ra = RunData(None, {"seeds": [0], "pipelines": [{"name": "p"}]}, [_rec(f"a{i}", 0, v) for i, v in enumerate(x)])
    rb = RunData(None, {"seeds": [1], "pipelines": [{"name": "p"}]}, [_rec(f"b{i}", 1, v) for i, v in enumerate(y)])
    c = next(c for c in compare_track(track, ra, rb) if c.group == "G" and c.metric == "riser_error_pct")
    ci = stats.ttest_ind(y, x, equal_var=False).confidence_interval(0.95)
    assert c.n_pairs == 0 and (c.n_a, c.n_b) == (7, 7)
    assert (c.low, c.high) == pytest.approx((ci.low, ci.high)) and c.diff == pytest.approx(y.mean() - x.mean())


def _rec(case, seed, value):
    return {"episode": f"{case}/s{seed}", "case": case, "group": "G", "run_seed": seed, "pipeline": "p",
            "metrics": {"riser_error_pct": value}}  # fmt: skip


def test_failed_records_are_left_out_and_one_pair_gives_no_interval(tmp_path):
    track = get_track("stairs")
    ra = RunData(None, {"seeds": [0], "pipelines": [{"name": "p"}]}, [_rec("c1", 0, 1.0), _rec("c2", 0, None)])
    rb = RunData(None, {"seeds": [0], "pipelines": [{"name": "p"}]}, [_rec("c1", 0, 9.0), _rec("c2", 0, 2.0)])
    c = next(c for c in compare_track(track, ra, rb) if c.group == ALL_GROUPS and c.metric == "riser_error_pct")
    assert c.n_pairs == 1 and c.diff == 8.0 and math.isnan(c.low) and c.verdict == ""


@pytest.fixture
def reg() -> PipelineRegistry:
    r = PipelineRegistry()
    r.register("fake", FakeStairs)
    return r


def test_a_planted_regression_is_flagged_and_two_seeds_of_the_same_code_are_quiet(reg, tmp_path, capsys):
    base = execute(_plan(reg, pipelines=["fake"], seeds=[0, 1, 2]), tmp_path / "base").out_dir
    other_seeds = execute(_plan(reg, pipelines=["fake"], seeds=[3, 4, 5]), tmp_path / "seeds").out_dir
    # the pipeline made worse: its S2 plane 3 cm off moves every touch-down prediction
    worse = execute(_plan(reg, pipelines=["fake"], seeds=[0, 1, 2], overrides={"fake.offset_m": 0.03}), tmp_path / "worse").out_dir

    code, out, err = _run(["compare", str(base), str(other_seeds), "--json"], capsys)
    verdicts = [json.loads(line)["verdict"] for line in out.splitlines()]
    assert code == 0 and err == "" and len(verdicts) > 8 and set(verdicts) == {""}, out

    code, out, err = _run(["compare", str(base), str(worse), "--json"], capsys)
    comps = [json.loads(line) for line in out.splitlines()]
    flagged = {(c["group"], c["metric"]) for c in comps if c["verdict"] == "worse"}
    assert code == 1 and (ALL_GROUPS, "touchdown_error_m") in flagged
    assert {m for _, m in flagged} == {"touchdown_error_m"}  # the riser and tread it does not touch stay quiet
    code, out, _ = _run(["compare", str(base), str(worse)], capsys)
    assert "stairs: fake.offset_m: 0.0 -> 0.03" in out and "WORSE" in out


def test_runs_of_other_suites_or_tracks_are_refused_in_one_line(tmp_path, capsys):
    a = _write_run(tmp_path / "a", {"c1": 1.0})
    for name, kw in (("suite", {"suite": "paper"}), ("track", {"track": "odometry", "metric": "ate_m"})):
        b = _write_run(tmp_path / name, {"c1": 1.0}, **kw)
        code, out, err = _run(["compare", str(a), str(b)], capsys)
        assert code == 2 and out == "" and len(err.strip().splitlines()) == 1 and err.startswith("exobench: error: RUN_B="), err
        assert ("'paper'" in err) if name == "suite" else ("odometry" in err)
    code, _, err = _run(["compare", str(a), str(tmp_path / "nothing-here")], capsys)
    assert code == 2 and err.startswith("exobench: error: RUN=")
