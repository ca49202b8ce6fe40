"""The Ray executor (``--executor ray``): the pool's records, its retry rule, resume across
executors, an unreachable address refused at once. One local Ray (2 CPUs, a small object store)
serves the whole module and is shut down after it."""

from __future__ import annotations

import contextlib
import json
import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path
from typing import ClassVar

import pytest
import ray
from test_benchmarks_runner import KillingTrack, _comparable, _plan
from test_benchmarks_support import FakeStairs, FakeTrack

from exobench.benchmarks import ray_executor
from exobench.benchmarks.cli import main
from exobench.benchmarks.pool import Death, lost_reason
from exobench.benchmarks.ray_executor import ClusterLostError, RayExecutor, run_actors
from exobench.benchmarks.registry import PipelineRegistry
from exobench.benchmarks.results import RESULTS_FILE, RUN_CONFIG_FILE
from exobench.benchmarks.run_tracks import execute_tracks
from exobench.benchmarks.runner import execute
from exobench.core import ConfigError

pytestmark = pytest.mark.long(seconds=36)  # the workers take it first (tests/conftest.py); 36: the file at -n 0 in one run at load 12-15, scaled to that run's CPU

HERE = Path(__file__).parent


@pytest.fixture(scope="module")
def executor():
    # the workers unpickle this folder's fake tracks and pipelines: they import them as the driver does
    old = os.environ.get("PYTHONPATH")
    os.environ["PYTHONPATH"] = os.pathsep.join(filter(None, [str(HERE), str(HERE.parent), old]))
    ex = RayExecutor(jobs=2, num_cpus=2)
    try:
        ex.connect()
        yield ex
    finally:
        ex.close()
        if old is None:
            os.environ.pop("PYTHONPATH", None)
        else:
            os.environ["PYTHONPATH"] = old
    assert not ray.is_initialized()


@pytest.fixture
def reg() -> PipelineRegistry:
    r = PipelineRegistry()
    r.register("fake", FakeStairs)
    return r


def test_ray_gives_the_pools_records_and_records_which_executor_ran(executor, reg, tmp_path):
    plan = _plan(reg, seeds=[0, 1], pipelines=["fake"])
    pool = execute(plan, tmp_path / "pool", jobs=2)
    on_ray = execute(plan, tmp_path / "ray", executor=executor)
    assert len(pool.records) == 12
    assert _comparable(on_ray.records) == _comparable(pool.records)
    assert json.loads((tmp_path / "ray" / RUN_CONFIG_FILE).read_text())["executor"]["name"] == "ray"
    assert json.loads((tmp_path / "pool" / RUN_CONFIG_FILE).read_text())["executor"] == {"name": "pool", "jobs": 2}


def test_workers_import_exobench_from_where_the_driver_does(executor):
    import exobench

    @ray.remote
    def where() -> str:
        import exobench

        return exobench.__file__

    assert ray.get(where.remote()) == exobench.__file__


def test_a_run_started_on_ray_is_resumed_on_the_pool_and_the_other_way(executor, reg, tmp_path):
    plan = _plan(reg, pipelines=["fake"])
    full = execute(plan, tmp_path / "whole", jobs=1).records
    for first, then in (("ray", "pool"), ("pool", "ray")):
        out = tmp_path / f"{first}-then-{then}"
        execute(plan, out, executor=executor if first == "ray" else None, jobs=2)
        lines = (out / RESULTS_FILE).read_text().splitlines(keepends=True)
        (out / RESULTS_FILE).write_text("".join(lines[:2]))  # as if the run stopped after two episodes
        resumed = execute(plan, out, resume=True, executor=executor if then == "ray" else None, jobs=2)
        assert len(resumed.skipped) == 2 and len(resumed.ran) == len(plan.episodes) - 2
        assert _comparable(resumed.records) == _comparable(full)


class OtherTrack(FakeTrack):
    name: ClassVar[str] = "stairs2"


class OtherStairs(FakeStairs):
    name: ClassVar[str] = "fake2"
    track: ClassVar[str] = "stairs2"


