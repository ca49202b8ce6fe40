"""A run of every track in one pool (`exobench run`, `make run`: benchmarks/run_tracks.py): the
tracks' episodes share the workers, each track's folder holds the records a run of that track
alone writes, its table and report come as soon as its last episode is in, printed in the
tracks' order; Ctrl-C and resume at two jobs.

Two fake tracks (no MuJoCo) whose episodes note when they start and end in files of a folder
named by $EXOBENCH_TEST_STAMPS (the pool's spawned workers inherit the variable). The first
episode of "stairs" to start waits until a file named by the test appears (at most
:data:`WAIT_S`): a deterministic way to see whether anything else happens meanwhile.
"""

from __future__ import annotations

import dataclasses
import json
import os
import shlex
import threading
import time
from pathlib import Path
from typing import ClassVar

import pytest
from click.testing import CliRunner
from test_benchmarks_support import FakeStairs, FakeTrack, serve_tracks

from exobench.benchmarks import registry as registry_mod
from exobench.benchmarks.cli import cli
from exobench.benchmarks.registry import PipelineRegistry
from exobench.benchmarks.results import RESULTS_FILE, RUN_CONFIG_FILE
from exobench.benchmarks.run_tracks import execute_tracks
from exobench.benchmarks.runner import plan_run, rerun_first_episode, untimed_metrics
from exobench.core.episode import EpisodeStream

pytestmark = pytest.mark.long(seconds=15)  # the workers take it first (tests/conftest.py); 15: the file at -n 0 in one run at load 12-15, scaled to that run's CPU

STAMPS = "EXOBENCH_TEST_STAMPS"
WAIT_S = 20.0


class StampedTrack(FakeTrack):
    """The fake stairs track; each episode leaves ``<track>-<seed>.start`` and ``.end`` files, and
    the first one of "stairs" (``waiter``) waits for the file ``go`` (see the module doc)."""

    def simulate(self, scenario, seed):
        folder = Path(os.environ[STAMPS])
        (folder / f"{self.name}-{seed}.start").write_text(repr(time.time()))
        if self.name == "stairs":
            try:
                fd = os.open(folder / "waiter", os.O_CREAT | os.O_EXCL | os.O_WRONLY)
                os.write(fd, str(seed).encode())
                os.close(fd)
                until = time.monotonic() + WAIT_S
                while not (folder / "go").exists() and time.monotonic() < until:
                    time.sleep(0.02)
            except FileExistsError:  # another episode is the waiter
                pass
        episode = super().simulate(scenario, seed)
        (folder / f"{self.name}-{seed}.end").write_text(repr(time.time()))
        return episode


class StampedTrack2(StampedTrack):
    name: ClassVar[str] = "stairs2"


class FakeStairs2(FakeStairs):
    name: ClassVar[str] = "fake2"
    track: ClassVar[str] = "stairs2"


@pytest.fixture
def stamps(tmp_path, monkeypatch) -> Path:
    folder = tmp_path / "stamps"
    folder.mkdir()
    monkeypatch.setenv(STAMPS, str(folder))
    return folder


@pytest.fixture
def reg(monkeypatch) -> PipelineRegistry:
    """Two tracks ("stairs", "stairs2"; the same case names), each with its fake pipeline."""
    serve_tracks(monkeypatch, stairs=StampedTrack, stairs2=StampedTrack2)
    r = registry_mod.PipelineRegistry()
    r.register("fake", FakeStairs)
    r.register("fake2", FakeStairs2)
    monkeypatch.setattr(registry_mod, "default_registry", lambda: r)
    monkeypatch.setattr("exobench.benchmarks.runner.default_registry", lambda: r)
    return r


def _run(args):
    return CliRunner().invoke(cli, [str(a) for a in args], catch_exceptions=False)


def _comparable(folder: Path) -> list[tuple]:
    out = []
    for line in (folder / RESULTS_FILE).read_text().splitlines():
        r = json.loads(line)
        out.append((r["track"], r["episode"], r["pipeline"], r["seed"], json.dumps(r["scenario"], sort_keys=True),
                    json.dumps(untimed_metrics(FakeTrack(), r["metrics"]), sort_keys=True)))  # fmt: skip
    return sorted(out)


def _times(stamps: Path, track: str, what: str) -> dict[int, float]:
    return {int(p.name.split("-")[-1].split(".")[0]): float(p.read_text()) for p in stamps.glob(f"{track}-*.{what}")}


