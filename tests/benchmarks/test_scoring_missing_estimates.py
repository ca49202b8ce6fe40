"""No scorer takes a missing estimate for a perfect one: no masks, masks for other scans, no
keyframes are failed records with a reason and NaN metrics; masks match scans by stamp; the
lidar-filter report reads such records."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
from click.testing import CliRunner

from exobench.benchmarks.cli import cli
from exobench.benchmarks.results import read_records
from exobench.benchmarks.tracks.lidar_filter.metrics import score_filter
from exobench.benchmarks.tracks.lidar_filter.report import filter_table
from exobench.benchmarks.tracks.loop_closure.metrics import score_place_recognition
from exobench.core import LidarScan, ReturnKind
from exobench.core.estimates import FilterEstimate, PlaceRecognitionEstimate


def _scan(t: float, n: int, sid: str = "lidar_trunk") -> LidarScan:
    z = np.zeros(n)
    return LidarScan(t, sid, np.ones((n, 3)), z.astype(np.uint8), z.astype(np.uint16), z, t - 0.1)


def _truth(t: float, kinds: list[int], sid: str = "lidar_trunk") -> SimpleNamespace:
    n = len(kinds)
    return SimpleNamespace(stamp_s=t, sensor_id=sid, kind=np.array(kinds, dtype=np.int8), surface_id=np.full(n, -1))


G, GL, GH = int(ReturnKind.GENUINE), int(ReturnKind.GLASS), int(ReturnKind.GHOST)


def _episode(dropped_truth: bool = False) -> SimpleNamespace:
    """Three scans; the middle one has no point truth when ``dropped_truth`` (a dropped scan)."""
    kinds = {0.1: [G, GL, GH], 0.2: [G, G], 0.3: [GH, G, G, GL]}
    frames = [_scan(t, len(k)) for t, k in kinds.items()]
    truths = [_truth(t, k) for t, k in kinds.items() if not (dropped_truth and t == 0.2)]
    return SimpleNamespace(frames=frames, truth=SimpleNamespace(lidar=truths, scene=SimpleNamespace(surfaces=()), lidar_scans=None))


def _est(stamps, keep) -> FilterEstimate:
    return FilterEstimate(np.asarray(stamps, dtype=float), tuple(np.asarray(k, dtype=bool) for k in keep), np.full(len(stamps), 1e-3))


def test_no_masks_is_a_failure_not_every_spurious_point_removed():
    m = score_filter(_episode(), _est([], []))
    assert m["failed"] is True and "3 of 3 scans" in m["failed_reason"]
    assert math.isnan(m["spurious_removed_frac"]) and math.isnan(m["ground_kept_frac"]) and m["bad_masks"] == 3


def test_masks_for_other_stamps_are_a_failure():
    m = score_filter(_episode(), _est([5.0, 5.1, 5.2], [[1, 1, 1], [1, 1], [1, 1, 1, 1]]))
    assert m["failed"] is True and math.isnan(m["spurious_removed_frac"])


def test_masks_match_scans_by_stamp_not_position():
    # the filter saw all three scans; the middle one has no truth (dropped): its mask must not
    # shift onto the third scan
    est = _est([0.1, 0.2, 0.3], [[1, 0, 0], [1, 1], [0, 1, 1, 0]])
    m = score_filter(_episode(dropped_truth=True), est)
    assert m["failed"] is False, m["failed_reason"]
    assert m["spurious_removed_frac"] == 1.0 and m["genuine_kept_frac"] == 1.0 and m["bad_masks"] == 0
    assert "1 masks match no scan" in m["failed_reason"]
    # a scan the filter never saw (dropped before the filter) leaves the others matched
    est2 = _est([0.1, 0.3], [[1, 0, 0], [0, 1, 1, 0]])
    m2 = score_filter(_episode(dropped_truth=True), est2)
    assert m2["failed"] is False and m2["spurious_removed_frac"] == 1.0


def test_no_keyframes_is_a_failure():
    e = np.zeros(0)
    est = PlaceRecognitionEstimate(e, e.astype(int), e, e, e)
    ep = SimpleNamespace(scenario={}, truth=SimpleNamespace(trajectory_w=np.zeros((0, 8))))
    m = score_place_recognition(ep, est)
    assert m["failed"] is True and m["failed_reason"] == "no keyframes"


def test_filter_report_reads_failed_and_null_records():
    nan_rec = {"pipeline": "filter-none", "metrics": {"failed": False, "time_per_scan_ms": None, "spurious_removed_frac": None}}
    failed = {"pipeline": "filter-none", "metrics": {"failed": True, "failed_reason": "x", "time_per_scan_ms": None}}
    lines = filter_table([nan_rec, failed], ["filter-none"])
    assert any(line.startswith("| filter-none |") for line in lines)


def test_a_filter_for_a_sensor_that_does_not_exist_fails_in_the_run(tmp_path):
    out = tmp_path / "run"
    args = ["run", "--track", "lidar-filter", "--pipeline", "filter-none", "--set", "filter-none.lidar_id=nope",
            "--set", "max_distance_m=1.5", "--out", str(out)]  # fmt: skip
    r = CliRunner().invoke(cli, args)
    assert r.exception is None or isinstance(r.exception, SystemExit), r.output
    (rec,) = read_records(out / "results.jsonl")
    assert rec["metrics"]["failed"] is True and "no mask" in rec["metrics"]["failed_reason"]
    assert rec["metrics"]["spurious_removed_frac"] is None
    assert (out / "report.md").exists()