def test_every_track_on_ray_in_one_run_gives_each_tracks_own_records(executor, reg, tmp_path):
    """Two tracks' episodes (of the same names) on Ray's actors at once (run_tracks): each track's
    folder holds what a run of that track alone writes, and says Ray ran it."""
    reg.register("fake2", OtherStairs)
    plans = [_plan(reg, pipelines=["fake"]), _plan(reg, track=OtherTrack(), pipelines=["fake2"])]
    outcomes = execute_tracks([(plan, tmp_path / plan.track.name, False) for plan in plans], executor=executor)
    for plan, outcome in zip(plans, outcomes, strict=True):
        alone = execute(plan, tmp_path / "alone" / plan.track.name, jobs=1)
        assert len(outcome.records) == 6 and {r["track"] for r in outcome.records} == {plan.track.name}
        assert _comparable(outcome.records) == _comparable(alone.records)
        assert json.loads((tmp_path / plan.track.name / RUN_CONFIG_FILE).read_text())["executor"]["name"] == "ray"


def test_a_killed_worker_is_retried_once_then_recorded_failed_with_the_pools_reason(executor, reg, tmp_path):
    plan = _plan(reg, track=KillingTrack(), pipelines=["fake"])
    out = execute(plan, tmp_path / "run", executor=executor)
    assert sorted(r["episode"] for r in out.records) == sorted(e.key for e in plan.episodes)
    b = [r for r in out.records if r["case"] == "B"]
    assert len(b) == 1 and b[0]["metrics"]["failed"]
    assert b[0]["harness_error"] == lost_reason(Death(-signal.SIGKILL, None))  # the pool's words for it
    assert not any(r["metrics"]["failed"] for r in out.records if r["case"] != "B")


def _kill_once(job):
    """(job, "done"); a job naming a marker path kills its worker the first time."""
    if job.startswith("kill:") and not os.path.exists(job[5:]):
        Path(job[5:]).write_text("killed once")
        os.kill(os.getpid(), 9)
    return job, "done"


def test_a_worker_killed_once_is_retried_and_its_episode_finishes(executor, tmp_path):
    got: dict[str, str] = {}
    job = f"kill:{tmp_path / 'marker'}"
    run_actors(["a", job, "b"], 2, _kill_once, got.__setitem__, lambda j, why: (j, f"lost: {why}"))
    assert got == {"a": "done", job: "done", "b": "done"}


def test_a_lost_cluster_keeps_what_finished_and_records_nothing_as_failed(executor, tmp_path, monkeypatch):
    marker = tmp_path / "marker"
    # every node gone once a worker dies (not before: under load, "a" may outlast a health check)
    monkeypatch.setattr(ray_executor, "_cluster_alive", lambda: not marker.exists())
    got: dict[str, str] = {}
    with pytest.raises(ClusterLostError, match="the Ray cluster was lost"):
        # one worker: "a" finishes before the job that kills its worker starts
        run_actors(["a", f"kill:{marker}", "b"], 1, _kill_once, got.__setitem__, lambda j, why: (j, "lost"))
    assert got == {"a": "done"}


def _slow(job):
    time.sleep(float(job))
    return job, "done"


def test_a_cluster_found_gone_while_waiting_stops_the_run_without_waiting_for_its_episodes(executor, monkeypatch):
    monkeypatch.setattr(ray_executor, "_cluster_alive", lambda: False)  # as if every node had gone
    t0 = time.monotonic()
    with pytest.raises(ClusterLostError, match="no node of the cluster is alive"):
        run_actors(["20"], 1, _slow, lambda *a: None, lambda j, why: (j, "lost"), health_every_s=0.5)
    assert time.monotonic() - t0 < 15  # not the 20 s of the episode (nor forever: no node would run it)