def test_two_jobs_run_the_second_track_while_the_first_is_unfinished_with_the_same_records(tmp_path, stamps, reg):
    """The waiter lets go when stairs2 has begun an episode: one track at a time, it would wait
    WAIT_S for nothing and stairs2 would begin after it."""
    (stamps / "go").write_text("")  # alone, nobody waits
    for track in ("stairs", "stairs2"):  # each track alone, one job: the reference records
        alone = _run(["run", "--track", track, "--out", tmp_path / "alone" / track, "--no-report"])
        assert alone.exit_code == 0, alone.stderr
    for p in stamps.iterdir():
        p.unlink()

    def let_go_once_stairs2_began():  # the test's hand
        until = time.monotonic() + 2 * WAIT_S
        while not _times(stamps, "stairs2", "start") and time.monotonic() < until:
            time.sleep(0.02)
        (stamps / "go").write_text("")

    watcher = threading.Thread(target=let_go_once_stairs2_began, daemon=True)
    watcher.start()
    result = _run(["run", "--jobs", "2", "--out", tmp_path / "all", "--no-report"])
    watcher.join()
    assert result.exit_code == 0, result.stderr
    waiter = int((stamps / "waiter").read_text())
    stairs_end = _times(stamps, "stairs", "end")
    assert min(_times(stamps, "stairs2", "start").values()) < stairs_end[waiter]  # the tracks overlapped
    assert stairs_end[waiter] - float(_times(stamps, "stairs", "start")[waiter]) < WAIT_S  # it was let go
    for track in ("stairs", "stairs2"):
        assert _comparable(tmp_path / "all" / track) == _comparable(tmp_path / "alone" / track)
        assert len(_comparable(tmp_path / "all" / track)) == 6
        assert json.loads((tmp_path / "all" / track / RUN_CONFIG_FILE).read_text())["executor"] == {"name": "pool", "jobs": 2}
    # stairs2 finished first; its table is printed after stairs' all the same
    out = result.stdout
    assert out.index("== track stairs /") < out.index("6 records (0 failed) in " + str(tmp_path / "all" / "stairs" / RESULTS_FILE))
    assert out.index(str(tmp_path / "all" / "stairs" / RESULTS_FILE)) < out.index("== track stairs2 /")


def test_a_track_is_done_as_soon_as_its_last_episode_is_in_while_another_still_runs(tmp_path, stamps, reg):
    """stairs2's on_done lets the stairs waiter go: it must come while that episode runs."""
    plans = [plan_run(StampedTrack(), "quick", ["fake"], [0], registry=reg),
             plan_run(StampedTrack2(), "quick", ["fake2"], [0], registry=reg)]  # fmt: skip
    done: list[tuple[int, int]] = []

    def on_done(i, outcome):
        done.append((i, len(outcome.records)))
        if i == 1:
            (stamps / "go").write_text("")

    outcomes = execute_tracks([(plans[0], tmp_path / "a", False), (plans[1], tmp_path / "b", False)], jobs=2, on_done=on_done)
    assert done == [(1, 6), (0, 6)]
    waiter = int((stamps / "waiter").read_text())
    assert _times(stamps, "stairs", "end")[waiter] - _times(stamps, "stairs", "start")[waiter] < WAIT_S
    assert [o.out_dir for o in outcomes] == [tmp_path / "a", tmp_path / "b"]
    assert {r["track"] for r in outcomes[0].records} == {"stairs"} and {r["track"] for r in outcomes[1].records} == {"stairs2"}


def test_ctrl_c_at_two_jobs_then_the_printed_command_completes_every_track_with_the_same_records(tmp_path, stamps, reg, monkeypatch):
    (stamps / "go").write_text("")  # nobody waits
    assert _run(["run", "--out", tmp_path / "whole", "--no-report"]).exit_code == 0
    import exobench.benchmarks.runner as runner

    real, stored = runner.append_records, []

    def append_records(path, records):  # Ctrl-C in the driver after 5 episodes are stored
        if len(stored) == 5:
            raise KeyboardInterrupt
        stored.append(path)
        real(path, records)

    with monkeypatch.context() as m:
        m.setattr(runner, "append_records", append_records)
        stopped = _run(["run", "--jobs", "2", "--out", tmp_path / "part", "--no-report"])
    assert stopped.exit_code == 130
    line = next(ln for ln in stopped.stderr.splitlines() if "continue: " in ln)
    command = line.split("continue: ", 1)[1].rsplit(")", 1)[0].split()
    assert command == ["exobench", "run", "--resume", "--out", str(tmp_path / "part"), "--jobs", "2", "--no-report"]
    resumed = _run(command[1:])
    assert resumed.exit_code == 0, resumed.stderr
    assert "resuming" in resumed.stderr
    for track in ("stairs", "stairs2"):
        assert _comparable(tmp_path / "part" / track) == _comparable(tmp_path / "whole" / track)
        assert len(_comparable(tmp_path / "part" / track)) == 6


