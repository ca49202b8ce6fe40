"""An analytic staircase seen by a pinhole camera (ray-rectangle intersection in numpy), shared by
the TSDF and plane-extraction tests: the independent truth their depth images come from."""

import numpy as np

RISER, TREAD, N_STEPS, X0, WIDTH = 0.17, 0.28, 4, 1.0, 1.6
W, H = 640, 480
K = np.array([[385.0, 0.0, 319.5], [0.0, 385.0, 239.5], [0.0, 0.0, 1.0]])


def faces():
    """The staircase (x up the stairs, z up): (kind, level, (lo, hi)) per face. Ground / tread:
    plane z = level for x in (lo, hi); riser: plane x = level for z in (lo, hi); |y| <= WIDTH/2."""
    out = [("flat", 0.0, (-5.0, X0))]
    for i in range(N_STEPS):
        xr = X0 + i * TREAD
        out.append(("riser", xr, (i * RISER, (i + 1) * RISER)))
        out.append(("flat", (i + 1) * RISER, (xr, xr + (TREAD if i < N_STEPS - 1 else 1.5))))
    return out


def face_planes():
    """(unit normal, offset) of each face, n . p = offset, normal towards a camera in front."""
    return [(np.array([0.0, 0.0, 1.0]), lvl) if kind == "flat" else (np.array([-1.0, 0.0, 0.0]), -lvl)
            for kind, lvl, _ in faces()]


def camera(x, pitch_deg, y=0.0, z=1.5, yaw_deg=0.0):
    """T_world_cam of an optical frame at (x, y, z) looking along +x, pitched down."""
    p, yw = np.radians(pitch_deg), np.radians(yaw_deg)
    fwd = np.array([np.cos(p) * np.cos(yw), np.cos(p) * np.sin(yw), -np.sin(p)])
    right = np.array([np.sin(yw), -np.cos(yw), 0.0])
    T = np.eye(4)
    T[:3, :3] = np.column_stack([right, np.cross(fwd, right), fwd])
    T[:3, 3] = [x, y, z]
    return T


def render(T, K=K, w=W, h=H):
    """z-depth (h, w) float32 (0 = nothing) and face index (-1 = nothing) seen from T."""
    v, u = np.mgrid[0:h, 0:w].astype(float)
    ray = np.stack([(u - K[0, 2]) / K[0, 0], (v - K[1, 2]) / K[1, 1], np.ones_like(u)], -1) @ T[:3, :3].T
    o = T[:3, 3]
    best = np.full((h, w), np.inf)
    fid = np.full((h, w), -1)
    with np.errstate(divide="ignore", invalid="ignore"):
        for k, (kind, lvl, (lo, hi)) in enumerate(faces()):
            a, b = (2, 0) if kind == "flat" else (0, 2)  # axis of the plane, axis of the range
            t = (lvl - o[a]) / ray[..., a]
            hit = (np.abs(o[1] + t * ray[..., 1]) <= WIDTH / 2) & (o[b] + t * ray[..., b] >= lo) \
                & (o[b] + t * ray[..., b] <= hi) & (t > 0) & (t < best)
            best[hit] = t[hit]
            fid[hit] = k
    return np.where(np.isfinite(best), best, 0.0).astype(np.float32), fid