def test_a_ray_call_that_fails_as_the_node_goes_is_a_lost_cluster_with_what_finished_kept(executor, monkeypatch):
    """The raylet killed between two episodes: the next ``ray.wait`` (or a kill, or a new actor)
    raises a system error rather than an episode's death; once no node answers, that is a lost
    cluster (resumable), not a crash of the run."""
    import ray
    from ray import exceptions as rx

    real_wait, got = ray.wait, {}

    def wait_then_fail(*args, **kwargs):
        if got:  # the first episode is finished and handed over; the node goes now
            monkeypatch.setattr(ray_executor, "_cluster_alive", lambda: False)
            raise rx.RaySystemError("raylet connection lost")
        return real_wait(*args, **kwargs)

    monkeypatch.setattr(ray, "wait", wait_then_fail)
    with pytest.raises(ClusterLostError, match="raylet connection lost"):
        run_actors(["0", "0.5"], 1, _slow, got.__setitem__, lambda j, why: (j, "lost"))
    assert got == {"0": "done"}


def test_an_unreachable_address_is_refused_at_once_before_anything_is_written(tmp_path, capsys):
    with socket.socket() as s:  # a port nothing listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    t0 = time.monotonic()
    with pytest.raises(SystemExit) as e:
        main(["run", "--track", "stairs", "--executor", "ray", "--address", f"127.0.0.1:{port}", "--out", str(tmp_path / "run")])
    assert e.value.code == 2 and time.monotonic() - t0 < 30
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("exobench: error: --address=") and f"127.0.0.1:{port}" in err[0], err
    assert not (tmp_path / "run").exists()


@pytest.mark.parametrize("address", ["nohost", "host:99999", "ray://:10001"])
def test_a_malformed_address_is_refused(address):
    with pytest.raises(ConfigError, match="--address"):
        RayExecutor(address=address)


def test_bench_executor_times_the_pool_at_1_and_2_and_ray_on_the_same_records(executor, reg):
    from exobench.benchmarks.bench.executor import bench_executor

    plan = _plan(reg, pipelines=["fake"], seeds=[0, 1])
    got = bench_executor(plan, ray_executor=executor)
    n = len(plan.episodes)
    assert got["episodes"] == n == 12 and got["records_identical"] is True
    walls = got["wall_s"]
    assert set(walls) == {"pool_1", "pool_2", "ray_2"} and all(w > 0 for w in walls.values())
    assert got["episodes_per_s"]["pool_1"] == pytest.approx(n / walls["pool_1"])
    assert got["pool_2_over_pool_1_speedup"] == pytest.approx(walls["pool_1"] / walls["pool_2"])
    # each executor's start-up inside its window (the pool's spawning) is out of the per-episode figures
    startup = got["startup_s"]
    assert set(startup) == set(walls) and all(0 <= startup[k] < walls[k] for k in walls)
    assert startup["pool_1"] > 0 and startup["pool_2"] > 0  # their processes are spawned inside the window
    per = {k: (walls[k] - startup[k]) / n for k in walls}
    assert got["per_episode_s"] == pytest.approx(per)
    assert got["ray_overhead_s_per_episode"] == pytest.approx(per["ray_2"] - per["pool_2"])
    assert got["ray_workers_start_s"] > 0  # Ray's actors were started before its window
    assert ray.is_initialized()  # the executor it was given is left connected


def _pid(job):
    return job, os.getpid()


def test_actors_started_ahead_run_the_episodes_and_end_with_the_run(executor):
    """start_workers starts at most the executor's concurrency (2) and has them import what it
    is given; the run that follows uses those actors, and ends them."""
    pids = set(ray.get(executor.start_workers(5, ["test_benchmarks_support"])))
    assert len(pids) == 2
    got: dict[str, int] = {}
    executor.run(["a", "b", "c", "d"], _pid, got.__setitem__, lambda j, why: (j, "lost"))
    assert set(got) == {"a", "b", "c", "d"} and set(got.values()) == pids
    assert executor.start_workers(0) == []  # none left over for the next run


