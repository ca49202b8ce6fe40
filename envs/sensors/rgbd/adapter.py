"""The RGB-D camera inside the simulation core: renders at every ``k / rate_hz``.

Truth (``SensorOutput.truth``): ``t_s`` measurement times (N,), ``T_world_sensor`` (N, 4, 4) of
the optical frame at each (lost frames included), ``watch_fraction`` (N, G) share of the image
covered by each group of the recording's watched geoms (pedestrians). With
``RgbdConfig.segmentation_truth``, one :class:`~exobench.core.SegmentationTruth` per emitted frame
(``SensorOutput.frame_truth``; :mod:`.segmentation`). The geom ids are rendered only for these
two consumers (watched geoms, segmentation truth) or when the config asks (``segmentation``).
Chunked: ``take`` hands over the frames captured so far (and their segmentation truth);
``finish`` then the rest and the whole truth. With ``RgbdConfig.exposure_s`` the colour image is
blurred by the camera's motion (:mod:`.blur`; the truth keeps the sharp pose at mid-exposure).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from typing import Any

import numpy as np

from ..adapter import BaseAdapter, MountedSensor, RecordContext, SensorOutput
from ..common import sample_times
from .blur import blur_flow, camera_twist, motion_blur
from .model import RgbdCamera
from .segmentation import SegmentationLabeler


class RgbdAdapter(BaseAdapter):
    chunked = True

    def __init__(self, sensor: MountedSensor, ctx: RecordContext) -> None:
        super().__init__(sensor, ctx)
        self.t = sample_times(sensor.config.rate_hz, ctx.duration_s)
        self.T = np.zeros((len(self.t), 4, 4))
        self.watch = [list(g) for g in ctx.watch_geoms]
        self.fraction = np.zeros((len(self.t), len(self.watch)))
        self.k = 0
        self.frames: list[Any] = []
        c = sensor.config
        # geom ids only for what reads them: the segmentation truth and the watched geoms' shares
        wants_ids = c.segmentation or c.segmentation_truth or any(len(g) for g in self.watch)
        self.camera = RgbdCamera(sensor.sensor_id, c, ctx.model, ctx.seed, segmentation=wants_ids)
        self.labeler = SegmentationLabeler(ctx.model, ctx.scene_truth) if sensor.config.segmentation_truth else None
        self.segmentation: list[Any] = []
        # motion blur reads the camera's velocity: the recorder then sets qvel at its instants
        self.needs_dynamics = c.exposure_s > 0.0

    def instants(self) -> np.ndarray:
        return self.t

    def observe(self, model: Any, data: Any, t: float) -> None:
        import mujoco

        mujoco.mj_camlight(model, data)
        frame, tr = self.camera.capture(model, data, t)
        if frame is not None and self.config.exposure_s > 0.0:
            v, w = camera_twist(model, data, self.camera.cam)
            du, dv = blur_flow(tr["depth_m"], frame.K, v, w, self.config.exposure_s)
            frame = dataclasses.replace(frame, rgb=motion_blur(frame.rgb, du, dv))
        k = self.k
        self.T[k] = tr["T_world_sensor"]
        for i, gs in enumerate(self.watch):
            self.fraction[k, i] = float(np.isin(tr["geom_id"], gs).mean())
        if frame is not None:
            self.frames.append(frame)
            if self.labeler is not None:
                self.segmentation.append(self.labeler.label(frame.stamp_s, self.sensor_id, tr["geom_id"], tr["depth_m"],
                                                            tr["T_world_sensor"], tr["K"]))  # fmt: skip
        self.k += 1

    def finish(self) -> SensorOutput:
        seg = self.segmentation if self.labeler is not None else None
        return SensorOutput(self.frames, seg, {"t_s": self.t, "T_world_sensor": self.T, "watch_fraction": self.fraction})

    def take(self) -> SensorOutput:
        out = self.finish()
        self.frames, self.segmentation = [], []
        return out

    def close(self) -> None:
        self.camera.close()

    @staticmethod
    def calibration_params(sensor: MountedSensor) -> dict[str, Any]:
        c = sensor.config
        return {"rate_hz": c.rate_hz, "width_px": c.width_px, "height_px": c.height_px, "fx_px": c.fx_px,
                "fy_px": c.fy_px, "cx_px": c.cx_px, "cy_px": c.cy_px, "min_depth_m": c.min_depth_m,
                "max_depth_m": c.max_depth_m, "latency_s": c.latency_s, "subpixel": c.subpixel,
                "baseline_m": c.baseline_m}  # fmt: skip

    @staticmethod
    def calibration_extra(sensor: MountedSensor, rig: Sequence[MountedSensor]) -> dict[str, Any]:
        """The first camera of a rig: ``camera``, its IMU (``camera_imu``; ``T_camera_imu``, the IMU's
        pose in the optical frame; ``timeshift_cam_imu_s``, t_imu = t_cam + shift, kalibr's
        convention, only when not 0 so that calibrations of before are unchanged) and odometry."""
        if next(s for s in rig if s.kind == "rgbd") is not sensor:
            return {}
        cam = sensor.sensor_id
        imu = [s for s in rig if s.kind == "imu" and s.attached_to == cam]
        odom = [s for s in rig if s.kind == "odometry" and s.attached_to == cam]
        out: dict[str, Any] = {"camera": cam}
        if imu:
            out["camera_imu"] = imu[0].sensor_id
        if odom:
            out["odometry"] = {
                "sensor_id": odom[0].sensor_id, "tracks": cam, "T_camera_body": np.eye(4).tolist(),
                "frame": "gravity-aligned (z up); origin and heading of the camera at the first frame",
                "rate_hz": odom[0].config.rate_hz,
            }  # fmt: skip
        if imu:
            out["T_camera_imu"] = imu[0].config.T_camera_imu().tolist()
            if imu[0].config.time_offset_s != 0.0:
                out["timeshift_cam_imu_s"] = float(imu[0].config.time_offset_s)
        return out
