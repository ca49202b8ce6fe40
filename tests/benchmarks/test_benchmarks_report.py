"""Summary table, report.md with plots, and the rerun recording."""

from __future__ import annotations

import numpy as np
import pytest
from test_benchmarks_support import FakeStairs, FakeTrack, make_episode, serve_tracks

from exobench.benchmarks.registry import PipelineRegistry
from exobench.benchmarks.report import cell, format_text, reference_text, summary_rows, write_report
from exobench.benchmarks.runner import execute, plan_run
from exobench.benchmarks.tracks.spec import SummaryRow
from exobench.benchmarks.tracks.stairs.track import published_references


def test_cell_is_mean_and_sample_std_in_the_rows_unit():
    row = SummaryRow("d_m_S2", "d S2 (mm)", scale=1000, absolute=True)
    assert cell([0.001, -0.003, None, float("nan")], row) == "2.00 ± 1.41"
    assert cell([None], row) == "–"
    assert cell([0.0042], SummaryRow("x", "x", digits=1)) == "0.0"


def test_published_figures_are_attached_to_their_groups_and_pipelines():
    refs = published_references()
    assert "2.61 ± 1.83 (Tab. III)" == reference_text(refs, "riser_error_pct", "0.153/0.294", ["rtls"])
    assert "4.32" in reference_text(refs, "riser_error_pct", "0.162/0.280", ["rtls-htvr"])
    s2_a = reference_text(refs, "alpha_deg_S2", "A", ["rtls", "rtls-htvr"])
    assert "2.607 (Tab. I, rtls)" in s2_a and "< 3" in s2_a
    assert "< 3" not in reference_text(refs, "alpha_deg_S2", "C", ["rtls"])
    assert "427" in reference_text(refs, "time_per_point_us", "A", ["rtls-htvr"])
    assert "10" in reference_text(refs, "touchdown_error_m", "0.175/0.270", ["rtls"])


@pytest.fixture
def finished_run(tmp_path, monkeypatch):
    reg = PipelineRegistry()
    reg.register("fake", FakeStairs)
    # write_report looks the track up by name: serve the fake under "stairs"
    serve_tracks(monkeypatch, stairs=FakeTrack)
    plan = plan_run(FakeTrack(), "quick", ["fake"], [0, 1], registry=reg)
    out = execute(plan, tmp_path / "run")
    return plan, out


def test_summary_table_groups_cases_and_shows_the_paper(finished_run):
    plan, out = finished_run
    rows = summary_rows(out.records, plan.track, ["fake"], episode_order=[e.key for e in plan.episodes])
    assert rows[0] == ["group", "metric", "fake", "paper"]
    groups = [r[0] for r in rows[1:] if r[0]]
    assert groups == ["A", "B", "C", "0.162/0.280"]
    text = format_text(rows)
    assert "alpha S2 (deg)" in text and "Tab. III" in text and "0/2" in text


def test_report_writes_markdown_and_pngs(finished_run):
    _, out = finished_run
    path = write_report(out.out_dir)
    text = path.read_text()
    assert "| group | metric | fake | paper |" in text
    assert (out.out_dir / "errors.png").stat().st_size > 1000
    for case in "ABC":
        png = out.out_dir / "figures" / f"{case}__s0.png"
        assert png.stat().st_size > 1000 and f"figures/{png.name}" in text


def test_rerun_recording_is_written_and_readable(tmp_path):
    from exobench.benchmarks.tracks.stairs.recording import write_recording

    ep = make_episode()
    pipe = FakeStairs()
    pipe.reset(ep.calibration)
    for f in ep.frames:
        pipe.process(f)
    est = pipe.finalize()
    path = write_recording(ep, {"fake": est, "fake-online": [(0.8, est), (1.2, est)]}, tmp_path / "ep.rrd")
    assert path.stat().st_size > 0
    chunk = pytest.importorskip("rerun.chunk")
    reader = chunk.RrdReader(path)
    assert reader.recordings() and reader.blueprints()
    paths = {str(p) for c in reader.stream().to_chunks() for p in [c.entity_path]}
    assert any("world/surfaces/S2" in p for p in paths)
    assert any("world/estimates/fake/S2" in p for p in paths)
    assert any("world/tof/tof_r_lat/hits" in p for p in paths)
    assert np.isfinite(ep.truth.stairs.touchdown_w).all()
