"""`bench locomotion`'s clock of an RGB-D frame's stages: each stage counted once per frame (twice
for a pass: its draw and its read-back), its CPU time within the block's, and MuJoCo and the
camera as they were afterwards."""

from __future__ import annotations

import time

import mujoco

from exobench.benchmarks.bench.locomotion import render_stage_clock
from exobench.envs.sensors.rgbd.model import RgbdCamera
from exobench.envs.sensors.rgbd.render import RgbdRenderer
from exobench.envs.sim.scenarios.course import LocomotionScenario, simulate_locomotion

COURSE = {"width_px": 48, "height_px": 32, "rate_hz": 5.0, "duration_cap_s": 2.0, "pedestrians": 0}


def test_each_stage_of_each_frame_is_clocked_once_and_the_functions_restored():
    originals = (mujoco.mjv_updateScene, mujoco.mjr_render, mujoco.mjr_readPixels, RgbdRenderer._metric_depth,
                 RgbdCamera.measure)  # fmt: skip
    cpu, calls = {}, {}
    with render_stage_clock(cpu, calls):
        t0 = time.process_time()
        episode = simulate_locomotion(LocomotionScenario.from_dict(COURSE), 3)
        total = time.process_time() - t0
    n = len(episode.truth.extra["camera_stamps_s"])
    assert n >= 5
    assert calls == {"scene": n, "depth_pass": 2 * n, "colour_pass": 2 * n, "depth_to_metres": n, "noise": n}
    assert all(v >= 0 for v in cpu.values()) and sum(cpu.values()) <= total
    assert (mujoco.mjv_updateScene, mujoco.mjr_render, mujoco.mjr_readPixels, RgbdRenderer._metric_depth,
            RgbdCamera.measure) == originals  # fmt: skip
