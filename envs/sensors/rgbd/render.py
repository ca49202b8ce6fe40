"""Off-screen MuJoCo rendering for the RGB-D cameras: GL back-end choice, exact intrinsics, and
colour, depth and (when asked) segmentation from two render passes.

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

Passes (:class:`RgbdRenderer`). The images are those :class:`mujoco.Renderer` gives in its depth,
segmentation and colour modes, bit for bit, from two passes instead of three:

1. a segmentation-mode pass (flat ID colours, no multisampling, no skybox): its depth buffer is
   the depth (``mujoco.Renderer`` renders depth this way too), and its colour buffer, read in the
   same ``mjr_readPixels`` call only when segmentation is asked for, the geom ids. It draws into
   a context of its own with a single-sample buffer: MuJoCo turns multisampling off in this
   mode, so every sample of the model's multisampled buffer holds the pixel centre's depth and
   ID colour, which are what a single-sample buffer holds, without writing four samples and
   resolving them (half the pass's time);
2. the colour pass, in a context with the model's buffer (multisampled, with the shadow map).
   Its own depth buffer cannot stand in for pass 1's: the colour pass is multisampled (the
   resolve takes a sample off the pixel centre: the depth differs in the last bits on every
   surface pixel) and draws the skybox at 0.7 of the far plane, where pass 1 leaves no surface.

Glass. With ``RgbdConfig.depth_through_glass`` (the default) pass 1 leaves out the transparent
geoms (rgba alpha < 1: the glass panes, which pass 2 draws see-through without writing depth), so
the depth and the geom ids are those of the surface behind the pane, as a D455's IR projector and
imagers see through clear glass (docs/vio-realism.md, "Depth through glass"). The colour image
is unchanged. Without it, pass 1 is :class:`mujoco.Renderer`'s: the pane's depth and id.

Both contexts live in one GL context (``mjr_render`` draws into whichever buffer is bound, so
each pass binds its own first). The off-screen buffers are made exactly the image's size (the
model's ``offwidth`` x ``offheight``, 1280 x 960 on exobench's worlds, would be cleared and kept
for nothing); the viewport, and so every pixel, is the same.
"""

from __future__ import annotations

import os
import sys
from typing import TYPE_CHECKING, Any

import numpy as np

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


def prepare_model(model: mujoco.MjModel, config: RgbdConfig) -> None:
    """Fit ``model``'s visual settings to the camera: enlarge the off-screen buffer
    (``vis.global_.offwidth/offheight``) when it is smaller than the image, and bring the near
    clipping plane (``vis.map.znear``) below half the minimum depth when it lies beyond it, so
    that no surface inside the depth range is clipped."""
    g = model.vis.global_
    g.offwidth = max(int(g.offwidth), config.width_px)
    g.offheight = max(int(g.offheight), config.height_px)
    extent = float(model.stat.extent)
    if config.min_depth_m > 0 and model.vis.map.znear * extent > 0.5 * config.min_depth_m:
        model.vis.map.znear = 0.5 * config.min_depth_m / extent


def _render_error(backend: str, err: Exception) -> RenderError:
    return RenderError(
        f"cannot create an off-screen renderer with MUJOCO_GL={backend or '(unset)'}: {err}. "
        "Set MUJOCO_GL=egl or MUJOCO_GL=osmesa before mujoco is imported (or leave it unset "
        "and let exobench choose); install libegl1 or libosmesa6."
    )


def make_renderer(model: mujoco.MjModel, config: RgbdConfig) -> RgbdRenderer:
    """An :class:`RgbdRenderer` of the config's image size for ``model`` (after
    :func:`prepare_model`)."""
    backend = select_gl_backend()
    prepare_model(model, config)
    try:
        return RgbdRenderer(model, config)
    except Exception as err:  # the GL wrappers raise ImportError, RuntimeError, GLError ...
        raise _render_error(backend, err) from err


