"""RGB-D camera (Intel RealSense D455): :class:`RgbdConfig`, the rendered :class:`RgbdCamera`,
and the off-screen rendering it needs (:func:`select_gl_backend`, :func:`make_renderer`, which
makes an :class:`RgbdRenderer`: two passes a frame)."""

from .config import RgbdConfig, depth_noise_sigma_m, intrinsics
from .model import RgbdCamera, edge_mask
from .render import RgbdRenderer, make_renderer, select_gl_backend, set_intrinsics

__all__ = [
    "RgbdCamera",
    "RgbdConfig",
    "RgbdRenderer",
    "depth_noise_sigma_m",
    "edge_mask",
    "intrinsics",
    "make_renderer",
    "select_gl_backend",
    "set_intrinsics",
]
