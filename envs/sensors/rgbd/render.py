"""Off-screen MuJoCo rendering for the RGB-D cameras: GL back-end choice and exact intrinsics.

MuJoCo picks its OpenGL back-end from ``MUJOCO_GL`` once, when ``mujoco`` is first imported.
:func:`select_gl_backend` therefore runs before that import: when ``MUJOCO_GL`` is unset it probes
EGL, then OSMesa, each in a short subprocess (a failed GL initialisation cannot be undone in this
process), and sets ``MUJOCO_GL`` (and ``PYOPENGL_PLATFORM``) to the first that renders. An explicit
``MUJOCO_GL`` is respected. :func:`make_renderer` raises :class:`RenderError` when no context can
be made.

A MuJoCo camera has square pixels and a centred principal point (its ``fovy`` fixes fy). To render
with any K, :func:`set_intrinsics` overwrites the scene camera's OpenGL frustum after each
``update_scene``: with near plane n, left = -(cx + 1/2) n / fx, right = (W - cx - 1/2) n / fx,
bottom = -(H - cy - 1/2) n / fy, top = (cy + 1/2) n / fy (pixel centres at integer coordinates;
image rows top-down, as :class:`mujoco.Renderer` returns them). The model's camera is unchanged.
"""

from __future__ import annotations

import os
import subprocess
import sys
from typing import TYPE_CHECKING

from exobench.core import RenderError

from .config import RgbdConfig

if TYPE_CHECKING:
    import mujoco

GL_BACKENDS = ("egl", "osmesa")
_PROBE = (
    "import mujoco\n"
    "m = mujoco.MjModel.from_xml_string('<mujoco><worldbody><geom size=\"1\"/></worldbody></mujoco>')\n"
    "r = mujoco.Renderer(m, 8, 8)\n"
    "r.update_scene(mujoco.MjData(m))\n"
    "r.render()\n"
    "r.close()\n"
)


def _probe(backend: str) -> bool:
    env = dict(os.environ, MUJOCO_GL=backend, PYOPENGL_PLATFORM=backend)
    try:
        res = subprocess.run([sys.executable, "-c", _PROBE], env=env, capture_output=True, timeout=120)
    except (OSError, subprocess.SubprocessError):
        return False
    return res.returncode == 0


def select_gl_backend() -> str:
    """The GL back-end MuJoCo will use, chosen (EGL, else OSMesa) if ``MUJOCO_GL`` is unset.

    Returns the value of ``MUJOCO_GL`` ("" when it is unset and ``mujoco`` was already imported
    with its default back-end, which cannot be changed any more). Raises :class:`RenderError`
    when it has to choose and neither back-end works.
    """
    backend = os.environ.get("MUJOCO_GL", "").strip().lower()
    if backend or "mujoco" in sys.modules:
        return backend
    for candidate in GL_BACKENDS:
        if _probe(candidate):
            os.environ["MUJOCO_GL"] = candidate
            os.environ.setdefault("PYOPENGL_PLATFORM", candidate)
            return candidate
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
