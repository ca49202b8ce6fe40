"""RGB-D camera (Intel RealSense D455) rendered by MuJoCo: colour, depth with the stereo noise model.

A camera named like the sensor id (``rgbd_head``, ``rgbd_chest``, ``rgbd_thigh_l``,
``rgbd_thigh_r`` on the exoskeleton; any MuJoCo camera works) is rendered with the config's
intrinsics (:func:`~exobench.envs.sensors.rgbd.render.set_intrinsics`) by one
:class:`~exobench.envs.sensors.rgbd.render.RgbdRenderer` kept for the camera's life (two render
passes a frame: depth, with the geom ids when asked, then colour). Depth is MuJoCo's depth buffer
converted to metres: the distance along the optical axis (z-depth, not the range along the pixel ray), as a RealSense reports it. The
camera sees what MuJoCo renders by default: geom groups 0-2, i.e. the world and the exoskeleton.

Depth model, per pixel, from the noise-free depth z (``docs/sensor-reference.md``):

1. no surface (the far clipping plane) -> invalid;
2. depth discontinuity: a 4-neighbour's z differs by more than ``edge_threshold_rel`` times the
   nearer z -> invalid (on the noise-free z, so noise does not create edges; no surface counts
   as infinitely far);
3. measured z' = z + sigma(z) * N(0, 1), sigma(z) = z^2 * s / (fx * baseline);
4. quantised to ``resolution_m``; invalid outside [min_depth_m, max_depth_m] (tested on z', as
   the device only knows its measurement); random pixel dropout;
5. invalid pixels are 0. Colour is rendered with lights and textures and is noise-free.

Each camera draws from its own generators (:func:`~exobench.envs.sensors.common.sensor_rngs`): the
noise stream draws one standard normal per pixel per frame; the dropout stream one uniform per
frame (frame loss) plus one per pixel when ``pixel_dropout_prob > 0``. Same seed, same frames.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from exobench.core import RgbdFrame, UnknownNameError
from exobench.core.transforms import make_T
from exobench.models.exo import R_OPTICAL_MJCAMERA

from ..common import sensor_rngs
from .config import RgbdConfig, depth_noise_sigma_m, intrinsics
from .render import make_renderer, select_gl_backend, set_intrinsics

if TYPE_CHECKING:
    import mujoco

__all__ = ["RgbdCamera", "edge_mask"]

_FAR_FRACTION = 0.999  # depths beyond this fraction of the far plane are background


def edge_mask(depth_m: np.ndarray, threshold_rel: float) -> np.ndarray:
    """Pixels next to a depth discontinuity: some 4-neighbour differs by more than
    ``threshold_rel`` times the nearer of the two depths. (H, W) bool; all False when 0."""
    z = np.asarray(depth_m, dtype=float)
    out = np.zeros(z.shape, dtype=bool)
    if threshold_rel <= 0:
        return out
    with np.errstate(invalid="ignore"):  # inf - inf between two background pixels: no edge
        dv = np.abs(z[1:, :] - z[:-1, :]) > threshold_rel * np.minimum(z[1:, :], z[:-1, :])
        du = np.abs(z[:, 1:] - z[:, :-1]) > threshold_rel * np.minimum(z[:, 1:], z[:, :-1])
    out[1:, :] |= dv
    out[:-1, :] |= dv
    out[:, 1:] |= du
    out[:, :-1] |= du
    return out


class RgbdCamera:
    """One RGB-D camera: call :meth:`capture` at each frame time after MuJoCo's kinematics
    (``mj_forward`` or ``mj_kinematics`` + ``mj_camlight``). Call :meth:`close` when done.

    ``segmentation``: render the geom ids of each frame (the truth's ``geom_id``); None = when
    the config asks (``segmentation`` or ``segmentation_truth``). A recording derives it from
    what reads the ids (:class:`~exobench.envs.sensors.rgbd.adapter.RgbdAdapter`)."""

    def __init__(self, sensor_id: str, config: RgbdConfig, model: mujoco.MjModel, seed: int,
                 segmentation: bool | None = None) -> None:  # fmt: skip
        select_gl_backend()  # before mujoco is imported, if this is the first import
        import mujoco

        self.sensor_id, self.config = sensor_id, config
        self.cam = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_CAMERA, sensor_id)
        if self.cam < 0:
            names = [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_CAMERA, i) or "" for i in range(model.ncam)]
            raise UnknownNameError("camera", sensor_id, names)
        self.K = intrinsics(config)
        self.noise_rng, self.drop_rng = sensor_rngs(seed, sensor_id)
        # reading and decoding the geom ids costs about a tenth of a frame: only when something reads them
        self.segmentation = bool(config.segmentation or config.segmentation_truth) if segmentation is None else bool(segmentation)
        self.renderer = make_renderer(model, config)

    def pose(self, data: mujoco.MjData) -> np.ndarray:
        """``T_world_sensor`` of the optical frame (z forward, x right, y down), 4x4."""
        R_world_mjcam = data.cam_xmat[self.cam].reshape(3, 3)
        return make_T(R_world_mjcam @ R_OPTICAL_MJCAMERA, data.cam_xpos[self.cam].copy())

    def render(self, data: mujoco.MjData) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Noise-free (rgb (H, W, 3) uint8, z-depth (H, W) float32 m with 0 = no surface,
        geom ids (H, W) int32 with -1 = no geom; all -1 without :attr:`segmentation`)."""
        r = self.renderer
        r.update_scene(data, self.cam)
        set_intrinsics(r, self.config)
        rgb, depth, geom_id = r.render(self.segmentation, self.config.shadows)
        if geom_id is None:
            geom_id = np.full(depth.shape, -1, dtype=np.int32)
        far = r.model.vis.map.zfar * r.model.stat.extent
        depth[depth >= _FAR_FRACTION * far] = 0.0
        return rgb, depth, geom_id

    def measure(self, depth_true_m: np.ndarray) -> np.ndarray:
        """The measured depth image (float32, 0 = invalid) from a noise-free one (0 = no surface)."""
        c = self.config
        z = depth_true_m.astype(np.float64)
        valid = z > 0
        valid &= ~edge_mask(np.where(valid, z, np.inf), c.edge_threshold_rel)
        zm = z + depth_noise_sigma_m(z, c) * self.noise_rng.standard_normal(z.shape)
        if c.resolution_m > 0:
            zm = np.round(zm / c.resolution_m) * c.resolution_m
        valid &= (zm >= c.min_depth_m) & (zm <= c.max_depth_m)
        if c.pixel_dropout_prob > 0:
            valid &= self.drop_rng.random(z.shape) >= c.pixel_dropout_prob
        return np.where(valid, zm, 0.0).astype(np.float32)

    def capture(self, model: mujoco.MjModel, data: mujoco.MjData, t: float) -> tuple[RgbdFrame | None, dict[str, Any]]:
        """Render and measure one frame at measurement time ``t`` (s).

        Returns ``(frame, truth)``; ``frame`` is None when the frame is dropped (``dropout_prob``).
        ``truth``: ``t_s`` (measurement time), ``stamp_s`` (t + latency), ``depth_m`` (noise-free
        z-depth, float32, 0 = no surface), ``geom_id`` (segmentation: geom id per pixel, int32,
        -1 = none), ``T_world_sensor`` (optical frame, 4x4), ``K``.
        """
        if model is not self.renderer.model:
            raise ValueError(f"camera {self.sensor_id!r} was made for another MjModel")
        rgb, depth_true, geom_id = self.render(data)
        lost = self.drop_rng.random() < self.config.dropout_prob
        depth = self.measure(depth_true)
        stamp = t + self.config.latency_s
        truth = {
            "t_s": t,
            "stamp_s": stamp,
            "depth_m": depth_true,
            "geom_id": geom_id,
            "T_world_sensor": self.pose(data),
            "K": self.K.copy(),
        }
        frame = None if lost else RgbdFrame(stamp, self.sensor_id, rgb, depth, self.K.copy())
        return frame, truth

    def close(self) -> None:
        """Free the renderer's GL context."""
        self.renderer.close()

    def __enter__(self) -> RgbdCamera:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
