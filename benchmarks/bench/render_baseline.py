"""The RGB-D rendering exobench had before issue 26 (three passes a frame: depth, segmentation,
colour, each through :class:`mujoco.Renderer`), kept as the baseline that `exobench bench
locomotion` measures the two-pass :class:`~exobench.envs.sensors.rgbd.render.RgbdRenderer`
against, and as the reference its images are tested bit for bit against."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

import numpy as np

from exobench.envs.sensors.rgbd import RgbdCamera, RgbdConfig
from exobench.envs.sensors.rgbd.render import prepare_model, select_gl_backend, set_intrinsics

_FAR_FRACTION = 0.999  # as RgbdCamera: depths beyond this fraction of the far plane are background


class ThreePassCamera(RgbdCamera):
    """An :class:`RgbdCamera` rendering as before: a :class:`mujoco.Renderer` with the model's
    off-screen buffer, and the geom ids rendered on every frame (the old default,
    ``segmentation=True``) whatever ``segmentation`` says."""

    def __init__(self, sensor_id: str, config: RgbdConfig, model: Any, seed: int, segmentation: bool | None = None) -> None:
        select_gl_backend()
        import mujoco

        prepare_model(model, config)
        self._baseline = mujoco.Renderer(model, height=config.height_px, width=config.width_px)
        try:
            super().__init__(sensor_id, config, model, seed, segmentation=True)
        except Exception:
            self._baseline.close()
            raise
        self.renderer.close()  # the two-pass renderer RgbdCamera made; only its model is used
        self._geom_type = int(mujoco.mjtObj.mjOBJ_GEOM)
        self._shadow_flag = int(mujoco.mjtRndFlag.mjRND_SHADOW)

    def render(self, data: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        r = self._baseline
        r.update_scene(data, camera=self.cam)
        set_intrinsics(r, self.config)
        r.scene.flags[self._shadow_flag] = bool(self.config.shadows)
        r.enable_depth_rendering()
        depth = r.render().copy()
        r.enable_segmentation_rendering()
        seg = r.render()
        r.disable_segmentation_rendering()
        geom_id = np.where(seg[..., 1] == self._geom_type, seg[..., 0], -1).astype(np.int32)
        rgb = r.render().copy()
        far = r.model.vis.map.zfar * r.model.stat.extent
        depth[depth >= _FAR_FRACTION * far] = 0.0
        return rgb, depth, geom_id

    def close(self) -> None:
        self._baseline.close()


@contextmanager
def three_pass_rendering() -> Iterator[None]:
    """Within the block, recordings render their RGB-D cameras with :class:`ThreePassCamera`."""
    from exobench.envs.sensors.rgbd import adapter

    saved = adapter.RgbdCamera
    adapter.RgbdCamera = ThreePassCamera  # type: ignore[misc]
    try:
        yield
    finally:
        adapter.RgbdCamera = saved  # type: ignore[misc]
