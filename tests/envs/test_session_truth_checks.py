"""A session's frames are checked against the truth they are scored with, whatever format
``meta.json`` claims: a halved truth is refused with one line naming the file even when
``meta.json`` has no hashes (an old format) or its counts and hashes were forged with it; hashes
are checked whenever they are listed; an untouched session of any format is scored as before."""

from __future__ import annotations

import dataclasses
import hashlib
import json
import shutil

import numpy as np
import pytest
from click.testing import CliRunner

from exobench.benchmarks.cli import cli
from exobench.benchmarks.tracks import get_track
from exobench.core import SessionError
from exobench.envs.session import read_session, write_session
from exobench.envs.session.checks import check_truth_matches_frames

pytestmark = pytest.mark.long(seconds=16)  # the workers take it first (tests/conftest.py); 16: the file at -n 0 in one run at load 12-15, scaled to that run's CPU


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    path = tmp_path_factory.mktemp("rec") / "stairs"
    r = CliRunner().invoke(cli, ["record", str(path)])
    assert r.exit_code == 0, r.output
    return path


@pytest.fixture
def session(recorded, tmp_path):
    path = tmp_path / "s"
    shutil.copytree(recorded, path)
    return path


def _meta(path):
    return json.loads((path / "meta.json").read_text())


def _write_meta(path, meta):
    (path / "meta.json").write_text(json.dumps(meta))


def _old_format(path, version=3):
    """meta.json as an older format writes it: no file list, no truth counts, no track."""
    meta = _meta(path)
    for key in ("files", "truth_counts", "track"):
        meta.pop(key, None)
    _write_meta(path, {**meta, "version": version})


def _rehash(path):
    meta = _meta(path)
    meta["files"] = {rel: {"bytes": (path / rel).stat().st_size, "sha256": hashlib.sha256((path / rel).read_bytes()).hexdigest()}
                     for rel in meta["files"] if (path / rel).exists()}  # fmt: skip
    _write_meta(path, meta)