class RgbdRenderer:
    """One camera's GL context, MuJoCo scene and read-back buffers (module docstring: passes).

    :meth:`render` returns what :class:`mujoco.Renderer` would in its three modes: colour
    (H, W, 3) uint8, z-depth (H, W) float32 m (the far plane where nothing is drawn), and with
    ``segmentation`` the geom id of each pixel (-1: background or not a geom), else None.
    """

    def __init__(self, model: mujoco.MjModel, config: RgbdConfig) -> None:
        import mujoco

        self.model, self.config = model, config
        w, h = config.width_px, config.height_px
        self._gl: Any = None
        self._con: Any = None
        self._depth_con: Any = None
        self._gl = mujoco.GLContext(w, h)
        try:
            self._gl.make_current()
            q = model.vis.quality
            self._con = _make_context(model, w, h, int(q.offsamples), int(q.shadowsize))
            # the depth pass needs neither samples nor a shadow map (module docstring)
            self._depth_con = _make_context(model, w, h, 0, 0) if self._con.offSamples else self._con
        except Exception:
            self.close()
            raise
        self._offscreen = mujoco.mjtFramebuffer.mjFB_OFFSCREEN.value
        for con in (self._con, self._depth_con):
            con.readDepthMap = mujoco.mjtDepthMap.mjDEPTH_ZEROFAR  # as mujoco.Renderer
        self.scene = mujoco.MjvScene(model=model, maxgeom=10000)
        self._option = mujoco.MjvOption()
        self._camera = mujoco.MjvCamera()
        self._camera.type = mujoco.mjtCamera.mjCAMERA_FIXED
        self._rect = mujoco.MjrRect(0, 0, w, h)
        self._rgb = np.empty((h, w, 3), dtype=np.uint8)
        self._ids = np.empty((h, w, 3), dtype=np.uint8)
        self._depth = np.empty((h, w), dtype=np.float32)
        self._flag = {n: int(getattr(mujoco.mjtRndFlag, f"mjRND_{n}")) for n in ("SEGMENT", "IDCOLOR", "SHADOW")}
        self._geom_type = int(mujoco.mjtObj.mjOBJ_GEOM)
        self._box = int(mujoco.mjtGeom.mjGEOM_BOX)

    def update_scene(self, data: mujoco.MjData, camera: int) -> None:
        """The scene of ``data`` seen from the model's camera ``camera`` (then :func:`set_intrinsics`)."""
        import mujoco

        self._camera.fixedcamid = int(camera)
        mujoco.mjv_updateScene(self.model, data, self._option, None, self._camera,
                               mujoco.mjtCatBit.mjCAT_ALL.value, self.scene)  # fmt: skip

    def render(self, segmentation: bool, shadows: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
        """Colour, z-depth and (with ``segmentation``) geom ids of the scene as it was last
        updated; rows top-down (OpenGL's are bottom-up)."""
        import mujoco

        if self._con is None:
            raise RuntimeError("render cannot be called after close")
        self._gl.make_current()
        flags = self.scene.flags
        flags[self._flag["SEGMENT"]] = flags[self._flag["IDCOLOR"]] = 1
        hidden = self._hide_transparent() if self.config.depth_through_glass else []
        mujoco.mjr_setBuffer(self._offscreen, self._depth_con)
        mujoco.mjr_render(self._rect, self.scene, self._depth_con)
        mujoco.mjr_readPixels(self._ids if segmentation else None, self._depth, self._rect, self._depth_con)
        for g, gtype, size in hidden:  # the colour pass draws the scene as it was updated
            g.type, g.size[:] = gtype, size
        depth = self._metric_depth(self._depth[::-1])
        geom_id = self._geom_ids(self._ids[::-1]) if segmentation else None
        flags[self._flag["SEGMENT"]] = flags[self._flag["IDCOLOR"]] = 0
        flags[self._flag["SHADOW"]] = int(bool(shadows))
        mujoco.mjr_setBuffer(self._offscreen, self._con)
        mujoco.mjr_render(self._rect, self.scene, self._con)
        mujoco.mjr_readPixels(self._rgb, None, self._rect, self._con)
        return np.ascontiguousarray(self._rgb[::-1]), depth, geom_id

    def _hide_transparent(self) -> list[tuple[Any, int, np.ndarray]]:
        """Collapse the scene's transparent geoms (alpha < 1: the glass, which the colour pass
        draws see-through) to a box of size zero, which covers no pixel, so that the depth pass
        gives the surface behind them (module docstring); returns what :meth:`render` restores.
        Segmentation mode draws every geom opaque with its id colour, alpha aside, so hiding
        them is the only way to leave them out of this pass."""
        hidden = []
        for g in self.scene.geoms[: self.scene.ngeom]:
            if g.rgba[3] < 1.0 and g.objtype == self._geom_type:
                hidden.append((g, int(g.type), g.size.copy()))
                g.type, g.size[:] = self._box, 0.0
        return hidden

    def _metric_depth(self, buffer: np.ndarray) -> np.ndarray:
        """Depth in metres from the reversed-Z buffer, with mujoco.Renderer's arithmetic
        (float32 clip planes, float64 division, float32 result) so that it is bit-identical."""
        extent = self.model.stat.extent
        zfar = np.float32(self.model.vis.map.zfar * extent)
        znear = np.float32(self.model.vis.map.znear * extent)
        z = buffer.astype(np.float64)
        if self.scene.camera[0].orthographic:
            z = zfar - z * (zfar - znear)
        else:
            c_coef = -(zfar + znear) / (zfar - znear)
            d_coef = -(np.float32(2) * zfar * znear) / (zfar - znear)
            c_coef = np.float32(-0.5) * c_coef - np.float32(0.5)
            d_coef = np.float32(-0.5) * d_coef
            z = d_coef / (z + c_coef)
        return z.astype(np.float32)

    def _geom_ids(self, id_colour: np.ndarray) -> np.ndarray:
        """Geom id per pixel from the ID colours (segid + 1 as 24-bit RGB; 0 background)."""
        n = self.scene.ngeom
        table = np.full(n + 1, -1, dtype=np.int32)  # segid + 1 <= ngeom
        for g in self.scene.geoms[:n]:
            if g.segid != -1 and g.objtype == self._geom_type:
                table[g.segid + 1] = g.objid
        c = id_colour.astype(np.uint32)
        return table[c[..., 0] + c[..., 1] * (2**8) + c[..., 2] * (2**16)]

    def close(self) -> None:
        """Free the MuJoCo and GL contexts (idempotent)."""
        contexts = [c for c in (self._con, self._depth_con) if c is not None]
        if contexts and self._gl is not None:
            self._gl.make_current()
        for con in {id(c): c for c in contexts}.values():
            con.free()
        self._con = self._depth_con = None
        if self._gl is not None:
            self._gl.free()
            self._gl = None


def _make_context(model: mujoco.MjModel, width: int, height: int, samples: int, shadow_size: int) -> mujoco.MjrContext:
    """A MuJoCo render context in the current GL context, its off-screen buffer ``width`` x
    ``height`` with ``samples`` samples and its shadow map ``shadow_size`` square (0: none), bound
    for drawing. MjrContext reads these from the model, which is left as it was."""
    import mujoco

    g, q = model.vis.global_, model.vis.quality
    saved = (int(g.offwidth), int(g.offheight), int(q.offsamples), int(q.shadowsize))
    g.offwidth, g.offheight, q.offsamples, q.shadowsize = width, height, samples, shadow_size
    try:
        con = mujoco.MjrContext(model, mujoco.mjtFontScale.mjFONTSCALE_150.value)
    finally:
        g.offwidth, g.offheight, q.offsamples, q.shadowsize = saved
    mujoco.mjr_setBuffer(mujoco.mjtFramebuffer.mjFB_OFFSCREEN.value, con)
    return con


def set_intrinsics(renderer: RgbdRenderer | mujoco.Renderer, config: RgbdConfig) -> None:
    """Make the scene camera of ``renderer`` (after ``update_scene``) project with the config's K."""
    w, h = config.width_px, config.height_px
    fx, fy, cx, cy = config.fx_px, config.fy_px, config.cx_px, config.cy_px
    for cam in renderer.scene.camera:  # both eyes: mono rendering averages them
        n = cam.frustum_near
        cam.frustum_width = 0.5 * w * n / fx  # MuJoCo stores the half width
        cam.frustum_center = (0.5 * w - cx - 0.5) * n / fx
        cam.frustum_bottom = -(h - cy - 0.5) * n / fy
        cam.frustum_top = (cy + 0.5) * n / fy
