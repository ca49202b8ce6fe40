"""Per-pixel segmentation truth of an RGB-D frame: the geom, surface and object each pixel shows.

MuJoCo's segmentation pass gives the geom of every pixel. A geom may make up several listed
surfaces (a stair box: its tread and its riser; ``SceneTruth.geom_surfaces``), or none of the
face the camera sees (a box's side), so the surface comes from the pixel's point: the pixel is
back-projected with the camera's K and pose from the noise-free z-depth rendered in the same
pass, and of its geom's surfaces whose planes face the camera it shows the one whose plane
passes nearest the point, if within :func:`plane_tolerance_m` of it; otherwise none (-1). With
MuJoCo's float depth buffer the points lie within about 1e-6 m of their planes; the tolerance
(1 mm + 0.1 % of the depth) leaves room for coarser buffers and only mislabels points of an
unlisted face that close to a listed one (the edge between them). Objects (``SceneTruth.objects``) are found by their geom names.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from exobench.core import SceneTruth, SegmentationTruth

__all__ = ["SegmentationLabeler", "plane_tolerance_m"]

TOL_ABS_M = 1e-3  # plane tolerance at zero depth
TOL_REL = 1e-3  # plus this fraction of the depth


def plane_tolerance_m(depth_m: np.ndarray) -> np.ndarray:
    """Largest distance of a pixel's back-projected point from the plane of the surface it shows."""
    return TOL_ABS_M + TOL_REL * np.asarray(depth_m, dtype=float)


class SegmentationLabeler:
    """Labels the frames of one camera in one compiled world (geom ids of ``model``, surfaces and
    objects of ``truth``)."""

    def __init__(self, model: Any, truth: SceneTruth) -> None:
        import mujoco

        names = [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, i) or "" for i in range(model.ngeom)]
        index = {s.surface_id: k for k, s in enumerate(truth.surfaces)}
        self.surface_ids = np.array([s.surface_id for s in truth.surfaces], dtype=np.int32)
        self.normals = np.array([np.asarray(s.normal_w, dtype=float) for s in truth.surfaces]).reshape(-1, 3)
        self.offsets = np.einsum("sk,sk->s", self.normals, np.array([s.point_w for s in truth.surfaces], dtype=float).reshape(-1, 3))
        cands = [[index[i] for i in truth.geom_surfaces.get(n, ()) if i in index] for n in names]
        self.candidates = [np.array(c, dtype=np.int64) for c in cands]
        # has_surface[ngeom] (reached by geom id -1) is the background
        self.has_surface = np.array([len(c) > 0 for c in cands] + [False])
        self.objects = np.full(model.ngeom + 1, -1, dtype=np.int32)
        by_name = {n: g for g, n in enumerate(names) if n}
        for k, obj in enumerate(truth.objects):
            for n in obj.get("geom_names", ()):
                if n in by_name:
                    self.objects[by_name[n]] = k

    def label(self, stamp_s: float, sensor_id: str, geom_id: np.ndarray, depth_m: np.ndarray,
              T_world_sensor: np.ndarray, K: np.ndarray) -> SegmentationTruth:  # fmt: skip
        """The truth of one frame from its geom ids (H, W; -1 background) and noise-free z-depth
        (H, W, m; 0 no surface), rendered at the optical-frame pose ``T_world_sensor`` with ``K``."""
        geom_id = np.asarray(geom_id, dtype=np.int32)
        surface = np.full(geom_id.shape, -1, dtype=np.int32)
        z = np.asarray(depth_m, dtype=float)
        v, u = np.nonzero(self.has_surface[geom_id] & (z > 0))
        if len(u):
            zp = z[v, u]
            R, t = T_world_sensor[:3, :3], T_world_sensor[:3, 3]
            p_w = np.stack([(u - K[0, 2]) / K[0, 0] * zp, (v - K[1, 2]) / K[1, 1] * zp, zp], axis=1) @ R.T + t
            g = geom_id[v, u]
            order = np.argsort(g, kind="stable")
            groups, starts = np.unique(g[order], return_index=True)
            label = np.full(len(u), -1, dtype=np.int32)
            for gi, lo, hi in zip(groups, starts, [*starts[1:], len(order)]):
                idx = order[lo:hi]
                c = self.candidates[gi]  # this geom's surfaces (indices into the tables)
                n, off = self.normals[c], self.offsets[c]  # (k, 3), (k,)
                pn = p_w[idx] @ n.T  # (n, k)
                dist = np.abs(pn - off)
                dist[pn >= t @ n.T] = np.inf  # a visible face faces the camera
                if len(c) == 1:
                    best, dmin = np.zeros(len(idx), dtype=np.intp), dist[:, 0]
                else:
                    best = np.argmin(dist, axis=1)
                    dmin = np.take_along_axis(dist, best[:, None], axis=1)[:, 0]
                ok = dmin <= plane_tolerance_m(zp[idx])
                label[idx[ok]] = self.surface_ids[c[best[ok]]]
            surface[v, u] = label
        return SegmentationTruth(
            stamp_s=float(stamp_s), sensor_id=sensor_id, surface_id=surface, geom_id=geom_id.copy(),
            object_index=self.objects[geom_id],
        )  # fmt: skip
