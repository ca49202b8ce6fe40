"""bench sim's stages (benchmarks.bench.sim.stages_of): a profile's time summed by where the code lives.

The oracle is a profile of code whose stages are known: functions compiled as if they lived in
the LiDAR caster and in the optics module, each sorting the same array (a library call, so its
time must go to its caller's stage), the caster three times as often.
"""

from __future__ import annotations

import cProfile
import os
import time

import numpy as np

import exobench
from exobench.benchmarks.bench.sim import STAGES, cpu_profile, stage_of, stages_of

# the package's own folder, whatever the checkout is named (/work/main is not named exobench)
PKG = os.path.dirname(os.path.abspath(exobench.__file__))

SRC = """
import numpy as np

def work(a, n):
    for _ in range(n):
        np.sort(a)
"""


def _module(path: str):
    scope: dict = {}
    exec(compile(SRC, path, "exec"), scope)
    return scope["work"]


def test_library_time_counts_in_the_stage_of_the_exobench_code_that_called_it():
    cast = _module(f"{PKG}/envs/sensors/lidar/cast.py")
    optics = _module(f"{PKG}/envs/sensors/lidar/optics.py")
    a = np.random.default_rng(0).random(300_000)
    profile = cProfile.Profile(time.process_time)  # CPU time: other processes do not move it
    profile.enable()
    cast(a, 12)
    optics(a, 4)
    profile.disable()
    got = stages_of(profile)
    assert set(got) == set(STAGES)
    assert got["casting"] > 0 and got["optics"] > 0
    assert 1.5 < got["casting"] / got["optics"] < 6.0  # 3x the same sorts
    assert got["other"] < 0.1 * got["casting"]  # numpy's time is not left unassigned


def test_stage_rules():
    assert stage_of("~", "<built-in method mujoco._functions.mj_multiRay>") == "casting"
    assert stage_of("~", "<built-in method mujoco._render.mjr_readPixels>") == "rendering"
    assert stage_of("~", "<method 'normal' of 'numpy.random._generator.Generator' objects>") == "noise"
    assert stage_of("~", "<method 'reduce' of 'numpy.ufunc' objects>") is None  # its caller's
    assert stage_of("/venv/site-packages/numpy/_core/fromnumeric.py", "sort") is None
    assert stage_of("/venv/site-packages/foo/models/x.py", "f") is None  # only exobench's own files have stages
    assert stage_of("/elsewhere/exobench/perception/stairs/rtls.py", "process") is None  # another copy is not this one
    assert stage_of(f"{PKG}/.venv/lib/python3.11/site-packages/numpy/_core/fromnumeric.py", "sort") is None  # a venv in the checkout
    assert stage_of(f"{PKG}/mapping/odometry/kiss_icp.py", "process") == "pipelines"
    assert stage_of(f"{PKG}/envs/motion/walk.py", "plan_walk") == "motion"
    assert stage_of(f"{PKG}/benchmarks/runner.py", "_run_job") == "other"


def test_bench_profiles_count_cpu_time_not_the_time_a_process_waits():
    # on the shared machine a wall-clock profile put several times an episode's CPU time in its
    # stages (load 18: 96 s of stages for 18 CPU-s)
    cast = _module(f"{PKG}/envs/sensors/lidar/cast.py")
    a = np.random.default_rng(0).random(300_000)
    profile = cpu_profile()
    c0 = time.process_time()
    profile.enable()
    cast(a, 3)
    time.sleep(0.5)  # waiting, as for a core another process holds
    cast(a, 3)
    profile.disable()
    cpu = time.process_time() - c0
    got = stages_of(profile)
    assert got["casting"] > 0
    assert sum(got.values()) < cpu + 0.05 < 0.5
