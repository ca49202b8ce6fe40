"""Motion blur of a rendered colour image from the camera's motion during the exposure.

A rolling camera that moves while its shutter is open smears each scene point along the path
its image takes. The renderer draws one instant; this post-process spreads every pixel along its
image motion over the exposure, centred on the frame's measurement time (a frame's stamp is the
middle of its exposure):

- the image motion of a pixel comes from the camera's twist in its optical frame (linear ``v``
  and angular ``w``, from MuJoCo's velocities at that instant) and the pixel's true depth ``Z``
  (:func:`blur_flow`): a point P = Z (x, y, 1) moves at dP/dt = -v - w x P relative to the
  camera; its pixel moves at fx (dX/dt - x dZ/dt) / Z (and likewise in v); pixels without depth
  (sky, beyond the far plane) move with the rotation alone, as points at infinity;
- the blurred pixel is the mean of the sharp image sampled (bilinearly, clamped at the borders)
  at evenly spaced points of that path (:func:`motion_blur`), as many as the longest path has
  pixels (at most ``max_taps``).

Constant velocity over the exposure and a path per pixel from the sharp image (occlusion changes
during the exposure are not drawn) are the model's approximations [A]. The depth image is left
sharp: the D455's depth comes from its global-shutter infrared pair with short exposures.
"""

from __future__ import annotations

import numpy as np


def camera_twist(model: object, data: object, cam: int) -> tuple[np.ndarray, np.ndarray]:
    """(linear velocity m/s, angular velocity rad/s) of a camera, both in its optical frame
    (z forward, x right, y down). Needs ``qvel`` and ``mj_comVel`` (the recorder's dynamics)."""
    import mujoco

    from exobench.models.exo import R_OPTICAL_MJCAMERA

    res = np.zeros(6)
    mujoco.mj_objectVelocity(model, data, mujoco.mjtObj.mjOBJ_CAMERA, cam, res, 1)
    R = np.asarray(R_OPTICAL_MJCAMERA)  # optical axes in MuJoCo's camera frame (x right, y up, z back)
    return R.T @ res[3:], R.T @ res[:3]


def blur_flow(depth_m: np.ndarray, K: np.ndarray, v: np.ndarray, w: np.ndarray, exposure_s: float) -> tuple[np.ndarray, np.ndarray]:
    """Image displacement (du, dv) in pixels of every pixel over ``exposure_s``, from the camera's
    twist (``v``, ``w`` in the optical frame) and the true z-depth (0 = no surface: rotation only)."""
    h, w_px = depth_m.shape
    fx, fy, cx, cy = K[0, 0], K[1, 1], K[0, 2], K[1, 2]
    vv, uu = np.mgrid[0:h, 0:w_px].astype(float)
    x, y = (uu - cx) / fx, (vv - cy) / fy
    # rotation: d(x, y, 1)/dt = -w x (x, y, 1)
    dxr = -(w[1] * 1.0 - w[2] * y)
    dyr = -(w[2] * x - w[0] * 1.0)
    dzr = -(w[0] * y - w[1] * x)
    du = fx * (dxr - x * dzr)
    dv = fy * (dyr - y * dzr)
    inv_z = np.divide(1.0, depth_m, out=np.zeros(depth_m.shape), where=depth_m > 0)
    du += fx * inv_z * (-v[0] + x * v[2])
    dv += fy * inv_z * (-v[1] + y * v[2])
    return du * exposure_s, dv * exposure_s


def _bilinear(img: np.ndarray, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    h, w = img.shape[:2]
    u = np.clip(u, 0.0, w - 1.0)
    v = np.clip(v, 0.0, h - 1.0)
    u0 = np.minimum(u.astype(int), w - 2) if w > 1 else np.zeros(u.shape, int)
    v0 = np.minimum(v.astype(int), h - 2) if h > 1 else np.zeros(v.shape, int)
    fu, fv = (u - u0)[..., None], (v - v0)[..., None]
    u1, v1 = np.minimum(u0 + 1, w - 1), np.minimum(v0 + 1, h - 1)
    return (img[v0, u0] * (1 - fu) * (1 - fv) + img[v0, u1] * fu * (1 - fv)
            + img[v1, u0] * (1 - fu) * fv + img[v1, u1] * fu * fv)  # fmt: skip


def motion_blur(rgb: np.ndarray, du: np.ndarray, dv: np.ndarray, max_taps: int = 32) -> np.ndarray:
    """``rgb`` (H, W, 3) uint8 averaged along each pixel's displacement (du, dv), centred on it."""
    length = float(np.max(np.hypot(du, dv))) if du.size else 0.0
    n = int(min(max_taps, max(1, np.ceil(length) + 1)))
    if n == 1:
        return rgb.copy()
    img = rgb.astype(np.float64)
    h, w = rgb.shape[:2]
    vv, uu = np.mgrid[0:h, 0:w].astype(float)
    acc = np.zeros_like(img)
    for s in np.linspace(-0.5, 0.5, n):
        acc += _bilinear(img, uu + s * du, vv + s * dv)
    return np.clip(np.rint(acc / n), 0, 255).astype(np.uint8)
