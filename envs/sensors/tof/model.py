"""Time-of-flight ranging (ST VL53L1X) by MuJoCo ray casting from the sensor site along its +z.

A ray sees the world (geom group 0) and the exoskeleton (group 2) except the sensor's own
shank. One ray is the paper's model. With ``n_cone_rays > 1`` sub-rays fill the 27 deg cone
(the central ray plus a sunflower pattern, uniform in solid angle) and the reading is their
return-weighted mean (weight cos(incidence) / r^2, like the photon histogram of a SPAD sensor
averaging mixed targets: a deterministic bias near edges and on grazing surfaces, not extra
noise). When the weighted spread of the sub-ranges exceeds ``sigma_limit_m`` the reading is
flagged SIGMA_FAIL, as the device flags ranges whose estimated sigma is too large. The truth of
a frame is always the central ray's exact hit.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from exobench.core import SceneTruth, ToFReading, TofStatus, ToFTruth
from exobench.core.transforms import make_T
from exobench.envs.terrain import label_hits

from ..common import EXO_GROUP, WORLD_GROUP, sensor_rngs
from .config import ToFConfig


def cone_directions(n: int, fov_deg: float) -> np.ndarray:
    """Unit sub-ray directions in the sensor frame, (n, 3); the first is the axis +z."""
    out = [np.array([0.0, 0.0, 1.0])]
    if n > 1:
        half = np.radians(0.5 * fov_deg)
        k = np.arange(1, n)
        cos_t = 1.0 - (1.0 - np.cos(half)) * (k - 0.5) / (n - 1)
        sin_t = np.sqrt(1.0 - cos_t * cos_t)
        phi = k * np.pi * (3.0 - np.sqrt(5.0))  # golden angle
        out += list(np.column_stack([sin_t * np.cos(phi), sin_t * np.sin(phi), cos_t]))
    return np.array(out)


@dataclass
class _Obs:
    t: float
    T_world_sensor: np.ndarray
    range_m: float  # central ray, NaN when no hit
    hit_w: np.ndarray
    geom: int
    mixed_m: float  # cone mixture (= range_m for a single ray)
    spread_m: float


class ToFSensor:
    """One calf ToF sensor. Call :meth:`observe` at each measurement time (after MuJoCo's
    kinematics), then :meth:`frames` to turn the observations into frames and truth: once at the
    end, or after every few observations (each call takes the observations since the last one and
    the noise streams go on, so the frames are the same either way)."""

    def __init__(self, sensor_id: str, config: ToFConfig, model: object, seed: int) -> None:
        import mujoco

        self.sensor_id, self.config = sensor_id, config
        self.site = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, sensor_id)
        if self.site < 0:
            raise KeyError(f"model has no site {sensor_id!r}")
        self.body = int(model.site_bodyid[self.site])  # type: ignore[attr-defined]
        self.group = np.zeros(6, dtype=np.uint8)
        self.group[[WORLD_GROUP, EXO_GROUP]] = 1
        self.dirs_s = cone_directions(config.n_cone_rays, config.fov_deg)
        n = len(self.dirs_s)
        self._gid = np.zeros(n, dtype=np.int32)
        self._dist = np.zeros(n)
        self._nrm = np.zeros(3 * n)
        self._gid1 = np.zeros(1, dtype=np.int32)
        self._nrm1 = np.zeros(3)
        self.noise_rng, self.drop_rng = sensor_rngs(seed, sensor_id)
        self.obs: list[_Obs] = []

    def observe(self, model: object, data: object, t: float) -> None:
        import mujoco

        p = data.site_xpos[self.site].copy()  # type: ignore[attr-defined]
        R = data.site_xmat[self.site].reshape(3, 3).copy()  # type: ignore[attr-defined]
        if len(self.dirs_s) == 1:
            r = mujoco.mj_ray(model, data, p, R[:, 2].copy(), self.group, 1, self.body, self._gid1, self._nrm1)
            geom = int(self._gid1[0])
            ok = r >= 0.0 and geom >= 0
            r0 = float(r) if ok else np.nan
            mixed, spread = r0, 0.0
        else:
            dirs_w = self.dirs_s @ R.T
            mujoco.mj_multiRay(
                model, data, p, dirs_w.ravel(), self.group, 1, self.body, self._gid, self._dist, self._nrm, len(dirs_w), 1e6
            )
            hit = (self._gid >= 0) & (self._dist >= 0.0)
            geom = int(self._gid[0]) if hit[0] else -1
            r0 = float(self._dist[0]) if hit[0] else np.nan
            if np.any(hit):
                r = self._dist[hit]
                nrm = self._nrm.reshape(-1, 3)[hit]
                cos_inc = np.abs(np.einsum("ij,ij->i", nrm, dirs_w[hit]))
                w = np.maximum(cos_inc, 1e-3) / np.maximum(r, 1e-3) ** 2
                mixed = float(np.sum(w * r) / np.sum(w))
                spread = float(np.sqrt(np.sum(w * (r - mixed) ** 2) / np.sum(w)))
            else:
                mixed, spread = np.nan, 0.0
        hit_w = p + r0 * R[:, 2] if np.isfinite(r0) else np.full(3, np.nan)
        self.obs.append(_Obs(t, make_T(R, p), r0, hit_w, geom, mixed, spread))

    def frames(self, model: object, truth: SceneTruth) -> list[tuple[ToFReading, ToFTruth]]:
        """Frames with noise, quantisation, latency and dropout, each with its truth, of the
        observations since the last call."""
        import mujoco

        c = self.config
        n = len(self.obs)
        z = self.noise_rng.standard_normal(n)
        keep = self.drop_rng.random(n) >= c.dropout_prob
        names = [(mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, o.geom) or "") if o.geom >= 0 else "" for o in self.obs]
        hits = np.array([o.hit_w for o in self.obs]).reshape(-1, 3)
        surface = label_hits(truth, names, np.nan_to_num(hits, nan=1e9))
        out = []
        for k, o in enumerate(self.obs):
            if not keep[k]:
                continue
            if not np.isfinite(o.mixed_m):
                rng_m, status = np.nan, TofStatus.NO_TARGET
            elif not (c.min_range_m <= o.mixed_m <= c.max_range_m):
                rng_m, status = np.nan, TofStatus.OUT_OF_BOUNDS
            else:
                rng_m = o.mixed_m + c.noise_m * z[k]
                if c.resolution_m > 0:
                    rng_m = np.round(rng_m / c.resolution_m) * c.resolution_m
                status = TofStatus.VALID if o.spread_m <= c.sigma_limit_m else TofStatus.SIGMA_FAIL
            sid = int(surface[k]) if o.geom >= 0 else -1
            stamp = o.t + c.latency_s
            out.append(
                (
                    ToFReading(stamp, self.sensor_id, float(rng_m), int(status)),
                    ToFTruth(stamp, self.sensor_id, o.range_m, o.hit_w, sid, o.T_world_sensor),
                )
            )
        self.obs = []
        return out
