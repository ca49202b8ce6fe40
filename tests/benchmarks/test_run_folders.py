"""Run folders (issue 24, 2): one writer per folder, resume of every kind of run with the command
the CLI prints, damaged folders, a full disk, and paths that cannot be written: one line, exit 2,
before anything runs, nothing half-written, what finished kept.

The tests run as root, whom permissions do not stop: a folder that cannot be written is made by
refusing the kernel call (``os.open``, see ``refuse_writes_in``), a full disk by making the write
raise ENOSPC; symbolic links and over-long names are real.
"""

from __future__ import annotations

import errno
import json
import os
import shlex
import subprocess
import sys
from pathlib import Path
from typing import ClassVar

import numpy as np
import pytest
from click.testing import CliRunner
from test_benchmarks_support import FakeStairs, FakeTrack, serve_tracks
from test_cli import refuse_writes_in

from exobench.benchmarks import registry as registry_mod
from exobench.benchmarks.cli import cli
from exobench.benchmarks.out_paths import LOCK_FILE, exclusive_lock
from exobench.benchmarks.report import summary_rows
from exobench.benchmarks.results import RESULTS_FILE, RUN_CONFIG_FILE, read_records
from exobench.benchmarks.runner import untimed_metrics
from exobench.core.errors import FolderError

pytestmark = pytest.mark.long(seconds=6)  # the workers take it first (tests/conftest.py); 6: the file at -n 0 in one run at load 12-15, scaled to that run's CPU


class FakeTrack2(FakeTrack):
    """A second track, so that a run of every track has two."""

    name: ClassVar[str] = "stairs2"


class FakeStairs2(FakeStairs):
    name: ClassVar[str] = "fake2"
    track: ClassVar[str] = "stairs2"


@pytest.fixture
def tracks(monkeypatch):
    """Two fake tracks ("stairs", "stairs2"), each with its fake pipeline; no MuJoCo."""
    _serve(monkeypatch)


def _serve(monkeypatch):
    serve_tracks(monkeypatch, stairs=FakeTrack, stairs2=FakeTrack2)
    reg = registry_mod.PipelineRegistry()
    reg.register("fake", FakeStairs)
    reg.register("fake2", FakeStairs2)
    monkeypatch.setattr(registry_mod, "default_registry", lambda: reg)
    monkeypatch.setattr("exobench.benchmarks.runner.default_registry", lambda: reg)


def _run(args):
    return CliRunner().invoke(cli, [str(a) for a in args], catch_exceptions=False)


def _one_error_line(result) -> str:
    """The one line exobench printed on stderr (beside the progress bar, if a run had started)."""
    lines = [ln for ln in result.stderr.splitlines() if ln.strip() and not ln.startswith("stairs")]
    assert len(lines) == 1, result.stderr
    assert lines[0].startswith("exobench: error: ") and len(lines[0]) < 400, lines[0]
    return lines[0]


def _lines(path: Path) -> list[dict]:
    return [json.loads(line) for line in path.read_text().splitlines()]


def _comparable(folder: Path) -> list[tuple]:
    """The records of a run folder without their timings, one per (episode, pipeline), sorted."""
    out = []
    for r in _lines(folder / RESULTS_FILE):
        metrics = untimed_metrics(FakeTrack(), r["metrics"])
        out.append((r["track"], r["episode"], r["pipeline"], r["seed"], json.dumps(r["scenario"], sort_keys=True),
                    json.dumps(r["config"], sort_keys=True), json.dumps(metrics, sort_keys=True)))  # fmt: skip
    assert len(out) == len({(t[1], t[2]) for t in out}), "an episode stored twice"
    return sorted(out)


def _interrupt_after(monkeypatch, n_episodes: int) -> None:
    """Ctrl-C while the episode after the first ``n_episodes`` runs (every fake pipeline counts)."""
    calls = {"n": 0}
    real = FakeStairs.finalize

    def finalize(self):
        calls["n"] += 1
        if calls["n"] > n_episodes:
            raise KeyboardInterrupt
        return real(self)

    monkeypatch.setattr(FakeStairs, "finalize", finalize)


