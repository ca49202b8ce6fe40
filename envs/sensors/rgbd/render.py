"""Off-screen MuJoCo rendering for the RGB-D cameras: GL back-end choice and exact intrinsics.

MuJoCo picks its OpenGL back-end from ``MUJOCO_GL`` once, when ``mujoco`` is first imported;
:mod:`exobench.envs.gl_platform` chooses it (EGL, then OSMesa) just before that import.
:func:`select_gl_backend` makes the choice now if it has not been made and raises
:class:`RenderError` when it has to choose and no platform works; :func:`make_renderer` raises
:class:`RenderError` when no context can be made.

A MuJoCo camera has square pixels and a centred principal point (its ``fovy`` fixes fy). To render
with any K, :func:`set_intrinsics` overwrites the scene camera's OpenGL frustum after each
``update_scene``: with near plane n, left = -(cx + 1/2) n / fx, right = (W - cx - 1/2) n / fx,
bottom = -(H - cy - 1/2) n / fy, top = (cy + 1/2) n / fy (pixel centres at integer coordinates;
image rows top-down, as :class:`mujoco.Renderer` returns them). The model's camera is unchanged.
"""

from __future__ import annotations

import os
import sys
from typing import TYPE_CHECKING

from exobench.core import RenderError

from ...gl_platform import choose_gl_platform
from .config import RgbdConfig

if TYPE_CHECKING:
    import mujoco

def select_gl_backend() -> str:
    """The GL back-end MuJoCo will use, chosen (EGL, else OSMesa) if ``MUJOCO_GL`` is unset.

    Returns the value of ``MUJOCO_GL`` ("" when it is unset and ``mujoco`` was already imported
    with its default back-end, which cannot be changed any more). Raises :class:`RenderError`
    when it has to choose and neither back-end works.
    """
    if os.environ.get("MUJOCO_GL", "").strip() or "mujoco" in sys.modules:
        return choose_gl_platform()
    backend = choose_gl_platform()
    if backend:
        return backend
    raise RenderError(
        "no off-screen OpenGL back-end works: EGL and OSMesa both failed to render; install "
        "libegl1 (with a GPU or Mesa llvmpipe) or libosmesa6"
    )


def make_renderer(model: mujoco.MjModel, config: RgbdConfig) -> mujoco.Renderer:
    """A :class:`mujoco.Renderer` of the config's image size for ``model``.

    Enlarges the model's off-screen buffer (``vis.global_.offwidth/offheight``) when it is
    smaller than the image, and brings the near clipping plane (``vis.map.znear``) below half the
    minimum depth when it lies beyond it, so that no surface inside the depth range is clipped.
    """
    backend = select_gl_backend()
    import mujoco

    g = model.vis.global_
    g.offwidth = max(int(g.offwidth), config.width_px)
    g.offheight = max(int(g.offheight), config.height_px)
    extent = float(model.stat.extent)
    if config.min_depth_m > 0 and model.vis.map.znear * extent > 0.5 * config.min_depth_m:
        model.vis.map.znear = 0.5 * config.min_depth_m / extent
    try:
        return mujoco.Renderer(model, height=config.height_px, width=config.width_px)
    except Exception as err:  # the GL wrappers raise ImportError, RuntimeError, GLError ...
        raise RenderError(
            f"cannot create an off-screen renderer with MUJOCO_GL={backend or '(unset)'}: {err}. "
            "Set MUJOCO_GL=egl or MUJOCO_GL=osmesa before mujoco is imported (or leave it unset "
            "and let exobench choose); install libegl1 or libosmesa6."
        ) from err


def set_intrinsics(renderer: mujoco.Renderer, config: RgbdConfig) -> None:
    """Make the scene camera of ``renderer`` (after ``update_scene``) project with the config's K."""
    w, h = config.width_px, config.height_px
    fx, fy, cx, cy = config.fx_px, config.fy_px, config.cx_px, config.cy_px
    for cam in renderer.scene.camera:  # both eyes: mono rendering averages them
        n = cam.frustum_near
        cam.frustum_width = 0.5 * w * n / fx  # MuJoCo stores the half width
        cam.frustum_center = (0.5 * w - cx - 0.5) * n / fx
        cam.frustum_bottom = -(h - cy - 0.5) * n / fy
        cam.frustum_top = (cy + 0.5) * n / fy
