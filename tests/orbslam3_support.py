"""Shared by the orb-slam3 tests: a hand-made camera calibration, a short simulated RGB-D-inertial
walk, and a vocabulary built from another walk (cached for the test session)."""

from __future__ import annotations

import functools
from pathlib import Path

import numpy as np

from exobench.core.calibration import Calibration, SensorMount

CAMERA = {"rate_hz": 30.0, "width_px": 424, "height_px": 240, "fx_px": 212.0, "fy_px": 213.0, "cx_px": 211.5,
          "cy_px": 119.5, "min_depth_m": 0.4, "max_depth_m": 6.0, "baseline_m": 0.095}  # fmt: skip
IMU = {"rate_hz": 200.0, "gyro_noise_density": 1.027e-4, "gyro_random_walk": 1.11e-6, "accel_noise_density": 1.038e-3,
       "accel_random_walk": 4.13e-5}  # fmt: skip


def calibration(T_camera_imu: np.ndarray | None = None, shift_s: float | None = None) -> Calibration:
    """A head camera and its IMU, with the extras the simulation's calibration carries."""
    extra: dict = {"camera": "rgbd_head", "camera_imu": "imu_head"}
    if T_camera_imu is not None:
        extra["T_camera_imu"] = np.asarray(T_camera_imu).tolist()
    if shift_s is not None:
        extra["timeshift_cam_imu_s"] = shift_s
    mounts = (SensorMount("rgbd_head", "rgbd", "head", np.eye(4), dict(CAMERA)),
              SensorMount("imu_head", "imu", "head", np.eye(4), dict(IMU)))  # fmt: skip
    return Calibration("", "pelvis", (), mounts, 0.08, 0.25, 0.05, extra)


@functools.cache
def walk():
    """A 7.5 s ramp-course walk (5.4 m), head camera at 424x240 and 15 Hz with its 200 Hz IMU, textured walls
    (what ORB-SLAM3 needs: more than 500 ORB features to start a map)."""
    from exobench.envs.sim.scenarios.course import LocomotionScenario, simulate_locomotion

    sc = LocomotionScenario(terrain="ramp", mount="head", rate_hz=15.0, duration_cap_s=7.5, surfaces="textured",
                            gaze="random", head_pitch_std_rad=0.05)  # fmt: skip
    return simulate_locomotion(sc, 0)


@functools.cache
def vocabulary(folder: str) -> Path:
    """A vocabulary of another walk (stairs, other textures and seed), in ``folder``."""
    from exobench.core.frames import RgbdFrame
    from exobench.envs.sim.scenarios.course import LocomotionScenario, simulate_locomotion
    from exobench.mapping.odometry.orbslam3 import vocabulary as voc

    sc = LocomotionScenario(terrain="stairs", mount="chest", rate_hz=5.0, duration_cap_s=12.0, surfaces="textured",
                            texture_seed=77)  # fmt: skip
    import cv2

    images = [cv2.cvtColor(f.rgb, cv2.COLOR_RGB2GRAY) for f in simulate_locomotion(sc, 3).frames if isinstance(f, RgbdFrame)]
    tree = voc.build_tree(images, voc.VocabularyParams(levels=4))
    return voc.write_vocabulary(Path(folder) / "orbvoc-test.txt", tree)