def _printed_command(stderr: str, marker: str = "continue: ") -> list[str]:
    line = next(ln for ln in stderr.splitlines() if marker in ln)
    words = shlex.split(line.split(marker, 1)[1].rsplit(")", 1)[0])
    assert words[:2] == ["exobench", "run"], line
    return words[1:]


# ---------------------------------------------------------------- done when: interrupt, resume as printed


def test_every_track_interrupted_and_resumed_as_printed_gives_the_records_of_an_uninterrupted_run(tmp_path, tracks, monkeypatch):
    whole = tmp_path / "whole"
    assert _run(["run", "--seeds", "2", "--out", whole, "--no-report"]).exit_code == 0
    for n in (3, 15):  # stopped in the first track, then in the second (the first finished)
        part = tmp_path / f"part {n}"  # a space: the printed command quotes it
        with monkeypatch.context() as m:
            _interrupt_after(m, n)
            stopped = _run(["run", "--seeds", "2", "--out", part, "--no-report"])
        assert stopped.exit_code == 130, stopped.stderr
        command = _printed_command(stopped.stderr)
        assert command == ["run", "--resume", "--out", str(part), "--no-report"]  # the settings are in the folder
        resumed = _run(command)
        assert resumed.exit_code == 0, resumed.stderr
        for name in ("stairs", "stairs2"):
            assert _comparable(part / name) == _comparable(whole / name)
            assert len(_comparable(whole / name)) == 12


def test_one_track_with_every_setting_resumed_as_printed_gives_the_same_records(tmp_path, tracks, monkeypatch):
    args = ["run", "quick", "--track", "stairs", "--pipeline", "fake", "--seeds", "2", "--set", "riser_m=0.17",
            "--set", "fake.offset_m=0.002", "--no-report"]  # fmt: skip
    assert _run([*args, "--out", tmp_path / "whole"]).exit_code == 0
    with monkeypatch.context() as m:
        _interrupt_after(m, 5)
        stopped = _run([*args, "--out", tmp_path / "part", "--jobs", "1"])
    assert stopped.exit_code == 130
    resumed = _run(_printed_command(stopped.stderr))
    assert resumed.exit_code == 0 and "5 finished episodes kept" in resumed.stderr, resumed.stderr
    assert _comparable(tmp_path / "part") == _comparable(tmp_path / "whole")
    assert {r[4] for r in _comparable(tmp_path / "part")} == {r[4] for r in _comparable(tmp_path / "whole")}
    assert all(json.loads(r[4])["riser_m"] == 0.17 for r in _comparable(tmp_path / "part"))


def test_resume_refuses_settings_that_differ_from_the_folders(tmp_path, tracks):
    out = tmp_path / "run"
    assert _run(["run", "--track", "stairs", "--seeds", "2", "--out", out, "--no-report"]).exit_code == 0
    for args, field in ((["--seeds", "3"], "seeds"), (["--track", "stairs2"], "track"), (["--track", "all"], "track"),
                        (["--set", "riser_m=0.2"], "overrides")):  # fmt: skip
        result = _run(["run", "--resume", "--out", out, *args])
        assert result.exit_code == 2 and field in _one_error_line(result)
    assert len(_lines(out / RESULTS_FILE)) == 12


def test_a_full_folder_refusal_hint_works_as_printed(tmp_path, tracks):
    for args in (["--track", "stairs"], []):  # one track, every track
        out = tmp_path / f"run{len(args)}"
        first = _run(["run", *args, "--out", out, "--no-report"])
        assert first.exit_code == 0
        again = _run(["run", *args, "--out", out, "--no-report"])
        assert again.exit_code == 2 and "or --resume to continue the run in it" in _one_error_line(again)
        resumed = _run(["run", *args, "--out", out, "--no-report", "--resume"])
        assert resumed.exit_code == 0 and "6 finished episodes kept" in resumed.stderr


