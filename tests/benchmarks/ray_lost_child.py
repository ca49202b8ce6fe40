"""The driver of test_benchmarks_ray's lost-cluster test, in a process of its own: runs a slow
fake suite on a local Ray of its own; the test kills that Ray's raylet after the first episode."""

from __future__ import annotations

import sys
import time

from test_benchmarks_runner import _plan
from test_benchmarks_support import FakeStairs, FakeTrack

from exobench.benchmarks.ray_executor import ClusterLostError, RayExecutor
from exobench.benchmarks.registry import PipelineRegistry
from exobench.benchmarks.runner import execute


class SlowTrack(FakeTrack):
    def simulate(self, scenario, seed):
        time.sleep(1.0)
        return super().simulate(scenario, seed)


if __name__ == "__main__":
    reg = PipelineRegistry()
    reg.register("fake", FakeStairs)
    ex = RayExecutor(jobs=1, num_cpus=1)
    ex.connect()
    try:
        execute(_plan(reg, track=SlowTrack(), pipelines=["fake"]), sys.argv[1], executor=ex)
    except ClusterLostError as e:
        print(f"LOST: {e}", flush=True)
        sys.exit(3)
    print("FINISHED", flush=True)
