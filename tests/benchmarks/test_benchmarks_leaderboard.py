"""`exobench leaderboard`: pipelines ranked as their headline metrics say (lower or higher is
better), beside the published figures, as markdown and a figure, with the runs' configs."""

from __future__ import annotations

import re

import pytest
from test_benchmarks_compare import _run

from exobench.benchmarks.results import RESULTS_FILE, RUN_CONFIG_FILE, append_records, write_json_atomic


def _run_folder(folder, values, *, versions=None):
    """A stairs/paper run whose pipelines (name -> {metric: [values per case]}) scored ``values``."""
    folder.mkdir()
    pipes = [{"name": p, "config": {"knob": i}} for i, p in enumerate(values)]
    write_json_atomic(folder / RUN_CONFIG_FILE, {"track": "stairs", "suite": "paper", "pipelines": pipes, "seeds": [0],
                                                 "versions": versions or {"exobench": "9.9"}})  # fmt: skip
    n = len(next(iter(next(iter(values.values())).values())))
    for i in range(n):
        recs = [{"episode": f"c{i}/s0", "case": f"c{i}", "group": "A", "run_seed": 0, "pipeline": p,
                 "metrics": {**{m: v[i] for m, v in metrics.items()}, "failed": any(v[i] is None for v in metrics.values())}}
                for p, metrics in values.items()]  # fmt: skip
        append_records(folder / RESULTS_FILE, recs)
    return folder


def _order(md, heading):
    """Pipeline names of the table under ``heading``, top to bottom."""
    block = md.split(heading, 1)[1].split("\n\n", 2)[1]
    return [line.split("|")[2].strip() for line in block.splitlines()[2:]]


def test_pipelines_are_ranked_as_their_metric_says_beside_the_published_figures(tmp_path, capsys):
    run = _run_folder(tmp_path / "run", {
        "rtls": {"riser_error_pct": [3.0, 5.0], "assignment_accuracy": [0.90, 0.92]},
        "ransac": {"riser_error_pct": [1.0, 2.0], "assignment_accuracy": [0.70, 0.75]},
        "bad": {"riser_error_pct": [9.0, None], "assignment_accuracy": [0.95, None]},
    })  # fmt: skip
    code, out, _ = _run(["leaderboard", str(run), "--out", str(tmp_path / "lb")], capsys)
    assert code in (0, None)
    md = (tmp_path / "lb" / "leaderboard.md").read_text()
    assert _order(md, "### riser error (%) (lower is better)") == ["ransac", "rtls", "bad"]  # 1.5 < 4.0 < 9.0
    assert _order(md, "### assignment accuracy (%) (higher is better)") == ["bad", "rtls", "ransac"]  # 95 > 91 > 72.5
    # mean ranks: ransac (1 + 3) / 2 = 2, rtls (2 + 2) / 2 = 2, bad (3 + 1) / 2 = 2: ties by name
    assert _order(md, "## stairs") == ["bad", "ransac", "rtls"]
    assert "| 1 | ransac | 1.50 ± 0.71 (n=2) |" in md and "| 3 | bad | 9.00 |" in md  # the failed episode has no value
    assert re.search(r"\| 1 \| bad \| 2\.00 \| 1/2 \|", md)
    assert "2.61 ± 1.83" in md  # the stairs paper's riser error, Tab. III, beside ours
    assert '"knob": 1' in md and '"exobench": "9.9"' in md and str(run) in md
    png = (tmp_path / "lb" / "leaderboard-stairs.png").read_bytes()
    assert png.startswith(b"\x89PNG") and len(png) > 5000
    assert md in out


def test_one_pipeline_in_two_runs_is_two_entries_told_apart_by_run(tmp_path, capsys):
    a = _run_folder(tmp_path / "a", {"rtls": {"riser_error_pct": [2.0]}})
    b = _run_folder(tmp_path / "b", {"rtls": {"riser_error_pct": [1.0]}})
    _run(["leaderboard", str(a), str(b), "--out", str(tmp_path / "lb")], capsys)
    md = (tmp_path / "lb" / "leaderboard.md").read_text()
    assert _order(md, "### riser error (%) (lower is better)") == [f"rtls ({b})", f"rtls ({a})"]


def test_a_folder_that_is_not_a_run_is_refused_in_one_line(tmp_path, capsys):
    code, out, err = _run(["leaderboard", str(tmp_path), "--out", str(tmp_path / "lb")], capsys)
    assert code == 2 and len(err.strip().splitlines()) == 1 and err.startswith("exobench: error: RUN=")
    assert not (tmp_path / "lb").exists()


@pytest.mark.parametrize("better", ["higher", "lower"])
def test_ranking_follows_the_rows_direction(better):
    from exobench.benchmarks.leaderboard import Entry, ranking
    from exobench.benchmarks.tracks.spec import SummaryRow

    row = SummaryRow("m", "m", better=better)
    es = [Entry("t", p, "r", {}, {}, {"m": v}, label=p) for p, v in (("a", [1.0]), ("b", [3.0]), ("c", [2.0]), ("d", []))]
    got = [(rank, e.label) for rank, e in ranking(es, row)]
    assert got == ([(1, "b"), (2, "c"), (3, "a"), (0, "d")] if better == "higher" else [(1, "a"), (2, "c"), (3, "b"), (0, "d")])