def test_a_run_of_every_track_is_continued_from_its_track_folders_without_run_all(tmp_path, tracks, monkeypatch):
    """A folder written before run_all.json existed: the command line's settings apply."""
    with monkeypatch.context() as m:
        _interrupt_after(m, 8)
        assert _run(["run", "--out", tmp_path / "old", "--no-report"]).exit_code == 130
    (tmp_path / "old" / "run_all.json").unlink()
    resumed = _run(["run", "--resume", "--out", tmp_path / "old", "--no-report"])
    assert resumed.exit_code == 0, resumed.stderr
    assert len(_comparable(tmp_path / "old" / "stairs")) == len(_comparable(tmp_path / "old" / "stairs2")) == 6


def test_report_of_a_run_of_every_track_reports_each_track(tmp_path, tracks):
    out = tmp_path / "all"
    assert _run(["run", "--out", out, "--no-report"]).exit_code == 0
    result = _run(["report", out])
    assert result.exit_code == 0, result.stderr
    assert (out / "stairs" / "report.md").exists() and (out / "stairs2" / "report.md").exists()


# ---------------------------------------------------------------- one writer, counted once


def test_a_second_writer_is_refused_while_a_run_writes_the_folder(tmp_path, tracks, monkeypatch):
    out = tmp_path / "run"
    assert _run(["run", "--track", "stairs", "--out", out, "--no-report"]).exit_code == 0
    (out / RESULTS_FILE).write_text("".join((out / RESULTS_FILE).read_text().splitlines(keepends=True)[:2]))
    seconds = []
    real = FakeStairs.finalize

    def finalize(self):  # while the first resume runs, a second one starts on the same folder
        if not seconds:
            seconds.append(_run(["run", "--resume", "--out", out, "--no-report"]))
        return real(self)

    monkeypatch.setattr(FakeStairs, "finalize", finalize)
    first = _run(["run", "--resume", "--out", out, "--no-report"])
    assert first.exit_code == 0, first.stderr
    assert seconds[0].exit_code == 2 and "in use by another exobench run" in _one_error_line(seconds[0])
    keys = [(r["episode"], r["pipeline"]) for r in _lines(out / RESULTS_FILE)]
    assert len(keys) == len(set(keys)) == 6


def test_every_track_run_holds_its_top_folder_too(tmp_path, tracks, monkeypatch):
    out = tmp_path / "all"
    seconds = []
    real = FakeStairs.finalize

    def finalize(self):
        if not seconds:
            seconds.append(_run(["run", "--resume", "--out", out, "--no-report"]))
        return real(self)

    monkeypatch.setattr(FakeStairs, "finalize", finalize)
    assert _run(["run", "--out", out, "--no-report"]).exit_code == 0
    assert seconds[0].exit_code == 2 and str(out) in _one_error_line(seconds[0])


def test_a_killed_writer_leaves_no_stale_lock(tmp_path):
    holder = ("import sys, time\nfrom exobench.benchmarks.out_paths import exclusive_lock\n"
              "with exclusive_lock(sys.argv[1]):\n    print('locked', flush=True)\n    time.sleep(60)\n")  # fmt: skip
    env = dict(os.environ, PYTHONPATH=str(Path(__file__).resolve().parents[3]))
    proc = subprocess.Popen([sys.executable, "-c", holder, str(tmp_path)], stdout=subprocess.PIPE, env=env, text=True)
    try:
        assert proc.stdout.readline().strip() == "locked"
        with pytest.raises(FolderError, match="in use"), exclusive_lock(tmp_path):
            pass
    finally:
        proc.kill()
        proc.wait()
    with exclusive_lock(tmp_path):  # the kernel released it with the process
        assert (tmp_path / LOCK_FILE).exists()


