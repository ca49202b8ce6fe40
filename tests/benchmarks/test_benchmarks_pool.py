"""The worker pool of --jobs N: a killed worker's job is retried once, then lost; workers end with their parent."""

from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from exobench.benchmarks.pool import LOST_REASON, WATCH_INTERVAL_S, Death, lost_reason, run_pool

pytestmark = pytest.mark.long(seconds=8)  # the workers take it first (tests/conftest.py); 8: the file at -n 0 in one run at load 12-15, scaled to that run's CPU


def _work(job):
    """(key, value); a job "kill:<marker>" kills its worker, once if a marker path is given;
    "hog:<MB>" holds that much memory for a while, then its worker is killed as the kernel's
    out-of-memory killer does (SIGKILL)."""
    if job.startswith("hog:"):
        held = np.ones(int(job.partition(":")[2]) * 2**20, dtype=np.uint8)  # touched: resident
        time.sleep(4 * WATCH_INTERVAL_S)
        held[0] = 0
        os.kill(os.getpid(), signal.SIGKILL)
    if job.startswith("kill"):
        marker = job.partition(":")[2]
        if not marker or not os.path.exists(marker):
            if marker:
                Path(marker).write_text("killed once")
            os.kill(os.getpid(), signal.SIGKILL)
    return job, f"done {job}"


def _lost(job, reason):
    return job, f"lost: {reason}"


def _run(jobs, workers=2):
    out: dict[str, str] = {}
    run_pool(jobs, workers, _work, lambda key, value: out.__setitem__(key, value), _lost)
    return out


def test_a_job_that_kills_its_worker_twice_is_lost_and_the_others_finish():
    jobs = ["a", "b", "kill", "c", "d", "e"]
    out = _run(jobs)
    assert {j: v for j, v in out.items() if j != "kill"} == {j: f"done {j}" for j in jobs if j != "kill"}
    assert out["kill"].startswith("lost: the worker process running the episode was killed (SIGKILL) twice, likely out of memory")


def test_a_worker_killed_as_out_of_memory_is_reported_with_its_peak():
    out = _run(["a", "hog:600", "b"])
    assert out["a"] == "done a" and out["b"] == "done b"
    reason = out["hog:600"]
    assert "killed (SIGKILL) twice, likely out of memory" in reason, reason
    peak_gb = float(re.search(r"peak ([0-9.]+) GB", reason).group(1))
    assert 0.6 <= peak_gb < 2.0  # the 629 MB it held, plus the interpreter's own


def test_how_a_worker_died_is_said():
    assert lost_reason(None) == LOST_REASON
    assert lost_reason(Death(-signal.SIGTERM, None)) == "the worker process running the episode was killed (SIGTERM) twice"
    assert lost_reason(Death(3, 2_500_000_000)).endswith("died twice (exit status 3), peak 2.50 GB")


def test_a_job_whose_worker_was_killed_once_is_retried(tmp_path):
    job = f"kill:{tmp_path / 'marker'}"
    out = _run(["a", job, "b"])
    assert out == {"a": "done a", job: f"done {job}", "b": "done b"}




def sleepy(job):  # replaced in the child script; defined so that workers can unpickle it
    open(os.path.join(os.environ["EXOBENCH_TEST_PID_DIR"], str(os.getpid())), "w").close()
    time.sleep(120)
    return job, None


def _alive(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except (FileNotFoundError, ProcessLookupError):
        return False
    return state not in ("Z", "X")  # a zombie has ended


def test_workers_end_when_the_parent_is_killed(tmp_path):
    script = (
        "import sys\n"
        f"sys.path.insert(0, {str(Path(__file__).parent)!r})\n"
        "from exobench.benchmarks.pool import run_pool\n"
        "import test_benchmarks_pool as t\n"
        "if __name__ == '__main__':\n"
        "    run_pool(['a', 'b'], 2, t.sleepy, print, print)\n"
    )
    env = dict(os.environ, EXOBENCH_TEST_PID_DIR=str(tmp_path))
    parent = subprocess.Popen([sys.executable, "-c", script], env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 60
        while len(list(tmp_path.iterdir())) < 2 and time.monotonic() < deadline:
            time.sleep(0.1)
        pids = [int(p.name) for p in tmp_path.iterdir()]
        assert len(pids) == 2 and all(_alive(p) for p in pids)
    finally:
        parent.kill()
        parent.wait()
    deadline = time.monotonic() + 5
    while any(_alive(p) for p in pids) and time.monotonic() < deadline:
        time.sleep(0.1)
    alive = [p for p in pids if _alive(p)]
    for p in alive:  # do not leave them behind if the test fails
        os.kill(p, signal.SIGKILL)
    assert not alive, "workers outlived their parent"


def _thread_vars(job):
    """(job, the thread-pool variables the worker was started with)."""
    from exobench.benchmarks.pool import THREAD_VARS

    return job, {v: os.environ.get(v) for v in THREAD_VARS}


def test_each_worker_gets_the_cpus_over_the_workers_and_a_users_setting_is_kept(monkeypatch):
    """Two workers that each keep a thread pool as wide as the machine oversubscribe it: the
    stairs paper suite ran 1.15x as fast at two workers as at one."""
    from exobench.benchmarks.pool import THREAD_VARS

    for v in THREAD_VARS:
        monkeypatch.delenv(v, raising=False)
    monkeypatch.setenv("MKL_NUM_THREADS", "3")  # the user's choice wins
    got: dict[str, dict] = {}
    run_pool(["a", "b"], 2, _thread_vars, got.__setitem__, lambda job, why: (job, why))
    want = str(max(1, (os.cpu_count() or 1) // 2))
    for seen in got.values():
        assert seen == {"OMP_NUM_THREADS": want, "OPENBLAS_NUM_THREADS": want, "MKL_NUM_THREADS": "3"}
    assert "OMP_NUM_THREADS" not in os.environ and os.environ["MKL_NUM_THREADS"] == "3"  # the parent's as it was


def test_two_workers_take_the_longest_episodes_first_and_the_records_are_the_same(monkeypatch):
    """Longest first by the scenario's length (ties in the run's order); one worker keeps the
    run's order; every job's record is handed over either way."""
    from concurrent.futures import ThreadPoolExecutor
    from types import SimpleNamespace

    import exobench.benchmarks.pool as pool

    submitted: list[str] = []

    class Recording(ThreadPoolExecutor):  # the pool's executor, in threads, noting the order jobs are given
        def submit(self, fn, job):
            submitted.append(job.plan.key)
            return super().submit(fn, job)

    monkeypatch.setattr(pool, "make_pool", lambda workers: Recording(max_workers=workers))
    lengths = {"corridor": 60.0, "ring": 500.0, "ring-glazed": 500.0, "quick": 4.0, "loop": 120.0}
    jobs = [SimpleNamespace(plan=SimpleNamespace(key=k, scenario={"route": "x", "max_distance_m": v})) for k, v in lengths.items()]

    def work(job):
        return job.plan.key, 2 * job.plan.scenario["max_distance_m"]

    for workers, order in ((2, ["ring", "ring-glazed", "loop", "corridor", "quick"]), (1, list(lengths))):
        submitted.clear()
        got: dict[str, float] = {}
        run_pool(jobs, workers, work, got.__setitem__, _lost)
        assert submitted == order
        assert got == {k: 2 * v for k, v in lengths.items()}