def test_the_command_line_runs_a_suite_on_ray_and_says_so_in_run_config(executor, tmp_path, capsys):
    out = tmp_path / "run"
    with pytest.raises(SystemExit) as e:
        main(["run", "quick", "--track", "stairs", "--pipeline", "rtls", "--executor", "ray", "--jobs", "2", "--out", str(out), "--no-report"])
    assert e.value.code in (0, None), capsys.readouterr().err
    config = json.loads((out / RUN_CONFIG_FILE).read_text())
    assert config["executor"] == {"name": "ray", "address": None, "jobs": 2, "episode_cpus": 1.0, "episode_gpus": 0.0}
    lines = (out / RESULTS_FILE).read_text().splitlines()
    assert len(lines) == len(config["episodes"]) > 0 and not any(json.loads(x)["metrics"]["failed"] for x in lines)


@pytest.mark.parametrize("option", [["--address", "h:1"], ["--episode-cpus", "2"], ["--episode-gpus", "0.5"]])
def test_ray_options_without_the_ray_executor_are_refused(option, tmp_path, capsys):
    with pytest.raises(SystemExit) as e:
        main(["run", "--track", "stairs", *option, "--out", str(tmp_path / "run")])
    err = capsys.readouterr().err
    assert e.value.code == 2 and err.startswith(f"exobench: error: {option[0]}=") and "with --executor ray" in err
    assert not (tmp_path / "run").exists()


def _descendants(pid: int) -> dict[int, str]:
    """pid -> command name of every process below ``pid``."""
    procs = {}
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            text = stat.read_text()
        except OSError:
            continue
        name, rest = text[text.index("(") + 1 : text.rindex(")")], text[text.rindex(")") + 2 :].split()
        procs[int(stat.parent.name)] = (name, int(rest[1]))
    out, frontier = {}, [pid]
    while frontier:
        parent = frontier.pop()
        for p, (name, ppid) in procs.items():
            if ppid == parent and p not in out:
                out[p] = name
                frontier.append(p)
    return out


def test_a_cluster_lost_mid_run_keeps_what_finished_and_resume_completes_it_on_the_pool(reg, tmp_path):
    out = tmp_path / "run"
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(filter(None, [str(HERE), str(HERE.parent), os.environ.get("PYTHONPATH")])),
               RAY_health_check_period_ms="500", RAY_health_check_failure_threshold="2")  # the dead node found in ~1 s, not ~15
    child = subprocess.Popen([sys.executable, str(HERE / "ray_lost_child.py"), str(out)], env=env,
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)  # fmt: skip
    seen: dict[int, str] = {}
    try:
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline and not ((out / RESULTS_FILE).exists() and (out / RESULTS_FILE).read_text()):
            time.sleep(0.2)
        seen.update(_descendants(child.pid))
        raylets = [p for p, name in seen.items() if name == "raylet"]
        assert raylets, "the child's Ray has no raylet"
        for p in raylets:
            os.kill(p, signal.SIGKILL)  # the only node of the child's cluster is gone
        stdout, stderr = child.communicate(timeout=120)
    finally:
        seen.update(_descendants(child.pid))
        for p, name in seen.items():  # leave none of the child's Ray behind (a pid taken since by another is spared)
            with contextlib.suppress(OSError, ValueError):
                if name in Path(f"/proc/{p}/stat").read_text():
                    os.kill(p, signal.SIGKILL)
        child.kill()
        child.wait()
    # the run says the cluster is lost (exit 3); or Ray's own driver process quits first, as its
    # raylet is gone (a race: about one run in ten here, exit 1 without a Python traceback). Either
    # way no exception of exobench escapes, and what finished is kept (below).
    lost_said = child.returncode == 3 and "LOST: the Ray cluster was lost" in stdout
    ray_quit = child.returncode not in (0, 3) and "Traceback" not in stderr
    assert lost_said or ray_quit, stdout + stderr[-3000:]
    kept = [json.loads(x) for x in (out / RESULTS_FILE).read_text().splitlines()]
    assert kept and not any(r["metrics"]["failed"] for r in kept)  # no unfinished episode recorded as failed
    plan = _plan(reg, pipelines=["fake"])  # the same plan as the child's (SlowTrack is a FakeTrack)
    resumed = execute(plan, out, resume=True, jobs=2)
    assert len(resumed.skipped) == len(kept) and len(resumed.records) == len(plan.episodes)