def _halve_lines(f):
    lines = f.read_text().splitlines(keepends=True)
    f.write_text("".join(lines[: len(lines) // 2]))
    return len(lines) // 2


def _replay(path):
    return CliRunner().invoke(cli, ["replay", str(path), "--track", "stairs", "--pipeline", "batch-ransac", "--json"])


def assert_refused(r, *needles):
    assert r.exit_code == 2, (r.exit_code, r.output)
    err = r.stderr.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("exobench: error: "), r.stderr
    for needle in needles:
        assert needle in err[0], (needle, err[0])


def _metrics(r):
    assert r.exit_code == 0, (r.output, r.exception)
    return json.loads(r.stdout.splitlines()[0])["metrics"]


def test_an_old_format_with_its_truth_halved_is_refused_naming_the_truth_file(session):
    _old_format(session)
    _halve_lines(session / "truth" / "tof.jsonl")
    assert_refused(_replay(session), "truth/tof.jsonl", "ToF reading")


def test_a_halved_truth_with_its_counts_and_hashes_forged_is_refused(session):
    kept = _halve_lines(session / "truth" / "tof.jsonl")
    meta = _meta(session)
    meta["truth_counts"]["tof"] = kept
    _write_meta(session, meta)
    _rehash(session)
    assert_refused(_replay(session), "truth/tof.jsonl")


def test_an_old_format_whose_counts_agree_is_scored_as_the_hashed_session(session, tmp_path):
    want = _metrics(_replay(session))
    _old_format(session)
    r = _replay(session)
    assert "no file hashes" in r.stderr
    got = _metrics(r)
    assert want["assignment_accuracy"] > 0.9
    assert {k: v for k, v in got.items() if k != "time_per_point_us"} == {k: v for k, v in want.items() if k != "time_per_point_us"}


def test_an_old_format_listing_hashes_has_them_checked(session):
    meta = _meta(session)
    _write_meta(session, {**meta, "version": 3})
    f = session / "frames.jsonl"
    f.write_text(f.read_text().replace('"range_m":0.5', '"range_m":0.9', 1))  # same counts, one value changed
    assert_refused(_replay(session), "frames.jsonl", "content differs")


@pytest.mark.parametrize("how", ["edited-and-unlisted", "empty-list"])
def test_a_file_taken_off_the_hash_list_is_refused(session, how):
    f = session / "truth" / "tof.jsonl"
    f.write_text(f.read_text().replace('"true_range_m":0.', '"true_range_m":1.', 1))  # a value edit, counts kept
    meta = _meta(session)
    if how == "empty-list":
        meta["files"] = {}
    else:
        del meta["files"]["truth/tof.jsonl"]
    _write_meta(session, meta)
    assert_refused(_replay(session), "calibration.json" if how == "empty-list" else "tof.jsonl", "not listed")  # the first unlisted


@pytest.mark.parametrize("version", [4, 5])
def test_a_format_with_hashes_but_no_file_list_is_refused(session, version):
    meta = _meta(session)
    meta.pop("files")
    _write_meta(session, {**meta, "version": version})
    assert_refused(_replay(session), "meta.json", "'files'")


# --- LiDAR scans and the trajectory (office walks), RGB-D segmentation and odometry (course walks)

FAULTS = {"lidar_scan_dropout": 0.3, "lidar_duplicate_scans": 0.3, "lidar_out_of_order": 0.3, "lidar_time_jump_prob": 0.2,
          "lidar_nan_points": 0.1, "lidar_point_dropout": 0.1}  # fmt: skip


@pytest.fixture(scope="module")
def office(tmp_path_factory):
    """An office walk with every LiDAR delivery fault, as format 4 (one truth file per scan)."""
    trk = get_track("odometry")
    ep = trk.simulate(trk.validate_scenario({**trk.smoke_scenario, **FAULTS}), 3)
    path = write_session(ep, tmp_path_factory.mktemp("office") / "s", track="odometry", compact=False)
    return ep, path


@pytest.mark.parametrize("compact", [False, True], ids=["format4", "format5"])
def test_an_untouched_session_with_every_lidar_fault_reads_back(office, tmp_path, compact):
    ep = office[0]
    scans = [f for f in ep.frames if type(f).__name__ == "LidarScan"]
    assert len({f.stamp_s for f in scans}) < len(scans)  # duplicated sweeps are in it
    back = read_session(write_session(ep, tmp_path / "s", track="odometry", compact=compact), track="odometry")
    assert len(back.truth.lidar) == len(scans) and len(back.truth.trajectory_w) == len(ep.truth.trajectory_w)


def test_an_old_format_with_lidar_truths_cut_is_refused(office, tmp_path):
    path = tmp_path / "s"
    shutil.copytree(office[1], path)
    _old_format(path)
    ep_json = json.loads((path / "truth" / "episode.json").read_text())
    n = ep_json["n_lidar"]
    for k in range(n // 2, n):
        (path / "truth" / "lidar" / f"{k:06d}.npz").unlink()
    (path / "truth" / "episode.json").write_text(json.dumps({**ep_json, "n_lidar": n // 2}))
    with pytest.raises(SessionError, match=r"truth/lidar: \d+ truths for \d+ LiDAR scans"):
        read_session(path)


def test_an_old_format_with_its_trajectory_halved_is_refused(office, tmp_path):
    path = tmp_path / "s"
    shutil.copytree(office[1], path)
    _old_format(path)
    ep_json = json.loads((path / "truth" / "episode.json").read_text())
    ep_json["trajectory_w"] = ep_json["trajectory_w"][: len(ep_json["trajectory_w"]) // 2]
    (path / "truth" / "episode.json").write_text(json.dumps(ep_json))
    with pytest.raises(SessionError, match=r"episode.json: trajectory_w has \d+ poses for \d+ sweeps of lidar_trunk"):
        read_session(path)


def test_a_lidar_truth_of_another_scan_is_refused(office, tmp_path):
    ep = office[0]
    lidar = list(ep.truth.lidar)
    lidar[1], lidar[2] = lidar[2], lidar[1]
    with pytest.raises(SessionError, match="truth 1 is of"):
        check_truth_matches_frames(tmp_path, ep.frames, dataclasses.replace(ep.truth, lidar=tuple(lidar)), ep.scenario)


@pytest.fixture(scope="module")
def course():
    trk = get_track("locomotion")
    sc = trk.validate_scenario({**trk.smoke_scenario, "duration_cap_s": 2.5, "segmentation_truth": True, "frame_dropout": 0.3})
    return trk.simulate(sc, 0)


def test_course_truths_follow_their_frames(course, tmp_path):
    ep = course
    check_truth_matches_frames(tmp_path, ep.frames, ep.truth, ep.scenario)  # untouched: accepted
    seg = ep.truth.segmentation
    assert len(seg) > 2
    with pytest.raises(SessionError, match=r"truth/segmentation: \d+ truths for \d+ RGB-D frames"):
        check_truth_matches_frames(tmp_path, ep.frames, dataclasses.replace(ep.truth, segmentation=seg[:-1]), ep.scenario)
    with pytest.raises(SessionError, match=r"truth/segmentation: 0 truths"):  # all removed, the scenario asked for them
        check_truth_matches_frames(tmp_path, ep.frames, dataclasses.replace(ep.truth, segmentation=()), ep.scenario)
    half = np.asarray(ep.truth.trajectory_w)[: len(ep.truth.trajectory_w) // 2]
    with pytest.raises(SessionError, match="trajectory_w has"):
        check_truth_matches_frames(tmp_path, ep.frames, dataclasses.replace(ep.truth, trajectory_w=half), ep.scenario)


def test_readings_delivered_twice_share_their_truth(session):
    """A duplicated delivery (same sensor, same stamp) is a fault of the stream, not of the
    truth: the session reads, every reading still with its truth."""
    _old_format(session)
    f = session / "frames.jsonl"
    lines = f.read_text().splitlines(keepends=True)
    doubled = [x for line in lines for x in ([line, line] if '"sensor_id":"tof_r_' in line else [line])]
    f.write_text("".join(doubled))
    meta = _meta(session)
    meta["frame_counts"]["tof"] += len(doubled) - len(lines)
    _write_meta(session, meta)
    ep = read_session(session)
    tof = [fr for fr in ep.frames if type(fr).__name__ == "ToFReading"]
    assert len(tof) == len(ep.truth.stairs.tof) + (len(doubled) - len(lines)) and len(doubled) > len(lines)