# ---------------------------------------------------------------- --rerun from the run's own episode


class RecordedTrack(StampedTrack):
    """Notes every simulation (a line in ``calls``) and writes a recording of JSON: the
    episode's seed and each pipeline's series of (time, riser)."""

    def simulate(self, scenario, seed):
        with open(Path(os.environ[STAMPS]) / "calls", "a") as f:
            f.write(f"{seed}\n")
        return super().simulate(scenario, seed)

    def write_recording(self, episode, estimates_by_pipeline, path, scoring=None):
        series = {p: [[t, float(e.riser_height_m)] for t, e in s] for p, s in estimates_by_pipeline.items()}
        Path(path).write_text(json.dumps({"seed": episode.seed, "series": series}))
        return Path(path)


class StreamedTrack(RecordedTrack):
    """Hands its frames out as a stream (the truth at the end, the frames not kept)."""

    def stream(self, scenario, seed):
        ep = self.simulate(scenario, seed)
        return EpisodeStream(ep.scenario, ep.seed, ep.calibration, iter(ep.frames), lambda: dataclasses.replace(ep, frames=()))


class OnlineStairs(FakeStairs):
    """The fake pipeline, with an online estimate once it has three readings (a recording's
    timeline)."""

    def process(self, frame):
        super().process(frame)
        return self.finalize() if len(self._frames) >= 3 else None


@pytest.mark.parametrize(("track_cls", "jobs", "simulations"), [(RecordedTrack, 1, 6), (RecordedTrack, 2, 6), (StreamedTrack, 1, 7)])
def test_rerun_is_written_from_the_runs_own_first_episode_unless_it_streams(tmp_path, stamps, monkeypatch, track_cls, jobs, simulations):
    """Six episodes: six simulations, the recording from the first (in a worker at two jobs); a
    streamed track's frames are gone once read, and its first episode is simulated again. The
    recording is the one `rerun_first_episode` writes on its own."""
    (stamps / "go").write_text("")  # nobody waits
    serve_tracks(monkeypatch, stairs=track_cls)
    r = registry_mod.PipelineRegistry()
    r.register("fake", OnlineStairs)
    monkeypatch.setattr(registry_mod, "default_registry", lambda: r)
    monkeypatch.setattr("exobench.benchmarks.runner.default_registry", lambda: r)
    rrd = tmp_path / "first.rrd"
    result = _run(["run", "--track", "stairs", "--jobs", jobs, "--out", tmp_path / "run", "--no-report", "--rerun", rrd])
    assert result.exit_code == 0, result.stderr
    assert f"rerun recording: {rrd}" in result.stdout
    assert len((stamps / "calls").read_text().split()) == simulations
    plan = plan_run(track_cls(), "quick", ["fake"], [0], registry=r)
    alone = rerun_first_episode(plan, tmp_path / "alone.rrd")
    written = json.loads(rrd.read_text())
    assert written == json.loads(alone.read_text()) and written["seed"] == plan.episodes[0].seed
    assert len(written["series"]["fake"]) > 3  # online estimates, then the final one


def test_a_report_that_fails_in_a_run_of_every_track_is_one_line_whose_hint_finishes_the_run(tmp_path, stamps, reg, monkeypatch):
    import matplotlib.figure
    from test_run_folders import _savefig_on_a_full_disk

    (stamps / "go").write_text("")  # nobody waits
    out = tmp_path / "all"
    with monkeypatch.context() as m:
        m.setattr(matplotlib.figure.Figure, "savefig", _savefig_on_a_full_disk)
        result = _run(["run", "--jobs", "2", "--out", out])
    assert result.exit_code == 2
    said = [ln for ln in result.stderr.splitlines() if ln.startswith("exobench:")]
    assert len(said) == 1 and "No space left on device" in said[0] and said[0].count("continue: ") == 1, said
    assert not (out / "stairs" / "report.md").exists()
    resumed = _run(shlex.split(said[0].split("continue: ", 1)[1].rsplit(")", 1)[0])[1:])
    assert resumed.exit_code == 0, resumed.stderr
    assert (out / "stairs" / "report.md").exists() and (out / "stairs2" / "report.md").exists()
    for track in ("stairs", "stairs2"):
        assert len(_comparable(out / track)) == 6
