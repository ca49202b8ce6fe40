"""The runner feeds a streamed episode to every pipeline in lockstep (benchmarks.runner.run_pipelines).

The oracle is the same run on the whole episode (``simulate``): same records but timings; and
the order of events: a pipeline sees frame k before the stream produces frame k + 1.
"""

from __future__ import annotations

import dataclasses
from typing import Any, ClassVar

import pytest
from test_benchmarks_support import FakeStairs, FakeTrack, RaisingStairs

from exobench.benchmarks.registry import PipelineRegistry
from exobench.benchmarks.runner import execute, plan_run, untimed_metrics
from exobench.core.episode import EpisodeStream

EVENTS: list[tuple[str, float]] = []


class StreamingTrack(FakeTrack):
    """The fake track whose episodes also stream, logging each frame it hands out."""

    fail_after: ClassVar[int | None] = None

    def stream(self, scenario: dict[str, Any], seed: int) -> EpisodeStream:
        whole = self.simulate(scenario, seed)

        def frames():
            for i, f in enumerate(whole.frames):
                if self.fail_after is not None and i == self.fail_after:
                    raise RuntimeError("simulator broke")
                EVENTS.append(("made", f.stamp_s))
                yield f

        return EpisodeStream(whole.scenario, whole.seed, whole.calibration, frames(),
                             lambda: dataclasses.replace(whole, frames=()))  # fmt: skip


class LoggingStairs(FakeStairs):
    name: ClassVar[str] = "fake-log"

    def process(self, frame: Any):
        EVENTS.append(("seen", frame.stamp_s))
        return super().process(frame)


@pytest.fixture
def reg():
    r = PipelineRegistry()
    r.register("fake", FakeStairs)
    r.register("fake-raise", RaisingStairs)
    r.register("fake-log", LoggingStairs)
    return r


def _records(track, reg, out):
    plan = plan_run(track, "quick", ["fake", "fake-raise", "fake-log"], [0, 1], None, registry=reg)
    got = execute(plan, out).records
    return sorted((r["episode"], r["pipeline"], untimed_metrics(track, r["metrics"]), r.get("harness_error")) for r in got)


def test_a_streamed_episode_scores_as_the_whole_one_each_frame_going_to_every_pipeline_in_turn(reg, tmp_path):
    EVENTS.clear()
    streamed = _records(StreamingTrack(), reg, tmp_path / "s")
    made = [e for e in EVENTS if e[0] == "made"]
    assert len(made) > 40
    # lockstep: every frame is seen before the next one is made
    for a, b in zip(EVENTS, EVENTS[1:]):
        if a[0] == "made":
            assert b == ("seen", a[1])
    whole = _records(FakeTrack(), reg, tmp_path / "w")
    assert streamed == whole
    by_pipe = {p: m for _, p, m, _ in streamed}
    assert by_pipe["fake-raise"]["failed"] and "boom" in by_pipe["fake-raise"]["failed_reason"]
    assert not by_pipe["fake"]["failed"] and not by_pipe["fake-log"]["failed"]  # the others went on


def test_a_stream_that_raises_fails_the_episode_for_every_pipeline(reg, tmp_path):
    class Broken(StreamingTrack):
        fail_after = 7

    got = _records(Broken(), reg, tmp_path / "b")
    assert len(got) >= 6 and len({e for e, _, _, _ in got}) * 3 == len(got)
    for _, _, metrics, harness in got:
        assert metrics["failed"] and harness == "simulation raised RuntimeError: simulator broke"