def test_an_episode_stored_twice_is_read_and_reported_once(tmp_path, tracks, capsys):
    out = tmp_path / "run"
    assert _run(["run", "--track", "stairs", "--pipeline", "fake", "--out", out, "--no-report"]).exit_code == 0
    lines = (out / RESULTS_FILE).read_text().splitlines(keepends=True)
    again = json.loads(lines[1])
    again["metrics"]["failed"] = True  # a second writer's copy of episode 2 that failed
    (out / RESULTS_FILE).write_text("".join(lines) + json.dumps(again) + "\n")
    records = read_records(out / RESULTS_FILE)
    assert len(records) == 6 and sum(r["episode"] == again["episode"] for r in records) == 1
    assert not any(r["metrics"]["failed"] for r in records)  # the first copy is kept
    assert "stored again" in capsys.readouterr().err
    rows = summary_rows(records, FakeTrack(), ["fake"])
    assert sorted(r[2] for r in rows if r[1] == "failed / episodes") == ["0/1", "0/1", "0/1", "0/3"]
    report = _run(["report", out])
    assert report.exit_code == 0 and "1/" not in "".join(ln for ln in report.output.splitlines() if "failed" in ln)
    resumed = _run(["run", "--resume", "--out", out, "--no-report"])
    assert resumed.exit_code == 0 and "6 finished episodes kept" in resumed.stderr


# ---------------------------------------------------------------- damaged folders


def _damage_config(out: Path, text: str) -> None:
    (out / RUN_CONFIG_FILE).write_text(text)


def _drop(field):
    def damage(out: Path) -> None:
        config = json.loads((out / RUN_CONFIG_FILE).read_text())
        del config[field]
        _damage_config(out, json.dumps(config))

    return damage


def _results_a_folder(out: Path) -> None:
    (out / RESULTS_FILE).unlink()
    (out / RESULTS_FILE).mkdir()


@pytest.mark.parametrize(
    ("damage", "named"),
    [
        (lambda out: _damage_config(out, '{"track": "stairs", '), RUN_CONFIG_FILE),
        (lambda out: _damage_config(out, "[1, 2]"), RUN_CONFIG_FILE),
        (lambda out: _damage_config(out, "\xff\xfe"), RUN_CONFIG_FILE),
        (_drop("track"), RUN_CONFIG_FILE),
        (_drop("pipelines"), RUN_CONFIG_FILE),
        (_drop("seeds"), RUN_CONFIG_FILE),
        (_results_a_folder, RESULTS_FILE),
    ],
)
@pytest.mark.parametrize("command", ["report", "resume"])
def test_a_damaged_run_folder_is_one_line_naming_the_file(tmp_path, tracks, monkeypatch, damage, named, command):
    out = tmp_path / "run"
    assert _run(["run", "--track", "stairs", "--out", out, "--no-report"]).exit_code == 0
    (out / RESULTS_FILE).write_text("".join((out / RESULTS_FILE).read_text().splitlines(keepends=True)[:4]))
    damage(out)
    monkeypatch.setattr(FakeTrack, "simulate", lambda *a: pytest.fail("ran an episode in a damaged folder"))
    result = _run(["report", out] if command == "report" else ["run", "--resume", "--out", out])
    assert result.exit_code == 2, result.output + result.stderr
    assert str(out / named) in _one_error_line(result)
    assert not (out / "report.md").exists()


# ---------------------------------------------------------------- full disk


