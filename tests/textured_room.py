"""A textured box room rendered by hand (ray-box intersection, bilinear texture lookup): RGB-D
views at any camera pose for the multisession tests, independent of MuJoCo.

Camera convention of OpenCV: x right, y down, z forward; ``T_world_cam`` maps camera to world.
Depth is the z coordinate of the hit in the camera frame (as the depth sensors give it).
"""

from __future__ import annotations

import cv2
import numpy as np
from scipy.ndimage import map_coordinates

WIDTH, HEIGHT = 424, 240  # the thigh camera of issue 28
FX = FY = 212.0  # 90 degrees horizontal field of view
K = np.array([[FX, 0.0, (WIDTH - 1) / 2], [0.0, FY, (HEIGHT - 1) / 2], [0.0, 0.0, 1.0]])
PX_PER_M = 120.0


def _texture(rng: np.random.Generator, w_m: float, h_m: float) -> np.ndarray:
    """Grey texture of a w_m x h_m face: blobs, rectangles and fine noise (rows = second axis)."""
    h, w = int(h_m * PX_PER_M), int(w_m * PX_PER_M)
    img = np.full((h, w), 128, np.uint8)
    for _ in range(int(w_m * h_m * 40)):
        c = (int(rng.integers(w)), int(rng.integers(h)))
        grey = int(rng.integers(0, 256))
        if rng.random() < 0.5:
            cv2.circle(img, c, int(rng.integers(4, 30)), grey, -1)
        else:
            d = rng.integers(5, 40, 2)
            cv2.rectangle(img, c, (c[0] + int(d[0]), c[1] + int(d[1])), grey, -1)
    noise = rng.normal(0, 12, (h, w))
    return np.clip(cv2.GaussianBlur(img, (3, 3), 0) + noise, 0, 255).astype(np.uint8)


class TexturedRoom:
    """Axis-aligned box ``[0, size_x] x [0, size_y] x [0, size_z]`` (m) seen from inside, each of
    its six faces with its own texture drawn from ``seed``."""

    def __init__(self, size: tuple[float, float, float] = (6.0, 5.0, 3.0), seed: int = 0) -> None:
        self.size = np.asarray(size, float)
        rng = np.random.default_rng(seed)
        # face (axis, side): texture over the two other axes (in increasing axis order)
        self.textures = {}
        for axis in range(3):
            a, b = [i for i in range(3) if i != axis]
            for side in (0, 1):
                self.textures[(axis, side)] = _texture(rng, self.size[a], self.size[b])

    def render(self, T_world_cam: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Grey image (HEIGHT, WIDTH) uint8 and depth (HEIGHT, WIDTH) float32 m from a camera
        inside the room."""
        u, v = np.meshgrid(np.arange(WIDTH), np.arange(HEIGHT))
        rays_cam = np.stack([(u - K[0, 2]) / FX, (v - K[1, 2]) / FY, np.ones_like(u, float)], -1).reshape(-1, 3)
        R, o = T_world_cam[:3, :3], T_world_cam[:3, 3]
        d = rays_cam @ R.T
        with np.errstate(divide="ignore", invalid="ignore"):
            bound = np.where(d > 0, self.size, 0.0)
            t_axis = np.where(np.abs(d) > 1e-12, (bound - o) / d, np.inf)
        face_axis = np.argmin(t_axis, axis=1)
        t = t_axis[np.arange(len(d)), face_axis]
        hit = o + t[:, None] * d
        grey = np.zeros(len(d))
        for axis in range(3):
            a, b = [i for i in range(3) if i != axis]
            for side in (0, 1):
                sel = (face_axis == axis) & ((d[:, axis] > 0) == bool(side))
                tex = self.textures[(axis, side)]
                coords = np.stack([hit[sel, b] * PX_PER_M - 0.5, hit[sel, a] * PX_PER_M - 0.5])
                grey[sel] = map_coordinates(tex.astype(float), coords, order=1, mode="nearest")
        return grey.reshape(HEIGHT, WIDTH).astype(np.uint8), t.reshape(HEIGHT, WIDTH).astype(np.float32)


def look_at(eye: np.ndarray, target: np.ndarray) -> np.ndarray:
    """T_world_cam of a camera at ``eye`` looking at ``target`` with the world z axis up."""
    z = np.asarray(target, float) - np.asarray(eye, float)
    z /= np.linalg.norm(z)
    x = np.cross(z, [0.0, 0.0, 1.0])
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    T = np.eye(4)
    T[:3, :3] = np.stack([x, y, z], axis=1)
    T[:3, 3] = eye
    return T
