"""`exobench bench` refuses what it cannot time with one line and exit 2: a session of another
track, an old session without a track in which the RTLS pipeline finds nothing, --session given
to a bench that takes none."""

from __future__ import annotations

import json

import pytest
from click.testing import CliRunner

from exobench.benchmarks.cli import cli

pytestmark = pytest.mark.long(seconds=7)  # the workers take it first (tests/conftest.py); 7: the file at -n 0 in one run at load 12-15, scaled to that run's CPU


@pytest.fixture(scope="module")
def lidar_session(tmp_path_factory):
    path = tmp_path_factory.mktemp("bench") / "office"
    r = CliRunner().invoke(cli, ["record", str(path), "--track", "lidar-filter", "--set", "max_distance_m=1.5"])
    assert r.exit_code == 0, r.output
    return path


def assert_one_error_line(r, *needles):
    assert r.exit_code == 2, (r.exit_code, r.output)
    err = r.stderr.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("exobench: error: "), r.stderr
    assert r.stdout == ""  # no table of zeros
    for needle in needles:
        assert needle in err[0], (needle, err[0])


def test_bench_rtls_on_a_session_of_another_track(lidar_session):
    assert_one_error_line(CliRunner().invoke(cli, ["bench", "rtls", "--session", str(lidar_session)]), "--session", "'lidar-filter'")
    assert_one_error_line(CliRunner().invoke(cli, ["bench", "rtls", "--json", "--session", str(lidar_session)]), "'lidar-filter'")


def test_bench_rtls_on_an_old_session_without_a_track_and_no_surfaces(lidar_session, tmp_path):
    import shutil

    path = tmp_path / "old"
    shutil.copytree(lidar_session, path)
    meta = json.loads((path / "meta.json").read_text())
    for key in ("track", "files", "truth_counts"):
        meta.pop(key)
    (path / "meta.json").write_text(json.dumps({**meta, "version": 3}))
    assert_one_error_line(CliRunner().invoke(cli, ["bench", "rtls", "--session", str(path)]), "--session", "assigned no points")


@pytest.mark.parametrize("what", ["sim", "lidar", "locomotion"])
def test_session_is_for_bench_rtls_only(lidar_session, what):
    assert_one_error_line(CliRunner().invoke(cli, ["bench", what, "--session", str(lidar_session)]), "--session", "bench rtls only")