def _full_disk_after(monkeypatch, n_ok: int, path_part: str = RESULTS_FILE) -> None:
    """Writes to files named ``path_part`` succeed ``n_ok`` times, then write half and fail with ENOSPC."""
    real_write, real_open = os.write, os.open
    state = {"ok": n_ok, "fds": set()}

    def fake_open(path, flags, *a, **kw):
        fd = real_open(path, flags, *a, **kw)
        if Path(os.fsdecode(path)).name == path_part:
            state["fds"].add(fd)
        return fd

    def fake_write(fd, data):
        if fd in state["fds"]:
            if state["ok"] <= 0:
                real_write(fd, bytes(data[: len(data) // 2]))
                raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
            state["ok"] -= 1
        return real_write(fd, data)

    monkeypatch.setattr(os, "open", fake_open)
    monkeypatch.setattr(os, "write", fake_write)


def test_a_full_disk_stops_the_run_with_one_line_and_keeps_whole_episodes(tmp_path, tracks, monkeypatch):
    args = ["run", "--track", "stairs", "--seeds", "2", "--no-report"]
    assert _run([*args, "--out", tmp_path / "whole"]).exit_code == 0
    part = tmp_path / "part"
    with monkeypatch.context() as m:
        _full_disk_after(m, 3)
        full = _run([*args, "--out", part])
    assert full.exit_code == 2
    line = _one_error_line(full)
    assert "No space left on device" in line and str(part / RESULTS_FILE) in line
    text = (part / RESULTS_FILE).read_text()
    assert text.endswith("\n") and len(text.splitlines()) == 3 == len(read_records(part / RESULTS_FILE))
    resumed = _run(_printed_command(full.stderr))  # once there is space again
    assert resumed.exit_code == 0, resumed.stderr
    assert _comparable(part) == _comparable(tmp_path / "whole")


def test_a_figure_that_cannot_be_saved_costs_only_itself(tmp_path, tracks, monkeypatch):
    real = np.savez

    def savez(f, **arrays):  # half a figure, then the disk is full
        f.write(b"PK\x03\x04" + b"\0" * 100)
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(np, "savez", savez)
    out = tmp_path / "run"
    result = _run(["run", "--track", "stairs", "--out", out, "--no-report"])
    assert result.exit_code == 0, result.stderr
    assert "3 figures not saved" in result.stderr and "records are kept" in result.stderr
    assert len(read_records(out / RESULTS_FILE)) == 6  # cases A, B, C have figures; their records are there
    assert list((out / "figures").iterdir()) == []  # no temporary file left behind
    monkeypatch.setattr(np, "savez", real)


def _savefig_on_a_full_disk(self, path, *a, **kw):
    Path(path).write_bytes(b"\x89PNG half")
    raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(path))


def test_a_report_on_a_full_disk_is_one_line_and_leaves_no_part_of_it(tmp_path, tracks, monkeypatch):
    import matplotlib.figure

    out = tmp_path / "run"
    assert _run(["run", "--track", "stairs", "--out", out, "--no-report"]).exit_code == 0
    before = sorted(p.relative_to(out) for p in out.rglob("*"))
    with monkeypatch.context() as m:
        m.setattr(matplotlib.figure.Figure, "savefig", _savefig_on_a_full_disk)
        result = _run(["report", out])
    assert result.exit_code == 2 and "No space left on device" in _one_error_line(result)
    assert sorted(p.relative_to(out) for p in out.rglob("*")) == before


def test_a_report_that_fails_after_a_run_keeps_the_records_and_its_hint_works(tmp_path, tracks, monkeypatch):
    import matplotlib.figure

    out = tmp_path / "run"
    with monkeypatch.context() as m:
        m.setattr(matplotlib.figure.Figure, "savefig", _savefig_on_a_full_disk)
        result = _run(["run", "--track", "stairs", "--out", out])
    line = _one_error_line(result)
    assert result.exit_code == 2 and "records are kept" in line and len(read_records(out / RESULTS_FILE)) == 6
    later = _run(shlex.split(line.split("write it later: ", 1)[1].rsplit(")", 1)[0])[1:])
    assert later.exit_code == 0 and (out / "report.md").exists()


def test_run_config_on_a_full_disk_is_one_line_and_no_temporary_file(tmp_path, tracks, monkeypatch):
    def fsync(fd):  # the data did not fit after all (as fsync reports on a full disk)
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(os, "fsync", fsync)
    monkeypatch.setattr(FakeTrack, "simulate", lambda *a: pytest.fail("ran without a run_config.json"))
    out = tmp_path / "run"
    result = _run(["run", "--track", "stairs", "--out", out])
    assert result.exit_code == 2 and "run_config.json: cannot be written (No space left" in _one_error_line(result)
    assert [p.name for p in out.iterdir()] == [LOCK_FILE]  # an empty folder, as if never run into
    monkeypatch.undo()
    _serve(monkeypatch)
    assert _run(["run", "--track", "stairs", "--out", out, "--no-report"]).exit_code == 0


# ---------------------------------------------------------------- paths


@pytest.mark.parametrize(
    "args",
    [
        ["run", "--track", "stairs", "--out", "{link}"],
        ["run", "--out", "{link}"],
        ["run", "--track", "stairs", "--out", "{link}/run"],
        ["run", "--track", "stairs", "--out", "{tmp}/run", "--rerun", "{link}"],
        ["record", "{link}"],
        ["record", "{tmp}/{long}"],
        ["record", "{tmp}/new/{long}"],
        ["run", "--track", "stairs", "--out", "{tmp}/new/{long}"],
        ["run", "--out", "{tmp}/{long}"],
        ["run", "--track", "stairs", "--out", "{tmp}/run", "--rerun", "{tmp}/{long}.rrd"],
        ["run", "--out", "{tmp}/run", "--rerun", "{tmp}/" + "r" * 250 + ".rrd"],  # NAME-<track>.rrd is longer
        ["report", "{tmp}/{long}"],
        ["run", "--track", "stairs", "--out", "{tmp}/" + "/".join(["d" * 200] * 25)],  # longer than PATH_MAX
    ],
)
def test_dangling_links_and_over_long_names_are_one_line_before_anything_runs(tmp_path, tracks, monkeypatch, args):
    link = tmp_path / "link"
    link.symlink_to(tmp_path / "gone" / "nowhere")
    monkeypatch.setattr(FakeTrack, "simulate", lambda *a: pytest.fail("simulated before the paths were checked"))
    result = _run([a.format(link=link, tmp=tmp_path, long="x" * 300) for a in args])
    assert result.exit_code == 2, result.output + result.stderr
    _one_error_line(result)
    assert [p.name for p in tmp_path.iterdir()] == ["link"]


def test_two_records_into_one_folder_the_second_is_refused_before_simulating(tmp_path, tracks, monkeypatch):
    out = tmp_path / "session"
    seconds = []
    real = FakeTrack.simulate

    def simulate(self, scenario, seed):  # while the first record simulates, a second one starts
        if not seconds:
            seconds.append(_run(["record", out, "--seed", "1"]))
        return real(self, scenario, seed)

    monkeypatch.setattr(FakeTrack, "simulate", simulate)
    first = _run(["record", out])
    assert first.exit_code == 0, first.stderr
    assert seconds[0].exit_code == 2 and "in use by another exobench record" in _one_error_line(seconds[0])
    assert json.loads((out / "meta.json").read_text())["seed"] == 0
    assert sorted(p.name for p in tmp_path.iterdir()) == ["session"]
    late = _run(["record", out])  # after it: the folder exists and is not empty
    assert late.exit_code == 2 and "does not exist yet" in _one_error_line(late)


def test_a_failed_record_leaves_no_folder_and_an_empty_one_is_taken(tmp_path, tracks, monkeypatch):
    monkeypatch.setattr(FakeTrack, "simulate", lambda *a: (_ for _ in ()).throw(OSError(errno.ENOSPC, "No space left on device")))
    result = _run(["record", tmp_path / "a" / "b"])
    assert result.exit_code == 2 and "No space left" in _one_error_line(result)
    assert list(tmp_path.iterdir()) == []
    monkeypatch.undo()
    _serve(monkeypatch)
    (tmp_path / "empty").mkdir()  # as a killed record leaves it
    assert _run(["record", tmp_path / "empty"]).exit_code == 0 and (tmp_path / "empty" / "meta.json").exists()


def test_a_report_into_a_read_only_folder_is_refused_before_anything(tmp_path, tracks, monkeypatch):
    out = tmp_path / "run"
    assert _run(["run", "--track", "stairs", "--out", out, "--no-report"]).exit_code == 0
    refuse_writes_in(monkeypatch, out, errno.EROFS)
    result = _run(["report", out])
    assert result.exit_code == 2 and "not writable" in _one_error_line(result)
    assert result.stdout == "" and not (out / "report.md").exists()


def test_resume_with_a_results_file_that_cannot_be_written_runs_nothing(tmp_path, tracks, monkeypatch):
    out = tmp_path / "run"
    assert _run(["run", "--track", "stairs", "--out", out, "--no-report"]).exit_code == 0
    results = out / RESULTS_FILE
    results.write_text("".join(results.read_text().splitlines(keepends=True)[:2]))
    real_open = os.open

    def fake_open(path, flags, *a, **kw):
        if Path(os.fsdecode(path)) == results and flags & (os.O_WRONLY | os.O_RDWR):
            raise PermissionError(errno.EACCES, os.strerror(errno.EACCES), str(results))
        return real_open(path, flags, *a, **kw)

    monkeypatch.setattr(os, "open", fake_open)
    monkeypatch.setattr(FakeTrack, "simulate", lambda *a: pytest.fail("ran an episode it could not store"))
    result = _run(["run", "--resume", "--out", out])
    assert result.exit_code == 2 and str(results) in _one_error_line(result)
    assert len(results.read_text().splitlines()) == 2


# ---------------------------------------------------------------- the other hints, run as printed


def test_ctrl_c_while_the_report_is_written_leaves_none_of_it_and_the_hint_finishes_it(tmp_path, tracks, monkeypatch):
    import matplotlib.figure

    def savefig(self, path, *a, **kw):
        Path(path).write_bytes(b"\x89PNG half")
        raise KeyboardInterrupt

    out = tmp_path / "all"
    with monkeypatch.context() as m:
        m.setattr(matplotlib.figure.Figure, "savefig", savefig)
        stopped = _run(["run", "--out", out])
    assert stopped.exit_code == 130
    assert not list(out.rglob("*.png")) and not list(out.rglob("*.tmp")) and not (out / "stairs" / "report.md").exists()
    # every track's folder is made before any episode runs; stairs2's had not run (one job)
    assert (out / "stairs2" / RUN_CONFIG_FILE).exists() and not (out / "stairs2" / RESULTS_FILE).exists()
    resumed = _run(_printed_command(stopped.stderr))
    assert resumed.exit_code == 0, resumed.stderr
    assert (out / "stairs" / "report.md").exists() and (out / "stairs2" / "report.md").exists()


def test_the_other_track_hint_of_replay_works_as_printed(tmp_path, tracks):
    session = tmp_path / "s"
    assert _run(["record", session]).exit_code == 0
    wrong = _run(["replay", session, "--track", "stairs2"])
    line = _one_error_line(wrong)
    assert wrong.exit_code == 2 and line.endswith("replay it with --track stairs")
    right = _run(["replay", session, *shlex.split(line.split("replay it with ", 1)[1])])
    assert right.exit_code == 0, right.stderr


def test_the_one_track_hint_of_a_run_of_every_track_works_as_printed(tmp_path, tracks):
    wrong = _run(["run", "--set", "riser_m=0.2", "--out", tmp_path / "r", "--no-report"])
    assert wrong.exit_code == 2 and "one track (--track NAME)" in _one_error_line(wrong)
    right = _run(["run", "--track", "stairs", "--set", "riser_m=0.2", "--out", tmp_path / "r", "--no-report"])
    assert right.exit_code == 0


def test_resuming_every_track_checks_every_track_folder_before_any_runs(tmp_path, tracks, monkeypatch):
    out = tmp_path / "all"
    with monkeypatch.context() as m:
        _interrupt_after(m, 3)
        assert _run(["run", "--out", out, "--no-report"]).exit_code == 130
    (out / "stairs2" / RUN_CONFIG_FILE).unlink()  # made before any episode ran: now a folder of something else
    (out / "stairs2" / "notes.txt").write_text("not a run")
    monkeypatch.setattr(FakeTrack, "simulate", lambda *a: pytest.fail("ran before every folder was checked"))
    result = _run(["run", "--resume", "--out", out])
    assert result.exit_code == 2 and str(out / "stairs2") in _one_error_line(result)
